"""Small OSM files for tests, written from a local metric sketch (x east, y north in metres)."""

from __future__ import annotations

import math
from pathlib import Path

LAT0, LON0 = 48.0, 11.0
M_PER_DEG_LAT = 111_320.0


class OsmSketch:
    def __init__(self, lat0: float = LAT0, lon0: float = LON0):
        """``lat0``, ``lon0``: where the sketch's origin lies (default: Bavaria)."""
        self.lat0, self.lon0 = lat0, lon0
        self.nodes: dict[str, tuple[float, float, dict]] = {}
        self.ways: list[tuple[str, list[str], dict]] = []
        self.ids: dict[str, str] = {}  # sketch name -> numeric OSM node id (what netconvert needs)
        self._next_way = 1000

    def node(self, name: str, x: float, y: float, **tags) -> str:
        nid = self.ids.setdefault(name, str(len(self.ids) + 1))
        self.nodes[nid] = (x, y, {k.replace("__", ":"): v for k, v in tags.items()})
        return nid

    def way(self, names: list[str], **tags) -> str:
        self._next_way += 1
        wid = str(self._next_way)
        self.ways.append(
            (wid, [self.ids[n] for n in names], {k.replace("__", ":"): v for k, v in tags.items()})
        )
        return wid

    def write(self, path: Path) -> Path:
        lines = ["<?xml version='1.0' encoding='UTF-8'?>", '<osm version="0.6" generator="cosim-tests">']
        for nid, (x, y, tags) in self.nodes.items():
            lat = self.lat0 + y / M_PER_DEG_LAT
            lon = self.lon0 + x / (M_PER_DEG_LAT * math.cos(math.radians(self.lat0)))
            body = "".join(f'<tag k="{k}" v="{v}"/>' for k, v in tags.items())
            lines.append(f'  <node id="{nid}" version="1" lat="{lat:.8f}" lon="{lon:.8f}">{body}</node>')
        for wid, refs, tags in self.ways:
            body = "".join(f'<nd ref="{r}"/>' for r in refs) + "".join(
                f'<tag k="{k}" v="{v}"/>' for k, v in tags.items()
            )
            lines.append(f'  <way id="{wid}" version="1">{body}</way>')
        lines.append("</osm>")
        path.write_text("\n".join(lines) + "\n")
        return path


def crossroads(major: str = "primary", minor: str = "residential", arm_m: float = 300.0, centre_tags=None,
               major_tags=None, minor_tags=None, origin: tuple[float, float] = (LAT0, LON0)) -> OsmSketch:  # fmt: skip
    """A + junction "c" of an east-west major road and a north-south minor road, arms of ``arm_m``; its
    centre at ``origin`` (lat, lon)."""
    s = OsmSketch(*origin)
    s.node("c", 0, 0, **(centre_tags or {}))
    s.node("w", -arm_m, 0)
    s.node("e", arm_m, 0)
    s.node("s", 0, -arm_m)
    s.node("n", 0, arm_m)
    s.way(["w", "c", "e"], highway=major, **(major_tags or {}))
    s.way(["s", "c", "n"], highway=minor, **(minor_tags or {}))
    return s

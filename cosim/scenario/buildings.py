"""Building footprints (paper IV.A) in network coordinates, with heights; also the radio obstacles.

polyconvert projects OSM building ways (and multipolygon relations) with the network's projection; cosim
adds ``height_m`` to each: OSM ``height`` (metres, "12 m" or "12"), else ``building:levels`` x 3 m
(+ ``roof:levels`` x 1.5 m), else DEFAULT_HEIGHT_M (10 m, about three storeys: the median of tagged
buildings in the shipped extracts is 2-4 levels).
"""

from __future__ import annotations

import re
from pathlib import Path
from xml.etree import ElementTree as ET
from xml.sax.saxutils import quoteattr

from cosim.errors import CosimError
from cosim.sumo_bridge.tools import ToolRun, run_tool

TYPE_FILE = Path(__file__).parent / "netconvert" / "buildings.typ.xml"
DEFAULT_HEIGHT_M = 10.0
LEVEL_HEIGHT_M = 3.0
ROOF_LEVEL_HEIGHT_M = 1.5
_NUMBER = re.compile(r"^\s*(\d+(?:[.,]\d+)?)")


def _number(text: str | None) -> float | None:
    if not text:
        return None
    m = _NUMBER.match(text)
    return float(m.group(1).replace(",", ".")) if m else None


def building_height_m(params: dict[str, str]) -> tuple[float, str]:
    """Height of a building from its OSM tags and where it came from ('height' | 'levels' | 'default')."""
    h = _number(params.get("height"))
    if h is not None and h > 0:
        return h, "height"
    levels = _number(params.get("building:levels"))
    if levels is not None and levels > 0:
        roof = _number(params.get("roof:levels")) or 0.0
        return levels * LEVEL_HEIGHT_M + roof * ROOF_LEVEL_HEIGHT_M, "levels"
    return DEFAULT_HEIGHT_M, "default"


def build_buildings(osm_path: Path, net_file: Path, out: Path) -> tuple[int, dict[str, int], ToolRun]:
    """polyconvert the buildings into ``out`` (with height_m); returns count, height sources, tool run."""
    raw = out.with_suffix(".raw.xml")
    run = run_tool(
        "polyconvert",
        ["--net-file", str(net_file), "--osm-files", str(osm_path), "--type-file", str(TYPE_FILE),
         "--all-attributes", "true", "--osm.merge-relations", "1", "--ignore-errors", "true",
         "--output-file", str(raw)],
    )  # fmt: skip
    if run.returncode != 0 or not raw.exists():
        raise CosimError(f"polyconvert failed on {osm_path}: {(run.errors or ['no output'])[0]}")
    sources = {"height": 0, "levels": 0, "default": 0}
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', "<additional>"]
    count = 0
    for poly in ET.parse(raw).getroot().iter("poly"):
        params = {p.get("key"): p.get("value") for p in poly.iter("param")}
        if "building" not in params or len(set(poly.get("shape").split())) < 3:
            continue  # polyconvert also emits non-building areas and open ways
        height, source = building_height_m(params)
        sources[source] += 1
        count += 1
        keep = {k: v for k, v in params.items() if k in ("building", "height", "building:levels", "name")}
        body = "".join(f"<param key={quoteattr(k)} value={quoteattr(v)}/>" for k, v in sorted(keep.items()))
        body += f'<param key="height_m" value="{height:.1f}"/><param key="height_source" value="{source}"/>'
        lines.append(
            f'    <poly id={quoteattr(poly.get("id"))} type="building" color="204,184,166" fill="1" '
            f'layer="1" shape={quoteattr(poly.get("shape"))}>{body}</poly>'
        )
    lines.append("</additional>")
    out.write_text("\n".join(lines) + "\n")
    raw.unlink()
    return count, sources, run


def load_buildings(path: str | Path):
    """Building footprints as (list of shapely Polygons, heights [m] as a numpy array)."""
    import numpy as np
    import shapely

    polys, heights = [], []
    for poly in ET.parse(path).getroot().iter("poly"):
        pts = [tuple(map(float, p.split(","))) for p in poly.get("shape").split()]
        if len(pts) < 3:
            continue
        geom = shapely.make_valid(shapely.Polygon(pts))
        if geom.is_empty or geom.area <= 0:
            continue
        if geom.geom_type != "Polygon":  # make_valid may split self-intersecting outlines
            parts = [g for g in getattr(geom, "geoms", []) if g.geom_type == "Polygon" and g.area > 0]
            if not parts:
                continue
            geom = max(parts, key=lambda g: g.area)
        h = next(
            (float(p.get("value")) for p in poly.iter("param") if p.get("key") == "height_m"),
            DEFAULT_HEIGHT_M,
        )
        polys.append(geom)
        heights.append(h)
    return polys, np.asarray(heights, dtype=np.float64)


def indexed_buildings(path: str | Path):
    """A scenario's footprints indexed for the radio's shadowing and system A (``cosim.buildings.Buildings``)."""
    from cosim.buildings import Buildings

    return Buildings(load_buildings(path)[0])

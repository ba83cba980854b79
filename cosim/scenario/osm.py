"""The OSM pre-pass: validate an OSM file and collect what netconvert drops.

netconvert ignores ``highway=stop`` / ``highway=give_way`` nodes (and turns non-junction nodes into plain
geometry), so cosim reads them here, together with the direction they apply to, city-limit signs and the
node coordinates needed to project them onto the network.
"""

from __future__ import annotations

import gzip
import math
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from xml.etree import ElementTree as ET

from cosim.errors import CosimError

# Highway types used by motorized traffic (paper IV.A); pedestrian / cycle-only ways are dropped.
MOTORIZED_HIGHWAYS = (
    "motorway", "motorway_link", "trunk", "trunk_link", "primary", "primary_link", "secondary",
    "secondary_link", "tertiary", "tertiary_link", "unclassified", "residential", "living_street", "service",
)  # fmt: skip
# Road types on which SCVs may be generated (paper V.A).
SPAWN_HIGHWAYS = ("primary", "secondary", "tertiary", "unclassified", "motorway", "residential")

CITY_LIMIT_SIGNS = ("city_limit", "DE:310", "AT:53", "FI:571")  # traffic_sign values that mark a city limit


@dataclass(frozen=True)
class SignNode:
    """An explicit sign or signal mapped on an OSM node."""

    node_id: str
    kind: str  # "stop" | "allway_stop" | "give_way" | "traffic_signals" | "city_limit"
    lat: float
    lon: float
    direction: str | None  # "forward" | "backward" relative to the way, or None (applies at the node)
    tags: dict[str, str] = field(default_factory=dict)


@dataclass
class OsmInfo:
    path: Path
    bounds: tuple[float, float, float, float] | None  # minlat, minlon, maxlat, maxlon
    n_nodes: int
    n_ways: int
    n_buildings: int
    highway_counts: dict[str, int]
    signs: list[SignNode]
    # node lists of the motorized ways that carry a directional sign node (to find where it applies)
    sign_ways: dict[str, list[str]]
    node_coords: dict[str, tuple[float, float]]  # lat, lon of the nodes of sign_ways
    oneway_ways: int
    centre: tuple[float, float] | None = None  # lat, lon of the middle of the nodes' extent

    @property
    def n_drivable_ways(self) -> int:
        return sum(self.highway_counts.get(h, 0) for h in MOTORIZED_HIGHWAYS)


def _open(path: Path):
    with path.open("rb") as fh:
        magic = fh.read(2)
    return gzip.open(path, "rb") if magic == b"\x1f\x8b" else path.open("rb")


def _classify(tags: dict[str, str]) -> str | None:
    hw = tags.get("highway")
    if hw == "stop":
        return "allway_stop" if tags.get("stop") == "all" else "stop"
    if hw == "give_way":
        return "give_way"
    if hw == "traffic_signals":
        return "traffic_signals"
    if any(v in tags.get("traffic_sign", "") for v in CITY_LIMIT_SIGNS):
        return "city_limit"
    return None


def _centre(lat_lo, lat_hi, lon_lo, lon_hi, lon360_lo, lon360_hi) -> tuple[float, float]:
    """(lat, lon) of the middle of the nodes' extent; an extract across the antimeridian (Fiji, Chukotka)
    spans less in 0..360 degrees than in -180..180."""
    if lon360_hi - lon360_lo < lon_hi - lon_lo:
        lon = (lon360_lo + lon360_hi) / 2
        return (lat_lo + lat_hi) / 2, lon - 360.0 if lon >= 180.0 else lon
    return (lat_lo + lat_hi) / 2, (lon_lo + lon_hi) / 2


def read_osm(path: str | Path) -> OsmInfo:
    """Parse and validate an OSM XML file (plain or gzip). Bad input raises CosimError with one clear line."""
    path = Path(path)
    if not path.is_file():
        raise CosimError(f"OSM file {path} does not exist")
    with open(path, "rb") as fh:
        head = fh.read(64)
    # a PBF file's first blob header names its type (wiki.openstreetmap.org/wiki/PBF_Format)
    if b"OSMHeader" in head:
        raise CosimError(
            f"{path} is OSM PBF; cosim (like netconvert) reads OSM XML (.osm or .osm.gz): convert it first, "
            f"e.g. `osmium cat {path.name} -o {path.name.removesuffix('.pbf').removesuffix('.osm')}.osm.gz`"
        )
    coords: dict[str, tuple[float, float]] = {}
    signs: list[SignNode] = []
    sign_node_ids: set[str] = set()
    way_nodes: dict[str, list[str]] = {}
    highway_counts: dict[str, int] = {}
    n_nodes = n_ways = n_buildings = oneway = 0
    lat_lo = lon_lo = lon360_lo = math.inf
    lat_hi = lon_hi = lon360_hi = -math.inf
    bounds = None
    root_seen = False
    try:
        with _open(path) as fh:
            for event, elem in ET.iterparse(fh, events=("start", "end")):
                if event == "start":
                    if not root_seen:
                        root_seen = True
                        if elem.tag != "osm":
                            raise CosimError(
                                f"{path} is not an OpenStreetMap XML file (root element <{elem.tag}>, expected <osm>)"
                            )
                    continue
                tag = elem.tag
                if tag == "node":
                    n_nodes += 1
                    nid = elem.get("id")
                    lat, lon = float(elem.get("lat")), float(elem.get("lon"))
                    coords[nid] = (lat, lon)
                    lat_lo, lat_hi = min(lat_lo, lat), max(lat_hi, lat)
                    lon_lo, lon_hi = min(lon_lo, lon), max(lon_hi, lon)
                    lon360_lo, lon360_hi = min(lon360_lo, lon % 360.0), max(lon360_hi, lon % 360.0)
                    if len(elem):
                        tags = {t.get("k"): t.get("v") for t in elem.iter("tag")}
                        kind = _classify(tags)
                        if kind:
                            direction = tags.get("direction")
                            if direction not in ("forward", "backward"):
                                direction = None
                            signs.append(SignNode(nid, kind, lat, lon, direction, tags))
                            sign_node_ids.add(nid)
                    elem.clear()
                elif tag == "way":
                    n_ways += 1
                    tags = {t.get("k"): t.get("v") for t in elem.iter("tag")}
                    if "building" in tags:
                        n_buildings += 1
                    hw = tags.get("highway")
                    if hw:
                        highway_counts[hw] = highway_counts.get(hw, 0) + 1
                        if hw in MOTORIZED_HIGHWAYS:
                            refs = [nd.get("ref") for nd in elem.iter("nd")]
                            if sign_node_ids.intersection(refs):
                                way_nodes[elem.get("id")] = refs
                            if tags.get("oneway") in ("yes", "1", "-1", "true"):
                                oneway += 1
                    elem.clear()
                elif tag == "bounds":
                    bounds = tuple(float(elem.get(k)) for k in ("minlat", "minlon", "maxlat", "maxlon"))
                elif tag == "relation":
                    elem.clear()
    except CosimError:
        raise
    except ET.ParseError as exc:
        line = exc.position[0] if getattr(exc, "position", None) else "?"
        raise CosimError(
            f"{path} is not valid OSM XML (parse error at line {line}): the file is corrupt or truncated"
        ) from None
    except (EOFError, OSError, zlib.error) as exc:
        raise CosimError(f"{path} cannot be read: {exc} (truncated or corrupt .osm.gz?)") from None
    except (TypeError, ValueError):
        raise CosimError(f"{path} has a node without valid lat/lon: not a usable OSM file") from None
    if not root_seen:
        raise CosimError(f"{path} is empty")
    info = OsmInfo(
        path=path, bounds=bounds, n_nodes=n_nodes, n_ways=n_ways, n_buildings=n_buildings,
        highway_counts=highway_counts, signs=signs, sign_ways=way_nodes,
        node_coords={n: coords[n] for refs in way_nodes.values() for n in refs if n in coords},
        oneway_ways=oneway, centre=_centre(lat_lo, lat_hi, lon_lo, lon_hi, lon360_lo, lon360_hi) if n_nodes else None,
    )  # fmt: skip
    if info.n_drivable_ways == 0:
        raise CosimError(
            f"{path} has no drivable road (no way tagged highway={'|'.join(MOTORIZED_HIGHWAYS[:6])}|...); "
            "choose an extract that contains streets"
        )
    return info

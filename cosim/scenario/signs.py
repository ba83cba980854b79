"""Every traffic sign the paper lists (IV.A), with position and heading, as a SUMO additional of POIs.

Each sign is ``<poi type="sign.<kind>" x y angle>`` with params ``kind``, ``heading_deg`` (direction of the
traffic the sign applies to, SUMO compass degrees), ``edge`` (the edge it stands on), ``value`` (km/h for
speed limits) and ``source``; sumo-gui shows them and ``load_signs`` reads them back. Kinds:

- explicit: ``stop``, ``allway_stop``, ``give_way`` (from OSM nodes, see network.py), ``traffic_light`` (one per
  signalised approach), ``city_limit`` (OSM traffic_sign=city_limit nodes, both directions);
- implicit: ``speed_limit`` at the start of an edge whose speed differs from the road it continues, for
  both directions; ``source`` says whether the limit is tagged (``maxspeed``), implied by a zone / city
  limit (``zone``) or by the road type (``road_type``); ``one_way`` where a one-way road leaves a junction
  that two-way roads meet, and ``no_entry`` at the one-way road's other end.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree as ET
from xml.sax.saxutils import quoteattr

from cosim.scenario.network import is_turning_loop

SIGN_SIDE_OFFSET_M = 1.0  # from the kerb-side edge of the road (the right one in right-hand traffic)
SPEED_CHANGE_MIN_MPS = 0.5
SIGN_KINDS = (
    "stop",
    "allway_stop",
    "give_way",
    "traffic_light",
    "speed_limit",
    "city_limit",
    "one_way",
    "no_entry",
)


@dataclass(frozen=True)
class Sign:
    kind: str
    x_m: float
    y_m: float
    heading_deg: float  # compass heading of the traffic it applies to
    edge: str
    value: float | None = None  # speed limit [km/h]
    source: str = ""


def _heading_deg(dx: float, dy: float) -> float:
    return math.degrees(math.atan2(dx, dy)) % 360.0


def _roadside(edge, at_end: bool, lefthand: bool = False) -> tuple[float, float, float]:
    """Point beside the kerb-side edge of the road (right, or left in left-hand traffic) at the start or end
    of ``edge``, and the travel heading."""
    shape = edge.getShape()
    (x0, y0), (x1, y1) = (shape[-2][:2], shape[-1][:2]) if at_end else (shape[0][:2], shape[1][:2])
    n = math.hypot(x1 - x0, y1 - y0) or 1.0
    ux, uy = (x1 - x0) / n, (y1 - y0) / n
    half_width = sum(lane.getWidth() for lane in edge.getLanes()) / 2
    off = (half_width + SIGN_SIDE_OFFSET_M) * (-1.0 if lefthand else 1.0)
    px, py = (x1, y1) if at_end else (x0, y0)
    return px + uy * off, py - ux * off, _heading_deg(ux, uy)


def _speed_source(edge) -> str:
    params = edge.getParams()
    tagged = params.get("maxspeed", "")
    if tagged and tagged.replace(".", "", 1).split(" ")[0].isdigit():
        return "maxspeed"
    if tagged or any(
        k in params for k in ("source:maxspeed", "maxspeed:type", "zone:maxspeed", "zone:traffic")
    ):
        return "zone"
    return "road_type"


def _is_oneway(edge) -> bool:
    frm, to = edge.getFromNode(), edge.getToNode()
    return not any(e.getToNode() is frm for e in to.getOutgoing())


def derive_signs(net, placements, junction_kind, tls_approaches, osm_signs) -> list[Sign]:
    signs: list[Sign] = []
    roadside = functools.partial(_roadside, lefthand=net.lefthand)

    # explicit stop / give-way: on each governed approach (an approach sign) or each minor approach
    from cosim.scenario.network import _minor_incoming

    for jid, kind in sorted(junction_kind.items()):
        node = net.getNode(jid)
        signed = {e for p in placements if p.junction == jid for e in p.approach_edges}
        approaches = (
            _minor_incoming(node, signed)
            if kind != "allway_stop"
            else [e for e in node.getIncoming() if e.getFunction() != "internal"]
        )
        for edge in approaches:
            x, y, h = roadside(edge, at_end=True)
            signs.append(Sign(kind, x, y, h, edge.getID(), source="osm"))
    for eid in tls_approaches:
        x, y, h = roadside(net.getEdge(eid), at_end=True)
        signs.append(Sign("traffic_light", x, y, h, eid, source="osm"))
    # implicit speed limits and one-way / no-entry signs, junction by junction
    for node in net.getNodes():
        if is_turning_loop(node.getID()):
            continue
        incoming = [e for e in node.getIncoming() if e.getFunction() != "internal"]
        outgoing = [e for e in node.getOutgoing() if e.getFunction() != "internal"]
        two_way_here = any(not _is_oneway(e) for e in incoming + outgoing)
        for out in outgoing:
            continued = [
                c.getFrom() for e in incoming for c in e.getConnections(out) if c.getDirection() == "s"
            ]
            if is_turning_loop(out.getID()) or any(is_turning_loop(e.getID()) for e in continued):
                continue  # the road on beyond the map's edge and back: no sign of the town's
            if any(abs(e.getSpeed() - out.getSpeed()) > SPEED_CHANGE_MIN_MPS for e in continued):
                x, y, h = roadside(out, at_end=False)
                signs.append(
                    Sign("speed_limit", x, y, h, out.getID(), round(out.getSpeed() * 3.6), _speed_source(out))
                )
            if two_way_here and _is_oneway(out) and len(incoming) + len(outgoing) > 2:
                x, y, h = roadside(out, at_end=False)
                signs.append(Sign("one_way", x, y, h, out.getID(), source="oneway"))
        for inc in incoming:
            if two_way_here and _is_oneway(inc) and len(incoming) + len(outgoing) > 2:
                x, y, h = roadside(inc, at_end=True)  # faces drivers who would enter against the one-way
                signs.append(Sign("no_entry", x, y, (h + 180.0) % 360.0, inc.getID(), source="oneway"))
    # city limits from OSM nodes: on the nearest edges, both directions
    for s in osm_signs:
        if s.kind != "city_limit":
            continue
        x, y = net.convertLonLat2XY(s.lon, s.lat)
        near = sorted(net.getNeighboringEdges(x, y, 25.0), key=lambda ed: (ed[1], ed[0].getID()))
        seen_dirs = set()
        for edge, _ in near:
            if edge.getFunction() == "internal":
                continue
            _, _, h = roadside(edge, at_end=False)
            key = round(h / 90.0) % 4
            if key in seen_dirs or (key + 2) % 4 in seen_dirs and len(seen_dirs) >= 2:
                continue
            seen_dirs.add(key)
            signs.append(Sign("city_limit", x, y, h, edge.getID(), source="osm"))
            if len(seen_dirs) == 2:
                break
    return signs


def write_signs(signs: list[Sign], path: Path) -> None:
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', "<additional>"]
    for i, s in enumerate(signs):
        params = [
            ("kind", s.kind),
            ("heading_deg", f"{s.heading_deg:.1f}"),
            ("edge", s.edge),
            ("source", s.source),
        ]
        if s.value is not None:
            params.append(("value", f"{s.value:g}"))
        body = "".join(f"<param key={quoteattr(k)} value={quoteattr(v)}/>" for k, v in params)
        lines.append(
            f'    <poi id="sign_{i}" type="sign.{s.kind}" x="{s.x_m:.2f}" y="{s.y_m:.2f}" '
            f'angle="{s.heading_deg:.1f}" layer="5" color="{_COLORS[s.kind]}">{body}</poi>'
        )
    lines.append("</additional>")
    path.write_text("\n".join(lines) + "\n")


_COLORS = {
    "stop": "red", "allway_stop": "red", "give_way": "orange", "traffic_light": "green", "speed_limit": "white",
    "city_limit": "yellow", "one_way": "blue", "no_entry": "red",
}  # fmt: skip


def load_signs(path: str | Path) -> list[Sign]:
    out = []
    for poi in ET.parse(path).getroot().iter("poi"):
        p = {e.get("key"): e.get("value") for e in poi.iter("param")}
        out.append(Sign(p["kind"], float(poi.get("x")), float(poi.get("y")), float(p["heading_deg"]), p["edge"],
                        float(p["value"]) if "value" in p else None, p.get("source", "")))  # fmt: skip
    return out

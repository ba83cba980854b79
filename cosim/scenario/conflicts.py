"""Geometric checks of netconvert's junctions: movements that cross but are not foes, impossible U-turns.

netconvert decides which connections of a junction conflict from the topology of the edges (directions,
angles), not from the shapes of the internal lanes it builds (SUMO issue #3155: sharp angles and small radii
underestimate the gaps). At the small, irregular junctions OSM produces (clusters of nodes a few metres
apart, bent roads, service roads joining at odd angles) two movements then pass closer than a car's width,
or cross outright, while neither waits for the other: with ``collision.check-junctions`` SUMO reports a
collision whenever both are used at once. Measured on the Krems network: 70 such pairs (41 on Monaco, 105 on
Helsinki), among them the junctions where the collisions of plain SUMO runs happened.

``geometric_prohibitions`` finds every pair of connections of a junction whose paths (the internal lanes plus
the ends of the lanes they join, where a car's body still is) come closer than a car's width plus a margin
without a foe relation, and returns a netconvert ``<prohibition>`` for it: the lower-ranked movement
yields to the higher-ranked one (major before minor, straight before right before left before U-turn; in
left-hand traffic straight before left before right).
``turnaround_deletions`` removes U-turns at junctions that are not dead ends (netconvert's turnarounds, turns
onto another road that reverse the heading within a car's length, and turns back to the junction just left
within a car's turning half circle): on a two-lane street a car cannot turn on the spot, and SUMO's
turnaround lane sweeps across the movements of the whole junction.
``sibling_change_bars`` bars lane changes inside a junction into a lane that another movement of the same
incoming lane runs beside (SUMO's lane changer does not see that one). ``separated_shapes`` gives custom
internal-lane shapes to movements that run side by side closer than two car widths without crossing: SUMO
relates foes inside a junction only by a crossing point, so such a pair is never kept apart there, foes or
not. ``approach_end_offsets`` moves a road's stop line back where another movement runs over its last metres,
so that the two cross inside the junction.
"""

from __future__ import annotations

import functools
import itertools
import math
import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

VEHICLE_WIDTH_M = 1.8  # the widest SCV body (SUMO's passenger default) [m]
CLEARANCE_MARGIN_M = 0.3  # paths closer than width + margin conflict [m]
LANE_END_M = 3.0  # how much of the incoming / outgoing lane a car at the junction still covers [m]
# a lane change takes 4.6 s on average, 1-13 s (Toledo & Zohar 2007, "Modeling duration of lane changes",
# Transportation Research Record 1999): a road shorter than this at its speed limit leaves no room for one
LANE_CHANGE_S = 4.6

# straight before the turn to the kerb side before the one across the oncoming lanes before a U-turn: in
# right-hand traffic s, R, r, L, l, t (left-hand traffic mirrors the turns: MIRRORED_DIR)
_DIR_RANK = {"s": 0, "R": 1, "r": 2, "L": 3, "l": 4, "t": 5}
MIRRORED_DIR = {"r": "l", "R": "L", "l": "r", "L": "R"}
_MAJOR = set("MOGgs=w")  # link states of movements that do not yield by default


@dataclass
class _Conn:
    from_edge: str
    from_lane: str
    to_edge: str
    to_lane: str
    direction: str  # SUMO's (l: a turn to the left, whichever side traffic keeps to)
    state: str
    chain: list[str] = field(default_factory=list)
    lefthand: bool = False  # the network's traffic keeps to the left


def _shape(s: str) -> list[tuple[float, float]]:
    return [tuple(map(float, p.split(",")[:2])) for p in s.split()]  # type: ignore[misc]


def _read(net_file: Path):
    """(lane shapes, junctions, internal junctions) of a network file. The passes of one fix round read the
    same file (north-bayreuth, ~2,000 junctions: 32 parses in 4 rounds, 18 of the build's 141 s in a profile):
    the last one is kept, keyed by the file's path, modification time and size, and shared (no pass changes
    what it gets)."""
    st = os.stat(net_file)
    return _parse(str(Path(net_file).resolve()), st.st_mtime_ns, st.st_size)


@functools.lru_cache(maxsize=1)
def _parse(net_file: str, _mtime_ns: int, _size: int):
    root = ET.parse(net_file).getroot()
    lefthand = root.get("lefthand") == "true"
    shapes: dict[str, list] = {}
    for edge in root.iter("edge"):
        for lane in edge.iter("lane"):
            shapes[lane.get("id")] = _shape(lane.get("shape", ""))
    conns: list[_Conn] = []
    cont: dict[str, str] = {}
    for c in root.iter("connection"):
        frm, via = c.get("from", ""), c.get("via")
        if frm.startswith(":"):
            if via:
                cont[f"{frm}_{c.get('fromLane')}"] = via
            continue
        if not via:
            continue
        conns.append(_Conn(frm, f"{frm}_{c.get('fromLane')}", c.get("to", ""), f"{c.get('to')}_{c.get('toLane')}",
                           c.get("dir", ""), c.get("state", ""), [via], lefthand))  # fmt: skip
    by_lane: dict[str, _Conn] = {}
    for c in conns:
        while c.chain[-1] in cont:
            c.chain.append(cont[c.chain[-1]])
        for lane in c.chain:
            by_lane[lane] = c
    junctions, internal = [], []
    for j in root.iter("junction"):
        if j.get("type") == "internal":
            waiting = by_lane.get(j.get("id", ""))  # the internal junction is named after the lane behind it
            internal.append((waiting, [by_lane.get(lane) for lane in j.get("intLanes", "").split()]))
            continue
        if j.get("type") == "dead_end":
            continue
        int_lanes = j.get("intLanes", "").split()
        foes = {int(r.get("index")): r.get("foes", "") for r in j.iter("request")}
        junctions.append((j.get("id"), [by_lane.get(lane) for lane in int_lanes], foes))
    return shapes, junctions, internal


def _cut(shape, length: float, from_end: bool):
    """The last (from_end) or first ``length`` metres of a polyline."""
    import shapely
    import shapely.ops

    line = shapely.LineString(shape)
    if line.length <= length:
        return list(line.coords)
    part = shapely.ops.substring(line, line.length - length, line.length) if from_end else \
        shapely.ops.substring(line, 0.0, length)  # fmt: skip
    return list(part.coords)


def _rank(c: _Conn) -> tuple:
    turn = MIRRORED_DIR.get(c.direction, c.direction) if c.lefthand else c.direction
    return (0 if c.state in _MAJOR else 1, _DIR_RANK.get(turn, 6))


def _ref(c: _Conn) -> str:
    """The attributes that name connection ``c`` in a connection file."""
    return (
        f"from={quoteattr(c.from_edge)} to={quoteattr(c.to_edge)} "
        f'fromLane="{c.from_lane.rsplit("_", 1)[1]}" toLane="{c.to_lane.rsplit("_", 1)[1]}"'
    )


def _delete_line(c: _Conn) -> str:
    return f"    <delete {_ref(c)}/>"


def _lanes_into(conns: list[_Conn]) -> dict[tuple[str, str], set[str]]:
    """(from edge, to edge) -> the from lanes of ``conns`` that lead from the one road into the other."""
    into: dict[tuple[str, str], set[str]] = {}
    for c in conns:
        into.setdefault((c.from_edge, c.to_edge), set()).add(c.from_lane)
    return into


def _lane_to_delete(a: _Conn, b: _Conn, into: dict[tuple[str, str], set[str]]) -> _Conn | None:
    """Of two movements that must not be used together, the lower-ranked one when another lane of its road
    still leads into the same road (cars change lanes before the junction), else the other one, else None;
    the one chosen is taken out of ``into``."""
    hi, lo = (a, b) if _rank(a) <= _rank(b) else (b, a)
    for c in (lo, hi):
        lanes = into[(c.from_edge, c.to_edge)]
        if c.from_lane in lanes and len(lanes) > 1:
            lanes.discard(c.from_lane)
            return c
    return None


def geometric_prohibitions(net_file: Path, skip: set[tuple[str, str]] = frozenset(),
                           clearance_m: float = VEHICLE_WIDTH_M + CLEARANCE_MARGIN_M):  # fmt: skip
    """``<prohibition>`` lines for connection pairs that come within ``clearance_m`` without being foes,
    and the list of (junction, prohibitor, prohibited, distance) behind them."""
    import shapely

    shapes, junctions, _ = _read(net_file)
    found: dict[tuple, tuple] = {}
    for jid, conns, foes in junctions:
        n = len(conns)
        if not foes or n < 2 or any(c is None for c in conns):
            continue
        paths = []
        for c in conns:
            pts = _cut(shapes[c.from_lane], LANE_END_M, True)
            for lane in c.chain:
                pts += shapes[lane]
            pts += _cut(shapes[c.to_lane], LANE_END_M, False)
            paths.append(shapely.LineString(pts))
        for i, k in itertools.combinations(range(n), 2):
            a, b = conns[i], conns[k]
            if (a.from_edge, a.to_edge) in skip or (b.from_edge, b.to_edge) in skip:
                continue  # deleted in the same pass
            if a is b or a.from_lane == b.from_lane or (a.from_edge, a.to_edge) == (b.from_edge, b.to_edge):
                continue  # one after the other on the same lane; or one movement's lanes (netconvert keeps them apart)
            if foes.get(i, "")[n - 1 - k : n - k] == "1" or foes.get(k, "")[n - 1 - i : n - i] == "1":
                continue
            d = paths[i].distance(paths[k])
            if d >= clearance_m:
                continue
            hi, lo = (a, b) if _rank(a) <= _rank(b) else (b, a)
            key = ((hi.from_edge, hi.to_edge), (lo.from_edge, lo.to_edge))
            if key[::-1] in found:  # already related the other way round (another lane pair)
                continue
            found.setdefault(key, (jid, round(d, 2)))
    lines = [
        f"    <prohibition prohibitor={quoteattr(f'{p[0]}->{p[1]}')} prohibited={quoteattr(f'{q[0]}->{q[1]}')}/>"
        for (p, q) in sorted(found)
    ]
    return lines, [(j, p, q, d) for (p, q), (j, d) in sorted(found.items())]


CAR_LENGTH_M = 5.0  # the longest SCV body waiting at an internal junction [m]
# a movement that reverses its heading by more than this is a U-turn, whatever netconvert calls it [deg]
U_TURN_DEG = 150.0
# AASHTO's passenger-car design vehicle turns on this minimum radius (A Policy on Geometric Design of Highways
# and Streets, 2011, Table 2-2b) [m]
MIN_TURN_RADIUS_M = 7.3


def _is_u_turn(conn) -> bool:
    """netconvert's turnaround ("t"), or a turn onto another road that reverses the heading within a car's
    length, which no car can (AASHTO's passenger-car design vehicle turns on a 7.3-m minimum radius: A
    Policy on Geometric Design of Highways and Streets, 2011, Table 2-2b). Monaco 258068679: a "left" from
    -159170450#1 into 33749606, which starts 2.1 m away heading back the way the car came; SUMO's loop
    ends with the car's rear over the stop line of its own approach, where the next car straight on ran
    into it: 13 of Monaco's 18 collisions in 10 seeds of plain SUMO."""
    if conn.getDirection() == "t":
        return True
    if _osm_way(conn.getFrom().getID()) == _osm_way(conn.getTo().getID()):
        return False  # the road's own way on (a hairpin OSM draws with few nodes): cars drive it
    if _short_loop(conn.getFrom(), conn.getTo()):
        return True
    return _reverses_within(conn.getFromLane().getShape(), conn.getToLane().getShape(), CAR_LENGTH_M)


# the design car turning round on its minimum radius drives a half circle; a way back to the junction just
# left that is shorter than this is a U-turn too
U_TURN_LOOP_M = math.pi * MIN_TURN_RADIUS_M


def _short_loop(edge, to_edge) -> bool:
    """Whether turning from ``edge`` into ``to_edge`` leads back to the junction ``edge`` left within
    U_TURN_LOOP_M of road, and every way on through that loop either turns round or is a movement the
    junction has directly. Krems 83637441 before its two lights 0.2 m apart were joined (network.py,
    junction_joins): SCVs that A* sent back up Hafenstrasse turned round through both links, and one
    stood at the red crosswise over the next lane, where a car going straight on hit it. Junctions that
    stay apart form the same loop: Krems 25096356#1 -> 59606607 -> 25096356#1, 11.7 m."""
    start = edge.getFromNode()
    if not (to_edge.getToNode() is start and edge.getToNode() is not start
            and edge.getLength() + to_edge.getLength() < U_TURN_LOOP_M):  # fmt: skip
        return False
    return all(
        on is edge or on in into.getOutgoing() or _reverses(into, on)
        for into in edge.getIncoming()
        for on in to_edge.getOutgoing()
    )


def _heading_change_deg(a_shape, b_shape) -> float:
    """The change of heading from the end of polyline ``a_shape`` to the start of ``b_shape`` [deg]."""
    heading_in = math.atan2(a_shape[-1][1] - a_shape[-2][1], a_shape[-1][0] - a_shape[-2][0])
    heading_out = math.atan2(b_shape[1][1] - b_shape[0][1], b_shape[1][0] - b_shape[0][0])
    return abs(math.degrees((heading_out - heading_in + math.pi) % (2 * math.pi) - math.pi))


def _reverses_within(a_shape, b_shape, within_m: float) -> bool:
    """Whether going from the end of polyline ``a_shape`` to the start of ``b_shape``, less than ``within_m``
    away, reverses the heading (more than U_TURN_DEG)."""
    if len(a_shape) < 2 or len(b_shape) < 2 or math.dist(a_shape[-1], b_shape[0]) >= within_m:
        return False
    return _heading_change_deg(a_shape, b_shape) > U_TURN_DEG


def _reverses(edge, to_edge) -> bool:
    return _heading_change_deg(edge.getLane(0).getShape(), to_edge.getLane(0).getShape()) > U_TURN_DEG


def _osm_way(edge_id: str) -> str:
    """The OSM way (and direction) an edge comes from: netconvert splits way 123 into 123#0, 123#1, ..."""
    return edge_id.split("#")[0]


# A dead end's turnaround stays only where a car can turn round clear of the junction it came from: on a road
# at least a turning circle long (AASHTO's passenger-car design vehicle, 7.3-m minimum radius: 14.6 m across).
# Krems 34170840, a 2.4-m stub off the stop-controlled 271438869: route-pool and rerouted SCVs went in to
# turn round, the first one waited on the main road for room beyond, and the queue behind it (with the ego)
# stood 300 s. Without the turnaround the stub leaves the drivable component, so no route enters it.
DEAD_END_TURN_MIN_M = 14.6


def _no_room_to_turn(edge) -> bool:
    """Whether dead-end ``edge`` is too short to turn round at its end (see DEAD_END_TURN_MIN_M)."""
    return edge.getLength() < DEAD_END_TURN_MIN_M


def turnaround_deletions(net) -> list[str]:
    """``<delete>`` lines for U-turns (``_is_u_turn``) where the edge has another way on and the U-turn's
    target another way in, and for the turnaround at the end of a dead end too short to turn round in
    (``_no_room_to_turn``)."""
    lines = []
    for edge in sorted(net.getEdges(), key=lambda e: e.getID()):
        if edge.getFunction() == "internal":
            continue
        outgoing = edge.getOutgoing()
        for to_edge, conns in sorted(outgoing.items(), key=lambda kv: kv[0].getID()):
            turns = [c for c in conns if _is_u_turn(c)]
            if not turns or len(turns) != len(conns):
                continue
            other_out = [t for t in outgoing if t is not to_edge]
            other_in = [f for f in to_edge.getIncoming() if f is not edge]
            if not other_out and not _no_room_to_turn(edge):
                continue  # a dead end to turn round in: the U-turn is needed
            if other_out and not other_in:
                continue  # the only way into the reverse edge
            for c in turns:
                lines.append(
                    f"    <delete from={quoteattr(edge.getID())} to={quoteattr(to_edge.getID())} "
                    f'fromLane="{c.getFromLane().getIndex()}" toLane="{c.getToLane().getIndex()}"/>'
                )
    return lines


def _path(shapes, c: _Conn, lead_in_m: float = 0.0, lead_out_m: float = 0.0):
    pts = _cut(shapes[c.from_lane], lead_in_m, True) if lead_in_m > 0 else []
    for lane in c.chain:
        pts += shapes[lane]
    return pts + (_cut(shapes[c.to_lane], lead_out_m, False) if lead_out_m > 0 else [])


def internal_stop_fixes(net_file: Path, clearance_m: float = VEHICLE_WIDTH_M / 2 + CLEARANCE_MARGIN_M):
    """``contPos`` for turns across oncoming traffic (left turns in right-hand traffic) whose waiting car
    would stand in the way of the movements it waits for.

    A turn that crosses oncoming traffic waits inside the junction at an internal junction; netconvert places
    it where the turn's centre line meets the foe lanes, assuming the two cross at a right angle. Where they
    meet at a shallow angle (a bent road through a cluster of OSM nodes) the waiting car's front corner stands
    in the oncoming lane and is hit (SUMO issue #3155). The stop is moved back along the turn until a car of
    ``CAR_LENGTH_M`` x ``VEHICLE_WIDTH_M`` clears every foe path by ``CLEARANCE_MARGIN_M``.
    """
    import shapely
    import shapely.ops

    shapes, _, internal = _read(net_file)
    lines, moved = [], []
    for waiting, foes in internal:
        if waiting is None or len(waiting.chain) < 2 or any(f is None for f in foes):
            continue
        first = shapely.LineString(shapes[waiting.chain[0]])
        lead = min(CAR_LENGTH_M, shapely.LineString(shapes[waiting.from_lane]).length)
        path = shapely.LineString(_path(shapes, waiting, lead))
        # a foe that has just left the junction still has its body on the first metres of its lane
        foe_paths = [_path(shapes, f, 0.0, CAR_LENGTH_M) for f in foes
                     if f is not waiting and f.from_lane != waiting.from_lane]  # fmt: skip
        if not foe_paths:
            continue
        # the body stands in a foe's way within this distance of its centre line: a distance test, not the
        # buffered union of the foe paths, which took 530 of 1,240 sampled s of campo-grande's build (a
        # 10 x 22-km extract, 7,673 junctions)
        foe_lines = shapely.MultiLineString(foe_paths)
        shapely.prepare(foe_lines)
        reach = VEHICLE_WIDTH_M / 2 + clearance_m
        cont = first.length
        best = None
        p = cont
        while p >= 0.0:
            front = lead + p
            body = shapely.ops.substring(path, max(0.0, front - CAR_LENGTH_M), front)
            if not shapely.dwithin(body, foe_lines, reach):
                best = p
                break
            p -= 0.25
        if best is None or best >= cont - 0.2:
            continue
        lines.append(f'    <connection {_ref(waiting)} contPos="{max(best, 0.1):.2f}"/>')
        moved.append((waiting.chain[0], round(cont, 2), round(best, 2)))
    return lines, moved


def _no_room_to_change_lanes(edge) -> bool:
    return edge.getLength() < LANE_CHANGE_S * edge.getSpeed()


def _onward_roads(edge) -> dict[int, set[str]]:
    """Lane index -> the roads a car leaves ``edge`` for from that lane."""
    onward: dict[int, set[str]] = {}
    for next_edge, conns in edge.getOutgoing().items():
        for c in conns:
            onward.setdefault(c.getFromLane().getIndex(), set()).add(next_edge.getID())
    return onward


def fan_out_deletions(net) -> list[str]:
    """``<delete>`` lines for one lane feeding two lanes of the same edge (a lane that widens into two).

    netconvert builds two internal lanes from the same point that part only ~3 m by the junction's end; two
    cars leaving the lane one after the other end up side by side on them, and in a queue they touch (seen on
    Helsinki, junction 2264808902: collisions every 90 s). One lane feeds one lane; a car that wants the
    new lane changes into it after the junction. Kept: the target lane fed by the fewest other lanes, then the
    rightmost.

    Except where the road after the junction has no room for a lane change (shorter than LANE_CHANGE_S at
    its speed limit) and a dropped lane is the only way on to a road beyond: graphhopper's bautzen.osm, a
    10-m edge whose left lane alone leads straight on; the ego changed lanes within those 10 m and the car
    behind hit it. There the fan-out is the choice of lane and stays (``stranded_lane_connections`` makes
    one where netconvert did not).
    """
    lines = []
    for edge in sorted(net.getEdges(), key=lambda e: e.getID()):
        if edge.getFunction() == "internal":
            continue
        for to_edge, conns in sorted(edge.getOutgoing().items(), key=lambda kv: kv[0].getID()):
            feeders: dict[int, set[int]] = {}
            for c in conns:
                feeders.setdefault(c.getToLane().getIndex(), set()).add(c.getFromLane().getIndex())
            onward = _onward_roads(to_edge) if _no_room_to_change_lanes(to_edge) else {}
            by_from: dict[int, list] = {}
            for c in conns:
                by_from.setdefault(c.getFromLane().getIndex(), []).append(c)
            for from_lane, group in sorted(by_from.items()):
                if len(group) < 2:
                    continue
                keep = min(
                    group, key=lambda c: (len(feeders[c.getToLane().getIndex()]), c.getToLane().getIndex())
                )
                reached = set(onward.get(keep.getToLane().getIndex(), ()))
                for c in group:
                    if c is keep:
                        continue
                    if onward.get(c.getToLane().getIndex(), set()) - reached:
                        reached |= onward[c.getToLane().getIndex()]
                        continue
                    lines.append(
                        f"    <delete from={quoteattr(edge.getID())} to={quoteattr(to_edge.getID())} "
                        f'fromLane="{from_lane}" toLane="{c.getToLane().getIndex()}"/>'
                    )
    return lines


def stranded_lane_connections(net) -> list[str]:
    """``<connection>`` lines into lanes no incoming lane reaches, on roads with no room to change lanes,
    where the lane is the only way on to a road beyond (a turn pocket that begins at a junction).

    netconvert leaves such a lane unfed when a road gains a lane at a node (Munich 276604365#0: 11 m, its
    third lane alone turns left; 189367280: 0.2 m). A car whose route needs it must change lanes within those
    metres. The lane is fed from the incoming lane that feeds its nearest fed neighbour, on its side (the
    leftmost such feeder for a lane to the left, the rightmost for one to the right): one lane fans out into
    two, the lane choice ``fan_out_deletions`` keeps on such roads.
    """
    lines = []
    for edge in sorted(net.getEdges(), key=lambda e: e.getID()):
        if edge.getFunction() == "internal" or not _no_room_to_change_lanes(edge):
            continue
        feeders: dict[int, list[tuple[str, int]]] = {}
        for from_edge, conns in edge.getIncoming().items():
            for c in conns:
                feeders.setdefault(c.getToLane().getIndex(), []).append(
                    (from_edge.getID(), c.getFromLane().getIndex())
                )
        if not feeders:
            continue
        onward = _onward_roads(edge)
        for lane in edge.getLanes():
            i = lane.getIndex()
            if i in feeders or not lane.allows("passenger"):
                continue
            others = set().union(*(roads for j, roads in onward.items() if j != i))
            if not onward.get(i, set()) - others:
                continue
            nearest = min(feeders, key=lambda j: (abs(j - i), j))
            from_id, from_lane = (max if i > nearest else min)(feeders[nearest], key=lambda f: (f[1], f[0]))
            lines.append(
                f"    <connection from={quoteattr(from_id)} to={quoteattr(edge.getID())} "
                f'fromLane="{from_lane}" toLane="{i}"/>'
            )
    return lines


# a one-way road that joins a two-way road at less than this angle runs into it beside its lanes: a merge [deg]
SHALLOW_MERGE_DEG = 30.0
# ... and it needs a spread when its lane ends closer to the opposite direction's lane than two cars need
# side by side (APPROACH_CLEARANCE_M, below): only then do its cars meet that direction's, and
# geometric_prohibitions makes it yield to both directions. Krems 38566227 ends 1.94 m from it, 24746413#1
# 2.06 m; Monaco 25103757 2.27 m (0.93 m off the lane it joins), which, spread, kept netconvert's stop
# lines at 273246852 moving back round after round (test_real_maps)


def _end(shape) -> tuple[float, float, float, float]:
    """(x, y, unit direction x, y) of a lane shape's last point."""
    (x0, y0), (x1, y1) = shape[-2], shape[-1]
    n = math.hypot(x1 - x0, y1 - y0) or 1.0
    return x1, y1, (x1 - x0) / n, (y1 - y0) / n


def oneway_merge_spreads(net) -> tuple[list[str], list[str]]:
    """``<edge spreadType="right">`` lines for one-way roads whose lanes end between the two directions of a
    two-way road they join at a shallow angle, and ``<delete>`` lines for their turns back the way they came.

    netconvert centres a one-way road's lanes on its OSM line and puts each direction of a two-way road beside
    its line, so where a one-way road joins a two-way one at a shallow Y, its lane ends on the two-way road's
    centre line: as close to the opposite direction as to the lane it joins (Krems 456774382: 38566227 ends
    1.1 m beyond the end of 38566228's eastbound lane, towards the westbound one, 2.2 m from its start). Its
    movement then passes the opposite one within a car's width, ``geometric_prohibitions`` rightly makes it
    yield to both directions, and in `make experiment` the ego stood 40 s at its give-way line for a stream
    the other way; and the two roads' lanes lay on top of each other over the last metres, so a car on each,
    side by side, touched (the ego and an SCV there, `make experiment` P4 system_B). Such a road is spread
    when its lane ends within APPROACH_CLEARANCE_M of the opposite direction's lane. Spread to the kerb side,
    as a two-way road's lanes are (netconvert's "right" is the kerb side in either driving side), the lane
    ends on the one it joins, and netconvert widens the junction over the merge. netconvert also offers such a road a "left" onto the opposite direction, a reversal of
    177 deg: with the lane ending 2 m from the other direction's start it went as a U-turn
    (``turnaround_deletions``); in the widened junction it would be a 6.5-m internal lane no car can turn
    in, so it goes with the spread.
    """
    import shapely

    spread = set()
    for node in net.getNodes():
        incoming = [e for e in node.getIncoming() if e.allows("passenger") and e.getFunction() != "internal"]
        outgoing = [e for e in node.getOutgoing() if e.allows("passenger") and e.getFunction() != "internal"]
        for edge in incoming:
            if any(o.getToNode() == edge.getFromNode() for o in outgoing):
                continue  # half of a two-way road: spread beside its line already
            inner = edge.getLane(edge.getLaneNumber() - 1)
            ex, ey, eux, euy = _end(inner.getShape())
            for joined in incoming:
                back = [o for o in outgoing if o.getToNode() == joined.getFromNode()]
                if joined is edge or not back:
                    continue  # not a two-way road
                joined_inner = joined.getLane(joined.getLaneNumber() - 1)
                ax, ay, ux, uy = _end(joined_inner.getShape())
                if math.hypot(ex - ax, ey - ay) > inner.getWidth() + joined_inner.getWidth():
                    continue  # the two lanes do not end side by side
                if math.degrees(math.acos(max(-1.0, min(1.0, eux * ux + euy * uy)))) > SHALLOW_MERGE_DEG:
                    continue
                opposite = shapely.LineString(back[0].getLane(back[0].getLaneNumber() - 1).getShape())
                if opposite.distance(shapely.Point(ex, ey)) < APPROACH_CLEARANCE_M:
                    spread.add(edge)
    edges = sorted(spread, key=lambda e: e.getID())
    reversals = [
        f"    <delete from={quoteattr(e.getID())} to={quoteattr(to.getID())} "
        f'fromLane="{c.getFromLane().getIndex()}" toLane="{c.getToLane().getIndex()}"/>'
        for e in edges
        for to, conns in sorted(e.getOutgoing().items(), key=lambda kv: kv[0].getID())
        if _reverses(e, to)
        for c in conns
    ]
    return [f'    <edge id={quoteattr(e.getID())} spreadType="right"/>' for e in edges], reversals


def crossing_merge_deletions(net_file: Path) -> tuple[list[str], list[tuple]]:
    """``<delete>`` lines for lanes of two roads that cross each other on their way into the same road.

    Where two multi-lane roads merge into one, netconvert maps every incoming lane onto a target lane and the
    lanes of one road cross those of the other (lane 0 of the left road to the right target lane, lane 1 of
    the right road to the left one): an X inside the junction where cars of both queues stand side by side
    (Helsinki 1375815868: a collision every few minutes). The crossing lane of the lower-ranked movement is
    deleted when another lane of its road still leads into the target road (cars change lanes before the
    junction); otherwise that of the other movement; otherwise the two stay foes.
    """
    import shapely

    shapes, junctions, _ = _read(net_file)
    lines, report = [], []
    for jid, conns, _foes in junctions:
        if any(c is None for c in conns):
            continue
        unique = list({id(c): c for c in conns}.values())
        inner = {id(c): shapely.LineString([p for lane in c.chain for p in shapes[lane]]) for c in unique}
        into = _lanes_into(unique)
        for a, b in itertools.combinations(unique, 2):
            if a.to_edge != b.to_edge or a.from_edge == b.from_edge or a.to_lane == b.to_lane:
                continue
            if not inner[id(a)].crosses(inner[id(b)]):
                continue
            c = _lane_to_delete(a, b, into)
            if c is not None:
                lines.append(_delete_line(c))
                report.append((jid, c.from_lane, c.to_lane))
    return lines, report


# a movement that reverses its heading closer to where it began than the design car's turning circle is a
# loop no car can drive [m]
TURNING_CIRCLE_M = 2 * MIN_TURN_RADIUS_M
# two paths from one lane have parted once they are this far apart, and meet again this close [m]
PARTED_M, MET_M = 1.0, 0.3


def _parts_and_meets(a, b) -> bool:
    """Whether line ``a``, starting where ``b`` starts, parts from ``b`` and comes back onto it."""
    import shapely.ops

    s = 0.0
    while s < a.length and a.interpolate(s).distance(b) <= PARTED_M:
        s += 0.5
    return s < a.length and shapely.ops.substring(a, s, a.length).distance(b) < MET_M


def looping_turn_deletions(net_file: Path) -> tuple[list[str], list[tuple[str, str, str]]]:
    """``<delete>`` lines for turns that reverse the heading within a turning circle (``TURNING_CIRCLE_M``,
    U_TURN_DEG) and loop across another movement from the same lane.

    SUMO never holds two movements from one lane apart: the car behind goes on its way while the one ahead
    loops back over it. graphhopper's north-bayreuth extract, cluster_21636285_331939793: the "right" from
    39407891#2 into -155200273 turns 162 deg between lane ends 8.6 m apart, through a 24-m loop over the
    straight movement's path, and the next car straight on hit the turning one (cosim seed 1 and plain SUMO
    seed 2). Where the target road has another way in; the turns a car can drive (a U-turn round a wide
    median) and netconvert's own turnarounds (``turnaround_deletions``) are left alone. Returns the lines
    and (junction, from lane, to lane)."""
    import shapely

    shapes, junctions, _ = _read(net_file)
    lines, report = [], []
    for jid, conns, _foes in junctions:
        unique = list({id(c): c for c in conns if c is not None}.values())
        inner = {id(c): shapely.LineString([p for lane in c.chain for p in shapes[lane]]) for c in unique}
        ways_in = {(c.from_edge, c.to_edge) for c in unique}
        for c in unique:
            if c.direction == "t" or _osm_way(c.from_edge) == _osm_way(c.to_edge):
                continue
            if not _reverses_within(shapes[c.from_lane], shapes[c.to_lane], TURNING_CIRCLE_M):
                continue
            if not any(f != c.from_edge for f, t in ways_in if t == c.to_edge):
                continue  # the only way into the target road
            siblings = [o for o in unique if o is not c and o.from_lane == c.from_lane]
            if any(_parts_and_meets(inner[id(c)], inner[id(o)]) or _parts_and_meets(inner[id(o)], inner[id(c)])
                   for o in siblings):  # fmt: skip
                lines.append(_delete_line(c))
                report.append((jid, c.from_lane, c.to_lane))
    return lines, report


def overlapping_end_deletions(net_file: Path, clearance_m: float = VEHICLE_WIDTH_M):
    """``<delete>`` lines for movements whose lane into a junction lies on top of another movement's lane out.

    Where two roads meet a node at a sharp angle (the two carriageways of a divided road joining a two-way
    road), OSM draws them so close that the last metres of one road's lane in and the first metres of the
    other road's lane out lie within ``clearance_m`` of each other, though neither leads into the other
    (Monaco 25198791: 166399498_1 and 68814581#0_1, centre lines 0-0.8 m apart over 10 m). Closer than a
    car's width, two cars on their centre lines touch; lanes merely narrow (1.8-2.1 m apart on Krems) are
    left alone. The two internal lanes do not cross, so SUMO's right of way does not keep the movements
    apart (MSLink: foe lanes without an intersection are disregarded): a car entering from one lane met a
    car that had just left the junction on the other (6 of 10 SCV collisions in the drive benchmark). The
    lower-ranked movement's lane is deleted when another lane of its road still leads into the same road
    (cars change lanes before the junction); otherwise the other movement's; otherwise both stay. Returns
    the lines and (junction, from lane, to lane, distance).
    """
    import shapely

    shapes, junctions, _ = _read(net_file)
    lines, report = [], []
    for jid, conns, _foes in junctions:
        if len(conns) < 2 or any(c is None for c in conns):
            continue
        unique = list({id(c): c for c in conns}.values())
        inner = {id(c): shapely.LineString([p for lane in c.chain for p in shapes[lane]]) for c in unique}
        # where a car's body still is before and after the junction: the last metres of the lane it comes
        # from, the first metres of the lane it goes to
        last = {id(c): shapely.LineString(_cut(shapes[c.from_lane], CAR_LENGTH_M, True)) for c in unique}
        first = {id(c): shapely.LineString(_cut(shapes[c.to_lane], CAR_LENGTH_M, False)) for c in unique}
        into = _lanes_into(unique)
        for a, b in itertools.combinations(unique, 2):
            if a.from_edge == b.from_edge or a.to_edge == b.to_edge:
                continue  # one road's lanes, or merging into one road: SUMO keeps them apart
            if inner[id(a)].intersects(inner[id(b)]):
                continue  # a crossing: SUMO keeps them apart by the crossing point
            d = min(last[id(a)].distance(first[id(b)]), last[id(b)].distance(first[id(a)]))
            if d >= clearance_m:
                continue
            c = _lane_to_delete(a, b, into)
            if c is not None:
                lines.append(_delete_line(c))
                report.append((jid, c.from_lane, c.to_lane, round(d, 2)))
    return lines, report


# a movement passes another road's lane end at least this far away (two car bodies and a margin) [m]
APPROACH_CLEARANCE_M = VEHICLE_WIDTH_M + CLEARANCE_MARGIN_M
MAX_END_OFFSET_M = 10.0  # a stop line is moved back at most this far [m] ...
MIN_LANE_LEFT_M = 10.0  # ... and leaves at least this much of its lane [m]


def approach_end_offsets(net_file: Path) -> tuple[list[str], list[tuple[str, str, str, float]]]:
    """``<edge endOffset>`` lines that move a road's stop line back behind where another movement of the
    junction passes over the road's last metres.

    Where OSM's nodes of one crossing lie apart (a cluster netconvert joined), a turn from another road can run
    across the end of a road's lanes, before its stop line (Monaco cluster_1784107719_937988304: the right turn
    from 80377815 crosses 4229220#1's lanes 0.0-0.2 m from their last 5 m). SUMO relates two movements only
    by where their internal lanes cross; these do not cross inside the junction, so the turning car went while
    a car came up to the stop line and hit it (every SCV collision of Monaco's drive benchmark and 4 of 6 in
    its traffic benchmark). With the stop line moved back, the road's movements start behind the turn's path
    and cross it inside the junction, where SUMO's right of way keeps them apart. Returns the lines and
    (junction, lane, movement's first internal lane, offset).
    """
    import shapely

    shapes, junctions, _ = _read(net_file)
    root = ET.parse(net_file).getroot()
    incoming = {j.get("id"): j.get("incLanes", "").split() for j in root.iter("junction")}
    lane_len: dict[str, float] = {}  # an edge's lanes as they are, up to its stop line [m]
    end_offset: dict[str, float] = {}  # where its stop line is already moved back (an earlier round) [m]
    for edge in root.iter("edge"):
        if edge.get("function") != "internal":
            lanes = list(edge.iter("lane"))
            lane_len[edge.get("id")] = min(float(lane.get("length", 0.0)) for lane in lanes)
            end_offset[edge.get("id")] = max(float(lane.get("endOffset", 0.0)) for lane in lanes)
    offsets: dict[str, float] = {}
    report = []
    tails: dict[str, tuple] = {}  # a lane's last MAX_END_OFFSET_M, towards its end and back from it

    def tail_of(lane: str) -> tuple:
        if lane not in tails:
            tail = _cut(shapes[lane], MAX_END_OFFSET_M, True)
            tails[lane] = (shapely.LineString(tail), shapely.LineString(tail[::-1]))
        return tails[lane]

    for jid, conns, _foes in junctions:
        unique = [c for c in {id(c): c for c in conns if c is not None}.values()]
        for c in unique:
            path = shapely.LineString([p for lane in c.chain for p in shapes[lane]])
            start = shapely.Point(shapes[c.chain[0]][0])
            for lane in incoming.get(jid, []):
                edge = lane.rsplit("_", 1)[0]
                if edge == c.from_edge or len(shapes.get(lane, [])) < 2 or edge not in lane_len:
                    continue
                if start.distance(shapely.Point(shapes[lane][-1])) < APPROACH_CLEARANCE_M:
                    continue  # two approaches that end side by side (a merge): SUMO relates them as it can
                tail, back = tail_of(lane)
                if path.distance(tail) >= APPROACH_CLEARANCE_M:
                    continue
                # the furthest point of the lane's last metres that the movement passes too close
                near = [d for d in np.arange(0.0, back.length + 0.01, 0.25).tolist()
                        if path.distance(back.interpolate(d)) < APPROACH_CLEARANCE_M]  # fmt: skip
                reach = max(near, default=0.0) + CLEARANCE_MARGIN_M
                if end_offset[edge] + reach > MAX_END_OFFSET_M or lane_len[edge] - reach < MIN_LANE_LEFT_M:
                    continue
                offsets[edge] = max(offsets.get(edge, 0.0), end_offset[edge] + reach)
                report.append((jid, lane, c.chain[0], round(reach, 2)))
    lines = [f'    <edge id={quoteattr(e)} endOffset="{d:.2f}"/>' for e, d in sorted(offsets.items())]
    return lines, report


def sibling_change_bars(net_file: Path) -> tuple[list[str], list[tuple[str, str, str]]]:
    """``<connection>`` lines that bar changing lanes, inside a junction, into a lane that another movement
    of the same incoming lane runs beside.

    Where one incoming lane feeds two roads (a slip road leaving at a shallow angle), netconvert builds the
    two internal lanes from one point, side by side for most of the junction (Krems 448934090: 1.5 m apart
    17 m in, parting only after 31 m). SUMO keeps cars on these siblings apart as leader and follower until
    they part (MSLink::computeDistToDivergence), but its lane changer does not look at them: a car standing on
    the other lane of the straight movement's internal edge changed into the lane beside the slip road's,
    onto the car standing there (plain SUMO on Krems, 6 seeds x 600 s: 3 of the 9 collisions, and one more at
    83637441). Such a change is barred (``changeLeft`` / ``changeRight`` "authority": only that class, which
    ignores the restriction anyway, may change; netconvert refuses an empty list); changes elsewhere in
    junctions stay, since barring them all raised Krems' teleports by half. Returns the lines and
    (junction, internal lane, the change barred on it)."""
    shapes, junctions, _ = _read(net_file)
    edge_lanes: dict[str, list[str]] = {}
    for lane in shapes:
        if lane.startswith(":"):
            edge_lanes.setdefault(lane.rsplit("_", 1)[0], []).append(lane)
    for lanes in edge_lanes.values():
        lanes.sort(key=lambda lane: int(lane.rsplit("_", 1)[1]))
    bars: dict[str, dict[str, str]] = {}  # internal lane -> the change attribute barred on it
    conn_of: dict[str, _Conn] = {}
    junction_of: dict[str, str] = {}
    for jid, conns, _foes in junctions:
        unique = [c for c in {id(c): c for c in conns if c is not None}.values()]
        for c in unique:
            conn_of[c.chain[0]] = c
            junction_of[c.chain[0]] = jid
        for c in unique:
            lane = c.chain[0]
            edge = lane.rsplit("_", 1)[0]
            lanes = edge_lanes.get(edge, [])
            if len(lanes) < 2 or not any(d.from_lane == c.from_lane and d.chain[0].rsplit("_", 1)[0] != edge
                                         for d in unique):  # fmt: skip
                continue
            i = lanes.index(lane)
            if i > 0:  # the lane to its right changes left into it
                bars.setdefault(lanes[i - 1], {})["changeLeft"] = '"authority"'
            if i + 1 < len(lanes):
                bars.setdefault(lanes[i + 1], {})["changeRight"] = '"authority"'
    # a later round of fixes reads a network that has them already
    have = {(lane.get("id"), k) for lane in ET.parse(net_file).getroot().iter("lane")
            for k in ("changeLeft", "changeRight") if lane.get(k) is not None}  # fmt: skip
    lines, report = [], []
    for lane, attrs in sorted(bars.items()):
        c = conn_of.get(lane)
        attrs = {k: v for k, v in attrs.items() if (lane, k) not in have}
        if c is None or not attrs:
            continue
        report += [(junction_of[lane], lane, k) for k in sorted(attrs)]
        lines.append(
            f"    <connection {_ref(c)} " + " ".join(f"{k}={v}" for k, v in sorted(attrs.items())) + "/>"
        )
    return lines, report


PATH_CLEARANCE_M = 2.6  # centre lines of two movements that do not cross stay this far apart [m]:
# a 1.8-m body each side (0.9 + 0.9), the 0.3-m margin and 0.5 m for the corners of a 5-m car on a curve


# a shape that turns more than this between two 0.5-m steps turns back, which no car can (on its 7.3-m
# minimum radius, AASHTO 2011 Table 2-2b, it turns 4 deg per 0.5 m; netconvert's own polylines have kinks of
# up to ~90 deg where two internal lanes meet). Monaco 25345339: pushes that kept a left turn from crossing
# itself folded its end back and forth (on 1.9 m, back 0.8 m, on 2.5 m), and SUMO, meeting the other
# movement's lane seven times along it, let a car on each go into the other (plain SUMO, seed 8)
MAX_STEP_TURN_DEG = 90.0


def _folds(pts) -> bool:
    """Whether a resampled polyline turns sharper than MAX_STEP_TURN_DEG between two consecutive steps."""
    import numpy as np

    d = np.diff(np.asarray(pts, dtype=float), axis=0)
    d = d[np.hypot(*d.T) > 1e-6]
    if len(d) < 2:
        return False
    heading = np.arctan2(d[:, 1], d[:, 0])
    turn = np.abs((np.diff(heading) + np.pi) % (2 * np.pi) - np.pi)
    return bool((turn > np.radians(MAX_STEP_TURN_DEG)).any())


def _resample(pts, step: float = 0.5):
    import numpy as np

    pts = np.asarray(pts, dtype=float)
    seg = np.hypot(*np.diff(pts, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    keep = np.concatenate([[True], seg > 1e-6])
    pts, s = pts[keep], s[keep]
    if s[-1] <= 0:
        return pts[:1]
    n = max(2, int(math.ceil(s[-1] / step)) + 1)
    t = np.linspace(0.0, s[-1], n)
    return np.column_stack([np.interp(t, s, pts[:, 0]), np.interp(t, s, pts[:, 1])])


def _nearest_on(points, line):
    """For each point, the nearest point on the polyline ``line`` and the distance to it."""
    import numpy as np

    a, b = line[:-1], line[1:]
    ab = b - a
    den = np.maximum((ab * ab).sum(1), 1e-12)
    t = np.clip(((points[:, None, :] - a[None]) * ab[None]).sum(2) / den[None], 0.0, 1.0)
    proj = a[None] + t[..., None] * ab[None]
    d = np.hypot(*(points[:, None, :] - proj).transpose(2, 0, 1))
    k = d.argmin(1)
    idx = np.arange(len(points))
    return proj[idx, k], d[idx, k]


def separated_shapes(net_file: Path, clearance_m: float = PATH_CLEARANCE_M, rounds: int = 60):
    """Custom internal-lane shapes (``<connection ... shape=...>``) that keep movements apart that do not cross.

    SUMO's junction model knows two movements inside a junction only by the point where their internal lanes
    cross (MSLink::setRequestInformation: foe lanes without an intersection get ``CONFLICT_NO_INTERSECTION``
    and are "disregarded"); merges and diverges by the point where their lanes part. Two movements that run
    side by side without crossing (a bent street through a cluster of OSM nodes, where netconvert's curves
    for both directions cut the same corner: Monaco cluster_1737147129_21914841, 0.83 m apart over 20 m;
    Helsinki cluster_4435014125_4435014127, 1.46 m) are therefore never kept apart, even when they are foes,
    and with ``collision.check-junctions`` every meeting there is a collision. The shapes are pushed apart
    symmetrically (the ends stay on their lanes) until their centre lines are ``clearance_m`` apart; a shape
    that a further push would make cross itself stays where it is (Monaco 258068679: a left turn that dips
    4 m south and comes back, pushed on, looped back over its own start beside the straight movement of the
    same lane, and SUMO, which never makes two movements of one lane foes, let both go: 2 SCV collisions).
    Returns the connection lines and a list of (junction, connection, connection, distance before, after).
    """
    import numpy as np
    import shapely

    shapes, junctions, _ = _read(net_file)
    lines, report = [], []
    for jid, conns, _foes in junctions:
        if len(conns) < 2 or any(c is None for c in conns):
            continue
        unique = list({id(c): c for c in conns}.values())
        orig = {}
        for c in unique:
            pts = [p for lane in c.chain for p in shapes[lane]]
            orig[id(c)] = _resample(pts)
        unique = [
            c for c in unique if len(orig[id(c)]) >= 2
        ]  # a zero-length internal lane has no shape to move
        pairs = []
        for a, b in itertools.combinations(unique, 2):
            if a.from_lane == b.from_lane or a.to_lane == b.to_lane:
                continue  # SUMO keeps siblings and merging lanes apart by their divergence point
            la, lb = shapely.LineString(orig[id(a)]), shapely.LineString(orig[id(b)])
            if la.intersects(lb):
                continue  # a crossing: SUMO keeps them apart by the crossing point
            d = la.distance(lb)
            if d < clearance_m - 0.05:
                pairs.append((a, b, d))
        if not pairs:
            continue
        cur = {k: v.copy() for k, v in orig.items()}
        involved = {id(c) for a, b, _ in pairs for c in (a, b)}
        # every non-crossing pair of the junction takes part: a shape pushed away from one path must not be
        # pushed into a third one
        watch = [(a, b) for a, b in itertools.combinations(unique, 2)
                 if a.from_lane != b.from_lane and a.to_lane != b.to_lane
                 and (id(a) in involved or id(b) in involved)
                 and not shapely.LineString(orig[id(a)]).intersects(shapely.LineString(orig[id(b)]))]  # fmt: skip
        kernel = np.array([1.0, 2.0, 3.0, 2.0, 1.0]) / 9.0
        # shapes that stop moving: another push would make them cross themselves (or netconvert's already do)
        frozen = {k for k in involved if not shapely.LineString(orig[k]).is_simple or _folds(orig[k])}
        for _ in range(rounds):
            disp = {k: np.zeros_like(v) for k, v in cur.items()}
            worst = clearance_m
            box = {k: (v.min(0), v.max(0)) for k, v in cur.items()}
            for a, b in watch:
                (lo_a, hi_a), (lo_b, hi_b) = box[id(a)], box[id(b)]
                if np.hypot(*np.maximum(0.0, np.maximum(lo_a - hi_b, lo_b - hi_a))) >= clearance_m:
                    continue  # bounding boxes this far apart: no point of one is near the other
                for p, q in ((a, b), (b, a)):
                    pts, other = cur[id(p)], cur[id(q)]
                    near, d = _nearest_on(pts, other)
                    worst = min(worst, float(d[1:-1].min()) if len(d) > 2 else worst)
                    close = d < clearance_m
                    if not close.any():
                        continue
                    away = pts - near
                    norm = np.maximum(d, 1e-6)[:, None]
                    disp[id(p)][close] += (away / norm * ((clearance_m - d) / 2.0 + 0.02)[:, None])[close]
            if worst >= clearance_m - 0.05:
                break
            changed = False
            for k, dv in disp.items():
                if not dv.any() or k in frozen:
                    continue
                pts = cur[k]
                s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
                taper = np.clip(np.minimum(s, s[-1] - s) / 1.5, 0.0, 1.0)[:, None]
                smooth = np.column_stack([np.convolve(np.pad(dv[:, i], 2, mode="edge"), kernel, "valid")
                                          for i in range(2)])  # fmt: skip
                moved = pts + 0.5 * smooth * taper
                if not shapely.LineString(moved).is_simple or _folds(moved):
                    frozen.add(k)  # pushed on, it would loop or fold over itself: it stays as it is now
                    continue
                changed = changed or not np.array_equal(moved, pts)
                cur[k] = moved
            if not changed:
                break  # every shape still close is frozen: the rounds left would repeat this one
        by_id = {id(c): c for c in unique}
        for k in sorted(involved, key=lambda k: (by_id[k].from_lane, by_id[k].to_lane)):
            moved = float(np.hypot(*(cur[k] - orig[k]).T).max())
            if moved < 0.05:
                continue
            c = by_id[k]
            # as written (simplified, to the centimetre), a tight bend can fold over itself: then less
            # simplified, or not at all (netconvert's shape stays)
            for line in (shapely.LineString(cur[k]).simplify(0.05), shapely.LineString(cur[k])):
                coords = [(round(x, 2), round(y, 2)) for x, y in line.coords]
                if shapely.LineString(coords).is_simple:
                    break
            else:
                continue
            shape = " ".join(f"{x:.2f},{y:.2f}" for x, y in coords)
            lines.append(f'    <connection {_ref(c)} shape="{shape}"/>')
        for a, b, d in pairs:
            after = shapely.LineString(cur[id(a)]).distance(shapely.LineString(cur[id(b)]))
            report.append((jid, a.chain[0], b.chain[0], round(d, 2), round(after, 2)))
    return lines, report


# SUMO sizes the conflict of two crossing internal lanes from their angle at the crossing point alone: the foe
# lane's width x (2 / max(sin(angle), 0.2) - 1), centred on the crossing (MSLink::setRequestInformation), and
# lets the other movement go once a car's rear is half that past the crossing. A turn that crosses and then
# bends to run alongside the other movement is still beside it there (SUMO issue #12721): Krems 268939011, a
# left turner stopped by the queue beyond stood 2.4 m past the crossing, cleared by SUMO at 1.6 m, and the car
# going straight on hit its rear corner; Helsinki's joined light 1371708587: a car standing 1.56 m past a
# right turn that bends after the crossing, cleared at 1.41 m (SUMO adds the size in lane units, 18 % longer
# there than the shape). ``conflict_extents`` gives such pairs the extent a car body really needs: the rear is
# past once the body no longer touches the strip the other movement's cars sweep.
SUMO_MIN_SIN = 0.2  # MSLink: the sine of the crossing angle is floored here
CONFLICT_STEP_M = 0.1


def _tangent(line, s: float) -> float:
    a, b = line.interpolate(max(s - 0.25, 0.0)), line.interpolate(min(s + 0.25, line.length))
    return math.atan2(b.y - a.y, b.x - a.x)


def conflict_extents(net_file: Path, min_gap_m: float, car_length_m: float = CAR_LENGTH_M,
                     car_width_m: float = VEHICLE_WIDTH_M, margin_m: float = CLEARANCE_MARGIN_M):  # fmt: skip
    """(junction, movement standing, movement passing, startPos, endPos, SUMO's startPos, SUMO's endPos) for
    every pair of foe movements where a car of the standing one, ``margin_m`` wider, would stand in the way
    of the passing one's cars where SUMO does not expect it: past SUMO's end (it lets the passing car go), or
    stopped ``min_gap_m`` short of SUMO's start (where it waits for the passing car). Positions are along the
    standing movement's whole path through the junction in lane units (an internal lane's ``length`` may
    exceed its shape's), as the net file's ``<conflict>`` element takes them."""
    import shapely

    root = ET.parse(net_file).getroot()
    lanes = {lane.get("id"): lane for edge in root.iter("edge") for lane in edge.iter("lane")}
    shapes, junctions, _ = _read(net_file)
    out = []
    for jid, conns, foes in junctions:
        n = len(conns)
        if not foes or n < 2 or any(c is None for c in conns):
            continue
        paths = [shapely.LineString([p for lane in c.chain for p in shapes[lane]]) for c in conns]
        scales = [_LaneScale(c.chain, shapes, lanes) for c in conns]
        for i, k in itertools.permutations(range(n), 2):
            a, b = conns[i], conns[k]
            if a is b or a.from_lane == b.from_lane or a.to_lane == b.to_lane:
                continue  # one lane's movements, merges and diverges: SUMO treats them apart
            if foes.get(i, "")[n - 1 - k : n - k] != "1" and foes.get(k, "")[n - 1 - i : n - i] != "1":
                continue
            crossing = paths[i].intersection(paths[k])
            points = [g for g in getattr(crossing, "geoms", [crossing]) if g.geom_type == "Point"]
            if not points:
                continue
            crossings = sorted(paths[i].project(p) for p in points)
            size = _conflict_size(paths[i], paths[k], crossings[-1], b.chain, shapes, lanes)
            # SUMO takes the last crossing; it places the start in geometry and adds the size in lane units
            sumo_start = scales[i].lane_pos(max(0.0, crossings[-1] - size / 2.0))
            sumo_end = sumo_start + size
            # paths that cross more than once: the extent starts before the first crossing (SUMO keeps one
            # crossing per pair of lanes, each lane's last: MSLink::setRequestInformation). Only for a movement
            # whose cars wait at the stop line: one that waits inside the junction (an internal junction) would
            # stand past such a start, and SUMO lets a car past the start ignore foes not yet in its way
            # (Monaco 25345339: a left turn's start moved from 11.3 m to 0 m, and a car collided there)
            first_start = sumo_start
            for s in crossings[:-1] if len(a.chain) == 1 else ():
                z = _conflict_size(paths[i], paths[k], s, b.chain, shapes, lanes)
                first_start = min(first_start, scales[i].lane_pos(max(0.0, s - z / 2.0)))
            # the passing movement's cars sweep its path and the first metres of the road after it
            strip = shapely.LineString(list(paths[k].coords) + _cut(shapes[b.to_lane], LANE_END_M, False)[1:])
            strip = strip.buffer(car_width_m / 2.0, cap_style="flat")
            lead_in = _cut(shapes[a.from_lane], car_length_m, True)
            track = shapely.LineString(
                lead_in[:-1] + list(paths[i].coords) + _cut(shapes[a.to_lane], car_length_m, False)[1:]
            )
            body = _Body(
                track, shapely.LineString(lead_in).length, car_length_m, car_width_m / 2.0 + margin_m
            )
            length = paths[i].length
            rear = scales[i].geo_pos(sumo_end)
            end = sumo_end
            if rear < length and body.touches(rear, strip):
                while rear < length and body.touches(rear, strip):
                    rear += CONFLICT_STEP_M
                end = scales[i].lane_pos(min(rear, length))
            front = scales[i].geo_pos(first_start) - min_gap_m  # where it stops for the passing car
            start = first_start
            if front > 0.0 and body.touches(front - car_length_m, strip):
                while front > 0.0 and body.touches(front - car_length_m, strip):
                    front -= CONFLICT_STEP_M
                start = scales[i].lane_pos(max(front, 0.0)) + min_gap_m
            if end > sumo_end or start < sumo_start:
                out.append(
                    (jid, a, b, round(start, 2), round(end, 2), round(sumo_start, 2), round(sumo_end, 2))
                )
    return out


def _conflict_size(path, foe_path, s: float, foe_chain: list[str], shapes, lanes) -> float:
    """SUMO's conflict size where ``path`` crosses ``foe_path`` at ``s`` along it: the foe lane's width x
    (2 / max(sin(angle), 0.2) - 1)."""
    s_foe = foe_path.project(path.interpolate(s))
    sine = abs(math.sin(_tangent(path, s) - _tangent(foe_path, s_foe)))
    width = float(lanes[_lane_at(foe_chain, shapes, s_foe)].get("width", 3.2))
    return width * (2.0 / max(sine, SUMO_MIN_SIN) - 1.0)


class _Body:
    """A car body along a movement's track (the end of its road, its path, the start of the next road),
    positions measured from the start of its path."""

    def __init__(self, track, lead_in_m: float, length_m: float, half_width_m: float):
        self.track, self.lead_in, self.length, self.half_width = track, lead_in_m, length_m, half_width_m

    def touches(self, rear: float, strip) -> bool:
        """Whether the body with its rear at ``rear`` touches ``strip``."""
        import shapely.ops

        s = self.lead_in + rear
        body = shapely.ops.substring(self.track, max(s, 0.0), s + self.length)
        return body.buffer(self.half_width, cap_style="flat").intersects(strip)


class _LaneScale:
    """Positions along a movement's internal lanes: geometric (along the shapes) <-> lane units (``length``)."""

    def __init__(self, chain: list[str], shapes, lanes):
        import shapely

        self.geo = [shapely.LineString(shapes[lane]).length for lane in chain]
        self.units = [float(lanes[lane].get("length", g)) for lane, g in zip(chain, self.geo, strict=True)]

    def _map(self, s: float, src: list[float], dst: list[float]) -> float:
        done = 0.0
        for j, (a, b) in enumerate(zip(src, dst, strict=True)):
            if s <= a or j == len(src) - 1:
                return done + (s / a * b if a > 0 else 0.0)
            s -= a
            done += b
        return done

    def lane_pos(self, s: float) -> float:
        return self._map(s, self.geo, self.units)

    def geo_pos(self, s: float) -> float:
        return self._map(s, self.units, self.geo)


def _lane_at(chain: list[str], shapes, s: float) -> str:
    """The internal lane of ``chain`` at distance ``s`` along the whole path."""
    import shapely

    for lane in chain[:-1]:
        length = shapely.LineString(shapes[lane]).length
        if s <= length:
            return lane
        s -= length
    return chain[-1]


def write_conflict_extents(net_file: Path, extents) -> None:
    """Nest ``<conflict>`` elements for ``extents`` (``conflict_extents``) in their connections of the net file.
    netconvert drops them when it reads a network, so this runs after the last netconvert pass."""
    by_conn: dict[tuple[str, str, str, str], list[str]] = {}
    for _jid, a, b, start, end, *_sumo in extents:
        key = (a.from_edge, a.to_edge, a.from_lane.rsplit("_", 1)[1], a.to_lane.rsplit("_", 1)[1])
        by_conn.setdefault(key, []).append(
            f'        <conflict {_ref(b)} startPos="{start:.2f}" endPos="{end:.2f}"/>'
        )
    if not by_conn:
        return
    lines = net_file.read_text().split("\n")
    for idx, line in enumerate(lines):
        if not line.lstrip().startswith("<connection ") or " via=" not in line:
            continue
        attrs = dict(re.findall(r'(\w+)="([^"]*)"', line))
        key = (attrs.get("from"), attrs.get("to"), attrs.get("fromLane"), attrs.get("toLane"))
        if key not in by_conn:
            continue
        children = "\n".join(by_conn.pop(key))
        if line.rstrip().endswith("/>"):
            lines[idx] = line.rstrip()[:-2] + ">\n" + children + "\n    </connection>"
        else:  # it has children already (params)
            lines[idx] = line + "\n" + children
    net_file.write_text("\n".join(lines))

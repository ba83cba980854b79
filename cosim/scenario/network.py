"""OSM -> SUMO network in two netconvert passes.

Pass 1 imports the motorized road network with netconvert's own OSM support (lanes, turn:lanes,
maxspeed, one-ways, traffic signals). netconvert ignores ``highway=stop`` / ``highway=give_way``, so cosim
maps those sign nodes (from the OSM pre-pass) onto the junctions and approaches they govern and pass 2
patches the network: junction types (priority_stop / allway_stop / priority), the priority of signed
approaches (so that they are the minor road), a 5 km/h passage on give-way connections, and connections
that contradict OSM ``turn:lanes`` arrows are removed; parking aisles and driveways are closed to cars
(``NOT_THROUGH_SERVICE``). Further netconvert rounds fix the junctions'
geometry (``cosim.scenario.conflicts``); last, the signal plans get split phasing where a left turn would
wait at a permissive green on a lane it shares (``split_signal_plans``).
"""

from __future__ import annotations

import math
import os
import re
from collections import defaultdict
from dataclasses import dataclass, field, replace
from pathlib import Path
from xml.sax.saxutils import quoteattr

from cosim.errors import CosimError
from cosim.scenario.behaviour import ScvBehaviour
from cosim.scenario.conflicts import (
    MIRRORED_DIR,
    approach_end_offsets,
    conflict_extents,
    crossing_merge_deletions,
    fan_out_deletions,
    geometric_prohibitions,
    internal_stop_fixes,
    looping_turn_deletions,
    oneway_merge_spreads,
    overlapping_end_deletions,
    separated_shapes,
    sibling_change_bars,
    stranded_lane_connections,
    turnaround_deletions,
    write_conflict_extents,
)
from cosim.scenario.osm import OsmInfo, SignNode
from cosim.sumo_bridge.network import read_network
from cosim.sumo_bridge.tools import ToolRun, run_tool

OPTIONS_DIR = Path(__file__).parent / "netconvert"
MAX_APPROACH_SEARCH_M = 150.0
# a road shorter than this between two lights holds a queue of at most ~8 cars per lane (7.5 m each)
SHORT_LINK_M = 60.0  # a sign node farther than this from its junction along the way is not used

# Options shared by both passes (junction geometry, turn speeds): pass 2 must not recompute them differently.
COMMON_OPTIONS = [
    "--junctions.limit-turn-speed", "5.5",  # curve speed limit on junctions: ~0.55 g lateral (paper IV.B)
    "--no-turnarounds.except-deadend", "true",
    # a merge into one lane of a multi-lane road yields to that lane only (HCM 2010 Exhibit 19-14: v_2 / N);
    # netconvert's default (foes per edge pair) made Monaco's 25193333 side street wait for gaps in the far
    # lane too: a car every 60-75 s. tests/integration/test_lane_merge_capacity.py
    "--check-lane-foes.all", "true",
    "--output.street-names", "true",
    "--output.original-names", "true",
]  # fmt: skip


TLS_TYPE = "actuated"


def side_options(lefthand: bool) -> list[str]:
    """netconvert builds right-hand traffic unless told otherwise; told in every pass, so that none depends
    on what netconvert keeps of the network it reads."""
    return ["--lefthand", "true"] if lefthand else []


def pass1_options(osm: Path, out: Path, lefthand: bool = False) -> list[str]:
    return [
        "--osm-files", str(osm),
        "--type-files", str(OPTIONS_DIR / "motorized.typ.xml"),
        "--keep-edges.by-vclass", "passenger",
        "--keep-edges.components", "1",  # the largest connected road network; islands are unusable
        "--osm.turn-lanes", "true",
        "--osm.all-attributes", "true",
        "--osm.extra-attributes", "maxspeed,source:maxspeed,maxspeed:type,zone:maxspeed,zone:traffic,oneway,turn:lanes,lanes,service",
        "--junctions.join", "true",
        # OSM often draws one crossing as two or three nodes 10-15 m apart (a dual carriageway, a triangle
        # of turn roads); left apart (netconvert's default 10 m), the road between them shrinks to 0.1-0.2 m
        # inside the junction shapes (153 such links on Krems) and a car standing on it blocks both
        # junctions. Plain SUMO, 600 s, default density (teleports / collisions): Krems seeds 1-3
        # 29/3, 38/3, 33/1 -> 25/3, 11/0, 16/2; Munich 2/0 -> 0/0; Helsinki 5/1 -> 2/0; Monaco 11/1 -> 7/1
        "--junctions.join-dist", "15",
        "--tls.guess-signals", "true",
        "--tls.discard-simple", "true",
        "--tls.join", "true",
        # gap-actuated plans (SUMO docs, Simulation/Traffic_Lights, "Actuated Traffic Lights": a green ends
        # early when its detectors see a gap, up to maxDur), deterministic, as most town signals are; with
        # fixed 90-s cycles the ego drove 1144 m on Helsinki in 300 s (seed 1), 1536 m gap-actuated
        "--tls.default-type", TLS_TYPE,
        # opposite approaches share a green (netconvert's default layout); a left turn without its own lane
        # waits at no permissive green: its phase is split into one green per approach (split_signal_plans)
        "--tls.layout", "opposites",
        "--ramps.guess", "true",
        # OSM width tags split over the lanes give 1.5-m lanes on narrow two-way streets (Helsinki
        # Siltavuorenpenger): a 1.8-m car on each touches the oncoming one; every car lane gets the default width
        "--ignore-widths", "true",
        "--geometry.remove", "true",
        *COMMON_OPTIONS,
        *side_options(lefthand),
        "--output-file", str(out),
    ]  # fmt: skip


@dataclass
class SignPlacement:
    """Where an explicit OSM sign applies in the network."""

    sign: SignNode
    junction: str | None  # SUMO junction id
    approach_edges: tuple[str, ...]  # incoming edges governed by the sign; () = the junction's minor roads
    note: str = ""


@dataclass
class NetworkBuild:
    net_file: Path
    placements: list[SignPlacement]
    junction_kind: dict[str, str]  # junction id -> "stop" | "allway_stop" | "give_way"
    signed_approaches: dict[str, str]  # edge id -> "stop" | "allway_stop" | "give_way"
    tls_approaches: list[str]
    runs: list[tuple[str, ToolRun]] = field(default_factory=list)
    fixes: dict = field(default_factory=dict)  # junction geometry fixes (cosim.scenario.conflicts) -> count


def _osm_nodes_of_junction(junction_id: str) -> list[str]:
    if junction_id.startswith("cluster_"):
        return [p for p in junction_id[len("cluster_") :].split("_") if p and not p.startswith("#")]
    return [junction_id]


def _xy(net, lat: float, lon: float) -> tuple[float, float]:
    return net.convertLonLat2XY(lon, lat)


def _edge_end_heading(shape) -> tuple[float, float]:
    (x0, y0), (x1, y1) = shape[-2][:2], shape[-1][:2]
    n = math.hypot(x1 - x0, y1 - y0) or 1.0
    return (x1 - x0) / n, (y1 - y0) / n


def _dist_point_polyline(px: float, py: float, shape) -> float:
    best = math.inf
    for (x0, y0, *_), (x1, y1, *_) in zip(shape, shape[1:], strict=False):
        dx, dy = x1 - x0, y1 - y0
        seg = dx * dx + dy * dy
        t = 0.0 if seg == 0 else max(0.0, min(1.0, ((px - x0) * dx + (py - y0) * dy) / seg))
        best = min(best, math.hypot(px - (x0 + t * dx), py - (y0 + t * dy)))
    return best


def place_signs(net, osm: OsmInfo) -> list[SignPlacement]:
    """Map each stop / give-way sign node onto a junction and (for approach signs) its incoming edge."""
    node_to_junction: dict[str, str] = {}
    for node in net.getNodes():
        for osm_id in _osm_nodes_of_junction(node.getID()):
            node_to_junction[osm_id] = node.getID()
    ways_of_node: dict[str, list[str]] = defaultdict(list)
    for way_id, refs in osm.sign_ways.items():
        for ref in refs:
            ways_of_node[ref].append(way_id)

    placements = []
    for sign in osm.signs:
        if sign.kind not in ("stop", "allway_stop", "give_way"):
            continue
        if sign.node_id in node_to_junction:
            placements.append(SignPlacement(sign, node_to_junction[sign.node_id], ()))
            continue
        # An approach sign: walk along its way(s) to the next junction in the sign's direction.
        sx, sy = _xy(net, sign.lat, sign.lon)
        candidates = []
        for way_id in ways_of_node.get(sign.node_id, []):
            refs = osm.sign_ways[way_id]
            i = refs.index(sign.node_id)
            steps = {"forward": [1], "backward": [-1]}.get(sign.direction or "", [1, -1])
            for step in steps:
                j = i + step
                dist = 0.0
                prev = osm.node_coords.get(refs[i])
                while 0 <= j < len(refs):
                    cur = osm.node_coords.get(refs[j])
                    if prev and cur:
                        dist += math.dist(_xy(net, *prev), _xy(net, *cur))
                    if refs[j] in node_to_junction:
                        candidates.append((dist, node_to_junction[refs[j]]))
                        break
                    prev = cur
                    j += step
        candidates = [c for c in candidates if c[0] <= MAX_APPROACH_SEARCH_M]
        if not candidates:
            placements.append(SignPlacement(sign, None, (), "no junction along its way within 150 m"))
            continue
        _, junction_id = min(candidates)
        junction = net.getNode(junction_id)
        jx, jy = junction.getCoord()[:2]
        # the approach edge: incoming edge nearest to the sign whose end points towards the junction
        best = None
        for edge in junction.getIncoming():
            if edge.getFunction() == "internal":
                continue
            shape = edge.getShape()
            hx, hy = _edge_end_heading(shape)
            to_j = (jx - sx, jy - sy)
            if hx * to_j[0] + hy * to_j[1] <= 0:
                continue
            d = _dist_point_polyline(sx, sy, shape)
            if best is None or d < best[0]:
                best = (d, edge.getID())
        if best is None or best[0] > 30.0:
            placements.append(
                SignPlacement(sign, junction_id, (), "approach edge not found; applied to the junction")
            )
        else:
            placements.append(SignPlacement(sign, junction_id, (best[1],)))
    return placements


_KIND_RANK = {"allway_stop": 3, "stop": 2, "give_way": 1}


def _minor_incoming(junction, signed: set[str]) -> list:
    """Incoming edges that are minor at this junction: signed ones, else those below the top priority."""
    incoming = [e for e in junction.getIncoming() if e.getFunction() != "internal"]
    if signed:
        return [e for e in incoming if e.getID() in signed]
    top = max((e.getPriority() for e in incoming), default=0)
    return [e for e in incoming if e.getPriority() < top]


# OSM turn:lanes arrows -> SUMO link directions they permit
_ARROW_DIRS = {
    "left": {"l", "t"}, "sharp_left": {"l", "t"}, "slight_left": {"L", "l", "s"}, "through": {"s"},
    "right": {"r"}, "sharp_right": {"r"}, "slight_right": {"R", "r", "s"}, "reverse": {"t"},
    "merge_to_left": {"s", "L"}, "merge_to_right": {"s", "R"},
}  # fmt: skip


def _arrow_dirs(arrow: str, lefthand: bool) -> set[str]:
    """The SUMO link directions an OSM turn arrow permits (a U-turn goes with the turn across the oncoming
    lanes: left in right-hand traffic, right in left-hand traffic)."""
    dirs = _ARROW_DIRS.get(arrow, {"s", "l", "r", "L", "R", "t"})
    if lefthand and arrow in ("left", "sharp_left", "right", "sharp_right"):
        dirs = (dirs - {"t"}) | ({"t"} if "right" in arrow else set())
    return dirs


def turn_lane_deletions(edge, lefthand: bool = False) -> list[str]:
    """Connections that contradict the edge's OSM ``turn:lanes`` arrows (netconvert uses them only as a hint).

    OSM lists lanes left to right; SUMO indexes them from the kerb: right to left in right-hand traffic, left
    to right in left-hand traffic. A connection is kept when its lane has no arrow ("none"/empty), and an
    outgoing edge never loses its last connection.
    """
    tokens = edge.getParams().get("turn:lanes", "").split("|")
    car_lanes = [lane for lane in edge.getLanes() if lane.allows("passenger")]
    if len(tokens) != len(car_lanes) or len(car_lanes) != edge.getLaneNumber():
        return []
    allowed = []
    for tok in tokens if lefthand else reversed(tokens):
        arrows = [a for a in tok.split(";") if a and a != "none"]
        allowed.append(set().union(*(_arrow_dirs(a, lefthand) for a in arrows)) if arrows else None)
    deletions = []
    for to_edge, conns in sorted(edge.getOutgoing().items(), key=lambda kv: kv[0].getID()):
        bad = [c for c in conns if allowed[c.getFromLane().getIndex()] is not None
               and c.getDirection() not in allowed[c.getFromLane().getIndex()]]  # fmt: skip
        if len(bad) == len(conns):
            continue
        for c in bad:
            deletions.append(
                f"    <delete from={quoteattr(edge.getID())} to={quoteattr(to_edge.getID())} "
                f'fromLane="{c.getFromLane().getIndex()}" toLane="{c.getToLane().getIndex()}"/>'
            )
    return deletions


@dataclass
class SignalPhase:
    """One phase of a light's plan (SUMO ``<phase>``); ``min_s`` / ``max_s`` for gap-actuated phases."""

    duration_s: float
    state: str
    min_s: float | None = None
    max_s: float | None = None


MIN_GREEN_S = 5.0  # netconvert's minDur of an actuated green
YELLOW_S = 3.0  # for a split green that had no yellow after it: netconvert's shortest yellow


def split_permissive_phases(phases: list[SignalPhase],
                            links: dict[int, tuple[str, str, str]]) -> list[SignalPhase] | None:  # fmt: skip
    """The plan with one green per approach in each phase where a left turn waits at a permissive green on a
    lane it shares with other movements and never gets a protected one, and in each phase that protects a
    left turn while the other movements of its lane stand at red (there each approach gets all its
    movements); None when there is no such phase.

    ``links``: the light's link index -> (approach edge, lane, direction). Queued behind a gap that may never
    come in the oncoming stream (Krems 255094759, where that stream turned into the same lane), such a left
    holds up every car behind it. netconvert gives a left turn a protected phase only when it has its own lane
    (SUMO docs, Simulation/Traffic_Lights, "Automatically Generated TLS-Programs"), or, as at Krems
    71582001, one in which the straight movement of its lane stands at red. Split phasing serves
    the approaches of that phase one after the other, each with all its movements protected (FHWA Signal
    Timing Manual, 2nd ed., NCHRP Report 812, 2015: split phasing for shared through-left lanes); the other
    phases keep netconvert's plan: at Krems 71582001 the main road keeps its shared green (24 s of 90) and
    only its protected-left phase and the side roads' shared phase are split, where one green per approach
    for all five approaches left the main road 15 s of 90 and the experiment's pair queued there for whole
    phases. The split phase's time is shared out equally."""
    protected = {i for ph in phases for i, c in enumerate(ph.state) if c == "G"}
    by_lane: dict[str, list[tuple[int, str]]] = defaultdict(list)
    for i, (_edge, lane, direction) in links.items():
        by_lane[lane].append((i, direction))
    waiting = set()  # left turns that only ever get a permissive green, on a lane shared with other movements
    shared_lefts = []  # (left turns, the other movements of their lane) on lanes shared with other movements
    for lane_links in by_lane.values():
        lefts = [i for i, d in lane_links if d in ("l", "L")]
        others = [i for i, d in lane_links if d not in ("l", "L", "t")]
        if lefts and others:
            shared_lefts.append((lefts, others))
            waiting |= {i for i in lefts if i not in protected and any(ph.state[i] == "g" for ph in phases)}

    def hollow(phase: SignalPhase) -> bool:
        """A left turn's protected green while the other movements of its lane stand at red: a car going
        straight at the head of the lane holds the turners behind it, and SUMO's actuated logic finds no
        detector for the phase (a lane counts only where all its movements are green), so the phase ends at
        its minimum whatever waits. Krems 71582001: 5 s per cycle of up to 215 s for the bridge's left turn
        into Austraße, whose queue stood through whole cycles."""
        return any(
            any(phase.state[i] == "G" for i in lefts) and any(phase.state[j] == "r" for j in others)
            for lefts, others in shared_lefts
        )

    if not waiting and not any(hollow(ph) for ph in phases if "y" not in ph.state):
        return None
    out: list[SignalPhase] = []
    k = 0
    while k < len(phases):
        green_phase = phases[k]
        green = [i for i, c in enumerate(green_phase.state) if c in "Gg"]
        k += 1
        transition = []  # the yellow after it (links green in it may stay green)
        while (
            k < len(phases)
            and "y" in phases[k].state
            and all(c not in "Gg" or green_phase.state[i] in "Gg" for i, c in enumerate(phases[k].state))
        ):
            transition.append(phases[k])
            k += 1
        whole = hollow(green_phase)  # each approach gets all its movements, not only those green here
        if not whole and not any(green_phase.state[i] == "g" for i in waiting):
            out += [green_phase, *transition]
            continue
        approaches = list(dict.fromkeys(links[i][0] for i in green if i in links))
        yellow_s = transition[0].duration_s if transition else YELLOW_S
        n = len(approaches)
        for approach in approaches:
            mine = {i for i in (links if whole else green) if i in links and links[i][0] == approach}
            lit = "".join("G" if i in mine else "r" for i in range(len(green_phase.state)))
            # a hollow phase is netconvert's short left-turn phase (--tls.left-green.time, 6 s) with the
            # generic actuated maximum: each approach gets its planned time at most, so the other approaches
            # keep their share of the cycle (Krems 71582001 with up to 25 s each: the side road's queue stood
            # 161 s in make experiment's P3)
            longest = max(green_phase.duration_s, MIN_GREEN_S) if whole else _share(green_phase.max_s, n)
            out.append(SignalPhase(_share(green_phase.duration_s, n), lit, _share(green_phase.min_s, n),
                                   longest if green_phase.max_s is not None else None))  # fmt: skip
            out.append(SignalPhase(yellow_s, lit.replace("G", "y")))
    return _yellow_between_greens(out)


def _yellow_between_greens(phases: list[SignalPhase]) -> list[SignalPhase]:
    """Each yellow phase shows yellow exactly to the movements green before it and red in the next green,
    the others green on stay green, the rest red; a yellow with nothing to show is left out. A split
    puts new greens after netconvert's yellows, which showed yellow to movements green again next (Krems
    71582001: the bridge's through traffic got yellow, then green)."""
    greens = [k for k, ph in enumerate(phases) if "y" not in ph.state]
    out = []
    for k, ph in enumerate(phases):
        if "y" not in ph.state or not greens:
            out.append(ph)
            continue
        before = phases[max((g for g in greens if g < k), default=greens[-1])].state
        after = phases[min((g for g in greens if g > k), default=greens[0])].state
        state = "".join(_through_yellow(b, a) for b, a in zip(before, after, strict=True))
        if "y" in state:
            out.append(replace(ph, state=state))
    return out


def _through_yellow(before: str, after: str) -> str:
    """A link's state in the yellow between a green phase (``before``) and the next (``after``)."""
    if before in "Gg":
        return before if after in "Gg" else "y"
    return before if before == after else "r"


def _share(duration_s: float | None, n: int) -> float | None:
    """One of ``n`` equal shares of a split phase's time, at least MIN_GREEN_S."""
    return None if duration_s is None else max(MIN_GREEN_S, round(duration_s / n))


def split_signal_plans(net) -> dict[str, dict[str, list[SignalPhase]]]:
    """The plans ``split_permissive_phases`` changes: light id -> programme id -> phases. Lights that control
    several junctions (tls.join) keep their plan, and so does a light with another light at the end of a
    short road (``SHORT_LINK_M``): a green for one approach at a time is too short to empty a queue into a
    road that holds a few cars and that the neighbour's plan empties at its own times (Helsinki 30471502#2
    into the 30-m 30259739#0: the queue stood through every green for whole experiment phases). In
    left-hand traffic the turns are mirrored first: the one across the oncoming lanes is the right turn."""
    plans: dict[str, dict[str, list[SignalPhase]]] = {}
    for tls in sorted(net.getTrafficLights(), key=lambda t: t.getID()):
        conns = tls.getConnections()
        nodes = {inl.getEdge().getToNode() for inl, _, _ in conns}
        if len(nodes) != 1 or _short_link_to_a_light(next(iter(nodes))):
            continue
        links = {}
        for inl, _, i in conns:
            direction = next((c.getDirection() for c in inl.getOutgoing() if c.getTLLinkIndex() == i), "s")
            if net.lefthand:
                direction = MIRRORED_DIR.get(direction, direction)
            links[i] = (inl.getEdge().getID(), inl.getID(), direction)
        for program_id, program in tls.getPrograms().items():
            phases = [SignalPhase(ph.duration, ph.state, _dur(ph.minDur), _dur(ph.maxDur))
                      for ph in program.getPhases()]  # fmt: skip
            split = split_permissive_phases(phases, links)
            if split is not None:
                plans.setdefault(tls.getID(), {})[program_id] = split
    return plans


def write_signal_plans(net_file: Path, plans: dict[str, dict[str, list[SignalPhase]]]) -> None:
    """Replace the phases of the given programmes in ``net_file`` (the rest of the file stays as it is)."""
    text = net_file.read_text()
    for tls_id, programs in plans.items():
        for program_id, phases in programs.items():
            tl_id, prog = re.escape(quoteattr(tls_id)), re.escape(quoteattr(program_id))
            block = re.compile(rf"( *)<tlLogic id={tl_id} [^>]*programID={prog}[^>]*>.*?</tlLogic>", re.S)
            match = block.search(text)
            head = re.match(r" *<tlLogic [^>]*>", match.group(0)).group(0)
            pad = match.group(1) + "    "
            body = "".join(f'\n{pad}<phase duration="{ph.duration_s:g}" state="{ph.state}"'
                           + ("" if ph.min_s is None else f' minDur="{ph.min_s:g}" maxDur="{ph.max_s:g}"') + "/>"
                           for ph in phases)  # fmt: skip
            text = text[: match.start()] + head + body + f"\n{match.group(1)}</tlLogic>" + text[match.end() :]
    if plans:
        net_file.write_text(text)


def _dur(value) -> float | None:
    """sumolib's minDur / maxDur of a phase: -1 (or None) when the phase has none."""
    return None if value is None or float(value) < 0 else float(value)


def _short_link_to_a_light(node) -> bool:
    """Whether a road shorter than SHORT_LINK_M joins ``node`` to another signalised junction."""
    ends = [(e, e.getFromNode()) for e in node.getIncoming()] + [
        (e, e.getToNode()) for e in node.getOutgoing()
    ]
    return any(e.getLength() < SHORT_LINK_M and other is not node and other.getType() == "traffic_light"
               for e, other in ends)  # fmt: skip


# Service roads that are not for through traffic (OSM wiki, Key:service): the aisles of a parking lot, a
# driveway to a building, a drive-through lane. The traffic is trips between streets, so a car is in one
# only to cut through or to turn round, which routers avoid too (OSRM's car profile penalises them; road
# inventories leave them out). Krems' parking lot at 860978174, junctions 0.2 m apart: every SCV collision
# of `make experiment` happened on its internal lane :860978174_3_0 (5 in 3600 s) once the turnaround in
# the driveway stub 34170840 was gone. Closed to cars, they leave the drivable component and no route
# enters them; other vehicle classes keep them.
NOT_THROUGH_SERVICE = ("parking_aisle", "driveway", "drive-through", "parking")
NO_CARS = "passenger private taxi bus coach delivery truck trailer motorcycle moped evehicle"


# SUMO holds a connection's speed over its whole passage, so the paper's walking pace at a give-way line
# (5 km/h) is also the speed across the junction: 7-12 s over an ordinary one (10-17 m). A roundabout entry
# of a large joined junction is 30-40 m (Berlin's Grosser Stern): 25-30 s at 5 km/h, while the ego, which
# looks and goes, passed the crawling lead on the next lane. Such a passage is crossed in this time instead.
GIVE_WAY_PASSAGE_MAX_S = 12.0


def give_way_passage_speed(conn, approach_mps: float) -> float:
    """The speed of a give-way connection: the approach speed, or what crosses it in GIVE_WAY_PASSAGE_MAX_S
    when it is longer (its length taken as the straight line from the lane's end to the next lane's start)."""
    (x0, y0), (x1, y1) = conn.getFromLane().getShape()[-1][:2], conn.getToLane().getShape()[0][:2]
    return max(approach_mps, math.hypot(x1 - x0, y1 - y0) / GIVE_WAY_PASSAGE_MAX_S)


def write_patches(net, placements: list[SignPlacement], behaviour: ScvBehaviour, workdir: Path):
    """Write node / edge / connection patch files for pass 2; returns them and the sign summary."""
    junction_kind: dict[str, str] = {}
    signed_by_junction: dict[str, set[str]] = defaultdict(set)
    signed_approaches: dict[str, str] = {}
    for p in placements:
        if p.junction is None:
            continue
        node = net.getNode(p.junction)
        if node.getType() == "traffic_light":
            p.note = "junction is signalised; the light governs"
            continue
        kind = p.sign.kind
        if _KIND_RANK[kind] > _KIND_RANK.get(junction_kind.get(p.junction, ""), 0):
            junction_kind[p.junction] = kind
        for e in p.approach_edges:
            signed_by_junction[p.junction].add(e)
            if _KIND_RANK[kind] > _KIND_RANK.get(signed_approaches.get(e, ""), 0):
                signed_approaches[e] = kind

    nodes, edges, cons = [], {}, []
    for jid, kind in sorted(junction_kind.items()):
        node = net.getNode(jid)
        x, y = node.getCoord()[:2]
        jtype = {"allway_stop": "allway_stop", "stop": "priority_stop", "give_way": "priority"}[kind]
        nodes.append(f'    <node id={quoteattr(jid)} x="{x:.2f}" y="{y:.2f}" type="{jtype}"/>')
        signed = signed_by_junction.get(jid, set())
        incoming = [e for e in node.getIncoming() if e.getFunction() != "internal"]
        others = [e.getPriority() for e in incoming if e.getID() not in signed]
        for eid in sorted(signed):
            edge = net.getEdge(eid)
            if others and edge.getPriority() >= min(others):
                new = min(others) - 1
                edges[eid] = f'priority="{new if new != -1 else -2}"'
        if kind == "give_way":  # approach the give-way line at walking pace, then look and go (paper IV.B)
            for edge in _minor_incoming(node, signed):
                for conns in edge.getOutgoing().values():
                    for c in conns:
                        speed = give_way_passage_speed(c, behaviour.give_way_approach_speed_kmh / 3.6)
                        cons.append(
                            f"    <connection from={quoteattr(edge.getID())} to={quoteattr(c.getTo().getID())} "
                            f'fromLane="{c.getFromLane().getIndex()}" toLane="{c.getToLane().getIndex()}" '
                            f'speed="{speed:.3f}"/>'
                        )
    for edge in sorted(net.getEdges(), key=lambda e: e.getID()):
        if edge.getParams().get("turn:lanes"):
            cons.extend(turn_lane_deletions(edge, net.lefthand))
        if edge.getParams().get("service") in NOT_THROUGH_SERVICE:
            edges[edge.getID()] = " ".join(filter(None, (edges.get(edge.getID()), f'disallow="{NO_CARS}"')))
    tls_approaches = [e.getID() for n in net.getNodes() if n.getType() == "traffic_light"
                      for e in n.getIncoming() if e.getFunction() != "internal"]  # fmt: skip
    files = {
        "nod": workdir / "signs.nod.xml",
        "edg": workdir / "signs.edg.xml",
        "con": workdir / "signs.con.xml",
    }
    files["nod"].write_text("<nodes>\n" + "\n".join(nodes) + "\n</nodes>\n")
    files["edg"].write_text(
        "<edges>\n"
        + "\n".join(f"    <edge id={quoteattr(e)} {a}/>" for e, a in sorted(edges.items()))
        + "\n</edges>\n"
    )
    files["con"].write_text("<connections>\n" + "\n".join(cons) + "\n</connections>\n")
    return files, junction_kind, signed_approaches, sorted(tls_approaches)


# netconvert passes that apply junction fixes; each one's output is checked again (a stop line moved back
# changes the junction's internal stops: Krems 1176938011 needed a fourth)
FIX_ROUNDS = 4


_CONN_KEY = ("from", "to", "fromLane", "toLane")


def _merge_connection_lines(text: str) -> str:
    """One ``<connection>`` line per lane pair, its attributes merged (later lines win): netconvert takes a
    repeated connection as a new definition, and a shape written after a contPos would drop the contPos."""
    out, merged = [], {}
    for line in text.splitlines():
        if not line.strip().startswith("<connection "):
            out.append(line)
            continue
        attrs = dict(re.findall(r'(\w+)=("[^"]*"|\'[^\']*\')', line))
        key = tuple(attrs.get(k) for k in _CONN_KEY)
        if key not in merged:
            merged[key] = {}
            out.append(key)
        merged[key].update(attrs)
    return "\n".join(
        line
        if isinstance(line, str)
        else "    <connection " + " ".join(f"{k}={v}" for k, v in merged[line].items()) + "/>"
        for line in out
    )


def junction_fixes(net, net_file: Path, con_file: Path, edg_file: Path, log: Path, *,
                   first_pass: bool = False) -> dict[str, int]:  # fmt: skip
    """Append the geometric fixes (see ``cosim.scenario.conflicts``) for ``net_file`` to a connection file;
    the stop lines moved back go to a new edge file (``edg_file``, written only when there are some).
    ``first_pass``: the network before any fix, whose looping turns are left for the next rounds (below)."""
    deletions = turnaround_deletions(net)
    deleted = {tuple(re.findall(r'(?:from|to)="([^"]*)"', line)[:2]) for line in deletions}
    fan_outs = fan_out_deletions(net)
    feeds = stranded_lane_connections(net)
    merges, crossed = crossing_merge_deletions(net_file)
    overlaps, overlapping = overlapping_end_deletions(net_file)
    # a loop is judged on the junction the other fixes have reshaped: they push most loops off the movement
    # from the same lane (Krems: 3 in pass 1, none after), and those turns stay
    loops, looping = ([], []) if first_pass else looping_turn_deletions(net_file)
    deletions += merges + overlaps + loops
    deleted |= {tuple(re.findall(r'(?:from|to)="([^"]*)"', line)[:2]) for line in merges + overlaps + loops}
    prohibitions, pairs = geometric_prohibitions(net_file, deleted)
    stops, moved = internal_stop_fixes(net_file)
    shapes, separated = separated_shapes(net_file)
    bars, barred = sibling_change_bars(net_file)
    ends, crossed_ends = approach_end_offsets(net_file)
    if ends:
        edg_file.write_text("<edges>\n" + "\n".join(ends) + "\n</edges>\n")
    body = con_file.read_text().replace("</connections>\n", "") if con_file.exists() else "<connections>\n"
    body = _merge_connection_lines(body + "\n".join(feeds + stops + shapes + bars))
    con_file.write_text(body + "\n" + "\n".join(deletions + fan_outs + prohibitions) + "\n</connections>\n")
    with log.open("a") as fh:
        fh.write(
            "".join(f"{j} {p[0]}->{p[1]} before {q[0]}->{q[1]} ({d} m)\n" for j, p, q, d in pairs)
            + "".join(f"{lane}: internal stop moved from {a} m to {b} m\n" for lane, a, b in moved)
            + "".join(line.strip() + "\n" for line in deletions + fan_outs + feeds)
            + "".join(f"{j} {a} / {b}: {d0} m apart -> {d1} m\n" for j, a, b, d0, d1 in separated)
            + "".join(
                f"{j} {a}->{b}: deleted, its lane end {d} m from another movement's\n"
                for j, a, b, d in overlapping
            )
            + "".join(f"{j} {a}->{b}: deleted, a loop over a movement from its lane\n" for j, a, b in looping)
            + "".join(
                f"{j} {lane}: {k} barred (into a lane a sibling runs beside)\n" for j, lane, k in barred
            )
            + "".join(
                f"{j} {lane}: stop line {d} m back, {via} passes its end\n"
                for j, lane, via, d in crossed_ends
            )
        )
    return {"turnarounds_removed": len(deletions) - len(merges) - len(overlaps) - len(loops),
            "looping_turns_removed": len(loops),
            "lane_fan_outs_removed": len(fan_outs), "stranded_lanes_fed": len(feeds),
            "crossing_merge_lanes_removed": len(merges),
            "overlapping_lanes_removed": len(overlaps),
            "prohibitions_added": len(prohibitions), "internal_stops_moved": len(moved),
            "internal_lanes_reshaped": len(shapes), "sibling_lane_changes_barred": len(bars),
            "stop_lines_moved_back": len(ends)}  # fmt: skip


# netconvert's junction join (--junctions.join) leaves a signalised crossing as two lights when joining would
# give it two parallel incoming roads ("Reducing junction cluster ... (parallel incoming ...)"): Krems 83637441
# and the light beside it, 0.2 m apart. Cars in one junction wait for room in the other, and in `make
# experiment` the crossing locked up with four cars (and the lead) inside. Lights this close are one.
LIGHT_LINK_MAX_M = 1.0
# It also gives up a whole cluster when one edge in it is long ("Not joining junctions ... (long edge)"):
# graphhopper's map-bug432.osm, Wallenhorst Kirchplatz, two priority junctions 0.49 m apart stayed two, and a
# car going straight on was led through a 125-deg left and then a 125-deg right between them (the ego left
# the road there). Junctions whose centres lie this close are one crossing, whatever their type.
JUNCTION_JOIN_MAX_M = 1.0


def junction_joins(net) -> list[list[str]]:
    """Groups of junctions to join: lights linked by a car road shorter than LIGHT_LINK_MAX_M, and any two
    linked by one whose ends lie within JUNCTION_JOIN_MAX_M of each other."""
    parent: dict[str, str] = {}

    def root(n: str) -> str:
        while parent.get(n, n) != n:
            n = parent[n]
        return n

    def one_crossing(a, b) -> bool:
        if a.getType() == b.getType() == "traffic_light":
            return True
        (ax, ay), (bx, by) = a.getCoord()[:2], b.getCoord()[:2]
        return math.hypot(ax - bx, ay - by) < JUNCTION_JOIN_MAX_M

    for e in sorted(net.getEdges(), key=lambda e: e.getID()):
        a, b = e.getFromNode(), e.getToNode()
        if e.allows("passenger") and e.getLength() < LIGHT_LINK_MAX_M and a is not b and one_crossing(a, b):
            ra, rb = root(a.getID()), root(b.getID())
            parent.update({ra: ra, rb: rb, max(ra, rb): min(ra, rb)})
    groups: dict[str, list[str]] = {}
    for n in sorted(parent):
        groups.setdefault(root(n), []).append(n)
    return list(groups.values())


# A map whose drivable part has no loop (a tree of roads cut from a town: a motorway junction with its feeder
# roads, a village street) strands every route at a cut end within minutes. There, each two-way road that the
# extract cut gets a turning loop beyond its end, where the real road would go on: a stem and a one-way circle,
# driven as round a cul-de-sac's island (anticlockwise where traffic keeps right). At 20 km/h the circle holds
# a car below 2 m/s^2 of lateral acceleration (5.56^2 / 16 = 1.9), and each half of it, less the junctions at
# its ends, is longer than HAIRPIN_WITHIN_M: a route through it turns round, but nowhere in a hairpin.
TURNING_LOOP_RADIUS_M = 16.0
TURNING_LOOP_STEM_M = 10.0
TURNING_LOOP_SPEED_MPS = 5.56  # 20 km/h
TURNING_LOOP_STEM_SPEED_MPS = 8.33  # 30 km/h at most on the stem
TURNING_LOOP_CLEARANCE_M = 5.0  # no other road within this of the circle
TURNING_LOOP_ID = "_turning_loop_"  # in the ids of a loop's nodes and edges, after the dead end's id


def is_turning_loop(element_id: str) -> bool:
    """Whether a node or edge id is a turning loop's (no road of the town's: no signs, no trip ends)."""
    return TURNING_LOOP_ID in element_id


@dataclass
class TurningLoops:
    """The dead ends that get a loop and the netconvert patch files' contents."""

    dead_ends: list[str] = field(default_factory=list)
    nodes: list[str] = field(default_factory=list)
    edges: list[str] = field(default_factory=list)
    connections: list[str] = field(default_factory=list)


def turning_loops(net, lefthand: bool) -> TurningLoops:
    """The turning loops a network needs: none when its drivable part has a loop a route can go on through
    for ever (``RouteChainer.endless``). A cut end qualifies when its loop lies outside the convex hull of the
    network's junctions (the extract cut the road there; a cul-de-sac inside the town would put the loop
    through its blocks) and clear of every other road."""
    import shapely

    from cosim.scenario.demand import RouteChainer, drivable_component

    loops = TurningLoops()
    comp = drivable_component(net)
    if RouteChainer(comp).endless:
        return loops
    comp_ids = {e.getID() for e in comp}
    hull = shapely.MultiPoint([n.getCoord()[:2] for n in net.getNodes()]).convex_hull
    roads = {e.getID(): shapely.LineString([p[:2] for p in e.getShape()]) for e in net.getEdges()}
    r = TURNING_LOOP_RADIUS_M
    for node in sorted(net.getNodes(), key=lambda n: n.getID()):
        inc, out = node.getIncoming(), node.getOutgoing()
        if not (len(inc) == 1 and len(out) == 1 and inc[0].getID() in comp_ids
                and out[0].getToNode() is inc[0].getFromNode()):  # fmt: skip
            continue  # not the end of a two-way road
        road, back = inc[0], out[0]
        (x0, y0), (x1, y1) = (p[:2] for p in road.getShape()[-2:])
        length = math.hypot(x1 - x0, y1 - y0)
        if length < 1e-6:
            continue
        dx, dy = (x1 - x0) / length, (y1 - y0) / length  # on, beyond the end
        fx, fy = node.getCoord()[:2]
        ax, ay = fx + dx * TURNING_LOOP_STEM_M, fy + dy * TURNING_LOOP_STEM_M  # the stem's far end
        cx, cy = ax + dx * r, ay + dy * r  # the circle's centre
        if hull.contains(shapely.Point(cx, cy)):
            continue
        disc = shapely.Point(cx, cy).buffer(r + TURNING_LOOP_CLEARANCE_M)
        if any(
            disc.intersects(line) for eid, line in roads.items() if eid not in (road.getID(), back.getID())
        ):
            continue
        side = (-dy, dx) if lefthand else (dy, -dx)  # into the circle by a turn to the kerb side
        first, second = (_arc((cx, cy), (dx, dy), side, t0) for t0 in (0.0, math.pi))
        n = node.getID()
        a, b = n + TURNING_LOOP_ID + "a", n + TURNING_LOOP_ID + "b"
        # the dead end becomes a junction with the stem (netconvert connects nothing at a dead_end node)
        for nid, x, y in ((n, fx, fy), (a, ax, ay), (b, cx + dx * r, cy + dy * r)):
            loops.nodes.append(f'    <node id={quoteattr(nid)} x="{x:.2f}" y="{y:.2f}" type="priority"/>\n')
        like_the_road = f'priority="{road.getPriority()}" type={quoteattr(road.getType())} numLanes="1"'
        stem_mps = min(road.getSpeed(), TURNING_LOOP_STEM_SPEED_MPS)
        for suffix, frm, to, extra in (
            ("out", n, a, f'speed="{stem_mps:.2f}"'),
            ("in", a, n, f'speed="{stem_mps:.2f}"'),
            ("1", a, b, f'speed="{TURNING_LOOP_SPEED_MPS}" spreadType="center" shape="{first}"'),
            ("2", b, a, f'speed="{TURNING_LOOP_SPEED_MPS}" spreadType="center" shape="{second}"'),
        ):
            loops.edges.append(f'    <edge id={quoteattr(n + TURNING_LOOP_ID + suffix)} from={quoteattr(frm)} '
                               f'to={quoteattr(to)} {like_the_road} {extra} name="turning loop"/>\n')  # fmt: skip
        # into the loop instead of turning round; lane by lane: netconvert does not connect a read network's
        # lanes anew from an edge-to-edge connection
        loops.connections.append(
            f"    <delete from={quoteattr(road.getID())} to={quoteattr(back.getID())}/>\n"
        )
        loops.connections += [
            f'    <connection from={quoteattr(road.getID())} to={quoteattr(n + TURNING_LOOP_ID + "out")} '
            f'fromLane="{lane.getIndex()}" toLane="0"/>\n'
            for lane in road.getLanes() if lane.allows("passenger")
        ]  # fmt: skip
        loops.connections.append(f'    <connection from={quoteattr(n + TURNING_LOOP_ID + "in")} '
                                 f'to={quoteattr(back.getID())} fromLane="0" toLane="0"/>\n')  # fmt: skip
        loops.dead_ends.append(n)
    return loops


def _arc(centre, outwards, side, t0: float) -> str:
    """A turning loop's half circle from angle t0 to t0 + pi (0: the point nearest the road's end, pi / 2: to
    ``side`` of the centre) as a netconvert shape."""
    (cx, cy), (dx, dy), (sx, sy), r = centre, outwards, side, TURNING_LOOP_RADIUS_M
    ts = (t0 + math.pi * k / 12 for k in range(13))
    return " ".join(
        f"{cx - r * (math.cos(t) * dx - math.sin(t) * sx):.2f},{cy - r * (math.cos(t) * dy - math.sin(t) * sy):.2f}"
        for t in ts
    )


def add_turning_loops(net, final: Path, workdir: Path, common: list[str], osm_path: Path) -> tuple[list[str], ToolRun | None]:  # fmt: skip
    """Add the ``turning_loops`` that ``net``, read from the network file ``final``, needs, into that file: (their
    dead ends, the netconvert run or None)."""
    loops = turning_loops(net, net.lefthand)
    if not loops.dead_ends:
        return [], None
    files = {}
    for kind, root, lines in (("nod", "nodes", loops.nodes), ("edg", "edges", loops.edges),
                              ("con", "connections", loops.connections)):  # fmt: skip
        files[kind] = workdir / f"loops.{kind}.xml"
        files[kind].write_text(f"<{root}>\n" + "".join(lines) + f"</{root}>\n")
    out = workdir / "loops.net.xml"
    run = run_tool("netconvert", ["--sumo-net-file", str(final), "--node-files", str(files["nod"]),
                                  "--edge-files", str(files["edg"]), "--connection-files", str(files["con"]),
                                  *common, "--offset.disable-normalization", "true", "--output-file", str(out)])  # fmt: skip
    with (workdir / "netconvert.log").open("a") as fh:
        fh.write("\n--- turning loops (a map without a loop) ---\n" + run.log)
    _check("netconvert (turning loops)", run, osm_path)
    os.replace(out, final)
    for f in files.values():
        f.unlink()
    return loops.dead_ends, run


def _check(tool: str, run: ToolRun, osm_path: Path) -> None:
    if run.returncode != 0:
        first = run.errors[0] if run.errors else run.log.strip().splitlines()[-1:] or ["unknown error"]
        raise CosimError(f"{tool} failed on {osm_path}: {first if isinstance(first, str) else first[0]}")


def build_network(
    osm: OsmInfo, behaviour: ScvBehaviour, workdir: Path, *, lefthand: bool = False
) -> NetworkBuild:
    """Run both netconvert passes into ``workdir``; returns the final network and the sign mapping.
    ``lefthand``: traffic keeps to the left (``cosim.scenario.driving_side``)."""
    pass1 = workdir / "pass1.net.xml"
    common = [*COMMON_OPTIONS, *side_options(lefthand)]
    run1 = run_tool("netconvert", pass1_options(osm.path, pass1, lefthand))
    (workdir / "netconvert.log").write_text(run1.log)
    _check("netconvert", run1, osm.path)
    net1 = read_network(pass1, programs=True)
    if not [e for e in net1.getEdges() if e.allows("passenger")]:
        raise CosimError(f"{osm.path} has no drivable road after conversion (no edge open to cars)")
    runs = [("pass1", run1)]

    def repass(patches: dict[str, tuple[str, str, list[str]]], label: str, what: str) -> None:
        """Pass 1 again with patch files, in place; ``patches``: netconvert option -> (file name, root
        element, lines)."""
        nonlocal net1
        args = []
        for option, (name, root, lines) in patches.items():
            (workdir / name).write_text(f"<{root}>\n" + "\n".join(lines) + f"\n</{root}>\n")
            args += [option, str(workdir / name)]
        out = workdir / "repassed.net.xml"
        run = run_tool("netconvert", ["--sumo-net-file", str(pass1), *args,
                                      "--tls.default-type", TLS_TYPE, "--tls.layout", "opposites",
                                      *common, "--offset.disable-normalization", "true",
                                      "--output-file", str(out)])  # fmt: skip
        with (workdir / "netconvert.log").open("a") as fh:
            fh.write(f"\n--- {label} ({what}) ---\n" + run.log)
        _check(f"netconvert ({what})", run, osm.path)
        os.replace(out, pass1)
        for name, _, _ in patches.values():
            (workdir / name).unlink()
        net1 = read_network(pass1, programs=True)
        runs.append((label, run))

    joins = junction_joins(net1)
    if joins:
        repass({"--node-files": ("join.nod.xml", "nodes", [f'    <join nodes="{" ".join(g)}"/>' for g in joins])},
               "pass1b", "one crossing, one junction")  # fmt: skip
    spreads, reversals = oneway_merge_spreads(net1)
    if spreads:
        repass({"--edge-files": ("spread.edg.xml", "edges", spreads),
                "--connection-files": ("spread.con.xml", "connections", reversals)}, "pass1c", "one-way merges")  # fmt: skip
    placements = place_signs(net1, osm)
    files, junction_kind, signed, tls_approaches = write_patches(net1, placements, behaviour, workdir)
    fix_log = workdir / "junction_fixes.txt"
    fix_log.unlink(missing_ok=True)
    ends = workdir / "ends.edg.xml"
    fixes = junction_fixes(net1, pass1, files["con"], ends, fix_log, first_pass=True)
    edge_files = ",".join(str(f) for f in (files["edg"], ends) if f.exists())  # later files modify earlier
    final = workdir / "network.net.xml"
    run2 = run_tool(
        "netconvert",
        ["--sumo-net-file", str(pass1), "--node-files", str(files["nod"]), "--edge-files", edge_files,
         "--connection-files", str(files["con"]), *common,
         "--offset.disable-normalization", "true",  # keep pass 1's coordinates (signs, buildings)
         "--output-file", str(final)],
    )  # fmt: skip
    with (workdir / "netconvert.log").open("a") as fh:
        fh.write("\n--- pass 2 (signs) ---\n" + run2.log)
    _check("netconvert (sign pass)", run2, osm.path)
    pass1.unlink()
    for f in (*files.values(), ends):
        f.unlink(missing_ok=True)
    runs.append(("pass2", run2))
    final_net = read_network(final)
    loop_ends, loop_run = add_turning_loops(final_net, final, workdir, common, osm.path)
    if loop_run is not None:
        runs.append(("turning loops", loop_run))
    # netconvert rebuilds the junctions it patched (a prohibition adds an internal stop, a deleted connection
    # reshapes its neighbours): check the result and fix again until nothing is left
    fixes["fix_rounds"] = 1
    for i in range(FIX_ROUNDS - 1):
        con = workdir / "fixes.con.xml"
        # the first round reads the network once with the loops' check (unless the loops changed the file)
        more = junction_fixes(
            final_net if i == 0 and loop_run is None else read_network(final), final, con, ends, fix_log
        )
        if not any(more.values()):
            con.unlink()
            break
        fixes = {k: fixes[k] + more.get(k, 1) for k in fixes}  # fix_rounds + 1
        fixed = workdir / "fixed.net.xml"
        edge_opts = ["--edge-files", str(ends)] if ends.exists() else []
        run = run_tool("netconvert", ["--sumo-net-file", str(final), "--connection-files", str(con), *edge_opts,
                                      *common, "--offset.disable-normalization", "true",
                                      "--output-file", str(fixed)])  # fmt: skip
        with (workdir / "netconvert.log").open("a") as fh:
            fh.write(f"\n--- junction fixes, round {i + 2} ---\n" + run.log)
        _check("netconvert (junction fixes)", run, osm.path)
        os.replace(fixed, final)
        con.unlink()
        ends.unlink(missing_ok=True)
        runs.append((f"fixes{i + 2}", run))
    plans = split_signal_plans(read_network(final, programs=True))
    write_signal_plans(final, plans)
    fixes["signal_plans_split"] = len(plans)
    fixes["turning_loops"] = len(loop_ends)
    fixes["oneway_merges_spread"] = len(spreads)
    # last: netconvert drops <conflict> elements when it reads a network
    extents = conflict_extents(final, behaviour.min_gap_m)
    write_conflict_extents(final, extents)
    fixes["conflicts_extended"] = len(extents)
    with fix_log.open("a") as fh:
        fh.write(
            "".join(
                f"{line.strip()}: a one-way road's lanes to the kerb side of its line\n" for line in spreads
            )
            + "".join(
                f"{n}: a turning loop beyond the road's cut end (the map has no loop)\n" for n in loop_ends
            )
            + "".join(
                f"{t}: a permissive left on a shared lane, its phase split by approach\n" for t in plans
            )
            + "".join(
                f"{j} {a.from_edge}->{a.to_edge} in the way of {b.from_edge}->{b.to_edge} from {s0} to {s1} m "
                f"(SUMO: {z0} to {z1} m)\n"
                for j, a, b, s0, s1, z0, z1 in extents
            )
        )
    return NetworkBuild(final, placements, junction_kind, signed, tls_approaches, runs, fixes)

"""Issue 15.5: SCVs must not collide at junctions, and they must not jam until SUMO teleports them.

Root causes found in netconvert's junctions built from OSM (cosim/scenario/conflicts.py): movements whose
internal lanes cross or pass closer than a car's width without being foes, left turns waiting inside the
junction with their front in the oncoming lane, one lane fanning out into two side-by-side internal lanes,
U-turns at junctions that are not dead ends, movements that run side by side closer than a car's width without
crossing (SUMO ignores such foes inside the junction: their internal lanes are pushed apart), 1.5-m lanes from
OSM width tags; cars driving into a vehicle that stood in the junction for 20 s (ignore-junction-blocker, now
off) and standoffs at minor links (impatience after 60 s); and free-flow routes that never avoid a jam (SCVs
now reroute).
The geometric tests check the built network itself (fast, no simulation); the plain-SUMO tests run 600 s of
each shipped map's traffic with collision checking on junctions (build.py's sumocfg).
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import sumolib

from cosim.scenario import build_scenario
from cosim.scenario.behaviour import ScvBehaviour
from cosim.scenario.check import check_scenario
from cosim.scenario.conflicts import (
    approach_end_offsets,
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
)

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ("krems", "munich")


@pytest.fixture(scope="module")
def scenarios(tmp_path_factory):
    class Built(dict):
        def __missing__(self, name):
            scn = build_scenario(ROOT / "configs" / "maps" / f"{name}.osm.gz", tmp_path_factory.mktemp(name),
                                 density="medium", seed=1, log=lambda *a: None)  # fmt: skip
            self[name] = scn
            return scn

    return Built()


@pytest.mark.slow
@pytest.mark.parametrize("name", SHIPPED)
def test_built_network_has_no_unsafe_junction_geometry(scenarios, name):
    scn = scenarios[name]
    fixes = scn.report["network"]["junction_fixes"]
    # they were needed (fewer internal stops since every signalised approach has its own green, e753290:
    # no left turn waits inside a signalised junction any more; Munich 7)
    assert fixes["prohibitions_added"] > 10 and fixes["internal_stops_moved"] >= 5, fixes
    net = sumolib.net.readNet(str(scn.net_file), withInternal=False)
    assert turnaround_deletions(net) == []  # no U-turn where the street goes on
    assert fan_out_deletions(net) == []  # one lane feeds one lane, but where a short road's lanes part ways
    assert stranded_lane_connections(net) == []  # such a road's lanes are all fed
    assert oneway_merge_spreads(net) == ([], [])  # no one-way road ends between a two-way road's directions
    _, pairs = geometric_prohibitions(scn.net_file)
    assert pairs == [], pairs[:5]  # every pair of movements closer than a car's width is a foe pair
    _, moved = internal_stop_fixes(scn.net_file)
    assert moved == [], moved[:5]  # no car waits inside a junction in the way of the traffic it waits for
    assert fixes["internal_lanes_reshaped"] > 0, fixes
    # every pair of crossing movements whose conflict SUMO sizes too small has its extent in the network
    assert scn.net_file.read_text().count("<conflict ") == fixes["conflicts_extended"] > 50, fixes
    # movements that do not cross stay apart (before: 0.01 m on Krems, 0.78 m on Munich); where the lanes
    # they join are themselves close (junctions joined by sub-metre edges), up to ~1.4 m are left
    _, close = separated_shapes(scn.net_file)
    assert all(before >= 1.0 for *_, before, _after in close), sorted(close, key=lambda c: c[3])[:5]
    # no movement comes into a junction on a lane lying on top of another movement's lane out (Monaco's
    # case is in test_real_maps)
    assert overlapping_end_deletions(scn.net_file) == ([], [])
    # no movement runs over the last metres of another road's lanes, before their stop line
    assert approach_end_offsets(scn.net_file) == ([], [])
    # no turn loops back over a movement from its own lane
    assert looping_turn_deletions(scn.net_file) == ([], [])


@pytest.mark.slow
@pytest.mark.parametrize("name", SHIPPED)
def test_every_actuated_phase_has_a_detector_sumo_can_use(scenarios, name):
    """SUMO counts a lane's detector only in phases that give all the lane's movements green; a phase without
    one ends at its minimum whatever waits. Krems 71582001 protected the bridge's left turn while the straight
    movement of its lane stood at red: 5 s per cycle, and the turning queue stood through whole cycles."""
    from cosim.sumo_bridge.tools import run_tool

    scn = scenarios[name]
    run = run_tool("sumo", ["-c", str(scn.sumocfg), "--end", "1", "--no-step-log", "true"])
    assert run.returncode == 0, run.errors
    assert not [
        line for line in run.log.splitlines() if "actuated phase" in line and "no controlling" in line
    ]


@pytest.mark.slow
@pytest.mark.parametrize("name", SHIPPED)
def test_600s_of_plain_sumo_on_shipped_map(scenarios, name):
    """Issue 15.5's target: no collision of any kind, at most 1 % of the departed vehicles teleported.

    Measured (medium, seeds 1-3, 600 s, tau 2 s): Munich 0/0/0 collisions, 0.2-1.5 % teleported; Krems
    4/2/8 -> 0/0/1 collisions (non-crossing movements pushed apart, no ignore-junction-blocker, impatience
    after 60 s), but 1.6-2.5 % teleported (queues at stop and minor approaches that cannot take the flow).
    With trips from street to street and stop lines moved back behind turns (session 22): Krems 0
    collisions, 1.06 % teleported (18 of 1694) on the tested seed. With no turning round in short stubs and
    parking aisles closed to cars (266477f): Krems 0 collisions, 0.65 % (10 of 1538); Munich 0 / 0 %.

    One SUMO seed is a lottery (any change of the network reshuffles the routes), so five are run. Krems,
    SUMO seeds 1-10 (the scenario's own, then 2-10): 2 collisions, both inside the crossing of 83637441 and
    the light 0.2 m beside it, and 4-29 teleports (up to 1.9 %); with that crossing one junction and no
    turning round through short loops (session 28): 0 collisions, 9-13 teleports (0.6-0.85 %); with the
    conflict extents on top: 0 collisions, 109 teleports in the 10 runs (0.7 %).

    The target is the share over the five seeds; a single seed may reach 1.5 %. Per seed the share is one
    draw of a random variable: on Krems, seeds 1-5 gave 7 / 11 / 12 / 11 / 14 teleports of ~1,535 departures
    (0.46-0.91 %) and, after the one-way merge spread changed two junctions and with them the routes drawn,
    12 / 9 / 20 / 13 / 12 (0.59-1.30 %, 0.86 % over the five), none of them at the two junctions changed:
    a third of them are a queue at the minor road 146409276 (left turns into a stream) backing up through
    the compact roundabout 50845692. Asking every seed for 1 % failed a network change by that lottery
    alone.
    """
    scn = scenarios[name]
    results = [check_scenario(scn.dir, 600.0, seed=seed, record=False) for seed in (None, 2, 3, 4, 5)]
    for result in results:
        assert result["departed"] > 300, result
        assert result["teleport_share"] <= 0.015, result
        assert result["collisions"] == 0, result["collision_list"][:5]
    teleports, departed = sum(r["teleports"] for r in results), sum(r["departed"] for r in results)
    assert teleports <= 0.01 * departed, [(r["teleports"], r["departed"]) for r in results]


def test_scvs_reroute_and_the_ego_type_does_not():
    import numpy as np

    xml = ScvBehaviour(n_vtypes=2).vtype_distribution_xml(np.random.default_rng(0))
    assert xml.count('key="has.rerouting.device" value="true"') == 2
    assert 'key="device.rerouting.period" value="30"' in xml
    assert "rerouting" not in ScvBehaviour(n_vtypes=1, reroute_period_s=0).vtype_distribution_xml(
        np.random.default_rng(0)
    )
    with pytest.raises(ValueError):
        ScvBehaviour(reroute_period_s=-1)


def test_a_turn_that_doubles_back_within_a_car_length_is_a_u_turn(tmp_path):
    """Monaco 258068679: a one-way road leaves a two-way road's junction heading back beside it; netconvert
    calls the turn into it from the far side a "left", but it reverses the heading within 2 m, which no car
    can. It goes like a turnaround where the street goes on; the road's own way on and a real left stay."""
    from tests.plain_net import plain_net

    # S <-> C <-> N two-way; the one-way C -> X leaves C southwards, 3 m beside C -> S; W -> C a side road
    nodes = {"S": (0, -100), "C": (0, 0), "N": (0, 100), "X": (4, -100), "W": (-100, 0)}
    edges = {"SC": ("S", "C", 2), "CS": ("C", "S", 2), "NC": ("N", "C", 2), "CN": ("C", "N", 2),
             "CX": ("C", "X", 1), "WC": ("W", "C", 1)}  # fmt: skip
    net = sumolib.net.readNet(str(plain_net(tmp_path, nodes, edges, priority_nodes=["C"])))
    assert "CX" in [e.getID() for e in net.getEdge("SC").getOutgoing()]  # netconvert built the turn
    deleted = turnaround_deletions(net)
    assert [line for line in deleted if 'from="SC" to="CX"' in line], deleted
    assert not [line for line in deleted if 'to="CX"' in line and 'from="SC"' not in line], deleted


def test_a_turn_that_loops_back_over_a_movement_from_its_lane_goes():
    """graphhopper's north-bayreuth extract, cluster_21636285_331939793 (the junction as cosim built it, in
    tests/data): the "right" from 39407891#2 into -155200273 reverses the heading between lane ends 8.6 m
    apart, within the 14.6-m circle of the design car's 7.3-m minimum radius, through a 24-m loop over the
    path of the straight movement from the same lane; SUMO never holds those two apart, and the next car
    straight on hit the turning one (cosim seed 1, plain SUMO seed 2). The loop goes and every other movement
    of the junction stays (the shipped maps have no such loop once built: the geometry test above)."""
    import math

    from cosim.scenario.conflicts import (
        TURNING_CIRCLE_M,
        U_TURN_DEG,
        _heading_change_deg,
        _read,
        looping_turn_deletions,
    )

    net_file = ROOT / "tests" / "data" / "north_bayreuth_loop.net.xml"
    shapes, _, _ = _read(net_file)
    a, b = shapes["39407891#2_0"], shapes["-155200273_0"]
    assert _heading_change_deg(a, b) > U_TURN_DEG and math.dist(a[-1], b[0]) < TURNING_CIRCLE_M
    lines, report = looping_turn_deletions(net_file)
    assert report == [("cluster_21636285_331939793", "39407891#2_0", "-155200273_0")]
    assert lines == ['    <delete from="39407891#2" to="-155200273" fromLane="0" toLane="0"/>']


@pytest.mark.slow
def test_one_crossing_is_one_junction_and_no_car_turns_round_inside_it(scenarios):
    """Krems 83637441 and the light beside it are one crossing, which netconvert left as two lights joined
    by 0.2-m links (its "parallel incoming" reduction). SCVs that A* sent back up Hafenstrasse turned round
    through both links, and one stood at the red crosswise over the next lane, where a car going straight
    on hit it (the collision of `make experiment`, P2 system_B); with that turn removed but the two lights
    left, four cars and the lead locked the crossing up from inside. The pipeline joins lights that close
    into one junction: one signal, SUMO's own foe relations between all its movements, no U-turn (where
    the street goes on), and every movement of the crossing still there."""
    from cosim.scenario.conflicts import _short_loop
    from cosim.scenario.network import junction_joins

    scn = scenarios["krems"]
    net = sumolib.net.readNet(str(scn.net_file))
    assert junction_joins(net) == []
    crossing = net.getEdge("104372792#0").getToNode()
    assert "83637441" in crossing.getID() and "1204188756" in crossing.getID(), crossing.getID()
    assert crossing.getType() == "traffic_light"
    north, south = net.getEdge("104372792#0"), net.getEdge("-104372792#0")
    assert south not in north.getOutgoing()  # no U-turn back up Hafenstrasse
    assert {e.getID() for e in north.getOutgoing()} == {"104372792#3", "4776001#4", "53304184#7"}
    assert [
        (e.getID(), t.getID()) for e in net.getEdges() for t in e.getOutgoing() if _short_loop(e, t)
    ] == []


def test_no_turning_round_in_a_stub_too_short_for_it_and_no_cars_in_parking_aisles(tmp_path):
    """Krems 34170840: route-pool and rerouted SCVs turned round in a 2.4-m stub off a main road; the first
    one waited on the main road for room and the queue behind it stood 300 s. Krems 860978174: SCVs cut
    through a parking lot whose junctions lie 0.2 m apart and collided there. The pipeline deletes the
    turnaround at the end of a road shorter than a turning circle and closes parking aisles and driveways to
    cars, so those leave the drivable component and no route enters them; a dead-end street and a plain
    service road keep their turnaround."""
    from osm_factory import OsmSketch

    from cosim.scenario.conflicts import DEAD_END_TURN_MIN_M
    from cosim.scenario.demand import drivable_component

    s = OsmSketch()
    corners = {"a": (0, 0), "b": (200, 0), "c": (400, 0), "d": (400, 300), "e": (200, 300), "f": (0, 300)}
    ends = {"drive": (200, -25), "stub": (200, 312), "close": (520, 0), "yard": (0, -40), "p1": (300, 100),
            "p2": (300, 200)}  # fmt: skip
    for name, (x, y) in {**corners, **ends}.items():
        s.node(name, x, y)
    s.way(["a", "b", "c", "d", "e", "f", "a"], highway="residential", maxspeed="50")
    s.way(["b", "e"], highway="residential", maxspeed="30")
    driveway = s.way(["b", "drive"], highway="service", service="driveway")
    stub = s.way(["e", "stub"], highway="residential")
    cul_de_sac = s.way(["c", "close"], highway="residential")
    yard = s.way(["a", "yard"], highway="service")
    aisle = s.way(["c", "p1", "p2", "d"], highway="service", service="parking_aisle")  # a short cut
    scn = build_scenario(s.write(tmp_path / "town.osm"), tmp_path / "scn", density="low", seed=1,
                         log=lambda *a: None)  # fmt: skip
    net = sumolib.net.readNet(str(scn.net_file))
    comp = {e.getID() for e in drivable_component(net)}
    for way, driven in ((driveway, False), (stub, False), (cul_de_sac, True), (yard, True), (aisle, False)):
        edge = net.getEdge(way)
        assert edge.allows("passenger") is (way not in (driveway, aisle)), way
        assert (way in comp) is driven and (f"-{way}" in comp) is driven, (way, sorted(comp))
    for way, turns in ((stub, False), (cul_de_sac, True), (yard, True)):
        assert bool(net.getEdge(way).getOutgoing()) is turns, way
    assert net.getEdge(stub).getLength() < DEAD_END_TURN_MIN_M < net.getEdge(yard).getLength()


def test_no_lane_change_inside_a_junction_into_the_lane_a_slip_road_runs_beside(tmp_path):
    """Krems 448934090: lane 0 of a two-lane road feeds both the road on and a slip road leaving at a shallow
    angle, and the two internal lanes run side by side through the junction. SUMO's lane changer does not
    look at the slip road's lane: a car on the road's other internal lane changed into the one beside it,
    onto a car standing there. That change is barred; the road without a slip road keeps its changes."""
    from cosim.sumo_bridge.tools import run_tool
    from tests.plain_net import plain_net

    nodes = {"W": (-200, 0), "C": (0, 0), "E": (200, 0), "R": (200, -25)}
    edges = {"WC": ("W", "C", 2, 2), "CE": ("C", "E", 2, 2), "CR": ("C", "R", 1)}
    net_file = plain_net(tmp_path, nodes, edges, priority_nodes=["C"])
    net = sumolib.net.readNet(str(net_file), withInternal=True)
    from_lane0 = {c.getTo().getID() for c in net.getEdge("WC").getLane(0).getOutgoing()}
    assert from_lane0 == {"CE", "CR"}, from_lane0  # the shared lane the issue is about
    lines, barred = sibling_change_bars(net_file)
    # the straight movement's internal edge has two lanes; no change from lane 1 into lane 0 beside CR's
    assert len(lines) == 1 and 'fromLane="1"' in lines[0] and 'changeRight="authority"' in lines[0], lines
    assert [k for _j, _lane, k in barred] == ["changeRight"], barred
    con = tmp_path / "bars.con.xml"
    con.write_text("<connections>\n" + "\n".join(lines) + "\n</connections>\n")
    fixed = tmp_path / "fixed.net.xml"
    run = run_tool("netconvert", ["-s", str(net_file), "-x", str(con), "-o", str(fixed)])
    assert run.returncode == 0, run.log
    assert "changeRight" in fixed.read_text()
    assert sibling_change_bars(fixed) == ([], [])  # a later round of fixes adds nothing
    # the same road without the slip road: nothing barred
    (tmp_path / "plain").mkdir()
    no_slip = plain_net(tmp_path / "plain", {k: nodes[k] for k in "WCE"}, {k: edges[k] for k in ("WC", "CE")},
                        priority_nodes=["C"])  # fmt: skip
    assert sibling_change_bars(no_slip) == ([], [])


def _two_road_junction(tmp_path: Path, half_m: float, roads: dict, connections: str) -> Path:
    """A priority junction C (a square of ``half_m`` each way) where one-lane roads meet: for each ``name`` of
    ``roads`` (the first is the major road) an edge ``name_in`` from its first point to C and ``name_out``
    from C to its second; ``connections`` is netconvert's connection file content. Returns the network."""
    from cosim.sumo_bridge.tools import run_tool

    h = half_m
    nodes = [f'<node id="C" x="0" y="0" type="priority" shape="-{h},-{h} {h},-{h} {h},{h} -{h},{h}"/>']
    edges, lane = [], 'numLanes="1" speed="13.9" spreadType="center"'
    for rank, (name, (start, end)) in enumerate(roads.items()):
        nodes += [
            f'<node id="{name}0" x="{start[0]}" y="{start[1]}"/>',
            f'<node id="{name}1" x="{end[0]}" y="{end[1]}"/>',
        ]
        prio = 3 if rank == 0 else 1
        edges += [f'<edge id="{name}_in" from="{name}0" to="C" priority="{prio}" {lane}/>',
                  f'<edge id="{name}_out" from="C" to="{name}1" priority="{prio}" {lane}/>']  # fmt: skip
    (tmp_path / "n.nod.xml").write_text(f"<nodes>{''.join(nodes)}</nodes>")
    (tmp_path / "n.edg.xml").write_text(f"<edges>{''.join(edges)}</edges>")
    (tmp_path / "n.con.xml").write_text(f"<connections>{connections}</connections>")
    net = tmp_path / "n.net.xml"
    run = run_tool("netconvert", ["-n", str(tmp_path / "n.nod.xml"), "-e", str(tmp_path / "n.edg.xml"),
                                  "-x", str(tmp_path / "n.con.xml"), "--no-turnarounds", "true", "-o", str(net)])  # fmt: skip
    assert run.returncode == 0, run.log
    return net


def test_a_car_standing_past_a_crossing_that_bends_alongside_is_waited_for(tmp_path):
    """SUMO clears a car standing past a crossing once its rear is half a conflict size (from the angle at
    the crossing only) beyond it (SUMO issue #12721). A turn that crosses a road at 75 deg and then bends to
    run 1.5 m beside it: a car F on the turn, stopped behind a standing car X, stands 2.4 m past the crossing
    with its body still over the road, and the car E on the road drove into it. With the pipeline's conflict
    extents (``conflict_extents``, written into the net file) E waits until F has gone."""
    from cosim.scenario.conflicts import conflict_extents, write_conflict_extents
    from cosim.sumo_bridge.tools import run_tool

    net = _two_road_junction(
        tmp_path, 12, {"b": ((-100, 0), (100, 0)), "a": ((-26.795, -100), (100, 25))},
        '<connection from="b_in" to="b_out" fromLane="0" toLane="0"/>'
        '<connection from="a_in" to="a_out" fromLane="0" toLane="0" keepClear="false" '
        'shape="-3.2154,-12 0.268,1.0 1.2,1.5 8,1.5 12,3"/>',
    )  # fmt: skip
    # F's minGap puts its rear 2.4 m past the crossing behind X; E comes along the road at 20 s
    (tmp_path / "r.rou.xml").write_text(
        '<routes><vType id="car" sigma="0" length="5" width="1.8" minGap="2.5"/>'
        '<vType id="carF" sigma="0" length="5" width="1.8" minGap="5.77"/>'
        '<vehicle id="X" type="car" depart="0" departPos="5" departSpeed="0"><route edges="a_out"/>'
        '<stop lane="a_out_0" endPos="5" duration="1000"/></vehicle>'
        '<vehicle id="F" type="carF" depart="0" departPos="40" departSpeed="max"><route edges="a_in a_out"/>'
        '</vehicle><vehicle id="E" type="car" depart="20" departPos="40" departSpeed="max">'
        '<route edges="b_in b_out"/></vehicle></routes>'
    )

    def collisions(net_file):
        out = tmp_path / f"{net_file.stem}.collisions.xml"
        run = run_tool("sumo", ["-n", str(net_file), "-r", str(tmp_path / "r.rou.xml"), "--end", "80",
                                "--collision.check-junctions", "true", "--collision.action", "warn",
                                "--collision-output", str(out), "--no-step-log", "true"])  # fmt: skip
        assert run.returncode == 0, run.log
        return out.read_text().count("<collision ")

    assert collisions(net) == 1  # the premise: SUMO alone lets E into F
    extents = conflict_extents(net, min_gap_m=2.5)  # the route file's car minGap
    # both ways: F past the crossing in E's way, and a car on the road in the way of the turn bending beside it
    assert sorted((a.from_edge, b.from_edge) for _j, a, b, *_ in extents) == [
        ("a_in", "b_in"),
        ("b_in", "a_in"),
    ]
    start, end, sumo_start, sumo_end = next(e[3:] for e in extents if e[1].from_edge == "a_in")
    assert (
        start <= sumo_start and sumo_end < 14.8 < end
    )  # F's rear (14.82 along the turn) is inside the extent, not SUMO's
    write_conflict_extents(net, extents)
    assert "<conflict " in net.read_text()
    assert collisions(net) == 0


def test_a_car_is_not_let_through_the_first_of_two_crossings(tmp_path):
    """SUMO keeps one crossing per pair of internal lanes, each lane's last (MSLink::setRequestInformation).
    graphhopper's campo-grande extract, cluster_1550538044_1550538067_1663974447: a right turn looping 44 m
    through the junction crosses the straight movement that yields to it twice; SUMO let the waiting car go
    once the turning one was inside the junction and past the crossing SUMO knew of, and the two met at the
    other one (cosim seed 1, 239 s). Here the same geometry: a yielding car M and a car J on a looping turn.
    With the pipeline's conflict extents, which start before the first crossing, M waits until J is through
    and then goes."""
    from cosim.scenario.conflicts import conflict_extents, write_conflict_extents
    from cosim.sumo_bridge.tools import run_tool

    # the turn crosses the straight path near the junction's centre and again near the straight's start
    net = _two_road_junction(
        tmp_path, 15, {"m": ((100, 5), (-12, 100)), "n": ((-80, 80), (80, -80))},
        '<connection from="n_in" to="n_out" fromLane="0" toLane="0"/>'
        '<connection from="m_in" to="m_out" fromLane="0" toLane="0" shape="15,5 3,2 -4,-2 -9,4 -11.8,15"/>'
        '<prohibition prohibitor="m_in->m_out" prohibited="n_in->n_out"/>',
    )  # fmt: skip
    (tmp_path / "r.rou.xml").write_text(
        '<routes><vType id="car" sigma="0" length="5" width="1.8" minGap="2.5"/>'
        '<vehicle id="M" type="car" depart="0" departPos="60" departSpeed="0"><route edges="n_in n_out"/>'
        '</vehicle><vehicle id="J" type="car" depart="2" departPos="0" departSpeed="max">'
        '<route edges="m_in m_out"/></vehicle></routes>'
    )

    def drive(net_file):
        out, trips = tmp_path / f"{net_file.stem}.collisions.xml", tmp_path / f"{net_file.stem}.trips.xml"
        run = run_tool("sumo", ["-n", str(net_file), "-r", str(tmp_path / "r.rou.xml"), "--end", "80",
                                "--collision.check-junctions", "true", "--collision.action", "warn",
                                "--collision-output", str(out), "--tripinfo-output", str(trips),
                                "--step-length", "0.1", "--no-step-log", "true"])  # fmt: skip
        assert run.returncode == 0, run.log
        return out.read_text().count("<collision "), trips.read_text().count("<tripinfo ")

    assert drive(net) == (1, 2)  # the premise: SUMO alone lets M into J at the first crossing
    extents = conflict_extents(net, min_gap_m=2.5)
    start, end, sumo_start, sumo_end = next(e[3:] for e in extents if e[1].from_edge == "n_in")
    assert start < sumo_start - 10.0 and end >= sumo_end  # from before the first crossing to past the last
    write_conflict_extents(net, extents)
    assert drive(net) == (0, 2)  # M waited, then both arrived


def test_a_pushed_shape_never_folds_back():
    """Monaco 25345339: pushes apart that kept a left turn from crossing itself folded its end back and forth,
    and SUMO, meeting the other movement's lane seven times along it, let a car on each go into the other.
    A shape that turns back between two 0.5-m steps is not pushed on; a car's tight turn is no fold."""
    from cosim.scenario.conflicts import _folds, _resample

    folded = [(364.56, 295.17), (366.21, 301.44), (367.78, 303.29), (368.70, 305.02), (368.48, 306.50),
              (366.84, 307.90), (367.50, 309.62), (368.48, 311.31), (367.88, 310.76), (368.27, 313.21)]  # fmt: skip
    assert _folds(_resample(folded))
    # a left turn on the 7.3-m minimum radius, sampled every 0.1 rad
    turn = [(7.3 * math.cos(t / 10), 7.3 * math.sin(t / 10)) for t in range(16)]
    assert not _folds(_resample(turn))

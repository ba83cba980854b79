"""Each sign rule of the scenario pipeline on a small hand-made OSM map (paper IV.A)."""

from __future__ import annotations

import pytest
import sumolib
from osm_factory import OsmSketch, crossroads

from cosim.scenario import build_scenario
from cosim.scenario.network import is_turning_loop
from cosim.scenario.signs import load_signs


def build(sketch: OsmSketch, tmp_path, name="map"):
    osm = sketch.write(tmp_path / f"{name}.osm")
    scn = build_scenario(osm, tmp_path / f"{name}-scn", density="low", seed=1, log=lambda *a: None)
    net = sumolib.net.readNet(str(scn.net_file), withInternal=True, withPrograms=True)
    return scn, net, load_signs(scn.signs_file)


def node_of(net, sketch: OsmSketch, name: str):
    """The network junction of a sketch node (junction ids are OSM node ids, or clusters of them)."""
    osm_id = sketch.ids[name]
    return next(n for n in net.getNodes() if osm_id in n.getID().removeprefix("cluster_").split("_"))


def test_stop_sign_on_the_junction_node(tmp_path):
    sk = crossroads(centre_tags={"highway": "stop"})
    scn, net, signs = build(sk, tmp_path)
    assert node_of(net, sk, "c").getType() == "priority_stop"
    stops = [s for s in signs if s.kind == "stop"]
    assert len(stops) == 2  # both minor (residential) approaches
    assert all(min(s.heading_deg % 180, 180 - s.heading_deg % 180) < 5 for s in stops)  # north/south-bound
    assert scn.report["network"]["stop_junctions"] == 1


def test_all_way_stop(tmp_path):
    sk = crossroads(centre_tags={"highway": "stop", "stop": "all"})
    _, net, signs = build(sk, tmp_path)
    assert node_of(net, sk, "c").getType() == "allway_stop"
    assert len([s for s in signs if s.kind == "allway_stop"]) == 4


def test_give_way_on_the_junction_node_slows_minor_connections(tmp_path):
    sk = crossroads(minor="residential", major="secondary", centre_tags={"highway": "give_way"})
    _, net, signs = build(sk, tmp_path)
    j = node_of(net, sk, "c")
    assert j.getType() == "priority"
    assert len([s for s in signs if s.kind == "give_way"]) == 2
    minor_in = [e for e in j.getIncoming() if e.getType() == "highway.residential"]
    assert len(minor_in) == 2
    checked = 0
    for edge in minor_in:
        for conns in edge.getOutgoing().values():
            for c in conns:
                # every connection across the junction has an internal lane: that lane carries the speed
                assert c.getViaLaneID(), f"{c.getFrom().getID()} -> {c.getTo().getID()} has no internal lane"
                assert net.getLane(c.getViaLaneID()).getSpeed() == pytest.approx(5 / 3.6, abs=0.01)
                checked += 1
    assert checked >= 6  # straight, left and right (and turnarounds) from both minor approaches


def test_a_wide_give_way_junction_is_crossed_within_the_passage_time(tmp_path):
    """Across an eight-lane road the 5 km/h of the give-way line would take ~25 s (SUMO holds a connection's
    speed over its whole passage); such passages are crossed in GIVE_WAY_PASSAGE_MAX_S; short ones (the right
    turn) keep the walking pace of the paper."""
    from cosim.scenario.network import GIVE_WAY_PASSAGE_MAX_S

    sk = crossroads(minor="residential", major="primary", major_tags={"lanes": "8"},
                    centre_tags={"highway": "give_way"})  # fmt: skip
    _, net, _ = build(sk, tmp_path)
    j = node_of(net, sk, "c")
    walking = 5 / 3.6
    speeds = {}
    for edge in (e for e in j.getIncoming() if e.getType() == "highway.residential"):
        for conns in edge.getOutgoing().values():
            for c in conns:
                (x0, y0), (x1, y1) = c.getFromLane().getShape()[-1][:2], c.getToLane().getShape()[0][:2]
                chord = ((x1 - x0) ** 2 + (y1 - y0) ** 2) ** 0.5
                speed = net.getLane(c.getViaLaneID()).getSpeed()
                assert speed == pytest.approx(max(walking, chord / GIVE_WAY_PASSAGE_MAX_S), abs=0.05)
                speeds[c.getDirection()] = max(speed, speeds.get(c.getDirection(), 0.0))
    assert speeds["s"] > 2 * walking  # straight over ~30 m of junction: ~2.5 m/s, not 1.4
    assert speeds["r"] == pytest.approx(walking, abs=0.01)  # an ordinary turn keeps the paper's pace


@pytest.mark.parametrize("direction", ["forward", "backward"])
def test_give_way_on_an_approach_node_with_direction(tmp_path, direction):
    """Two equal residential roads (right-before-left by default); a give-way sign 30 m south of the
    junction governs only the northbound approach, whichever way the OSM way is drawn."""
    s = OsmSketch()
    s.node("c", 0, 0)
    for nid, x, y in (("w", -300, 0), ("e", 300, 0), ("s", 0, -300), ("n", 0, 300)):
        s.node(nid, x, y)
    s.node("g", 0, -30, highway="give_way", direction=direction)
    s.way(["w", "c", "e"], highway="residential")
    # forward: way drawn south -> north (traffic towards c moves forward); backward: drawn north -> south
    s.way(["s", "g", "c", "n"] if direction == "forward" else ["n", "c", "g", "s"], highway="residential")
    _, net, signs = build(s, tmp_path, name=direction)
    j = node_of(net, s, "c")
    assert j.getType() == "priority"
    gw = [sg for sg in signs if sg.kind == "give_way"]
    assert len(gw) == 1
    edge = net.getEdge(gw[0].edge)
    assert edge.getToNode() is j
    assert edge.getFromNode().getCoord()[1] < j.getCoord()[1]  # the approach from the south
    others = [e for e in j.getIncoming() if e is not edge and e.getFunction() != "internal"]
    assert all(edge.getPriority() < e.getPriority() for e in others)


def test_speed_limit_change_gives_a_sign_each_way(tmp_path):
    s = OsmSketch()
    s.node("a", -400, 0)
    s.node("m", 0, 0)
    s.node("b", 400, 0)
    s.way(["a", "m"], highway="secondary", maxspeed="50")
    s.way(["m", "b"], highway="secondary", maxspeed="30")
    _, net, signs = build(s, tmp_path)
    limits = sorted((sg.value, round(sg.heading_deg / 90) * 90) for sg in signs if sg.kind == "speed_limit")
    assert limits == [(30, 90), (50, 270)]  # eastbound enters the 30 zone, westbound the 50 zone
    assert {sg.source for sg in signs if sg.kind == "speed_limit"} == {"maxspeed"}


def test_speed_limit_implied_by_road_type(tmp_path):
    s = OsmSketch()
    s.node("a", -400, 0)
    s.node("m", 0, 0)
    s.node("b", 400, 0)
    s.way(["a", "m"], highway="trunk")  # no maxspeed: the road type's default limit (100 km/h, an expressway)
    s.way(["m", "b"], highway="residential")  # 50 km/h
    _, _, signs = build(s, tmp_path)
    limit_signs = [sg for sg in signs if sg.kind == "speed_limit"]
    assert len(limit_signs) == 2
    assert {sg.source for sg in limit_signs} == {"road_type"}


def test_an_untagged_town_main_road_has_the_urban_limit(tmp_path):
    """Primary, secondary and tertiary roads without a maxspeed tag get the urban legal default, 50 km/h (as
    SUMO's osmNetconvertUrbanDe typemap), not SUMO's rural 100 km/h; a tag still wins."""
    s = OsmSketch()
    for name, x in (("a", -400), ("m", 0), ("b", 400), ("c", 800)):
        s.node(name, x, 0)
    s.way(["a", "m"], highway="primary")
    s.way(["m", "b"], highway="tertiary")
    s.way(["b", "c"], highway="secondary", maxspeed="70")
    _, net, _ = build(s, tmp_path)
    speeds = {e.getType().removeprefix("highway."): round(e.getSpeed() * 3.6) for e in net.getEdges()
              if e.getType().startswith("highway.") and not is_turning_loop(e.getID())}  # fmt: skip
    assert speeds == {"primary": 50, "tertiary": 50, "secondary": 70}


def test_one_way_sign_where_a_one_way_road_leaves_a_two_way_junction(tmp_path):
    sk = crossroads(major="secondary", minor="residential")
    sk.node("x", 300, 300)
    sk.way(["n", "x"], highway="residential", oneway="yes")  # leaves the northern arm's end node
    sk.node("y", -300, 300)
    sk.way(["y", "n"], highway="residential")  # a two-way road also meets at n
    sk.node("z", 600, 300)
    sk.way(["x", "z"], highway="residential")  # and one at the one-way's far end x
    sk.node("q", 300, 600)
    sk.way(["x", "q"], highway="residential")
    _, net, signs = build(sk, tmp_path)
    one_way = [s for s in signs if s.kind == "one_way"]
    assert one_way, "a one-way entry sign is expected at n"
    edge = net.getEdge(one_way[0].edge)
    assert edge.getToNode() is node_of(net, sk, "x")
    no_entry = [s for s in signs if s.kind == "no_entry"]
    assert [net.getEdge(s.edge).getToNode() for s in no_entry] == [node_of(net, sk, "x")]


def test_turn_lanes_are_honoured(tmp_path):
    sk = crossroads(major="primary", minor="secondary",
                    major_tags={"lanes": "3", "oneway": "yes", "turn:lanes": "left|through|right"})  # fmt: skip
    _, net, _ = build(sk, tmp_path)
    j = node_of(net, sk, "c")
    (eastbound,) = [e for e in j.getIncoming() if e.getFromNode() is node_of(net, sk, "w")]
    assert eastbound.getLaneNumber() == 3
    dirs = {}
    for conns in eastbound.getOutgoing().values():
        for c in conns:
            dirs.setdefault(c.getFromLane().getIndex(), set()).add(c.getDirection())
    assert dirs == {0: {"r"}, 1: {"s"}, 2: {"l"}}  # OSM lists lanes left to right, SUMO right to left


def test_traffic_light_from_osm(tmp_path):
    sk = crossroads(centre_tags={"highway": "traffic_signals"})
    _, net, signs = build(sk, tmp_path)
    assert node_of(net, sk, "c").getType() == "traffic_light"
    assert len([s for s in signs if s.kind == "traffic_light"]) == 4


def _green_approaches(net, tls_id: str) -> list[set[str]]:
    """For each green phase of a light, the incoming edges with a green (G or g) link."""
    tls = net.getTLS(tls_id)
    edge_of = {i: inl.getEdge().getID() for inl, _, i in tls.getConnections()}
    phases = [ph.state for prog in tls.getPrograms().values() for ph in prog.getPhases()]
    return [{edge_of[i] for i, s in enumerate(state) if s in "Gg" and i in edge_of} for state in phases
            if "G" in state or "g" in state]  # fmt: skip


def test_a_left_turn_sharing_its_lane_gets_its_own_approach_green(tmp_path):
    """Single-lane two-way roads: every left turn shares its lane, so it would wait at a permissive green
    for gaps and block the lane; every approach gets its own green and no link is left permissive."""
    sk = crossroads(major="secondary", minor="tertiary", centre_tags={"highway": "traffic_signals"})
    _, net, _ = build(sk, tmp_path)
    (tls,) = net.getTrafficLights()
    greens = _green_approaches(net, tls.getID())
    assert len(greens) == 4 and all(len(g) == 1 for g in greens)
    states = [ph.state for prog in tls.getPrograms().values() for ph in prog.getPhases()]
    assert not any("g" in s for s in states)

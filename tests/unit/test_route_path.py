"""The ego's route path: projection of the car onto it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fake_net import Conn, Edge, Lane, Net, Node

from cosim.driver.route import RoutePath


def path_through(points: list[tuple[float, float]]) -> RoutePath:
    """A RoutePath over a hand-made centre line (the network part is not needed to project)."""
    return RoutePath(points)


def _lanes(path: RoutePath) -> list[tuple[str, int]]:
    return [(eid, lane) for _, _, eid, lane in path.edge_lanes]


def test_a_route_that_passes_an_edge_twice_knows_its_lane_on_each_pass():
    """A route round a block comes back onto an edge it started on, leaving it by another lane: the lane is
    the one of the pass nearest the asking position (keyed by edge alone, the lead was held in the first
    pass's lane 0 at the end of the second, where its way went on from lane 1: Munich seed 1, 135 s)."""
    path = RoutePath([(0.0, 0.0), (0.0, 300.0)], edge_lanes=[(0.0, 100.0, "b", 0), (100.0, 200.0, "c", 2),
                                                            (200.0, 300.0, "b", 1)])  # fmt: skip
    assert path.lane_on("b", 20.0) == 0
    assert path.lane_on("b", 290.0) == 1
    assert path.lane_on("b", 180.0) == 1  # about to come onto it again
    assert path.lane_on("c", 0.0) == 2
    assert path.lane_on("x", 0.0) is None


def test_a_later_pass_close_by_does_not_capture_the_projection():
    """A route that comes back 1.5 m beside itself a few points later (a block round, then the parallel
    road): the car 1 m off its current pass stays on it, though the later pass is nearer."""
    p = path_through([(0, 0), (100, 0), (100, 200), (300, 200), (300, 1.5), (-50, 1.5)])
    for x in np.arange(0.0, 95.0, 2.0):
        s, offset = p.project(float(x), 1.0)
        assert abs(s - x) < 1e-9 and abs(offset - 1.0) < 1e-9
    # driving the whole route, the car is found on each pass in turn
    p._last_s = 0.0
    for s_true in np.arange(0.0, p.length_m, 2.0):
        x, y = np.interp(s_true, p.s, p.xy[:, 0]), np.interp(s_true, p.s, p.xy[:, 1])
        s, offset = p.project(float(x), float(y))
        assert abs(s - s_true) < 1e-6 and abs(offset) < 1e-6


def test_a_second_point_tracked_near_its_own_arc_position_leaves_the_ego_projection_alone():
    """The lead's rear is projected near its own arc position; the ego's last hit stays where it was."""
    p = path_through([(0, 0), (100, 0), (100, 200), (300, 200), (300, 1.5), (-50, 1.5)])
    s_ego, _ = p.project(10.0, 0.5)
    s_lead, off = p.project(100.5, 30.0, near_s=120.0)
    assert abs(s_lead - 130.0) < 1e-9 and abs(off + 0.5) < 1e-9  # right of the northward pass
    assert p._last_s == s_ego


def test_the_lane_at_a_position_is_the_internal_lane_inside_a_junction_and_the_edges_lane_on_it():
    """SUMO's hint for placing the twin (cosim.phases.ego): two internal lanes that start at one point (one
    turning, one going straight) are a tie for SUMO's free mapping; the path's own breaks it."""
    path = RoutePath([(0.0, 0.0), (0.0, 130.0)], edge_lanes=[(0.0, 100.0, "a", 1), (110.0, 130.0, "b", 0)],
                     via_lanes=[(100.0, 110.0, ":j_12_0")])  # fmt: skip
    assert path.lane_at(50.0) == ("a", 1)
    assert path.lane_at(104.0) == (":j_12", 0)
    assert path.lane_at(120.0) == ("b", 0)
    assert path.lane_at(140.0) is None


def test_the_path_keeps_the_lane_it_arrives_on_when_that_lane_leads_on():
    """Arriving on lane 2 of a three-lane road whose every lane continues, the path stays on lane 2 instead
    of crossing two lanes (blind to the cars beside it) to reach lane 0."""
    a, b, c = Edge.straight("a", 0, 100, 3), Edge.straight("b", 100, 200, 3), Edge.straight("c", 200, 300, 3)
    a.out[b] = [Conn(a.lanes[2], b.lanes[2])]
    b.out[c] = [Conn(b.lanes[i], c.lanes[i]) for i in range(3)]
    path = RoutePath.from_network(Net([a, b, c]), ["a", "b", "c"])
    on_b = path.xy[(path.xy[:, 0] > 100) & (path.xy[:, 0] < 200)]
    assert np.allclose(on_b[:, 1], -6.4)
    assert _lanes(path) == [("a", 2), ("b", 2), ("c", 2)]  # the lead is told these


def test_the_path_changes_to_the_lane_that_leads_on():
    a, b, c = Edge.straight("a", 0, 100, 3), Edge.straight("b", 100, 200, 3), Edge.straight("c", 200, 300, 1)
    a.out[b] = [Conn(a.lanes[2], b.lanes[2])]
    b.out[c] = [Conn(b.lanes[0], c.lanes[0])]
    path = RoutePath.from_network(Net([a, b, c]), ["a", "b", "c"])
    assert np.isclose(path.xy[path.xy[:, 0] > 150][0, 1], 0.0)


def test_the_path_changes_lanes_on_the_long_road_before_a_short_one_it_must_leave_by_its_first_lane():
    """The turn after a 25-m edge leaves from its lane 0 only: the path moves over on the 200-m road before
    it (one lane change per 100 m there), not across three lanes within the short edge (Munich 209452710#0,
    where that crossing put the ego in front of a car at 16 m/s)."""
    z, a = Edge.straight("z", -100, 0, 3), Edge.straight("a", 0, 200, 3)
    b, c = Edge.straight("b", 200, 225, 4), Edge.straight("c", 225, 300, 1)
    z.out[a] = [Conn(z.lanes[2], a.lanes[2])]
    a.out[b] = [Conn(a.lanes[i], b.lanes[i]) for i in range(3)] + [Conn(a.lanes[2], b.lanes[3])]
    b.out[c] = [Conn(b.lanes[0], c.lanes[0])]
    path = RoutePath.from_network(Net([z, a, b, c]), ["z", "a", "b", "c"])
    assert _lanes(path) == [("z", 2), ("a", 0), ("b", 0), ("c", 0)]
    on_b = path.xy[(path.xy[:, 0] >= 200) & (path.xy[:, 0] <= 225)]
    assert np.allclose(on_b[:, 1], 0.0)  # no lane change on the short edge


def test_the_path_changes_lanes_on_the_first_edge_long_enough_not_after_the_junction():
    """Helsinki 25523727#0 (75 m, to a light) -> 194850767#2 (199 m): the turn at the end leaves from lane 1,
    and both lanes go straight on through the light. The path moves over on the 75-m approach, so the pair
    queues at the light in the lane it needs; deferred to the longer road (the cost per metre of edge
    alone), it queued in lane 0 while the cars of lane 1 passed and came between the lead and the ego."""
    z, a = Edge.straight("z", -100, 0, 1), Edge.straight("a", 0, 75, 2)
    b, c = Edge.straight("b", 75, 275, 2), Edge.straight("c", 275, 400, 1)
    z.out[a] = [Conn(z.lanes[0], a.lanes[0])]
    a.out[b] = [Conn(a.lanes[i], b.lanes[i]) for i in range(2)]
    b.out[c] = [Conn(b.lanes[1], c.lanes[0])]
    path = RoutePath.from_network(Net([z, a, b, c]), ["z", "a", "b", "c"])
    assert _lanes(path) == [("z", 0), ("a", 1), ("b", 1), ("c", 0)]
    assert [change.edge_index for change in path.lane_changes] == [1]  # none after the junction


def test_a_turn_split_at_its_waiting_point_is_followed_through_both_internal_lanes():
    """A left turn with an internal junction drives two internal lanes, the second one curved (Munich
    :cluster_3424935801_..._15): the path takes both instead of cutting the curve straight to the next road."""
    a, b = Edge.straight("a", 0, 100, 1), Edge.straight("b", 110, 200, 1)
    second = Lane(0, [(105.0, 0.0), (108.0, 3.0), (110.0, 0.0)], lid=":j_1_0")
    first = Lane(0, [(100.0, 0.0), (105.0, 0.0)], lid=":j_0_0", conns=[Conn(to_lane=b.lanes[0], via=second)])
    a.out[b] = [Conn(a.lanes[0], b.lanes[0], via=first)]
    path = RoutePath.from_network(Net([a, b], internal_lanes=[first, second]), ["a", "b"])
    assert any(np.allclose(p, (108.0, 3.0)) for p in path.xy)


def test_a_lane_change_knows_the_lanes_it_moves_into_and_those_leading_into_them():
    """Arriving on lane 2 of b, which it must leave by lane 0: the path crosses lanes 1 and 0 early on b. It
    watches those two lanes and every lane entering them at the junction before (through its internal lanes)
    but not its own way in; positions are metres from b's start, negative before it."""
    node = Node("n", (100.0, 0.0), type="priority")
    a = Edge("a", [Lane(0, [(0.0, -6.4), (100.0, -6.4)])], node)
    side_lanes = [Lane(i, [(103.0 + 3.2 * i, -60.0), (103.0 + 3.2 * i, -12.0)]) for i in range(2)]
    side = Edge("side", side_lanes, node)
    b = Edge("b", [Lane(i, [(110.0, -3.2 * i), (210.0, -3.2 * i)]) for i in range(3)], Node("m", (210.0, 0.0)),
             from_node=node)  # fmt: skip
    c = Edge.straight("c", 210, 300, 1)
    own = Lane(0, [(100.0, -6.4), (110.0, -6.4)], lid=":n_0_0")
    turn = Lane(0, [(100.0, -3.2), (110.0, -3.2)], lid=":n_1_0")
    a.out[b] = [Conn(a.lanes[0], b.lanes[2], via=own)]
    side.out[b] = [Conn(side.lanes[0], b.lanes[0]), Conn(side.lanes[1], b.lanes[1], via=turn)]
    b.out[c] = [Conn(b.lanes[0], c.lanes[0])]
    path = RoutePath.from_network(Net([a, side, b, c], internal_lanes=[own, turn]), ["a", "b", "c"])
    (change,) = path.lane_changes
    assert change.lanes_crossed == 2 and set(change.enters) == {"b_1", "b_0"}
    assert set(change.feeders) == {"side_0", "side_1", ":n_1_0"}  # not a_0 or :n_0_0, the path's own way
    assert change.s_start == pytest.approx(110.0, abs=0.5) and change.s_end - change.s_start == pytest.approx(
        math.hypot(30.0, 6.4), abs=0.1)  # fmt: skip
    assert change.position("b_0", 150.0, 0.3) == pytest.approx(40.0)
    assert change.position("side_0", 103.0, -20.0) == pytest.approx(-math.hypot(7.0, 20.0))


def test_a_lane_change_put_off_starts_further_on_but_ends_before_the_edge_does():
    a, b, c = Edge.straight("a", 0, 100, 1), Edge.straight("b", 100, 300, 2), Edge.straight("c", 300, 400, 1)
    b.from_node = a.node
    a.node.outgoing.append(b)
    a.out[b] = [Conn(a.lanes[0], b.lanes[0])]
    b.out[c] = [Conn(b.lanes[1], c.lanes[0])]
    net = Net([a, b, c])
    now = RoutePath.from_network(net, ["a", "b", "c"])
    later = RoutePath.from_network(net, ["a", "b", "c"], {1: 40.0})
    latest = RoutePath.from_network(net, ["a", "b", "c"], {1: 1000.0})
    assert [ch.s_start for ch in (now, later, latest) for ch in ch.lane_changes] == pytest.approx(
        [100.0, 140.0, 100.0 + 200.0 - 30.0 - 5.0])  # fmt: skip
    (change,) = later.lane_changes
    assert change.delay_m == 40.0 and change.max_delay_m == pytest.approx(165.0) and change.edge_index == 1
    on_lane_0 = later.xy[(later.xy[:, 0] > 100.0) & (later.xy[:, 0] <= 140.0)]
    assert np.allclose(on_lane_0[:, 1], 0.0)  # in its lane until then
    assert later.length_m == pytest.approx(now.length_m, abs=0.01)  # the same diagonal, further on
    assert later.edge_index(150.0) == 1 and later.speed_limit(120.0)[0] == now.speed_limit(120.0)[0]


def test_where_a_path_passes_over_its_own_earlier_stretch():
    """A route that loops round and passes over its first street (a bridge, or a junction passed twice):
    the later pass is found, the first pass and the loop's own bends are not (Moscow seed 2: SUMO put the
    ego's twin onto the road it had driven four edges earlier, under which it now passed)."""
    # east 200 m, north 100, west 100, south 150: crosses the first leg at (100, 0), 500 m along the path
    path = RoutePath([(0.0, 0.0), (200.0, 0.0), (200.0, 100.0), (100.0, 100.0), (100.0, -50.0)])
    spans = path.passes_near_itself(radius_m=5.0, min_back_m=60.0)
    assert len(spans) == 1
    a, b = spans[0]
    assert 494.0 <= a <= 496.0 and 504.0 <= b <= 506.0, spans  # within 5 m of (100, 0) on the last leg
    assert RoutePath([(0.0, 0.0), (300.0, 0.0)]).passes_near_itself(5.0, 60.0) == []


def test_the_end_of_the_junction_at_a_line():
    path = RoutePath([(0.0, 0.0), (0.0, 130.0)], edge_lanes=[(0.0, 100.0, "a", 1), (110.0, 130.0, "b", 0)])
    assert path.junction_end(100.0) == 110.0  # the line at the edge's end: the junction runs to 110 m
    assert path.junction_end(98.5) == 110.0  # a line a little before the lane's end
    assert path.junction_end(50.0) == 50.0  # no junction there

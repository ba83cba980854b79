"""How lanes meet at a junction: where one lane may feed two (cosim.scenario.conflicts.fan_out_deletions),
where a lane netconvert left unfed gets a feed (stranded_lane_connections: only on a road too short to change
lanes on, and only when the lane is the only way on to a road beyond), and where a one-way road's lanes move
to the kerb side of its line (oneway_merge_spreads)."""

from __future__ import annotations

from fake_net import Edge, Lane, Net, Node

from cosim.scenario.conflicts import (
    LANE_CHANGE_S,
    fan_out_deletions,
    oneway_merge_spreads,
    stranded_lane_connections,
)


def _widening(length_m: float, feeds: list[tuple[int, int]], lane1_to: str = "straight") -> Net:
    """One lane into a two-lane road of ``length_m`` (13.89 m/s) whose right lane turns right and whose left
    lane goes on to ``lane1_to`` (graphhopper's bautzen.osm, -318290576 -> -65084754: 10.2 m)."""
    into = Edge.straight("in", -100.0, 0.0, 1)
    road = Edge.straight("road", 0.0, length_m, 2)
    road.length_m = length_m
    right, straight = Edge.straight("right", length_m, length_m + 100, 1), Edge.straight("straight", 0, 1, 1)
    into.connect(road, feeds)
    if lane1_to == "straight":
        road.connect(right, [(0, 0)])
        road.connect(straight, [(1, 0)])
    else:
        road.connect(right, [(0, 0), (1, 0)])
    return Net([into, road, right, straight])


def test_a_fan_out_stays_where_the_road_is_too_short_to_change_lanes_and_the_lane_is_the_only_way_on():
    assert LANE_CHANGE_S * 13.89 > 60.0  # the 10.2-m road below is short, a 100-m one is long
    assert fan_out_deletions(_widening(10.2, [(0, 0), (0, 1)])) == []
    # a long road: one lane feeds one lane (the rightmost), the car changes lanes after the junction
    assert fan_out_deletions(_widening(100.0, [(0, 0), (0, 1)])) == [
        '    <delete from="in" to="road" fromLane="0" toLane="1"/>'
    ]
    # a short road whose lanes both lead to the same road: nothing to choose, the fan-out goes
    assert fan_out_deletions(_widening(10.2, [(0, 0), (0, 1)], lane1_to="right")) == [
        '    <delete from="in" to="road" fromLane="0" toLane="1"/>'
    ]


def test_an_unfed_lane_on_a_short_road_gets_a_feed_when_it_alone_leads_on():
    assert stranded_lane_connections(_widening(10.2, [(0, 0)])) == [
        '    <connection from="in" to="road" fromLane="0" toLane="1"/>'
    ]
    # the feed it gets is the fan-out fan_out_deletions keeps
    assert fan_out_deletions(_widening(10.2, [(0, 0), (0, 1)])) == []
    # long enough to change lanes on, or no road only it reaches, or already fed: nothing to add
    assert stranded_lane_connections(_widening(100.0, [(0, 0)])) == []
    assert stranded_lane_connections(_widening(10.2, [(0, 0)], lane1_to="right")) == []
    assert stranded_lane_connections(_widening(10.2, [(0, 0), (0, 1)])) == []


def _y_merge(end_y: float, from_xy=(0.0, -10.0)) -> Net:
    """A two-way road along y = 0 (eastbound lane at y = -1.6, westbound at +1.6) and a one-way road from
    ``from_xy`` joining it at node n (100, 0), its lane ending at (100, end_y)."""
    w, n, s = Node("w", (0.0, 0.0), "priority"), Node("n", (100.0, 0.0), "priority"), Node("s", from_xy)
    east = Edge("east", [Lane(0, [(0.0, -1.6), (100.0, -1.6)])], n, from_node=w)
    west = Edge("west", [Lane(0, [(100.0, 1.6), (0.0, 1.6)])], w, from_node=n)
    slip = Edge("slip", [Lane(0, [from_xy, (100.0, end_y)])], n, from_node=s)
    return Net([east, west, slip])


def test_a_one_way_road_ending_between_the_two_directions_of_a_road_it_joins_at_a_shallow_angle_is_spread():
    """Krems 456774382: netconvert centred the one-way 38566227 on its line, so its lane ended on the two-way
    road's centre line, 2 m from the opposite direction's lane; spread to the kerb side it ends on the lane
    it joins."""
    net = _y_merge(end_y=0.0)
    net.getEdge("slip").connect(net.getEdge("west"), [(0, 0)])  # netconvert's 177-deg "left"
    assert oneway_merge_spreads(net) == (
        ['    <edge id="slip" spreadType="right"/>'],
        ['    <delete from="slip" to="west" fromLane="0" toLane="0"/>'],
    )
    assert oneway_merge_spreads(_y_merge(end_y=-1.6))[0] == []  # ends on the lane it joins
    # spread only when its lane ends closer to the opposite lane (y = +1.6) than two cars need side by side
    # (APPROACH_CLEARANCE_M, 2.1 m): Monaco 25103757 ends 2.27 m from it and stays
    assert oneway_merge_spreads(_y_merge(end_y=-0.4))[0] == ['    <edge id="slip" spreadType="right"/>']
    assert oneway_merge_spreads(_y_merge(end_y=-0.7))[0] == []
    assert oneway_merge_spreads(_y_merge(end_y=0.0, from_xy=(100.0, -60.0)))[0] == []  # a T, not a merge

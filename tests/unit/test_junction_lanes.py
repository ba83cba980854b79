"""Where one lane may feed two (cosim.scenario.conflicts.fan_out_deletions) and where a lane netconvert left
unfed gets a feed (stranded_lane_connections): only on a road too short to change lanes on, and only when
the lane is the only way on to a road beyond."""

from __future__ import annotations

from fake_net import Edge, Net

from cosim.scenario.conflicts import LANE_CHANGE_S, fan_out_deletions, stranded_lane_connections


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

"""Shared geometry of the assistance systems: headings, gaps, building line of sight, events."""

from __future__ import annotations

import pytest
import shapely

from cosim.adas import VehicleState, along_heading_gap_m
from cosim.adas.common import EventRecorder, chord_gap_m, heading_unit, left_unit
from cosim.buildings import Buildings
from cosim.world import World


def test_heading_units_follow_sumo_compass():
    assert heading_unit(0.0) == pytest.approx((0.0, 1.0))
    assert heading_unit(90.0) == pytest.approx((1.0, 0.0))
    assert heading_unit(180.0) == pytest.approx((0.0, -1.0))
    assert left_unit(0.0) == pytest.approx((-1.0, 0.0))
    assert left_unit(90.0) == pytest.approx((0.0, 1.0))


def test_rear_point_and_gap():
    v = VehicleState(10.0, 20.0, 90.0, 5.0, 4.0)
    assert v.rear_xy() == pytest.approx((6.0, 20.0))
    # ego heading east at the origin: the rear point (6, 20) is 6 m ahead along the heading
    assert along_heading_gap_m(0.0, 0.0, 90.0, 6.0, 20.0) == pytest.approx(6.0)
    assert along_heading_gap_m(0.0, 0.0, 270.0, 6.0, 20.0) == pytest.approx(-6.0)


def test_chord_gap_counts_a_leader_out_of_a_sharp_bend_as_ahead():
    """Ego heading east at the origin. A leader that has turned left (110 deg) and drives north 30 m away,
    its rear just abeam of the ego's front, is ahead: V2V showed a 0-s time gap there (Krems, a left turn)."""
    assert chord_gap_m(0.0, 0.0, 90.0, -1.0, 30.0, 344.0) == pytest.approx(30.017, abs=1e-3)
    # a car in the next lane overlapping the ego (same heading, rear 2 m behind the ego's front) is not ahead
    assert chord_gap_m(0.0, 0.0, 90.0, -2.0, 3.5, 90.0) < 0.0
    # nor one that drives the other way past the ego's front
    assert chord_gap_m(0.0, 0.0, 90.0, -1.0, 3.5, 270.0) < 0.0
    # straight ahead: the distance
    assert chord_gap_m(0.0, 0.0, 90.0, 20.0, 0.0, 90.0) == pytest.approx(20.0)


def test_from_world():
    w = World(capacity=4)
    s = w.add("lead")
    w.x_m[s], w.y_m[s], w.heading_deg[s], w.speed_mps[s], w.length_m[s], w.accel_mps2[s] = (
        1,
        2,
        45,
        7,
        4.5,
        -1,
    )
    v = VehicleState.from_world(w, s)
    assert v == VehicleState(1.0, 2.0, 45.0, 7.0, 4.5, -1.0)
    with pytest.raises(ValueError, match="slot 3"):
        VehicleState.from_world(w, 3)


def test_buildings_line_of_sight():
    idx = Buildings([shapely.box(0, 0, 10, 10), shapely.box(20, 0, 30, 10)])
    assert len(idx) == 2
    assert idx.line_of_sight(-5, 12, 35, 12)  # passes above both
    assert not idx.line_of_sight(-5, 5, 15, 5)  # through the first
    assert not idx.line_of_sight(15, -5, 25, 5)  # clips the second's corner
    assert idx.line_of_sight(12, -5, 18, 15)  # between them
    assert not idx.line_of_sight(-5, 10, 35, 10)  # grazing a wall counts as blocked
    assert Buildings().line_of_sight(0, 0, 1, 1)


def test_vehicle_state_validation():
    with pytest.raises(ValueError, match="finite"):
        VehicleState(float("inf"), 0.0, 0.0, 0.0, 4.0)
    with pytest.raises(ValueError, match="length_m"):
        VehicleState(0.0, 0.0, 0.0, 0.0, -1.0)


def test_event_recorder():
    rec = EventRecorder("B")
    rec.record(0.5, "level", "none", "warning", 1.5)
    rec.record(0.7, "level", "warning", "none", 3.5)
    assert [e.t_s for e in rec.pop_events()] == [0.5, 0.7]
    assert rec.pop_events() == []
    rec.record(0.9, "data", "ok", "stale", None)
    assert [e.kind for e in rec.pop_events()] == ["data"] and len(rec.events) == 3

"""Gap acceptance at yield lines: the HCM 2010 headways, impatience, and the scripted driver using them."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from cosim.driver import Percept
from cosim.driver.gap_acceptance import (
    HEADWAYS_S,
    arrival_time_s,
    critical_gap_s,
    follow_up_s,
    movement_of,
)
from cosim.driver.profiles import PROFILES
from cosim.driver.scripted import ScriptedDriver


def test_headways_are_the_hcm_2010_values():
    # HCM 2010 Exhibit 19-10 (TWSC, two-lane major street) and the roundabout capacity 1130 exp(-0.001 v_c)
    assert HEADWAYS_S["minor_right"] == (6.2, 3.3)
    assert HEADWAYS_S["minor_through"] == (6.5, 4.0)
    assert HEADWAYS_S["minor_left"] == (7.1, 3.5)
    assert HEADWAYS_S["permissive_left"] == (4.1, 2.2)
    t_c, t_f = HEADWAYS_S["roundabout"]
    assert 3600.0 / t_f == pytest.approx(1130.0, rel=0.01)  # saturation flow of the entry [veh/h]
    assert (t_c - t_f / 2.0) / 3600.0 == pytest.approx(0.0010, rel=0.01)  # the exponent's factor [h/veh]


def test_movements_of_sumo_directions():
    assert movement_of("r") == movement_of("R") == "minor_right"
    assert movement_of("s") == "minor_through"
    assert movement_of("l") == movement_of("L") == "minor_left"
    assert movement_of("l", permissive=True) == "permissive_left"
    assert movement_of("s", into_roundabout=True) == "roundabout"


def test_impatience_shrinks_the_critical_gap_to_the_follow_up_headway():
    assert critical_gap_s("minor_left", 0.0) == pytest.approx(7.1)
    assert critical_gap_s("minor_left", 30.0, time_to_impatience_s=60.0) == pytest.approx(0.5 * (7.1 + 3.5))
    assert critical_gap_s("minor_left", 600.0, time_to_impatience_s=60.0) == pytest.approx(3.5)
    assert critical_gap_s("minor_left", 0.0, factor=1.2) == pytest.approx(1.2 * 7.1)
    assert follow_up_s("minor_through", 1.2) == pytest.approx(4.8)


def test_arrival_time_of_cruising_and_standing_foes():
    assert arrival_time_s(100.0, 10.0) == pytest.approx(10.0)
    # from a standstill at 1.5 m/s^2: d = a t^2 / 2
    assert arrival_time_s(12.0, 0.0) == pytest.approx(math.sqrt(2 * 12.0 / 1.5))
    assert arrival_time_s(0.0, 5.0) == 0.0


def _percept(t: float, v: float, x: float, gap_s: float, movement: str = "minor_through", kind="give_way"):
    path = np.array([[x - 5.0, 0.0], [200.0, 0.0]])
    return Percept(t_s=t, speed_mps=v, x_m=x, y_m=0.0, yaw_rad=0.0, path_xy_m=path, speed_limit_mps=13.9,
                   sign_kind=kind, sign_dist_m=max(0.0, 100.0 - x - 2.3), sign_id="J",
                   junction_gap_s=gap_s, junction_movement=movement)  # fmt: skip


def _drive(gap_of_t, seconds: float, movement="minor_through", kind="give_way", profile="daily_commuter"):
    """A point-mass car under the driver, 100 m before a yield line; returns (t, x, yielding) per step."""
    prof = PROFILES[profile].without_noise()
    drv = ScriptedDriver(prof, np.random.default_rng(1), math.radians(35.0), 2.7)
    t, x, v, out = 0.0, 30.0, 8.0, []
    while t < seconds:
        c = drv.act(_percept(t, v, x, gap_of_t(t), movement, kind), 0.1)
        a = 3.0 * c.throttle - 8.8 * c.brake
        v = max(0.0, v + a * 0.1)
        x += v * 0.1
        out.append((t, x, drv.debug.yielding))
        t += 0.1
    return out


def test_give_way_waits_for_a_stream_then_takes_an_acceptable_gap():
    """Priority cars every 4 s (each gap < t_c = 6.5 s) until t = 40 s, then a 12-s gap: the driver waits at
    the line while the gaps are short and crosses in the long one, not before."""

    def gap(t):
        if t < 40.0:
            return 4.0 - (t % 4.0)
        return max(0.0, 52.0 - t)

    run = _drive(gap, 60.0)
    crossed = next(t for t, x, _ in run if x > 100.0)
    assert 40.0 < crossed < 48.0, crossed
    stopped = [x for t, x, _ in run if 20.0 < t < 38.0]
    assert max(stopped) < 100.0 and max(stopped) - min(stopped) < 0.5  # waited at the line


def test_impatience_lets_the_driver_take_shorter_gaps_after_waiting():
    """A steady stream of 5-s gaps (below t_c, above t_f): a patient driver would wait forever; with
    impatience the driver goes within its time_to_impatience_s (60 s for the commuter)."""
    run = _drive(lambda t: 5.0 - (t % 5.0), 120.0)
    crossed = next((t for t, x, _ in run if x > 100.0), None)
    assert crossed is not None and 20.0 < crossed < 75.0, crossed


def test_stop_sign_with_a_car_approaching_waits_until_it_passed():
    """Stop sign; one car approaching, reaching the conflict at t = 14 s (less than t_c after the driver's
    full stop at the line), nothing after: the driver stops, lets it pass, then goes."""

    def gap(t):
        return 14.0 - t if t < 14.0 else math.inf

    run = _drive(gap, 45.0, kind="stop")
    at_line = next(t for t, x, _ in run if t > 1.0 and abs(x - (100.0 - 2.3 - 0.5)) < 0.3)
    assert at_line > 14.0 - 6.5  # it reached the line within the car's critical gap ...
    crossed = next(t for t, x, _ in run if x > 100.0)
    assert crossed > 14.0  # ... and crossed only once the car had passed


def test_unprotected_left_turn_at_a_green_yields_to_oncoming_traffic():
    """A green without priority ('g'): the oncoming stream leaves 3-s gaps (< t_c = 4.1 s) until t = 30 s."""

    def gap(t):
        return 3.0 - (t % 3.0) if t < 30.0 else math.inf

    run = _drive(gap, 50.0, movement="permissive_left", kind="yield")
    crossed = next(t for t, x, _ in run if x > 100.0)
    assert crossed > 28.0
    assert any(y for t, x, y in run if t < 30.0)  # it yielded


def test_queued_behind_a_leader_that_enters_a_gap_the_driver_follows_it_through():
    """Standing 1.6 m behind a leader at a give-way line (front 8 m short of it); the leader enters a gap
    of 11 s (its own t_c + t_f with margin) and pulls away at 2.5 m/s^2; then the stream comes every 3 s.
    The occasional driver (slow to pull away, critical gaps x 1.15).
    The driver takes the follow-up headway behind it and keeps it while it moves up (not re-judging the gap
    as a first driver once the leader is 12 m past the line): it crosses inside the gap and never stops at
    the line (it did, and waited through the stream, at Monaco's -166149542#0)."""
    prof = PROFILES["occasional_driver"].without_noise()
    drv = ScriptedDriver(prof, np.random.default_rng(1), math.radians(35.0), 2.7)
    line = 97.7  # sign_dist_m = 100 - x - 2.3 (_percept)
    t, x, v, out = 0.0, line - 8.0, 0.0, []
    rear = x + 1.6  # the leader's rear bumper

    def gap(t):
        return 12.0 - t if t < 12.0 else 3.0 - ((t - 12.0) % 3.0)

    while t < 20.0:
        lead_rear = rear + (0.0 if t < 1.0 else 1.25 * (t - 1.0) ** 2)
        p = _percept(t, v, x, gap(t))
        p = dataclasses.replace(p, leader_present=True, leader_id="lead", leader_gap_m=lead_rear - x,
                                leader_speed_mps=0.0 if t < 1.0 else 2.5 * (t - 1.0))  # fmt: skip
        c = drv.act(p, 0.1)
        v = max(0.0, v + (3.0 * c.throttle - 8.8 * c.brake) * 0.1)
        x += v * 0.1
        out.append((t, x, v))
        t += 0.1
    crossed = next((t for t, x, _ in out if x > line), None)
    assert crossed is not None and crossed < 11.0, crossed
    assert not any(v < 0.1 for t, x, v in out if 3.0 < t < crossed)  # moved up without stopping again

"""Pure-pursuit lane keeping of the scripted driver, with and without the wandering lateral error."""

import math

import numpy as np
import pytest
from driver_testsim import Route, scripted, simulate


@pytest.mark.parametrize("speed", [5.0, 12.0, 20.0])
def test_converges_onto_a_straight_line(speed):
    drv = scripted("daily_commuter")
    tr = simulate(drv, Route.straight(), 20.0, v0_mps=speed, lateral0_m=1.5, yaw_err0_rad=math.radians(10),
                  speed_limit_mps=speed)  # fmt: skip
    assert abs(tr.lat[tr.at(8.0)]) < 0.05
    assert np.abs(tr.lat[tr.at(10.0) :]).max() < 0.01
    assert tr.lat.min() > -0.4  # little overshoot to the other side
    assert np.abs(np.diff(tr.steer)).max() < 0.2  # no steering jerks (0.1-s steps)


def test_steers_left_for_a_left_curve():
    drv = scripted("daily_commuter")
    tr = simulate(
        drv, Route.straight_then_circle(30.0, 40.0, math.pi / 2), 12.0, v0_mps=8.0, speed_limit_mps=8.0
    )
    centre = tr.s_front - 2.25
    in_curve = (centre > 90.0) & (centre < 80.0 + 40.0 * math.pi / 2)
    # steady steering = atan(L / R) / max_steer, positive (left)
    wanted = math.atan(2.7 / 40.0) / 0.6
    assert np.median(tr.steer[in_curve]) == pytest.approx(wanted, rel=0.1)


@pytest.mark.parametrize("radius", [30.0, 60.0, 150.0])
def test_follows_a_curve_with_small_lateral_error(radius):
    drv = scripted("daily_commuter")
    route = Route.straight_then_circle(100.0, radius, math.pi)
    tr = simulate(drv, route, 60.0, v0_mps=10.0, speed_limit_mps=13.9)
    centre = tr.s_front - 2.25
    in_curve = (centre > 150.0) & (centre < 150.0 + radius * math.pi)
    assert in_curve.sum() > 50
    assert np.abs(tr.lat[in_curve]).mean() < 0.1
    assert np.abs(tr.lat[in_curve]).max() < 0.35


def test_wandering_lateral_error_has_the_profile_amplitude():
    for name in ("daily_commuter", "occasional_driver"):
        drv = scripted(name, noise=True, seed=7)
        tr = simulate(drv, Route.straight(5000.0), 300.0, v0_mps=12.0, speed_limit_mps=13.9)
        lat = tr.lat[100:]
        sd = drv.profile.lateral_wander_std_m
        assert np.std(lat) == pytest.approx(sd, rel=0.45)  # a slow process: ~60 correlation times
        assert np.abs(lat).mean() < 0.3  # the integration requirement: mean |offset| < 0.3 m
        # the wander is slow (human-like drift), not steering noise
        assert np.abs(np.diff(tr.steer)).max() < 0.05

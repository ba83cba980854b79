"""Seeded randomness, determinism, perception-noise statistics, and measurable profile differences."""

import dataclasses
import math

import numpy as np
import pytest
from driver_testsim import MAX_STEER_RAD, WHEELBASE_M, Leader, Route, scripted, simulate

from cosim.driver.base import Percept
from cosim.driver.profiles import profile_by_name
from cosim.driver.scripted import ScriptedDriver

LINE_S = 400.0


def busy_run(seed: int):
    """Everything at once: noise, a braking leader, a light, a stop sign, both displays."""
    drv = scripted("occasional_driver", noise=True, seed=seed, a_brake_prob=0.5)
    ld = Leader(
        25.0, 12.0, accel=lambda t, _: -2.0 if 20.0 <= t < 23.0 else (1.0 if 30.0 <= t < 33.0 else 0.0)
    )

    def extras(t, s, v):
        out = dict(
            sys_a_lit=(t % 10.0) < 3.0, sys_b_gap_s=None if 50 < t < 55 else 1.7, sys_b_level="advisory"
        )
        if s < LINE_S:
            out.update(tls_state="r" if t < 45.0 else "g", tls_dist_m=LINE_S - s)
        return out

    return simulate(drv, Route.straight(), 60.0, v0_mps=12.0, leader=ld, extras=extras)


def test_same_seed_same_trace_byte_for_byte():
    a, b = busy_run(5), busy_run(5)
    for name in ("s_front", "v", "a", "gap", "lat", "throttle", "brake", "steer"):
        assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), name
    assert a.debug == b.debug


def test_different_seed_different_trace():
    a, b = busy_run(5), busy_run(6)
    assert not np.array_equal(a.s_front, b.s_front)
    assert not np.array_equal(a.lat, b.lat)


def test_reset_with_the_same_generator_seed_repeats_the_run():
    drv = scripted("daily_commuter", noise=True, seed=1)
    first = simulate(drv, Route.straight(), 20.0, v0_mps=10.0, leader=Leader(30.0, 10.0))
    drv.reset(np.random.default_rng(1))
    again = simulate(drv, Route.straight(), 20.0, v0_mps=10.0, leader=Leader(30.0, 10.0))
    assert np.array_equal(first.throttle, again.throttle) and np.array_equal(first.steer, again.steer)


def test_perception_noise_has_the_profile_statistics():
    """Gap estimate = gap * exp(V_s w): log-ratio std ~ V_s; errors are correlated in time (Wiener-like)."""
    vs, tau = 0.1, 2.0
    prof = profile_by_name("daily_commuter")
    prof = dataclasses.replace(prof, gap_error_rel=vs, perception_error_time_s=tau, reaction_time_s=0.5)
    drv = ScriptedDriver(prof, np.random.default_rng(3), MAX_STEER_RAD, WHEELBASE_M)
    path = np.array([[-10.0, 0.0], [300.0, 0.0]])
    logs = []
    for k in range(4000):  # standing 30 m behind a standing leader: the estimate is the only thing changing
        p = Percept(t_s=0.1 * k, speed_mps=0.0, x_m=0.0, y_m=0.0, yaw_rad=0.0, path_xy_m=path,
                    speed_limit_mps=13.9, leader_present=True, leader_id="L", leader_gap_m=30.0)  # fmt: skip
        drv.act(p, 0.1)
        logs.append(math.log(drv.debug.gap_est_m / 30.0))
    logs = np.array(logs)
    assert np.std(logs) == pytest.approx(vs, rel=0.25)
    lag1 = np.corrcoef(logs[:-1], logs[1:])[0, 1]
    assert lag1 == pytest.approx(math.exp(-0.1 / tau), abs=0.02)  # smooth, not white noise


def test_profiles_differ_measurably():
    out = {}
    for name in ("daily_commuter", "occasional_driver", "aggressive", "cautious"):
        # following gap behind a 15 m/s leader
        fol = simulate(scripted(name), Route.straight(), 80.0, v0_mps=15.0, leader=Leader(30.0, 15.0),
                       speed_limit_mps=22.0)  # fmt: skip
        # free speed on a 50 km/h road
        free = simulate(scripted(name), Route.straight(), 60.0, v0_mps=10.0, speed_limit_mps=13.9)
        # brake onset after the leader brakes
        ld = Leader(30.0, 15.0, accel=lambda t, _: -3.0 if t >= 50.0 else 0.0)
        brk = simulate(scripted(name), Route.straight(), 56.0, v0_mps=15.0, leader=ld, speed_limit_mps=22.0)
        k0 = brk.at(50.0)
        out[name] = (fol.gap[-1], free.v[-1], brk.t[k0 + np.argmax(brk.brake[k0:] > 0.02)] - 50.0)
    c, o, a, k = out["daily_commuter"], out["occasional_driver"], out["aggressive"], out["cautious"]
    assert a[0] < c[0] - 3.0 and c[0] < o[0] - 3.0 and o[0] < k[0]  # gap [m]
    assert a[1] > c[1] + 0.5 and c[1] > o[1] + 0.5 and o[1] > k[1]  # free speed [m/s]
    assert c[2] < o[2] - 0.3  # reaction [s]

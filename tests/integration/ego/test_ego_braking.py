"""Straight-line braking from 50 km/h at full brake: stopping distance vs v^2 / (2 mu g)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.ego_mujoco import BrakeParams, CarParams, EgoCar, TyreParams

G = 9.81
V0 = 50.0 / 3.6  # [m/s]


def brake_to_stop(params: CarParams, yaw_rad: float) -> tuple[float, list]:
    car = EgoCar(params)
    car.reset(10.0, -20.0, yaw_rad, V0)
    states = []
    for _ in range(100):  # at most 10 s
        states.append(car.step(0.0, 1.0, 0.0, 0.1))
        if states[-1].speed_mps < 0.01:
            break
    s = states[-1]
    return math.hypot(s.x_m - 10.0, s.y_m + 20.0), states


@pytest.mark.parametrize("abs_enabled", [True, False], ids=["abs", "locked"])
@pytest.mark.parametrize("mu", [0.9, 0.5])
def test_stopping_distance_matches_friction_limit(mu: float, abs_enabled: bool) -> None:
    params = CarParams(tyre=TyreParams(mu=mu), brakes=BrakeParams(abs=abs_enabled))
    yaw = 0.7  # off-axis heading: the friction circle must not depend on the world direction
    dist, states = brake_to_stop(params, yaw)
    ideal = V0**2 / (2.0 * mu * G)
    print(f"mu={mu} abs={abs_enabled}: stopping distance {dist:.2f} m, v^2/(2 mu g) = {ideal:.2f} m")
    assert states[-1].speed_mps < 0.01, "the car did not stop within 10 s"
    assert abs(dist / ideal - 1.0) < 0.10
    # Straight, upright, on the road.
    s = states[-1]
    lateral = -(s.x_m - 10.0) * math.sin(yaw) + (s.y_m + 20.0) * math.cos(yaw)
    assert abs(lateral) < 0.05
    assert abs(s.yaw_rad - yaw) < math.radians(0.5)
    assert all(st.in_contact.all() for st in states)
    assert max(abs(st.pitch_rad) for st in states) < math.radians(3.0)
    # Dive: braking at a = mu*g moves m*a*h/L of load to the front axle (checked mid-stop).
    mid = states[len(states) // 2]
    front = (
        params.mass_kg
        * (G * params.cog_to_rear_axle_m - mid.accel_mps2 * params.cog_height_m)
        / params.wheelbase_m
    )
    assert mid.wheel_load_n[:2].sum() == pytest.approx(front, rel=0.05)


def test_full_brake_torque_reaches_the_friction_limit() -> None:
    """Without ABS, full pedal locks all four wheels: the brakes can exceed the tyres' grip."""
    _, states = brake_to_stop(CarParams(brakes=BrakeParams(abs=False)), 0.0)
    locked = [s for s in states if s.speed_mps > 2.0][2:]  # skip the first 0.2 s of spin-down
    assert locked, "no braking phase above 2 m/s"
    for s in locked:
        np.testing.assert_allclose(s.wheel_speed_radps, 0.0, atol=0.1)  # the brake row's creep: ~0.06 rad/s
        # Deceleration at the friction limit (+ drag and rolling resistance, - nothing else).
        assert -s.accel_mps2 == pytest.approx(0.9 * G, rel=0.05)


def test_abs_keeps_wheels_turning() -> None:
    _, states = brake_to_stop(CarParams(), 0.0)
    rolling = [s for s in states if s.speed_mps > 2.0][2:]
    for s in rolling:
        slip = 1.0 - s.wheel_speed_radps * CarParams().wheel_radius_m / s.speed_mps
        assert np.all(slip < 0.25), f"ABS let a wheel lock: slip ratios {slip}"


def test_stopped_car_stays_put_with_brake() -> None:
    car = EgoCar()
    car.reset(0.0, 0.0, 0.0, 0.0)
    for _ in range(50):
        s = car.step(0.0, 1.0, 0.0, 0.1)
    assert math.hypot(s.x_m, s.y_m) < 1e-4
    assert abs(s.speed_mps) < 1e-4

"""Helpers for the ego-physics validation tests (real MuJoCo)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest

from cosim.ego_mujoco import CarParams, EgoCar

G = 9.81  # [m/s^2]
DT = 0.1  # [s] the SUMO step: the tests drive the car the way the co-simulation loop does


@dataclass(frozen=True)
class Corner:
    """Steady-state cornering measured over the last seconds of a constant-speed, constant-steer run."""

    speed_mps: float
    steer_rad: float  # actual bicycle road-wheel angle
    radius_m: float  # radius of the rear-axle midpoint's path
    lateral_accel_mps2: float
    max_abs_roll_rad: float
    max_abs_pitch_rad: float
    max_z_dev_m: float  # largest deviation of the body height from the rest height
    all_wheels_in_contact: bool


def hold_speed(car: EgoCar, target_mps: float, steer: float, seconds: float) -> list:
    """Drive with a PI speed controller (throttle / brake) and a constant steering command."""
    integral, states = 0.0, []
    for _ in range(round(seconds / DT)):
        err = target_mps - car.state().speed_mps
        integral = min(max(integral + err * DT, -5.0), 5.0)
        u = 0.5 * err + 0.2 * integral
        states.append(car.step(max(min(u, 1.0), 0.0), max(min(-u, 1.0), 0.0), steer, DT))
    return states


def steady_corner(
    params: CarParams, speed_mps: float, steer: float, seconds: float = 16.0, tail_s: float = 4.0
) -> Corner:
    car = EgoCar(params)
    car.reset(0.0, 0.0, 0.0, speed_mps)
    rest_z = car.state().z_m
    states = hold_speed(car, speed_mps, steer, seconds)
    tail = states[-round(tail_s / DT) :]
    v = np.mean([s.speed_mps for s in tail])
    r = np.mean([s.yaw_rate_rps for s in tail])
    v_lat = np.mean([s.lateral_speed_mps for s in tail])
    # Rear-axle midpoint velocity = centre velocity + yaw_rate x (rear_axle_x, 0).
    v_rear_lat = v_lat + r * params.rear_axle_x_m
    return Corner(
        speed_mps=float(v),
        steer_rad=float(np.mean([s.steer_rad for s in tail])),
        radius_m=float(math.hypot(v, v_rear_lat) / abs(r)),
        lateral_accel_mps2=float(np.mean([s.lateral_accel_mps2 for s in tail])),
        max_abs_roll_rad=max(abs(s.roll_rad) for s in states),
        max_abs_pitch_rad=max(abs(s.pitch_rad) for s in states),
        max_z_dev_m=max(abs(s.z_m - rest_z) for s in states),
        all_wheels_in_contact=all(bool(s.in_contact.all()) for s in states),
    )


@pytest.fixture
def corner() -> Callable[..., Corner]:
    return steady_corner


@pytest.fixture
def drive() -> Callable[..., list]:
    return hold_speed

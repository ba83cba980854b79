"""EgoCar conventions and input handling: poses, signs, rate limits, SUMO write-back, obstacles."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim import frames
from cosim.ego_mujoco import CarParams, EgoCar, StaticBox, StaticMesh

G = 9.81


@pytest.fixture(scope="module")
def car() -> EgoCar:
    return EgoCar()


def test_reset_pose_speed_and_rest(car: EgoCar) -> None:
    car.reset(120.0, -35.0, 2.5, 12.0)
    s = car.state()
    assert (s.x_m, s.y_m, s.yaw_rad) == pytest.approx((120.0, -35.0, 2.5))
    assert s.speed_mps == pytest.approx(12.0)
    assert s.lateral_speed_mps == pytest.approx(0.0, abs=1e-9)
    assert s.t_s == 0.0
    np.testing.assert_allclose(s.wheel_speed_radps, 12.0 / car.params.wheel_radius_m)
    assert s.in_contact.all()
    assert s.wheel_load_n.sum() == pytest.approx(car.params.mass_kg * G, rel=0.01)
    assert s.gear > 1  # a gear that suits 43 km/h
    with pytest.raises(ValueError, match="speed_mps"):
        car.reset(0.0, 0.0, 0.0, -1.0)
    with pytest.raises(ValueError, match="x_m"):
        car.reset(math.nan, 0.0, 0.0, 0.0)


def test_rests_without_drift(car: EgoCar) -> None:
    car.reset(5.0, 7.0, 1.0, 0.0)
    for _ in range(100):
        s = car.step(0.0, 0.0, 0.0, 0.1)
    assert math.hypot(s.x_m - 5.0, s.y_m - 7.0) < 1e-6
    assert abs(s.yaw_rad - 1.0) < 1e-9
    assert abs(s.pitch_rad) < 1e-6 and abs(s.roll_rad) < 1e-6  # level at rest


def test_time_and_substeps(car: EgoCar) -> None:
    car.reset(0.0, 0.0, 0.0, 10.0)
    s = car.step(0.2, 0.0, 0.0, 0.1)
    assert s.t_s == pytest.approx(0.1, abs=1e-12)
    assert car.time_s == pytest.approx(0.1, abs=1e-12)
    car.step(0.2, 0.0, 0.0, 0.0031)  # round(1.55) = 2 steps of 2 ms
    assert car.time_s == pytest.approx(0.104, abs=1e-12)
    car.step(0.2, 0.0, 0.0, 0.0)
    assert car.time_s == pytest.approx(0.104, abs=1e-12)


def test_heading_moves_the_car_forward(car: EgoCar) -> None:
    car.reset(0.0, 0.0, -2.0, 10.0)
    s = car.step(0.3, 0.0, 0.0, 1.0)
    direction = math.atan2(s.y_m, s.x_m)
    assert direction == pytest.approx(-2.0, abs=1e-3)
    assert s.speed_mps > 9.0


@pytest.mark.parametrize("steer", [1.0, -1.0])
def test_steer_sign_and_rate_limit(car: EgoCar, steer: float) -> None:
    p = car.params
    car.reset(0.0, 0.0, 0.0, 5.0)
    s = car.step(0.1, 0.0, steer, 0.5)
    ramp = p.max_steer_rate_rad_s * 0.5  # where the rate limit allows the wheels to be after 0.5 s
    assert math.copysign(1.0, s.steer_rad) == steer
    assert 0.85 * ramp < abs(s.steer_rad) <= ramp + 1e-6
    assert math.copysign(1.0, s.yaw_rate_rps) == steer  # +1 = left = counter-clockwise
    s = car.step(0.1, 0.0, steer, 1.0)
    assert abs(s.steer_rad) == pytest.approx(p.max_steer_rad, rel=1e-2)  # full lock after 1.5 s (servo error)


def test_inputs_are_clipped_and_validated(car: EgoCar) -> None:
    car.reset(0.0, 0.0, 0.0, 0.0)
    a = car.step(5.0, -1.0, 3.0, 1.0)
    car.reset(0.0, 0.0, 0.0, 0.0)
    b = car.step(1.0, 0.0, 1.0, 1.0)
    assert (a.x_m, a.y_m, a.yaw_rad) == (b.x_m, b.y_m, b.yaw_rad)
    for bad in ((math.nan, 0.0, 0.0, 0.1), (0.0, math.inf, 0.0, 0.1), (0.0, 0.0, 0.0, -0.1)):
        with pytest.raises(ValueError):
            car.step(*bad)


def test_constructor_validation() -> None:
    with pytest.raises(ValueError, match="500 Hz"):
        EgoCar(timestep_s=0.005)
    with pytest.raises(ValueError, match="multiple"):
        EgoCar(timestep_s=0.002, control_period_s=0.003)
    car = EgoCar(timestep_s=0.001, control_period_s=0.005)
    car.reset(0.0, 0.0, 0.0, 0.0)
    assert car.model.opt.timestep == 0.001


def test_to_sumo_is_the_front_bumper(car: EgoCar) -> None:
    car.reset(100.0, 200.0, math.radians(30.0), 0.0)
    s = car.state()
    half = 0.5 * car.params.length_m
    x, y, angle = s.to_sumo()
    assert (x, y) == pytest.approx(
        (100.0 + half * math.cos(math.radians(30.0)), 200.0 + half * math.sin(math.radians(30.0)))
    )
    assert angle == pytest.approx(60.0)  # 30 deg ccw from east = 60 deg clockwise from north
    xo, yo, _ = s.to_sumo(origin_xy=(1000.0, 2000.0))
    assert (xo, yo) == pytest.approx((x + 1000.0, y + 2000.0))
    # Inverse through cosim.frames gives back the MuJoCo pose.
    cx, cy, yaw = frames.sumo_to_mujoco(xo, yo, angle, s.length_m, origin_xy=(1000.0, 2000.0))
    assert (float(cx), float(cy), float(yaw)) == pytest.approx((100.0, 200.0, math.radians(30.0)))


def test_state_arrays_are_read_only(car: EgoCar) -> None:
    s = car.state()
    assert s.wheel_speed_radps.shape == s.wheel_load_n.shape == s.in_contact.shape == (4,)
    with pytest.raises(ValueError):
        s.wheel_speed_radps[0] = 1.0


@pytest.mark.parametrize(
    "obstacle",
    [
        StaticBox((30.0, 0.0, 1.0), (1.0, 3.0, 1.0)),
        StaticMesh(tuple((x, y, z) for x in (29.0, 31.0) for y in (-3.0, 3.0) for z in (0.0, 2.0))),
    ],
    ids=["box", "mesh"],
)
def test_static_obstacle_stops_the_car(obstacle) -> None:
    car = EgoCar(CarParams(), obstacles=(obstacle,))
    car.reset(0.0, 0.0, 0.0, 10.0)
    states = [car.step(0.3, 0.0, 0.0, 0.1) for _ in range(50)]
    bumper = max(s.x_m for s in states) + 0.5 * car.params.length_m
    assert 28.8 < bumper < 29.2  # the obstacle's face is at x = 29 m
    assert states[-1].x_m < 29.0 - 0.5 * car.params.length_m + 0.2


def test_coasting_deceleration_is_plausible() -> None:
    """Drag + rolling resistance + engine braking at 100 km/h: ~0.4-0.7 m/s^2."""
    car = EgoCar()
    car.reset(0.0, 0.0, 0.0, 100.0 / 3.6)
    s = car.step(0.0, 0.0, 0.0, 5.0)
    mean_decel = (100.0 / 3.6 - s.speed_mps) / 5.0
    p = car.params
    drag = 0.5 * p.air_density_kg_m3 * p.drag_coefficient * p.frontal_area_m2 * (100.0 / 3.6) ** 2
    assert drag / p.mass_kg + p.tyre.rolling_resistance * G < mean_decel < 0.8

"""Pure parts of the ego car: parameter validation, config loading, engine/gearbox logic, Ackermann."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.config import from_dict
from cosim.ego_mujoco import BrakeParams, CarParams, PowertrainParams, TyreParams
from cosim.ego_mujoco.powertrain import (
    RPM_PER_RADPS,
    PowertrainState,
    full_load_torque_nm,
    overall_ratio,
    step_powertrain,
)
from cosim.errors import ConfigError

PT = PowertrainParams()


def test_full_load_curve_respects_torque_and_power_limits() -> None:
    rpm = np.linspace(PT.idle_rpm, PT.redline_rpm + 500.0, 2000)
    torque = np.array([full_load_torque_nm(PT, r) for r in rpm])
    power = torque * rpm / RPM_PER_RADPS
    assert torque.max() == pytest.approx(PT.max_torque_nm)
    assert power.max() == pytest.approx(PT.max_power_w, rel=1e-3)
    assert power.max() <= PT.max_power_w * (1 + 1e-12)
    assert np.all(torque[rpm >= PT.redline_rpm] == 0.0)
    assert full_load_torque_nm(PT, PT.idle_rpm) == pytest.approx(PT.low_torque_fraction * PT.max_torque_nm)


def test_launch_clutch_slips_at_launch_rpm() -> None:
    out, state = step_powertrain(PT, PowertrainState(), 1.0, 0.0, 0.01)
    assert not out.clutch_engaged and out.reflected_inertia_kgm2 == 0.0
    assert out.engine_rpm == PT.launch_rpm
    expected = full_load_torque_nm(PT, PT.launch_rpm) * overall_ratio(PT, 1) * PT.efficiency
    assert out.axle_torque_nm == pytest.approx(expected)
    assert state.gear == 1
    idle, _ = step_powertrain(PT, PowertrainState(), 0.0, 0.0, 0.01)
    assert idle.axle_torque_nm == 0.0  # no creep, no engine braking with the clutch open


def test_full_throttle_upshifts_with_a_torque_pause() -> None:
    omega = 6100.0 / (overall_ratio(PT, 1) * RPM_PER_RADPS)  # above the full-pedal upshift point
    out, state = step_powertrain(PT, PowertrainState(gear=1), 1.0, omega, 0.01)
    assert state.gear == 2 and state.shift_left_s == PT.shift_time_s and out.axle_torque_nm == 0.0
    t = 0.0
    while state.shift_left_s > 0.0:
        out, state = step_powertrain(PT, state, 1.0, omega, 0.01)
        t += 0.01
        if state.shift_left_s > 0.0:
            assert out.axle_torque_nm == 0.0
    assert t == pytest.approx(PT.shift_time_s, abs=0.011)
    out, state = step_powertrain(PT, state, 1.0, omega, 0.01)
    assert out.axle_torque_nm > 0.0 and out.clutch_engaged and state.gear == 2


@pytest.mark.parametrize("throttle", [0.2, 0.6, 1.0])
def test_gears_never_hunt_while_accelerating(throttle: float) -> None:
    state, gears = PowertrainState(), []
    for omega in np.linspace(0.0, 190.0, 4000):  # 0 .. ~210 km/h, slowly
        _, state = step_powertrain(PT, state, throttle, float(omega), 0.01)
        gears.append(state.gear)
    assert all(b >= a for a, b in zip(gears, gears[1:], strict=False))
    assert gears[-1] == len(PT.gear_ratios)


def test_engine_braking_and_brake_pedal() -> None:
    omega = 2000.0 / (overall_ratio(PT, 3) * RPM_PER_RADPS)  # below the zero-pedal upshift point
    out, _ = step_powertrain(PT, PowertrainState(gear=3), 0.0, omega, 0.01)
    assert out.axle_torque_nm == pytest.approx(
        -PT.engine_brake_torque_nm * overall_ratio(PT, 3) / PT.efficiency
    )
    out, state = step_powertrain(PT, PowertrainState(gear=3), 0.5, omega, 0.01, brake=0.3)
    assert out.axle_torque_nm == 0.0 and out.reflected_inertia_kgm2 == 0.0  # lock-up clutch open
    _, state = step_powertrain(PT, PowertrainState(gear=5), 0.0, 0.0, 0.01, brake=1.0)
    assert state.gear == 1  # locked wheels: the gearbox is back in 1st
    _, state = step_powertrain(PT, PowertrainState(gear=4), 0.0, 0.5, 0.01)
    assert state.gear == 1  # rolled to a stop without braking


def test_parameter_validation() -> None:
    with pytest.raises(ValueError, match="mass_kg"):
        CarParams(mass_kg=-1.0)
    with pytest.raises(ValueError, match="overhang"):
        CarParams(length_m=3.0)
    with pytest.raises(ValueError, match="front_weight_share"):
        CarParams(front_weight_share=1.0)
    with pytest.raises(ValueError, match="mu"):
        TyreParams(mu=0.0)
    with pytest.raises(ValueError, match="decrease"):
        PowertrainParams(gear_ratios=(3.0, 3.5))
    with pytest.raises(ValueError, match="hunting"):
        PowertrainParams(upshift_rpm_full=3500.0)
    with pytest.raises(ValueError, match="front_share"):
        BrakeParams(front_share=1.2)


def test_default_brakes_can_lock_all_wheels() -> None:
    """Full-pedal torque exceeds what each axle's tyres transmit when braking at mu*g (with load transfer)."""
    p = CarParams()
    g, mu = 9.81, p.tyre.mu
    front_load = p.mass_kg * g * (p.cog_to_rear_axle_m + mu * p.cog_height_m) / p.wheelbase_m
    rear_load = p.mass_kg * g - front_load
    r = p.wheel_radius_m
    assert p.brakes.front_share * p.brakes.max_torque_nm > mu * front_load * r
    assert (1.0 - p.brakes.front_share) * p.brakes.max_torque_nm > mu * rear_load * r


def test_config_loader_builds_nested_params() -> None:
    p = from_dict(
        CarParams,
        {"mass_kg": 1600, "tyre": {"mu": 0.5}, "powertrain": {"gear_ratios": [3.5, 2.0, 1.3, 1.0]}},
    )
    assert p.mass_kg == 1600.0 and p.tyre.mu == 0.5 and p.powertrain.gear_ratios == (3.5, 2.0, 1.3, 1.0)
    with pytest.raises(ConfigError, match="tyre.grip"):
        from_dict(CarParams, {"tyre": {"grip": 1.0}})
    with pytest.raises(ConfigError, match="mass_kg"):
        from_dict(CarParams, {"mass_kg": 0})


def test_ackermann_round_trip() -> None:
    from cosim.ego_mujoco.car import ackermann_angles, bicycle_angle

    p = CarParams()
    for delta in np.radians([-35.0, -10.0, -0.5, 0.0, 0.5, 10.0, 35.0]):
        left, right = ackermann_angles(float(delta), p.wheelbase_m, p.track_front_m)
        if delta > 0:
            assert left > delta > right > 0  # left turn: the left wheel is the inner one
        elif delta < 0:
            assert left > delta > right  # right turn: |right| is the larger
            assert abs(right) > abs(delta) > abs(left)
        assert bicycle_angle(left, right) == pytest.approx(float(delta), abs=1e-12)
        # Both wheels' axles pass through the same point on the rear axle line.
        if delta != 0:
            radius = p.wheelbase_m / math.tan(float(delta))
            assert p.wheelbase_m / math.tan(left) == pytest.approx(radius - 0.5 * p.track_front_m)
            assert p.wheelbase_m / math.tan(right) == pytest.approx(radius + 0.5 * p.track_front_m)


def test_parameters_import_without_mujoco() -> None:
    """The config loader can build CarParams without loading the simulator."""
    import subprocess
    import sys

    code = (
        "import sys; from cosim.ego_mujoco import CarParams, EgoState; CarParams(); "
        "assert 'mujoco' not in sys.modules; from cosim.ego_mujoco import EgoCar; assert 'mujoco' in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True)

"""Engine + automatic gearbox + launch clutch as a pure function of pedal and wheel speed (no MuJoCo).

The physics wrapper calls :func:`step_powertrain` every control period (a few ms) with the mean spin
speed of the driven wheels and applies the returned axle torque to the wheel joints. Engine inertia is
not a state here: while the clutch is engaged it is reflected onto the driven wheels
(``reflected_inertia_kgm2``, MuJoCo joint armature), so the engine speed is always the wheel speed times
the overall ratio.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from cosim.ego_mujoco.params import PowertrainParams

RPM_PER_RADPS = 60.0 / (2.0 * math.pi)


# Immutable records as NamedTuples, not frozen dataclasses: the physics builds two every 20 ms control
# period, and a NamedTuple is several times cheaper to create.
class PowertrainState(NamedTuple):
    gear: int = 1  # current gear, 1-based
    shift_left_s: float = 0.0  # [s] remaining torque interruption of a running shift


class PowertrainOutput(NamedTuple):
    axle_torque_nm: float  # [N m] total drive torque on the driven wheels (negative = engine braking)
    engine_rpm: float  # [1/min]
    clutch_engaged: bool  # engine speed locked to the wheels (launch clutch closed, not shifting)
    reflected_inertia_kgm2: float  # [kg m^2] engine inertia seen at the driven wheels (total over them)


def full_load_torque_nm(p: PowertrainParams, rpm: float) -> float:
    """Engine full-load torque [N m] at ``rpm``: low-end ramp, torque plateau, constant power, fuel cut."""
    if rpm >= p.redline_rpm:
        return 0.0
    if rpm <= p.idle_rpm:
        ramp = p.low_torque_fraction
    elif rpm < p.full_torque_rpm:
        ramp = p.low_torque_fraction + (1.0 - p.low_torque_fraction) * (rpm - p.idle_rpm) / (
            p.full_torque_rpm - p.idle_rpm
        )
    else:
        ramp = 1.0
    torque = ramp * p.max_torque_nm
    omega = rpm / RPM_PER_RADPS
    return min(torque, p.max_power_w / omega) if omega > 0.0 else torque


def overall_ratio(p: PowertrainParams, gear: int) -> float:
    return p.gear_ratios[gear - 1] * p.final_drive


def gear_for_speed(p: PowertrainParams, wheel_omega_radps: float) -> int:
    """The gear a relaxed driver (light pedal) would be in at this wheel speed: used on reset."""
    for gear in range(len(p.gear_ratios), 0, -1):
        if wheel_omega_radps * overall_ratio(p, gear) * RPM_PER_RADPS >= p.downshift_rpm_light * 1.2:
            return gear
    return 1


def step_powertrain(
    p: PowertrainParams,
    s: PowertrainState,
    throttle: float,
    wheel_omega_radps: float,
    dt_s: float,
    brake: float = 0.0,
) -> tuple[PowertrainOutput, PowertrainState]:
    """Advance the gearbox by ``dt_s`` and return the drive torque for the next ``dt_s``.

    throttle, brake: pedals in [0, 1]; wheel_omega_radps: mean spin speed of the driven wheels [rad/s].
    With the brake pressed the converter lock-up clutch is open (no drive torque, no engine braking, no
    engine inertia on the wheels, which therefore lock as fast as their brakes allow) and the gearbox
    follows the wheel speed down without shift pauses, as an automatic does.
    """
    throttle = min(max(float(throttle), 0.0), 1.0)
    omega = max(float(wheel_omega_radps), 0.0)  # no reverse gear
    if brake > 0.0:
        gear = min(s.gear, gear_for_speed(p, omega))
        rpm = max(omega * overall_ratio(p, gear) * RPM_PER_RADPS, p.idle_rpm)
        return PowertrainOutput(0.0, rpm, False, 0.0), PowertrainState(gear, 0.0)
    gear, shift_left = s.gear, max(s.shift_left_s - dt_s, 0.0)
    ratio = overall_ratio(p, gear)
    rpm_wheels = omega * ratio * RPM_PER_RADPS
    launch = p.idle_rpm + throttle * (p.launch_rpm - p.idle_rpm)

    # Nearly stopped in a higher gear (rolled to a stop): the clutch is open, so select 1st directly.
    if gear > 1 and rpm_wheels < p.idle_rpm:
        gear, shift_left = 1, 0.0
        ratio = overall_ratio(p, gear)
        rpm_wheels = omega * ratio * RPM_PER_RADPS

    if shift_left > 0.0:
        out = PowertrainOutput(0.0, max(rpm_wheels, p.idle_rpm), False, 0.0)
        return out, PowertrainState(gear, shift_left)

    if gear == 1 and rpm_wheels < launch:
        # Slipping launch clutch: the engine runs at the launch speed and passes its torque through.
        engine_rpm = max(launch, p.idle_rpm)
        engine_torque = throttle * full_load_torque_nm(p, engine_rpm)
        engaged = False
    else:
        engine_rpm = rpm_wheels
        engine_torque = throttle * full_load_torque_nm(p, engine_rpm)
        if rpm_wheels > p.idle_rpm:
            engine_torque -= (1.0 - throttle) * p.engine_brake_torque_nm
        engaged = True

    if engine_torque >= 0.0:
        axle_torque = engine_torque * ratio * p.efficiency
    else:  # drag flows backwards through the drivetrain: its losses add to the braking
        axle_torque = engine_torque * ratio / p.efficiency
    reflected = p.engine_inertia_kgm2 * ratio * ratio if engaged else 0.0

    # Shift decision (takes effect now; no torque for shift_time_s).
    if engaged:
        up = p.upshift_rpm_light + throttle * (p.upshift_rpm_full - p.upshift_rpm_light)
        down = p.downshift_rpm_light + throttle * (p.downshift_rpm_full - p.downshift_rpm_light)
        new_gear = gear
        if engine_rpm > up and gear < len(p.gear_ratios):
            new_gear = gear + 1
        elif engine_rpm < down and gear > 1:
            new_gear = gear - 1
        if new_gear != gear:
            return PowertrainOutput(0.0, engine_rpm, False, 0.0), PowertrainState(new_gear, p.shift_time_s)
    return PowertrainOutput(axle_torque, engine_rpm, engaged, reflected), PowertrainState(gear, 0.0)

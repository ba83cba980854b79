"""Steady-state cornering: kinematic radius at low speed, understeer growing with speed, the grip limit."""

from __future__ import annotations

import math

import pytest

from cosim.ego_mujoco import CarParams, EgoCar

G = 9.81
P = CarParams()


def kinematic_radius(steer_rad: float) -> float:
    """Bicycle model: the rear-axle midpoint turns on R = L / tan(delta)."""
    return P.wheelbase_m / math.tan(abs(steer_rad))


def understeer_gradient() -> float:
    """Linear bicycle model: delta = L / R + K a_y, K = m_f / C_f - m_r / C_r [rad / (m/s^2)]."""
    m_front = P.front_weight_share * P.mass_kg
    c_front = 2.0 * P.tyre.cornering_stiffness_front_n_per_rad
    c_rear = 2.0 * P.tyre.cornering_stiffness_rear_n_per_rad
    return m_front / c_front - (P.mass_kg - m_front) / c_rear


@pytest.mark.parametrize("steer", [0.3, -0.3, 1.0])
def test_low_speed_radius_is_kinematic(corner, steer: float) -> None:
    c = corner(P, 2.0, steer, seconds=14.0)
    expected = kinematic_radius(c.steer_rad)
    print(
        f"steer {steer:+.1f}: delta {math.degrees(c.steer_rad):.2f} deg, "
        f"R {c.radius_m:.2f} m, L/tan = {expected:.2f} m"
    )
    assert c.steer_rad == pytest.approx(steer * P.max_steer_rad, rel=0.01)  # servo reached the command
    assert c.radius_m == pytest.approx(expected, rel=0.10)
    assert c.all_wheels_in_contact


def test_understeer_grows_with_speed(corner) -> None:
    speeds = [2.0, 10.0, 15.0, 20.0]
    results = [corner(P, v, 0.1) for v in speeds]
    radii = [c.radius_m for c in results]
    print("R at", speeds, "m/s:", [round(r, 2) for r in radii])
    assert all(b > a * 1.02 for a, b in zip(radii, radii[1:], strict=False)), radii
    k = understeer_gradient()
    assert k > 0.0  # the default car understeers by design (front tyres softer per unit load)
    for c in results:
        predicted = P.wheelbase_m / (c.steer_rad - k * c.lateral_accel_mps2)
        assert c.radius_m == pytest.approx(predicted, rel=0.05)
        # Stays upright and on the plane: no suspension, so only the tyres' vertical compliance rolls it.
        assert c.all_wheels_in_contact
        assert c.max_abs_roll_rad < math.radians(2.0)
        assert c.max_abs_pitch_rad < math.radians(1.0)
        assert c.max_z_dev_m < 0.02


def test_lateral_grip_limit_is_mu_g() -> None:
    """Winding the steering in at 25 m/s: lateral acceleration saturates near mu*g, the car plows on."""
    car = EgoCar(P)
    car.reset(0.0, 0.0, 0.0, 25.0)
    states = [car.step(0.4, 0.0, min(1.0, i * 0.01), 0.1) for i in range(60)]
    peak = max(abs(s.lateral_accel_mps2) for s in states)
    print(f"peak lateral acceleration {peak / G:.2f} g (mu = {P.tyre.mu})")
    assert 0.85 * P.tyre.mu * G < peak < 1.05 * P.tyre.mu * G
    last = states[-1]
    assert abs(math.atan2(last.lateral_speed_mps, last.speed_mps)) < math.radians(10.0)  # no spin
    assert last.in_contact.all() and abs(last.roll_rad) < math.radians(3.0)

"""0 -> 100 km/h at full throttle: MuJoCo against a point-mass reference and the power/mass bound.

Expected range for a car of power P and mass m (state it in the report):
- physics bound: with every watt of engine power turned into kinetic energy from standstill,
  t >= m v^2 / (2 P) = 5.4 s for the default 1400 kg / 100 kW car (71 W/kg);
- point-mass reference: the same engine curve, gearbox, shift pauses, traction limit (front-axle load
  with longitudinal load transfer), drag, rolling resistance and rotational inertia integrated in 1-D;
  the MuJoCo car must be within 10 % of it (wheel-road contact delivers the torque without loss);
- production cars of ~70 W/kg do 0-100 km/h in 9-11 s; the default car must land there.
"""

from __future__ import annotations

import pytest

from cosim.ego_mujoco import CarParams, EgoCar, PowertrainParams, TyreParams
from cosim.ego_mujoco.physics import TCS_MARGIN
from cosim.ego_mujoco.powertrain import PowertrainState, step_powertrain

G = 9.81
V100 = 100.0 / 3.6  # [m/s]


def mujoco_0_100(params: CarParams) -> float:
    car = EgoCar(params)
    car.reset(0.0, 0.0, 0.0, 0.0)
    for _ in range(300):  # 30 s
        s = car.step(1.0, 0.0, 0.0, 0.1)
        if s.speed_mps >= V100:
            return s.t_s
    raise AssertionError(f"0-100 km/h not reached in 30 s (speed {s.speed_mps * 3.6:.1f} km/h)")


def reference_0_100(p: CarParams, dt: float = 0.001) -> float:
    """Quasi-static point mass (front-wheel drive), explicit Euler at 1 ms."""
    assert p.powertrain.driven_axle == "front"
    m, r, h, L = p.mass_kg, p.wheel_radius_m, p.cog_height_m, p.wheelbase_m
    drag = 0.5 * p.air_density_kg_m3 * p.drag_coefficient * p.frontal_area_m2
    state, v, a, t = PowertrainState(), 0.0, 0.0, 0.0
    while v < V100:
        out, state = step_powertrain(p.powertrain, state, 1.0, v / r, dt)
        front_load = m * (G * p.cog_to_rear_axle_m - a * h) / L
        traction = out.axle_torque_nm / r
        if p.powertrain.traction_control:
            traction = min(
                traction, TCS_MARGIN * p.tyre.mu * front_load + out.reflected_inertia_kgm2 * a / r**2
            )
        resist = p.tyre.rolling_resistance * m * G + drag * v * v
        m_eff = m + (4.0 * p.wheel_inertia_kgm2 + out.reflected_inertia_kgm2) / r**2
        a = (traction - resist) / m_eff
        v += a * dt
        t += dt
    return t


def test_default_car_0_100_in_expected_range() -> None:
    p = CarParams()
    t = mujoco_0_100(p)
    ref = reference_0_100(p)
    bound = p.mass_kg * V100**2 / (2.0 * p.powertrain.max_power_w)
    print(f"0-100 km/h: MuJoCo {t:.2f} s, point-mass reference {ref:.2f} s, power bound {bound:.2f} s")
    assert t > bound
    assert t == pytest.approx(ref, rel=0.10)
    assert 9.0 <= t <= 11.0


def test_more_power_is_faster_and_matches_its_reference() -> None:
    strong = CarParams(powertrain=PowertrainParams(max_power_w=150_000.0, max_torque_nm=320.0))
    t = mujoco_0_100(strong)
    ref = reference_0_100(strong)
    print(f"0-100 km/h with 150 kW: MuJoCo {t:.2f} s, reference {ref:.2f} s")
    assert t == pytest.approx(ref, rel=0.10)
    assert t < mujoco_0_100(CarParams()) - 1.0


def test_traction_limited_launch_on_low_friction() -> None:
    """On mu = 0.3 the launch is limited by the front tyres, not the engine."""
    p = CarParams(tyre=TyreParams(mu=0.3))
    car = EgoCar(p)
    car.reset(0.0, 0.0, 0.0, 0.0)
    accels = [car.step(1.0, 0.0, 0.0, 0.1).accel_mps2 for _ in range(20)][5:]
    front_share = p.front_weight_share
    # a = mu * N_front / m with N_front reduced by load transfer: a = mu g b / (L + mu h)
    expected = (
        TCS_MARGIN
        * 0.3
        * G
        * front_share
        * p.wheelbase_m
        / (p.wheelbase_m + TCS_MARGIN * 0.3 * p.cog_height_m)
    )
    mean = sum(accels) / len(accels)
    assert mean == pytest.approx(expected, rel=0.10)

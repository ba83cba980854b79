"""Parameters of the ego car (pure: no MuJoCo import, so the config loader can use them cheaply).

Defaults describe a compact front-wheel-drive passenger car of 1400 kg with a 100 kW petrol engine and a
6-speed automatic gearbox on dry asphalt (mu = 0.9): 0-100 km/h in about 10 s, braking at mu*g.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal


def _positive(obj: object, *names: str) -> None:
    for name in names:
        value = getattr(obj, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ValueError(f"{type(obj).__name__}.{name} must be a positive number, got {value!r}")


def _non_negative(obj: object, *names: str) -> None:
    for name in names:
        value = getattr(obj, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
            raise ValueError(f"{type(obj).__name__}.{name} must be >= 0, got {value!r}")


@dataclass(frozen=True)
class TyreParams:
    """A linear tyre (force = cornering stiffness x slip angle) saturating on the friction circle mu*Fz,
    on a vertical spring-damper (the car has no separate suspension).

    The same stiffness acts on the longitudinal slip ratio (a simplification: real tyres are ~1.5x stiffer
    longitudinally). MuJoCo's elliptic friction cone gives the combined-slip friction circle.
    """

    mu: float = 0.9  # [-] tyre-road friction coefficient (peak = sliding); 0.9 dry asphalt, ~0.5 wet
    cornering_stiffness_front_n_per_rad: float = 60_000.0  # [N/rad] per front tyre
    cornering_stiffness_rear_n_per_rad: float = 65_000.0  # [N/rad] per rear tyre (stiffer: understeer)
    vertical_stiffness_n_per_m: float = 200_000.0  # [N/m] per tyre
    vertical_damping_ratio: float = 0.5  # [-] of the vertical mode of one corner (no suspension dampers)
    rolling_resistance: float = 0.012  # [-] rolling-resistance coefficient (force / normal load)
    min_slip_speed_mps: float = 1.0  # [m/s] slip stiffness is evaluated at least at this speed (at rest)

    def __post_init__(self) -> None:
        _positive(
            self,
            "mu",
            "cornering_stiffness_front_n_per_rad",
            "cornering_stiffness_rear_n_per_rad",
            "vertical_stiffness_n_per_m",
            "vertical_damping_ratio",
            "min_slip_speed_mps",
        )
        _non_negative(self, "rolling_resistance")
        if self.mu > 2.0:
            raise ValueError(f"TyreParams.mu = {self.mu} is not a road tyre (expected 0 < mu <= 2)")
        if self.rolling_resistance > 0.1:
            raise ValueError(
                f"TyreParams.rolling_resistance = {self.rolling_resistance} is too large (<= 0.1)"
            )
        if not (20_000.0 <= self.vertical_stiffness_n_per_m <= 2_000_000.0):
            raise ValueError(
                f"TyreParams.vertical_stiffness_n_per_m = {self.vertical_stiffness_n_per_m} is outside "
                "[2e4, 2e6] N/m (a tyre is ~2e5)"
            )


@dataclass(frozen=True)
class PowertrainParams:
    """Engine full-load curve, automatic gearbox with torque interruption while shifting, launch clutch.

    Full-load engine torque: ramps linearly from ``low_torque_fraction * max_torque_nm`` at idle to
    ``max_torque_nm`` at ``full_torque_rpm``, is capped by ``max_power_w / omega`` above that (constant
    power) and is cut at ``redline_rpm``. The pedal scales this torque linearly.
    """

    driven_axle: Literal["front", "rear", "all"] = "front"
    max_power_w: float = 100_000.0  # [W] engine peak power
    max_torque_nm: float = 250.0  # [N m] engine peak torque
    low_torque_fraction: float = 0.5  # [-] share of max torque available at idle
    idle_rpm: float = 800.0  # [1/min]
    full_torque_rpm: float = 1500.0  # [1/min]
    redline_rpm: float = 6500.0  # [1/min] fuel cut above
    launch_rpm: float = 2500.0  # [1/min] engine speed held by the slipping clutch at full pedal
    gear_ratios: tuple[float, ...] = (3.60, 2.10, 1.45, 1.10, 0.88, 0.72)  # [-] 1st gear first
    final_drive: float = 3.9  # [-]
    efficiency: float = 0.92  # [-] drivetrain efficiency (engine -> wheels)
    engine_inertia_kgm2: float = 0.15  # [kg m^2] engine + flywheel, reflected to the wheels when engaged
    engine_brake_torque_nm: float = 25.0  # [N m] engine drag at closed throttle (clutch engaged)
    shift_time_s: float = 0.3  # [s] no drive torque while shifting
    upshift_rpm_light: float = 2500.0  # [1/min] upshift point at zero pedal ...
    upshift_rpm_full: float = 6000.0  # [1/min] ... and at full pedal (linear in between)
    downshift_rpm_light: float = 1300.0  # [1/min] downshift point at zero pedal ...
    downshift_rpm_full: float = 3000.0  # [1/min] ... and at full pedal (kick-down)
    traction_control: bool = True  # cap drive torque at the driven tyres' friction limit

    def __post_init__(self) -> None:
        _positive(
            self,
            "max_power_w",
            "max_torque_nm",
            "idle_rpm",
            "full_torque_rpm",
            "redline_rpm",
            "launch_rpm",
            "final_drive",
            "efficiency",
            "engine_inertia_kgm2",
        )
        _non_negative(self, "engine_brake_torque_nm", "shift_time_s", "low_torque_fraction")
        if self.driven_axle not in ("front", "rear", "all"):
            raise ValueError(
                f"PowertrainParams.driven_axle must be front, rear or all, got {self.driven_axle!r}"
            )
        if not self.gear_ratios or any(not (r > 0) for r in self.gear_ratios):
            raise ValueError(
                f"PowertrainParams.gear_ratios must be positive numbers, got {self.gear_ratios!r}"
            )
        if any(b >= a for a, b in zip(self.gear_ratios, self.gear_ratios[1:], strict=False)):
            raise ValueError(
                f"PowertrainParams.gear_ratios must decrease from 1st gear, got {self.gear_ratios!r}"
            )
        if self.efficiency > 1.0:
            raise ValueError(f"PowertrainParams.efficiency must be <= 1, got {self.efficiency}")
        if self.low_torque_fraction > 1.0:
            raise ValueError(
                f"PowertrainParams.low_torque_fraction must be <= 1, got {self.low_torque_fraction}"
            )
        if not (self.idle_rpm < self.full_torque_rpm < self.redline_rpm):
            raise ValueError("PowertrainParams needs idle_rpm < full_torque_rpm < redline_rpm")
        if not (self.idle_rpm <= self.launch_rpm < self.redline_rpm):
            raise ValueError("PowertrainParams needs idle_rpm <= launch_rpm < redline_rpm")
        if not (self.upshift_rpm_light <= self.upshift_rpm_full <= self.redline_rpm):
            raise ValueError("PowertrainParams needs upshift_rpm_light <= upshift_rpm_full <= redline_rpm")
        if not (self.downshift_rpm_light <= self.downshift_rpm_full):
            raise ValueError("PowertrainParams needs downshift_rpm_light <= downshift_rpm_full")
        # No gear hunting: after an upshift the engine must stay above the downshift point and vice versa.
        steps = [a / b for a, b in zip(self.gear_ratios, self.gear_ratios[1:], strict=False)]
        for up, down in (
            (self.upshift_rpm_light, self.downshift_rpm_light),
            (self.upshift_rpm_full, self.downshift_rpm_full),
        ):
            for step in steps:
                if up / step <= down:
                    raise ValueError(
                        f"PowertrainParams: upshift at {up:.0f} rpm lands at {up / step:.0f} rpm, "
                        "at or below "
                        f"the downshift point {down:.0f} rpm (gear hunting); widen the shift points"
                    )


@dataclass(frozen=True)
class BrakeParams:
    """Friction brakes on all four wheels; full pedal must be able to lock the wheels (reach mu*Fz)."""

    max_torque_nm: float = 6000.0  # [N m] total brake torque of all four wheels at full pedal
    front_share: float = 0.7  # [-] share of the brake torque on the front axle
    abs: bool = True  # cap each wheel's brake torque at its tyre's friction limit (no locking)
    abs_margin: float = 0.98  # [-] ABS cap as a fraction of mu*Fz*r

    def __post_init__(self) -> None:
        _positive(self, "max_torque_nm", "abs_margin")
        if not (0.0 <= self.front_share <= 1.0):
            raise ValueError(f"BrakeParams.front_share must be in [0, 1], got {self.front_share}")
        if self.abs_margin > 1.0:
            raise ValueError(
                f"BrakeParams.abs_margin must be <= 1 (a cap above mu*Fz*r locks), got {self.abs_margin}"
            )


@dataclass(frozen=True)
class CarParams:
    """Geometry, mass and subsystems of the ego car. Lengths in metres, the car frame: x forward, y left."""

    mass_kg: float = 1400.0  # [kg] total, including wheels
    length_m: float = 4.40  # [m] bumper to bumper
    width_m: float = 1.80  # [m]
    height_m: float = 1.45  # [m]
    wheelbase_m: float = 2.65  # [m]
    front_overhang_m: float = 0.90  # [m] front bumper to front axle
    track_front_m: float = 1.55  # [m]
    track_rear_m: float = 1.53  # [m]
    front_weight_share: float = 0.60  # [-] static share of the weight on the front axle (sets the CoG x)
    cog_height_m: float = 0.55  # [m] above the road
    wheel_radius_m: float = 0.31  # [m] loaded rolling radius
    wheel_mass_kg: float = 20.0  # [kg] each, wheel + tyre + brake disc + hub (part of mass_kg)
    wheel_inertia_kgm2: float = 1.0  # [kg m^2] spin inertia of one wheel
    yaw_gyration_radius_m: float = 1.30  # [m] chassis yaw inertia = m_chassis * r^2
    pitch_gyration_radius_m: float = 1.25  # [m]
    roll_gyration_radius_m: float = 0.60  # [m]
    max_steer_deg: float = 35.0  # [deg] max road-wheel angle of the equivalent bicycle (front axle centre)
    max_steer_rate_deg_s: float = 40.0  # [deg/s] max road-wheel angle rate
    drag_coefficient: float = 0.30  # [-] Cd
    frontal_area_m2: float = 2.20  # [m^2]
    air_density_kg_m3: float = 1.20  # [kg/m^3]
    tyre: TyreParams = field(default_factory=TyreParams)
    powertrain: PowertrainParams = field(default_factory=PowertrainParams)
    brakes: BrakeParams = field(default_factory=BrakeParams)

    def __post_init__(self) -> None:
        _positive(
            self,
            "mass_kg",
            "length_m",
            "width_m",
            "height_m",
            "wheelbase_m",
            "track_front_m",
            "track_rear_m",
            "cog_height_m",
            "wheel_radius_m",
            "wheel_mass_kg",
            "wheel_inertia_kgm2",
            "yaw_gyration_radius_m",
            "pitch_gyration_radius_m",
            "roll_gyration_radius_m",
            "max_steer_deg",
            "max_steer_rate_deg_s",
            "air_density_kg_m3",
        )
        _non_negative(self, "front_overhang_m", "drag_coefficient", "frontal_area_m2")
        if self.front_overhang_m + self.wheelbase_m > self.length_m:
            raise ValueError(
                f"CarParams: front overhang {self.front_overhang_m} m + wheelbase {self.wheelbase_m} m "
                "exceed "
                f"the length {self.length_m} m"
            )
        if not (0.0 < self.front_weight_share < 1.0):
            raise ValueError(f"CarParams.front_weight_share must be in (0, 1), got {self.front_weight_share}")
        if max(self.track_front_m, self.track_rear_m) > self.width_m:
            raise ValueError("CarParams: a track is wider than the car")
        if 4 * self.wheel_mass_kg >= 0.5 * self.mass_kg:
            raise ValueError("CarParams: four wheels weigh more than half the car; check wheel_mass_kg")
        if self.max_steer_deg >= 60.0:
            raise ValueError(f"CarParams.max_steer_deg = {self.max_steer_deg} is not a road car (< 60)")
        if self.cog_height_m >= self.height_m:
            raise ValueError("CarParams.cog_height_m must be below the roof (height_m)")
        # The inner wheel's Ackermann angle must stay below 90 deg at full lock.
        t = math.tan(math.radians(self.max_steer_deg))
        if 0.5 * max(self.track_front_m, self.track_rear_m) * t >= 0.95 * self.wheelbase_m:
            raise ValueError(
                "CarParams: max_steer_deg too large for this wheelbase/track (inner wheel > 90 deg)"
            )

    # -- derived geometry (car frame: origin at the footprint centre on the road, x forward, y left) ------
    @property
    def front_axle_x_m(self) -> float:
        return 0.5 * self.length_m - self.front_overhang_m

    @property
    def rear_axle_x_m(self) -> float:
        return self.front_axle_x_m - self.wheelbase_m

    @property
    def cog_x_m(self) -> float:
        """CoG x in the car frame: the front axle carries front_weight_share of the weight."""
        return self.rear_axle_x_m + self.front_weight_share * self.wheelbase_m

    @property
    def cog_to_front_axle_m(self) -> float:
        return self.front_axle_x_m - self.cog_x_m

    @property
    def cog_to_rear_axle_m(self) -> float:
        return self.cog_x_m - self.rear_axle_x_m

    @property
    def max_steer_rad(self) -> float:
        return math.radians(self.max_steer_deg)

    @property
    def max_steer_rate_rad_s(self) -> float:
        return math.radians(self.max_steer_rate_deg_s)


@dataclass(frozen=True)
class StaticBox:
    """A static box obstacle in MuJoCo world coordinates."""

    centre_m: tuple[float, float, float]  # [m] box centre
    half_size_m: tuple[float, float, float]  # [m] half extents along the box's own x, y, z
    yaw_rad: float = 0.0  # [rad] rotation about z, ccw from +x

    def __post_init__(self) -> None:
        if len(self.centre_m) != 3 or len(self.half_size_m) != 3:
            raise ValueError("StaticBox needs 3 centre coordinates and 3 half sizes")
        if any(not (h > 0) for h in self.half_size_m):
            raise ValueError(f"StaticBox half sizes must be positive, got {self.half_size_m}")


@dataclass(frozen=True)
class StaticMesh:
    """A static obstacle given as a triangle mesh in world coordinates (collides as its convex hull)."""

    vertices_m: tuple[tuple[float, float, float], ...]  # (N, 3) [m]
    faces: tuple[tuple[int, int, int], ...] = ()  # (M, 3) vertex indices; empty = hull of the vertices

    def __post_init__(self) -> None:
        if len(self.vertices_m) < 4:
            raise ValueError("StaticMesh needs at least 4 vertices (a volume)")
        n = len(self.vertices_m)
        if any(len(f) != 3 or min(f) < 0 or max(f) >= n for f in self.faces):
            raise ValueError("StaticMesh faces must be index triples into the vertices")


Obstacle = StaticBox | StaticMesh

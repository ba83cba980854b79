"""The ego car's state after a step (pure: no MuJoCo import)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cosim import frames


@dataclass(frozen=True, eq=False)
class EgoState:
    """Snapshot of the ego car in MuJoCo world coordinates (x east, y north, network frame - origin).

    Per-wheel arrays are read-only, shape (4,), in the order front-left, front-right, rear-left, rear-right.
    (eq=False: states hold arrays; compare fields explicitly.)
    """

    t_s: float  # [s] simulated time since the last reset
    x_m: float  # [m] centre of the car footprint
    y_m: float  # [m]
    z_m: float  # [m] height of the body origin (axle height when resting on the road)
    yaw_rad: float  # [rad] heading, counter-clockwise from +x, in (-pi, pi]
    pitch_rad: float  # [rad] nose down positive
    roll_rad: float  # [rad] right side down positive
    speed_mps: float  # [m/s] velocity of the centre along the heading (negative when rolling backwards)
    lateral_speed_mps: float  # [m/s] velocity of the centre to the left of the heading
    accel_mps2: float  # [m/s^2] acceleration of the centre along the heading
    lateral_accel_mps2: float  # [m/s^2] acceleration of the centre to the left (centripetal in a left turn)
    yaw_rate_rps: float  # [rad/s] counter-clockwise positive
    steer_rad: float  # [rad] actual road-wheel angle of the equivalent bicycle, left positive
    wheel_speed_radps: np.ndarray  # (4,) float64 [rad/s] wheel spin, positive rolling forward
    wheel_load_n: np.ndarray  # (4,) float64 [N] tyre normal force
    in_contact: np.ndarray  # (4,) bool, tyre touches the road
    gear: int  # current gear, 1-based
    engine_rpm: float  # [1/min]
    length_m: float  # [m] car length (needed for the front-bumper position)

    def __post_init__(self) -> None:
        for name in ("wheel_speed_radps", "wheel_load_n", "in_contact"):
            arr = getattr(self, name)
            if arr.shape != (4,):
                raise ValueError(f"EgoState.{name} must have shape (4,), got {arr.shape}")
            arr.setflags(write=False)

    def to_sumo(self, origin_xy: frames.XY = (0.0, 0.0)) -> tuple[float, float, float]:
        """Front-bumper centre in network coordinates [m] and SUMO angle [deg], for ``moveToXY``.

        origin_xy: the network point used as the MuJoCo world origin (see cosim.frames).
        """
        x, y, angle = frames.mujoco_to_sumo(self.x_m, self.y_m, self.yaw_rad, self.length_m, origin_xy)
        return float(x), float(y), float(angle)

"""What a driver perceives, what it commands, and the interface every driver implements.

Conventions (shared with ``cosim.ego_mujoco``): the ego's pose is its CENTRE in network coordinates with yaw
in radians counter-clockwise from +x (the MuJoCo convention; ``cosim.frames`` converts from SUMO's
front-bumper + compass angle). Every distance to something ahead (leader, stop line, sign, speed-limit change,
route end) is measured along the route from the ego's FRONT bumper, because that is what SUMO reports and what
decides whether the car stopped before a line.
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np

from cosim.driver.gap_acceptance import MOVEMENTS

TlsState = Literal["r", "y", "g"]
SignKind = Literal["stop", "give_way", "yield"]  # yield: a green without priority at a light
WarningLevel = Literal["none", "advisory", "warning"]

_TLS_STATES = ("r", "y", "g")
_SIGN_KINDS = ("stop", "give_way", "yield")
_LEVELS = ("none", "advisory", "warning")


def _check_unit(name: str, value: float, lo: float, hi: float) -> None:
    if not (lo <= value <= hi):  # also rejects NaN
        raise ValueError(f"{name} must be within [{lo}, {hi}], got {value!r}")


@dataclass(frozen=True, slots=True)
class Controls:
    """The driver's command for one step.

    steer = +1 is full LEFT (counter-clockwise) and maps to the car's maximum road-wheel angle; the ego model
    applies its own steering-rate limit on top.
    """

    throttle: float = 0.0  # [0, 1] accelerator pedal travel
    brake: float = 0.0  # [0, 1] brake pedal travel (1 = the car's maximum braking force)
    steer: float = 0.0  # [-1, 1] normalised road-wheel angle, +1 = full left

    def __post_init__(self) -> None:
        _check_unit("Controls.throttle", self.throttle, 0.0, 1.0)
        _check_unit("Controls.brake", self.brake, 0.0, 1.0)
        _check_unit("Controls.steer", self.steer, -1.0, 1.0)

    @classmethod
    def clipped(cls, throttle: float, brake: float, steer: float) -> Controls:
        """Build Controls from raw values, clipping each to its range (NaN counts as 0)."""

        def clip(v: float, lo: float, hi: float) -> float:
            v = float(v)
            return 0.0 if math.isnan(v) else min(hi, max(lo, v))

        return cls(clip(throttle, 0.0, 1.0), clip(brake, 0.0, 1.0), clip(steer, -1.0, 1.0))


@dataclass(frozen=True, eq=False)
class PathGeometry:
    """Segment vectors and arc lengths of a polyline (computed once per step, shared by all users)."""

    seg_xy_m: np.ndarray  # (M-1, 2) float64 [m] segment vectors
    seg_len_m: np.ndarray  # (M-1,) float64 [m] segment lengths (zero-length segments count as 1e-9 m)
    cum_m: np.ndarray  # (M,) float64 [m] arc length at each point, cum_m[0] = 0

    @classmethod
    def of(cls, path_xy_m: np.ndarray) -> PathGeometry:
        seg = path_xy_m[1:] - path_xy_m[:-1]
        seg_len = np.maximum(np.hypot(seg[:, 0], seg[:, 1]), 1e-9)
        cum = np.empty(len(path_xy_m))
        cum[0] = 0.0
        np.cumsum(seg_len, out=cum[1:])
        return cls(seg, seg_len, cum)


def path_errors(
    path_xy_m: np.ndarray, x_m: float, y_m: float, yaw_rad: float, geom: PathGeometry | None = None
) -> tuple[float, float, float]:
    """Lateral and heading error of a pose against a polyline, and the arc length of the projection.

    path_xy_m: (M, 2) float64 [m], M >= 2. Returns (lateral_error_m, heading_error_rad, s_proj_m):
    lateral error is positive when the point is LEFT of the line (same sign as World.lateral_offset_m);
    heading error = yaw - path direction, wrapped to (-pi, pi]; s_proj_m is the arc length from path[0] to the
    nearest point. Beyond the ends the first/last segment is extended, so a path starting slightly ahead of
    the car still gives a sensible error.
    """
    g = geom if geom is not None else PathGeometry.of(path_xy_m)
    d = g.seg_xy_m
    rel = np.array([x_m, y_m]) - path_xy_m[:-1]
    t = np.einsum("ij,ij->i", rel, d) / (g.seg_len_m * g.seg_len_m)
    t_clip = np.minimum(np.maximum(t, 0.0), 1.0)  # np.clip, without its Python-level dispatch
    t_clip[0] = min(t[0], 1.0)  # extend the first segment backwards
    t_clip[-1] = max(t[-1], 0.0) if len(d) > 1 else t[-1]  # and the last one forwards
    off = rel - t_clip[:, None] * d  # from the projection to the point
    i = int(np.einsum("ij,ij->i", off, off).argmin())
    di = d[i]
    seg_len = float(g.seg_len_m[i])
    lateral = (di[0] * rel[i, 1] - di[1] * rel[i, 0]) / seg_len  # > 0: point left of the segment direction
    heading = math.atan2(di[1], di[0])
    herr = (yaw_rad - heading + math.pi) % (2.0 * math.pi) - math.pi
    s_proj = float(g.cum_m[i] + t_clip[i] * seg_len)
    return float(lateral), float(herr), s_proj


@dataclass(frozen=True, eq=False)
class Percept:
    """Everything a driver can perceive at one step (ground truth: noise and delay are the driver's business).

    Distances to things ahead are along the route from the ego's front bumper [m]; ``math.inf`` means "none
    ahead". Fields the bridge cannot fill keep their defaults, which mean "nothing there".
    """

    t_s: float  # [s] simulated time of this percept (monotonic within one run)
    speed_mps: float  # [m/s] own speed along the heading
    x_m: float  # [m] own CENTRE, network x
    y_m: float  # [m] own CENTRE, network y
    yaw_rad: float  # [rad] own yaw, counter-clockwise from +x
    # (M, 2) float64 [m], M >= 2: centre-line of the ego's lane along the predefined route in network
    # coordinates, from at most a few metres behind the car to the preview horizon (~100-200 m) ahead. The
    # lateral / heading errors below are derived from it.
    path_xy_m: np.ndarray
    speed_limit_mps: float  # [m/s] limit where the car is now
    accel_mps2: float = 0.0  # [m/s^2] own longitudinal acceleration
    yaw_rate_rps: float = 0.0  # [rad/s] own yaw rate, counter-clockwise positive
    next_speed_limit_mps: float | None = None  # [m/s] the next different limit along the route, if any
    next_speed_limit_dist_m: float = math.inf  # [m] to where that limit starts
    leader_present: bool = False  # a vehicle ahead on the route (the one to follow or any other)
    leader_id: str | None = None  # its SUMO id
    leader_gap_m: float = math.inf  # [m] bumper-to-bumper: own front bumper to the leader's rear bumper
    leader_speed_mps: float = 0.0  # [m/s]
    # the next vehicle on the route beyond the leader (HDM multi-anticipation: a driver sees past the car in
    # front, e.g. a car standing behind one that pulls out of the way); inf = none seen
    next_leader_gap_m: float = math.inf  # [m] own front bumper to its rear bumper
    next_leader_speed_mps: float = 0.0  # [m/s]
    tls_state: TlsState | None = None  # next traffic light on the route: 'r' | 'y' | 'g'; None = none ahead
    tls_dist_m: float = math.inf  # [m] to that light's stop line
    tls_id: str | None = None  # optional id: tells consecutive lights apart
    sign_kind: SignKind | None = None  # next stop / give-way sign on the route; None = none ahead
    sign_dist_m: float = math.inf  # [m] to the sign's stop / yield line
    sign_id: str | None = None  # optional id (e.g. the junction id): tells consecutive signs apart
    junction_conflict: bool = False  # the junction of that sign is blocked: wait whatever the gap
    # [s] until the first vehicle the ego must let pass reaches the conflict area (inf: none near); the driver
    # judges it against its critical gap for the movement (cosim.driver.gap_acceptance)
    junction_gap_s: float = math.inf
    junction_movement: str = "minor_through"  # HCM movement through that junction (gap_acceptance.MOVEMENTS)
    route_end_dist_m: float = math.inf  # [m] to the end of the predefined route (the driver stops there)
    # [m] to where a vehicle crossing the route (in the junction ahead, or standing across it) will be in the
    # ego's way when the ego gets there: the driver stops short of it
    crossing_dist_m: float = math.inf
    # [m] to where the route's next lane change would begin to enter a lane with no gap in its traffic for the
    # ego: the driver waits short of it
    merge_dist_m: float = math.inf
    sys_a_lit: bool = False  # system A: the leader's rear "keep distance" display is lit AND legible
    sys_b_gap_s: float | None = None  # system B: time gap shown in the car [s]; None = "no data" / off
    sys_b_level: WarningLevel = "none"  # system B: 'none' | 'advisory' | 'warning'

    def __post_init__(self) -> None:
        path = np.asarray(self.path_xy_m, dtype=np.float64)
        if path.ndim != 2 or path.shape[1] != 2 or path.shape[0] < 2:
            raise ValueError(f"Percept.path_xy_m must have shape (M>=2, 2), got {path.shape}")
        if not np.isfinite(path).all():
            raise ValueError("Percept.path_xy_m must be finite")
        object.__setattr__(self, "path_xy_m", path)
        for name in ("t_s", "speed_mps", "x_m", "y_m", "yaw_rad", "accel_mps2", "yaw_rate_rps"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"Percept.{name} must be finite, got {getattr(self, name)!r}")
        if not self.speed_limit_mps > 0.0:
            raise ValueError(f"Percept.speed_limit_mps must be > 0, got {self.speed_limit_mps!r}")
        if self.next_speed_limit_mps is not None and not self.next_speed_limit_mps > 0.0:
            raise ValueError(
                f"Percept.next_speed_limit_mps must be > 0 or None, got {self.next_speed_limit_mps!r}"
            )
        for name in (
            "next_speed_limit_dist_m",
            "leader_gap_m",
            "next_leader_gap_m",
            "tls_dist_m",
            "sign_dist_m",
            "route_end_dist_m",
            "crossing_dist_m",
            "merge_dist_m",
            "junction_gap_s",
        ):
            if math.isnan(getattr(self, name)):
                raise ValueError(f"Percept.{name} must not be NaN")
        if self.leader_present and not math.isfinite(self.leader_gap_m):
            raise ValueError("Percept.leader_gap_m must be finite when leader_present")
        if self.tls_state is not None:
            if self.tls_state not in _TLS_STATES:
                raise ValueError(
                    f"Percept.tls_state must be one of {_TLS_STATES} or None, got {self.tls_state!r}"
                )
            if not math.isfinite(self.tls_dist_m):
                raise ValueError("Percept.tls_dist_m must be finite when tls_state is set")
        if self.sign_kind is not None:
            if self.sign_kind not in _SIGN_KINDS:
                raise ValueError(
                    f"Percept.sign_kind must be one of {_SIGN_KINDS} or None, got {self.sign_kind!r}"
                )
            if not math.isfinite(self.sign_dist_m):
                raise ValueError("Percept.sign_dist_m must be finite when sign_kind is set")
        if self.junction_movement not in MOVEMENTS:
            raise ValueError(
                f"Percept.junction_movement must be one of {MOVEMENTS}, got {self.junction_movement!r}"
            )
        if self.sys_b_level not in _LEVELS:
            raise ValueError(f"Percept.sys_b_level must be one of {_LEVELS}, got {self.sys_b_level!r}")
        if self.sys_b_gap_s is not None and not (self.sys_b_gap_s >= 0.0):
            raise ValueError(f"Percept.sys_b_gap_s must be >= 0 or None, got {self.sys_b_gap_s!r}")

    @cached_property
    def path_geometry(self) -> PathGeometry:
        """Segments and arc lengths of path_xy_m (computed on first use)."""
        return PathGeometry.of(self.path_xy_m)

    @cached_property
    def _errors(self) -> tuple[float, float, float]:
        return path_errors(self.path_xy_m, self.x_m, self.y_m, self.yaw_rad, self.path_geometry)

    @property
    def lateral_error_m(self) -> float:
        """[m] signed distance of the car centre from the path, LEFT positive."""
        return self._errors[0]

    @property
    def heading_error_rad(self) -> float:
        """[rad] yaw minus the path direction at the nearest point, wrapped to (-pi, pi]."""
        return self._errors[1]

    @property
    def path_progress_m(self) -> float:
        """[m] arc length from path_xy_m[0] to the car centre's projection onto the path."""
        return self._errors[2]


class Driver(abc.ABC):
    """Who drives the ego: turns one Percept into one Controls per SUMO step."""

    @abc.abstractmethod
    def reset(self, rng: np.random.Generator | None = None) -> None:
        """Forget all internal state (buffers, ramps, latched decisions); use ``rng`` from now on if given."""

    @abc.abstractmethod
    def act(self, percept: Percept, dt_s: float) -> Controls:
        """The command for the step that starts at ``percept.t_s`` and lasts ``dt_s`` [s]."""

"""Shared pieces of the assistance systems: vehicle state, following-gap geometry, events, building index.

Geometry follows cosim.world: a vehicle's position is the centre of its FRONT bumper in network
coordinates [m], its heading is SUMO's compass angle (degrees clockwise from north, unit vector
(sin, cos)). Everything here is pure (floats, numpy, shapely); no simulator handle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cosim.world import World


@dataclass(frozen=True)
class VehicleState:
    """One vehicle at one step, as the assistance systems need it (true state, e.g. from World)."""

    x_m: float  # front-bumper centre, network x [m]
    y_m: float  # front-bumper centre, network y [m]
    heading_deg: float  # compass heading, clockwise from north [deg]
    speed_mps: float  # speed along the heading [m/s]
    length_m: float  # vehicle length [m]
    accel_mps2: float = 0.0  # longitudinal acceleration [m/s^2]

    def __post_init__(self) -> None:
        for name in ("x_m", "y_m", "heading_deg", "speed_mps", "length_m", "accel_mps2"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"VehicleState.{name} must be finite, got {getattr(self, name)!r}")
        if self.length_m < 0.0:
            raise ValueError(f"VehicleState.length_m must be >= 0, got {self.length_m}")

    @classmethod
    def from_world(cls, world: World, slot: int) -> VehicleState:
        """The state of the vehicle in ``slot`` (which must be valid)."""
        if not (0 <= slot < world.capacity and world.valid[slot]):
            raise ValueError(f"world slot {slot} does not hold a live vehicle")
        return cls(
            x_m=float(world.x_m[slot]),
            y_m=float(world.y_m[slot]),
            heading_deg=float(world.heading_deg[slot]),
            speed_mps=float(world.speed_mps[slot]),
            length_m=float(world.length_m[slot]),
            accel_mps2=float(world.accel_mps2[slot]),
        )

    def unit(self) -> tuple[float, float]:
        return heading_unit(self.heading_deg)

    def rear_xy(self) -> tuple[float, float]:
        """Centre of the rear bumper [m]."""
        ux, uy = self.unit()
        return self.x_m - ux * self.length_m, self.y_m - uy * self.length_m


def heading_unit(heading_deg: float) -> tuple[float, float]:
    """Unit vector (x, y) of a compass heading: 0 deg = +y (north), 90 deg = +x (east)."""
    rad = math.radians(heading_deg)
    return math.sin(rad), math.cos(rad)


def left_unit(heading_deg: float) -> tuple[float, float]:
    """Unit vector pointing to the driver's left of a compass heading."""
    ux, uy = heading_unit(heading_deg)
    return -uy, ux


def along_heading_gap_m(
    ego_x_m: float, ego_y_m: float, ego_heading_deg: float, rear_x_m: float, rear_y_m: float
) -> float:
    """Bumper-to-bumper gap [m]: the leader's rear point projected on the ego's heading from its front bumper.

    Negative when the leader's rear is behind the ego's front bumper (overlap or not ahead at all).
    On straight roads this equals SUMO's leader gap (front bumper to rear bumper, minGap not subtracted).
    """
    ux, uy = heading_unit(ego_heading_deg)
    return (rear_x_m - ego_x_m) * ux + (rear_y_m - ego_y_m) * uy


def chord_gap_m(
    ego_x_m: float,
    ego_y_m: float,
    ego_heading_deg: float,
    rear_x_m: float,
    rear_y_m: float,
    leader_heading_deg: float,
) -> float:
    """Bumper-to-bumper gap [m] as a V2V system computes it from two positions: the straight distance from
    the ego's front bumper to the leader's rear, negative when the leader is not ahead of the ego.

    Unlike the projection on the ego's heading it stays close to the distance along the road in curves
    (a chord, not a projection that shrinks to zero after a 90-degree bend). The leader is ahead when its
    rear is ahead along the ego's heading, or the ego's front is behind it along the leader's heading: a
    leader that has turned out of a sharp bend the ego is still entering is ahead though it is abeam.
    """
    ahead = along_heading_gap_m(ego_x_m, ego_y_m, ego_heading_deg, rear_x_m, rear_y_m) > 0.0
    turned = abs((leader_heading_deg - ego_heading_deg + 180.0) % 360.0 - 180.0)
    if not ahead and turned < 150.0:  # (one driving the other way is never ahead)
        # the ego's front as the leader sees it: behind its rear?
        ahead = along_heading_gap_m(rear_x_m, rear_y_m, leader_heading_deg, ego_x_m, ego_y_m) < 0.0
    dist = math.hypot(rear_x_m - ego_x_m, rear_y_m - ego_y_m)
    return dist if ahead else -dist


def time_gap_s(gap_m: float, speed_mps: float, cap_s: float) -> float:
    """Time gap [s] = gap / own speed, saturated at ``cap_s``.

    Saturation is the low-speed handling: at standstill the quotient diverges, and a display can only show
    "more than cap" anyway; a finite cap keeps traces comparable (RMSE) and loggable. A negative gap (the
    leader's rear is not ahead of the front bumper) counts as 0 s.
    """
    gap = max(gap_m, 0.0)
    if speed_mps <= 0.0 or gap >= cap_s * speed_mps:
        return cap_s
    return gap / speed_mps


@dataclass(frozen=True)
class AdasEvent:
    """A transition of what a system shows (for the log: what was displayed and when)."""

    t_s: float  # simulated time of the step at which the new state was first shown [s]
    system: str  # 'A' (rear stereo) or 'B' (V2V time gap)
    kind: str  # A: 'display' | 'perceived'; B: 'level' | 'data'
    old: str  # previous state, e.g. 'off', 'none', 'ok'
    new: str  # new state, e.g. 'on', 'warning', 'no_data'
    value: float | None = None  # A: measured distance [m]; B: displayed time gap [s]; None if not available


class EventRecorder:
    """Keeps the transitions a system made; the loop drains them each step with ``pop_events``."""

    def __init__(self, system: str) -> None:
        self._system = system
        self.events: list[AdasEvent] = []  # every transition since construction
        self._undrained = 0

    def record(self, t_s: float, kind: str, old: str, new: str, value: float | None) -> None:
        self.events.append(AdasEvent(float(t_s), self._system, kind, old, new, value))
        self._undrained += 1

    def pop_events(self) -> list[AdasEvent]:
        """Events recorded since the previous call (the full history stays in ``events``)."""
        if self._undrained == 0:
            return []
        out = self.events[-self._undrained :]
        self._undrained = 0
        return out

"""What one rendered frame shows (pure data), and the vehicle pool's assignment rule.

Live driving (drive.py) and replay (replay.py) both fill a :class:`FrameState`; :class:`Scene.apply`
(scene.py) poses the MuJoCo scene from it. All positions here are NETWORK coordinates of vehicle CENTRES
(not front bumpers) and yaw in radians counter-clockwise from +x (the MuJoCo convention, ``cosim.frames``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from cosim.world3d.hud import HudState


@dataclass(frozen=True)
class EgoPose:
    """The ego car's pose: footprint centre in network coordinates [m], yaw [rad] ccw from +x."""

    x_m: float
    y_m: float
    yaw_rad: float
    z_m: float = 0.0  # [m] body lift above its resting height (bounce, from the physics car)
    pitch_rad: float = 0.0  # [rad] nose down positive
    roll_rad: float = 0.0  # [rad] right side down positive
    braking: bool = False

    def __post_init__(self) -> None:
        for name in ("x_m", "y_m", "yaw_rad", "z_m", "pitch_rad", "roll_rad"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"EgoPose.{name} must be finite, got {getattr(self, name)!r}")


@dataclass(frozen=True, eq=False)
class VehicleFrame:
    """Simulation-controlled vehicles at one instant (struct of arrays, N vehicles)."""

    ids: tuple[str, ...]  # (N,) SUMO vehicle ids
    x_m: np.ndarray  # (N,) float64 [m] footprint centre, network x
    y_m: np.ndarray  # (N,) float64 [m] footprint centre, network y
    yaw_rad: np.ndarray  # (N,) float64 [rad] ccw from +x
    braking: np.ndarray  # (N,) bool, brake lights on

    def __post_init__(self) -> None:
        n = len(self.ids)
        object.__setattr__(self, "ids", tuple(self.ids))
        for name, dtype in (
            ("x_m", np.float64),
            ("y_m", np.float64),
            ("yaw_rad", np.float64),
            ("braking", bool),
        ):
            arr = np.asarray(getattr(self, name), dtype=dtype).reshape(-1)
            if len(arr) != n:
                raise ValueError(f"VehicleFrame.{name} has {len(arr)} entries for {n} ids")
            object.__setattr__(self, name, arr)

    @classmethod
    def empty(cls) -> VehicleFrame:
        z = np.zeros(0)
        return cls((), z, z, z, np.zeros(0, dtype=bool))

    def __len__(self) -> int:
        return len(self.ids)


@dataclass(frozen=True, eq=False)
class FrameState:
    """Everything the scene shows at one instant."""

    t_s: float  # [s] simulated time
    ego: EgoPose | None  # None: no ego (cameras then look at the scene origin)
    vehicles: VehicleFrame = field(default_factory=VehicleFrame.empty)
    lights: dict[str, str] = field(default_factory=dict)  # traffic-light id -> SUMO state string ('GrYy...')
    leader_id: str | None = None  # the ego's leader: the vehicle that carries system A's rear display
    rear_display_lit: bool | None = None  # that display is lit (True) / dark (False); None = no system A
    hud: HudState | None = None


class VehiclePool:
    """Assigns vehicles to a fixed number of car bodies: the ``size`` nearest, keeping a vehicle on the same
    body as long as it stays selected (so colours do not jump between cars)."""

    def __init__(self, size: int) -> None:
        if size < 0:
            raise ValueError(f"VehiclePool size must be >= 0, got {size}")
        self.size = size
        self.slot_of: dict[str, int] = {}
        self._free = list(range(size - 1, -1, -1))  # pop() gives the lowest

    def assign(
        self, ids: tuple[str, ...] | list[str], dist_m: np.ndarray, max_dist_m: float = math.inf
    ) -> np.ndarray:
        """Pool slot per vehicle ((N,) int, -1 = not shown) for this frame.

        dist_m: (N,) float64 [m] distance to the viewer; vehicles farther than max_dist_m are never shown.
        Ties are broken by id, so the result does not depend on the input order.
        """
        n = len(ids)
        dist = np.asarray(dist_m, dtype=np.float64).reshape(-1)
        if len(dist) != n:
            raise ValueError(f"assign: {len(dist)} distances for {n} ids")
        cand = np.flatnonzero(dist <= max_dist_m)
        if len(cand) > self.size:
            order = sorted(cand.tolist(), key=lambda i: (dist[i], ids[i]))
            cand = np.asarray(order[: self.size], dtype=np.int64)
        chosen = {ids[i] for i in cand.tolist()}
        for vid in [v for v in self.slot_of if v not in chosen]:
            self._free.append(self.slot_of.pop(vid))
        self._free.sort(reverse=True)
        out = np.full(n, -1, dtype=np.int64)
        new = []
        for i in cand.tolist():
            slot = self.slot_of.get(ids[i])
            if slot is None:
                new.append(i)
            else:
                out[i] = slot
        for i in sorted(new, key=lambda j: (dist[j], ids[j])):
            slot = self._free.pop()
            self.slot_of[ids[i]] = slot
            out[i] = slot
        return out


def _lerp_angle(a: np.ndarray | float, b: np.ndarray | float, t: float):
    """Angles [rad] from a to b by the shorter way round."""
    return a + t * ((np.asarray(b) - a + np.pi) % (2 * np.pi) - np.pi)


class Interpolator:
    """Frames between two states ``a`` (earlier) and ``b``: poses blend linearly (angles the short way);
    vehicles present in only one of them are shown from ``b`` (a newcomer) or not at all (gone by ``b``);
    lights, displays and the HUD are ``b``'s. The id matching is done once per pair."""

    def __init__(self, a: FrameState, b: FrameState) -> None:
        self.a, self.b = a, b
        index_a = {vid: i for i, vid in enumerate(a.vehicles.ids)}
        self._ia = np.fromiter((index_a.get(vid, -1) for vid in b.vehicles.ids), dtype=np.int64,
                               count=len(b.vehicles))  # fmt: skip
        self._both = self._ia >= 0

    def at(self, alpha: float) -> FrameState:
        """The state at fraction ``alpha`` in [0, 1] of the way from a to b."""
        t = min(1.0, max(0.0, float(alpha)))
        a, b = self.a, self.b
        ego = b.ego
        if a.ego is not None and b.ego is not None:
            ea, eb = a.ego, b.ego
            ego = EgoPose(
                ea.x_m + t * (eb.x_m - ea.x_m), ea.y_m + t * (eb.y_m - ea.y_m),
                float(_lerp_angle(ea.yaw_rad, eb.yaw_rad, t)), ea.z_m + t * (eb.z_m - ea.z_m),
                ea.pitch_rad + t * (eb.pitch_rad - ea.pitch_rad), ea.roll_rad + t * (eb.roll_rad - ea.roll_rad),
                eb.braking,
            )  # fmt: skip
        vb, va = b.vehicles, a.vehicles
        x, y, yaw = vb.x_m.copy(), vb.y_m.copy(), vb.yaw_rad.copy()
        m, ia = self._both, self._ia[self._both]
        x[m] = va.x_m[ia] + t * (vb.x_m[m] - va.x_m[ia])
        y[m] = va.y_m[ia] + t * (vb.y_m[m] - va.y_m[ia])
        yaw[m] = _lerp_angle(va.yaw_rad[ia], vb.yaw_rad[m], t)
        vehicles = VehicleFrame(vb.ids, x, y, yaw, vb.braking)
        return FrameState(a.t_s + t * (b.t_s - a.t_s), ego, vehicles, b.lights, b.leader_id, b.rear_display_lit,
                          b.hud)  # fmt: skip


class Playback:
    """What a viewer shows at a wall-clock instant while simulation steps arrive one by one.

    ``push(frame, arrival_s, tag)`` hands over each step's state as it arrives; ``at(now_s)`` gives the state to
    show: with ``smooth``, the interpolation from the previous step to the newest one, ``(now_s - arrival) /
    step_s`` of the way (clamped to the newest: a late step holds the picture, it never extrapolates), so the
    picture trails the simulation by one step and moves at the wall clock's pace; without it, the newest step.
    ``tag`` is any integer carried with a step (``cosim drive``: the input event the step has read); ``at``
    reports the tag of the step it moves towards (``tag_next``) and of the newest step it shows completely
    (``tag_shown``), so input-to-display latency can be measured at the frame.
    """

    def __init__(self, step_s: float, smooth: bool = True) -> None:
        if not step_s > 0:
            raise ValueError(f"step_s must be > 0, got {step_s}")
        self.step_s = step_s
        self.smooth = smooth
        self._prev: tuple[FrameState, int] | None = None
        self._cur: tuple[FrameState, int] | None = None
        self._arrival = 0.0
        self._interp: Interpolator | None = None
        self.received = 0

    def push(self, frame: FrameState, arrival_s: float, tag: int = 0) -> None:
        self._prev, self._cur = self._cur, (frame, int(tag))
        self._arrival = float(arrival_s)
        self._interp = (
            Interpolator(self._prev[0], frame) if (self.smooth and self._prev is not None) else None
        )
        self.received += 1

    @property
    def empty(self) -> bool:
        return self._cur is None

    def alpha(self, now_s: float) -> float:
        """How far (0..1) the picture is from the previous step to the newest at ``now_s``."""
        if self._interp is None:
            return 1.0
        return min(1.0, max(0.0, (now_s - self._arrival) / self.step_s))

    def at(self, now_s: float) -> tuple[FrameState, int, int] | None:
        """(state to show, tag_next, tag_shown), or None before the first step."""
        if self._cur is None:
            return None
        frame, tag = self._cur
        t = self.alpha(now_s)
        if self._interp is None or t >= 1.0:
            return frame, tag, tag
        return self._interp.at(t), tag, self._prev[1]

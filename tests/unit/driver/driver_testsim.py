"""A tiny closed-loop world for the driver tests: a point-mass + kinematic-bicycle car on a polyline route.

Not the real ego physics (that is cosim.ego_mujoco): just enough to close the loop. The car's pedal response
matches the driver's PedalModel feed-forward except for an optional model mismatch, so the PI loop is tested.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from cosim.driver.base import Controls, Driver, Percept, path_errors
from cosim.driver.scripted import PedalModel

CAR_LENGTH_M = 4.5
WHEELBASE_M = 2.7
MAX_STEER_RAD = 0.6


class Route:
    """A polyline with arc length; (N, 2) float64 [m]."""

    def __init__(self, xy: np.ndarray):
        self.xy = np.asarray(xy, dtype=np.float64)
        seg = np.diff(self.xy, axis=0)
        self.cum = np.concatenate(([0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))))

    @classmethod
    def straight(cls, length_m: float = 3000.0, step_m: float = 5.0) -> Route:
        x = np.arange(-50.0, length_m + step_m, step_m)
        return cls(np.stack([x, np.zeros_like(x)], axis=1))

    @classmethod
    def straight_then_circle(
        cls, straight_m: float, radius_m: float, angle_rad: float, step_m: float = 1.0
    ) -> Route:
        x = np.arange(-50.0, straight_m, step_m)
        pts = [np.stack([x, np.zeros_like(x)], axis=1)]
        n = max(int(radius_m * angle_rad / step_m), 2)
        th = np.linspace(0.0, angle_rad, n)
        # left turn: centre at (straight_m, radius_m)
        pts.append(np.stack([straight_m + radius_m * np.sin(th), radius_m - radius_m * np.cos(th)], axis=1))
        end_dir = np.array([math.cos(angle_rad), math.sin(angle_rad)])
        tail = pts[-1][-1] + np.arange(1, 1000)[:, None] * step_m * end_dir
        pts.append(tail)
        return cls(np.concatenate(pts))

    def point(self, s: float) -> tuple[float, float, float]:
        """(x, y, heading) at arc length s."""
        x = float(np.interp(s, self.cum, self.xy[:, 0]))
        y = float(np.interp(s, self.cum, self.xy[:, 1]))
        i = int(np.clip(np.searchsorted(self.cum, s) - 1, 0, len(self.cum) - 2))
        d = self.xy[i + 1] - self.xy[i]
        return x, y, math.atan2(d[1], d[0])

    def window(self, s_from: float, s_to: float) -> tuple[int, np.ndarray]:
        """(index of the first point, points) covering arc lengths [s_from, s_to]."""
        lo = min(max(int(np.searchsorted(self.cum, s_from)) - 1, 0), len(self.cum) - 2)
        hi = min(int(np.searchsorted(self.cum, s_to)) + 1, len(self.cum))
        return lo, self.xy[lo:hi]


@dataclass
class Car:
    x: float
    y: float
    yaw: float
    v: float
    params: PedalModel = field(default_factory=PedalModel)
    drive_gain: float = 1.0  # model mismatch: real drive force / what the driver assumes
    brake_gain: float = 1.0  # model mismatch: real brake force / what the driver assumes
    a: float = 0.0

    def step(self, c: Controls, dt: float, substeps: int = 5) -> None:
        h = dt / substeps
        p = self.params
        for _ in range(substeps):
            a = c.throttle * p.drive_accel_max(self.v) * self.drive_gain - p.resistance_decel(self.v)
            a -= c.brake * p.max_brake_decel_mps2 * self.brake_gain if self.v > 0 else 0.0
            v_new = max(self.v + a * h, 0.0)
            self.a = (v_new - self.v) / h
            delta = c.steer * MAX_STEER_RAD
            beta = math.atan(0.5 * math.tan(delta))
            v_mid = 0.5 * (self.v + v_new)
            self.x += v_mid * math.cos(self.yaw + beta) * h
            self.y += v_mid * math.sin(self.yaw + beta) * h
            self.yaw += v_mid * math.cos(beta) * math.tan(delta) / WHEELBASE_M * h
            self.v = v_new


@dataclass
class Leader:
    s_rear: float  # [m] arc length of its rear bumper
    v: float  # [m/s]
    accel: Callable[[float, Leader], float] = lambda t, ld: 0.0  # noqa: E731

    def step(self, t: float, dt: float) -> None:
        a = self.accel(t, self)
        v_new = max(self.v + a * dt, 0.0)
        self.s_rear += 0.5 * (self.v + v_new) * dt
        self.v = v_new


@dataclass
class Trace:
    t: np.ndarray
    s_front: np.ndarray  # [m] arc length of the ego's front bumper
    v: np.ndarray
    a: np.ndarray
    gap: np.ndarray  # [m] true bumper gap to the leader (nan without)
    lat: np.ndarray  # [m] lateral error of the centre
    throttle: np.ndarray
    brake: np.ndarray
    steer: np.ndarray
    leader_v: np.ndarray
    debug: list

    def at(self, t: float) -> int:
        return int(np.searchsorted(self.t, t - 1e-9))


def simulate(
    driver: Driver,
    route: Route,
    t_end_s: float,
    *,
    dt_s: float = 0.1,
    v0_mps: float = 0.0,
    s0_m: float = 0.0,
    lateral0_m: float = 0.0,
    yaw_err0_rad: float = 0.0,
    leader: Leader | None = None,
    speed_limit_mps: float = 13.9,
    extras: Callable[[float, float, float], dict] | None = None,
    drive_gain: float = 1.0,
    brake_gain: float = 1.0,
) -> Trace:
    """Close the loop for t_end_s. ``extras(t, s_front, v)`` adds Percept fields (lights, signs, displays)."""
    x, y, hd = route.point(s0_m)
    car = Car(
        x - lateral0_m * math.sin(hd),
        y + lateral0_m * math.cos(hd),
        hd + yaw_err0_rad,
        v0_mps,
        drive_gain=drive_gain,
        brake_gain=brake_gain,
    )
    n = int(round(t_end_s / dt_s))
    rec = {k: np.full(n, np.nan) for k in ("t s v a gap lat thr brk steer lv".split())}
    debug = []
    s_c = s0_m
    for k in range(n):
        t = k * dt_s
        start, win = route.window(s_c - 30.0, s_c + 60.0)
        lat, _, s_loc = path_errors(win, car.x, car.y, car.yaw)
        s_c = route.cum[start] + s_loc  # arc length of the centre
        s_front = s_c + 0.5 * CAR_LENGTH_M
        kw = {}
        if leader is not None:
            kw.update(
                leader_present=True,
                leader_id="lead",
                leader_gap_m=leader.s_rear - s_front,
                leader_speed_mps=leader.v,
            )
        if extras is not None:
            kw.update(extras(t, s_front, car.v))
        kw.setdefault("speed_limit_mps", speed_limit_mps)
        _, path = route.window(s_c - 5.0, s_c + 200.0)
        p = Percept(
            t_s=t,
            speed_mps=car.v,
            x_m=car.x,
            y_m=car.y,
            yaw_rad=car.yaw,
            path_xy_m=path,
            accel_mps2=car.a,
            **kw,
        )
        c = driver.act(p, dt_s)
        debug.append(getattr(driver, "debug", None))
        for key, val in (
            ("t", t), ("s", s_front), ("v", car.v), ("a", car.a), ("lat", lat), ("thr", c.throttle),
            ("brk", c.brake), ("steer", c.steer),
        ):  # fmt: skip
            rec[key][k] = val
        if leader is not None:
            rec["gap"][k] = leader.s_rear - s_front
            rec["lv"][k] = leader.v
            leader.step(t, dt_s)
        car.step(c, dt_s)
    return Trace(
        rec["t"], rec["s"], rec["v"], rec["a"], rec["gap"], rec["lat"], rec["thr"], rec["brk"], rec["steer"],
        rec["lv"], debug,
    )  # fmt: skip


def scripted(name: str = "daily_commuter", *, noise: bool = False, seed: int = 0, **overrides: float):
    """A ScriptedDriver with a named profile, optionally noise-free, with profile overrides."""
    import dataclasses

    from cosim.driver.profiles import profile_by_name
    from cosim.driver.scripted import ScriptedDriver

    prof = profile_by_name(name)
    if not noise:
        prof = prof.without_noise()
    if overrides:
        prof = dataclasses.replace(prof, **overrides)
    return ScriptedDriver(prof, np.random.default_rng(seed), MAX_STEER_RAD, WHEELBASE_M)


def time_gap(tr: Trace) -> np.ndarray:
    """[s] true bumper gap / own speed."""
    return tr.gap / np.maximum(tr.v, 0.1)

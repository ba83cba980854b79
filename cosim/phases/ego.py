"""The ego in the loop: what its driver perceives, how MuJoCo moves it, and its write-back into SUMO.

Hooks (ARCHITECTURE.md phase order): ``driver`` builds the Percept from the snapshot and SUMO's view of
the ego (leader, next light), and asks the driver; ``ego`` integrates the MuJoCo car for one SUMO step;
``writeback`` places the ego in SUMO (moveToXY + speed) for the next step.
"""

from __future__ import annotations

import bisect
import itertools
import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from cosim import frames
from cosim.driver import Controls, Percept, make_driver
from cosim.sumo_bridge.bridge import EGO_ID

PREVIEW_BEHIND_M = 5.0
PREVIEW_AHEAD_M = 160.0
TLS_NEAR_M = 150.0  # a light nearer than this is looked up every step, farther ones once a second
TLS_REFRESH_S = 1.0
CONFLICT_RADIUS_M = 200.0  # paper IV.B: "approaching vehicles within 200 m"
LANE_CHANGE_LENGTH_M = 30.0
PROJECT_BEHIND_M, PROJECT_AHEAD_M = 20.0, 50.0  # the ego moves < 5 m a step: the path is searched this near
# SUMO is given the ego's route this far ahead, renewed at half of it: enough for its next light (read
# within 300 m) and right of way. It matches every pose against each edge of the route it holds (the ones
# passed too, which it keeps), so the whole route ahead would cost up to 0.3 ms a step.
SUMO_ROUTE_AHEAD_M = 800.0
ON_PATH_M = 2.0  # the ego's centre this close to its path's centre line is certainly on the road [m]
BOX_SEGMENTS = 8  # vehicles_on_path pre-selects points by the bounding boxes of runs of this many segments
PATH_HALF_WIDTH_M = (
    1.0  # a vehicle whose rear is this close to the path's centre line (+ half its width) is ahead
)


@dataclass(frozen=True)
class StopLine:
    s_m: float  # arc position of the stop line on the route path [m]
    junction: str
    state: str  # SUMO link state of the route's connection ('M','m','s','w','=', ...)
    xy: tuple[float, float]  # junction centre


class RoutePath:
    """The route as one lane centre-line polyline with arc lengths, its stop lines and speed limits."""

    def __init__(self, net, route: list[str]):
        line = _Polyline()
        self.stop_lines: list[StopLine] = []
        limits: list[tuple[float, float]] = []  # (s where it starts, speed)
        entry_lane = None
        for i, eid in enumerate(route):
            edge = net.getEdge(eid)
            nxt = net.getEdge(route[i + 1]) if i + 1 < len(route) else None
            conns = [c for c in edge.getOutgoing().get(nxt, [])] if nxt else []
            conns = sorted(conns, key=lambda c: c.getFromLane().getIndex())
            lane = conns[0].getFromLane() if conns else (entry_lane or edge.getLane(0))
            shape = [tuple(p[:2]) for p in lane.getShape()]
            if (
                entry_lane is not None and entry_lane is not lane and line.pts
            ):  # change lanes early on the edge
                shape = _trim_start(shape, min(LANE_CHANGE_LENGTH_M, 0.5 * lane.getLength()))
            s0 = line.extend(shape)
            limits.append((s0, lane.getSpeed()))
            if conns:
                c = conns[0]
                node = edge.getToNode()
                self.stop_lines.append(
                    StopLine(line.length, node.getID(), c.getState(), tuple(node.getCoord()[:2]))
                )
                via = c.getViaLaneID()
                if via:
                    line.extend([tuple(p[:2]) for p in net.getLane(via).getShape()])
                entry_lane = c.getToLane()
        self.stop_s = [stop.s_m for stop in self.stop_lines]  # arc positions, non-decreasing
        xy = np.asarray(line.pts, dtype=np.float64)
        keep = np.concatenate([[True], np.hypot(*np.diff(xy, axis=0).T) > 1e-3])
        self.xy = xy[keep]
        self.s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(self.xy, axis=0).T))])
        self.length_m = float(self.s[-1])
        self.limit_s = np.asarray([a for a, _ in limits])
        self.limit_v = np.asarray([b for _, b in limits])
        self._last_s = 0.0  # arc position of the last projection

    def project(self, x: float, y: float) -> tuple[float, float]:
        """(arc position [m], signed lateral offset, left positive [m]) of a point; searches near the last hit.

        The search is bounded by arc length around the last hit: a route that comes back past the same
        place later must not capture the projection (the driver would steer for the later pass)."""
        lo = max(0, int(self.s.searchsorted(self._last_s - PROJECT_BEHIND_M)) - 1)
        hi = min(len(self.xy) - 1, max(lo + 1, int(self.s.searchsorted(self._last_s + PROJECT_AHEAD_M))))
        s, offset, at_window_end = self._nearest(lo, hi, x, y)
        if at_window_end and abs(offset) > 20.0 and hi - lo < len(self.xy) - 1:  # lost: search everywhere
            s, offset, _ = self._nearest(0, len(self.xy) - 1, x, y)
        self._last_s = s
        return s, offset

    @cached_property
    def _segments(self) -> tuple[np.ndarray, ...]:
        """Per segment (point i to i + 1): start x, start y, direction x, direction y, squared length (at
        least 1e-12) and length; constants of the route, computed once for every projection."""
        a, d = self.xy[:-1], np.diff(self.xy, axis=0)
        seg2 = np.maximum((d**2).sum(axis=1), 1e-12)
        return a[:, 0].copy(), a[:, 1].copy(), d[:, 0].copy(), d[:, 1].copy(), seg2, np.sqrt(seg2)

    def _nearest(self, lo: int, hi: int, x: float, y: float) -> tuple[float, float, bool]:
        """Projection onto the segments from point ``lo`` to point ``hi``; also whether it fell on the
        first or last of them."""
        ax, ay, dx, dy, seg2, seg_len = (v[lo:hi] for v in self._segments)
        t = np.minimum(np.maximum(((x - ax) * dx + (y - ay) * dy) / seg2, 0.0), 1.0)
        dist2 = (ax + t * dx - x) ** 2 + (ay + t * dy - y) ** 2
        k = int(dist2.argmin())
        cross = dx[k] * (y - ay[k]) - dy[k] * (x - ax[k])
        s = float(self.s[lo + k] + t[k] * seg_len[k])
        return s, math.copysign(math.sqrt(dist2[k]), cross), k in (0, len(dist2) - 1)

    def edge_index(self, s: float) -> int:
        """Index in the route of the edge at arc position ``s`` (the edge just left while in a junction)."""
        return max(0, int(self.limit_s.searchsorted(s, side="right")) - 1)

    def window(self, s_from: float, s_to: float) -> np.ndarray:
        """The path from arc position ``s_from`` to ``s_to``: both ends interpolated, the points between."""
        s_from, s_to = max(0.0, s_from), min(self.length_m, s_to)
        first = int(self.s.searchsorted(s_from, side="right"))  # the points strictly inside
        inner = self.xy[first : max(first, int(self.s.searchsorted(s_to, side="left")))]
        out = np.empty((len(inner) + 2, 2))
        out[1:-1] = inner
        out[0, 0], out[-1, 0] = np.interp([s_from, s_to], self.s, self.xy[:, 0]).tolist()
        out[0, 1], out[-1, 1] = np.interp([s_from, s_to], self.s, self.xy[:, 1]).tolist()
        return out

    @cached_property
    def _boxes(self) -> tuple[np.ndarray, ...]:
        """x min, y min, x max, y max of each run of BOX_SEGMENTS segments (run k: segments from k *
        BOX_SEGMENTS on), for a first cheap test of which points can be near the path."""
        x, y = self.xy[:, 0], self.xy[:, 1]
        starts = np.arange(0, len(self.xy) - 1, BOX_SEGMENTS)
        return (
            np.minimum.reduceat(np.minimum(x[:-1], x[1:]), starts),
            np.minimum.reduceat(np.minimum(y[:-1], y[1:]), starts),
            np.maximum.reduceat(np.maximum(x[:-1], x[1:]), starts),
            np.maximum.reduceat(np.maximum(y[:-1], y[1:]), starts),
        )

    def vehicles_on_path(self, xs: np.ndarray, ys: np.ndarray, s_from: float, s_to: float,
                         half_width_m: float) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """Arc positions of points lying on the path between ``s_from`` and ``s_to`` (within
        ``half_width_m`` of its centre line); returns (index into xs, arc position) of those points."""
        lo = max(0, int(self.s.searchsorted(s_from)) - 1)
        hi = min(len(self.s) - 1, int(self.s.searchsorted(s_to)) + 1)
        if hi <= lo or len(xs) == 0:
            return np.zeros(0, dtype=int), np.zeros(0)
        # Only points inside the bounding box of some run of segments (1 m spare for rounding) can lie on
        # the path: the others are dropped before the (points x segments) search, which treats every
        # point on its own.
        c0, c1 = lo // BOX_SEGMENTS, (hi - 1) // BOX_SEGMENTS + 1
        pad = half_width_m + 1.0
        x0, y0, x1, y1 = (b[c0:c1] for b in self._boxes)
        px, py = xs[:, None], ys[:, None]
        inside = (px >= x0 - pad) & (px <= x1 + pad) & (py >= y0 - pad) & (py <= y1 + pad)
        rows = np.flatnonzero(inside.any(axis=1))
        if rows.size == 0:
            return rows, np.zeros(0)
        ax, ay, dx, dy, seg2, seg_len = (v[lo:hi] for v in self._segments)
        px, py = xs[rows, None], ys[rows, None]
        t = np.minimum(np.maximum(((px - ax) * dx + (py - ay) * dy) / seg2, 0.0), 1.0)
        dist2 = (ax + t * dx - px) ** 2 + (ay + t * dy - py) ** 2
        k = dist2.argmin(axis=1)
        near = np.arange(len(rows))
        s_at = self.s[lo + k] + t[near, k] * seg_len[k]
        on = (dist2[near, k] <= half_width_m**2) & (s_at >= s_from) & (s_at <= s_to)
        return rows[on], s_at[on]

    def speed_limit(self, s: float) -> tuple[float, float | None, float]:
        """(limit here, next different limit or None, distance to it)."""
        i = max(0, int(self.limit_s.searchsorted(s, side="right")) - 1)
        j = self._next_limit_change[i]
        if j is None:
            return float(self.limit_v[i]), None, math.inf
        return float(self.limit_v[i]), float(self.limit_v[j]), float(self.limit_s[j] - s)

    @cached_property
    def _next_limit_change(self) -> list[int | None]:
        """For each limit, the index of the next one that differs from it by more than 0.1 m/s (or None)."""
        v = self.limit_v
        return [
            next((j for j in range(i + 1, len(v)) if abs(v[j] - v[i]) > 0.1), None) for i in range(len(v))
        ]


def _length(pts) -> float:
    return float(sum(math.dist(a, b) for a, b in itertools.pairwise(pts)))


class _Polyline:
    """Points appended shape by shape, with the running length (the route can have thousands)."""

    def __init__(self):
        self.pts: list[tuple[float, float]] = []
        self.length = 0.0

    def extend(self, shape: list) -> float:
        """Append ``shape``; returns the length before it (the limit of a lane starts at its joint)."""
        s0 = self.length
        gap = math.dist(self.pts[-1], shape[0]) if self.pts and shape else 0.0
        self.pts.extend(shape)
        self.length = s0 + gap + _length(shape)
        return s0


def _trim_start(shape: list, dist: float) -> list:
    acc = 0.0
    for i in range(1, len(shape)):
        seg = math.dist(shape[i - 1], shape[i])
        if acc + seg >= dist:
            f = (dist - acc) / seg if seg else 0.0
            p = (
                shape[i - 1][0] + f * (shape[i][0] - shape[i - 1][0]),
                shape[i - 1][1] + f * (shape[i][1] - shape[i - 1][1]),
            )
            return [p, *shape[i:]]
        acc += seg
    return shape[-1:]


_SIGN_OF_STATE = {"s": "stop", "w": "stop", "m": "give_way", "=": "give_way"}
_TLS = {"g": "g", "G": "g", "y": "y", "Y": "y", "u": "y", "r": "r", "R": "r", "s": "r"}


class EgoController:
    """Owns the MuJoCo car and the driver; plugs into the driver / ego / writeback phases."""

    def __init__(self, sim):
        from cosim.ego_mujoco import EgoCar

        self.sim = sim
        cfg = sim.config.ego
        self.car = EgoCar(cfg.car, timestep_s=sim.config.timing.physics_timestep_s)
        self.path = RoutePath(sim.net, sim.ego_route)
        p = cfg.car
        self.driver = make_driver(cfg.driver, np.random.default_rng([sim.config.seed, 11, cfg.driver_seed]),
                                  math.radians(p.max_steer_deg), p.wheelbase_m)  # fmt: skip
        self.origin: tuple[float, float] | None = None
        self.controls = Controls()
        self.started = False
        self.percept: Percept | None = None
        self._passed_signs: set[int] = set()
        self._last_tls = None
        self._tls_cache = None  # (SUMO's next light, arc position and step when read)
        self._on_sumo_route = True  # SUMO holds the planned route ahead of the ego ...
        self._sumo_route_end: int | None = None  # ... up to this route index (exclusive); None: all of it
        sim.add_hook("sumo", self.own_state)
        sim.add_hook("driver", self.drive)
        sim.add_hook("ego", self.integrate)
        sim.add_hook("writeback", self.write_back)

    def _start(self, w, slot: int) -> None:
        cx, cy, yaw = frames.sumo_to_mujoco(
            w.x_m[slot], w.y_m[slot], w.heading_deg[slot], self.car.params.length_m
        )
        self.origin = (float(cx), float(cy))
        self.car.reset(0.0, 0.0, float(yaw), float(w.speed_mps[slot]))
        self.started = True

    def own_state(self, sim) -> None:
        """The ego is MuJoCo's: its speed and acceleration in the snapshot come from the physics, not from
        SUMO's reconstruction of the moveToXY jumps."""
        slot = sim.world.slot_of.get(EGO_ID)
        if slot is not None and self.started:
            st = self.car.state()
            sim.world.speed_mps[slot] = st.speed_mps
            sim.world.accel_mps2[slot] = st.accel_mps2

    def drive(self, sim) -> None:
        w = sim.world
        slot = w.slot_of.get(EGO_ID)
        if slot is None:
            return
        if not self.started:
            self._start(w, slot)
        st = self.car.state()
        cx, cy = st.x_m + self.origin[0], st.y_m + self.origin[1]
        s_c, _ = self.path.project(cx, cy)
        s_front = s_c + 0.5 * self.car.params.length_m
        limit, next_limit, next_dist = self.path.speed_limit(s_front)
        self._on_sumo_route = self._keep_sumo_route(sim, slot, s_front)
        kw = self._leader_on_path(w, slot, cx, cy, s_front)
        tls = self._next_tls(sim, s_front)
        self._check_red_light(sim, tls)
        if tls and tls[2] < 300.0 and _TLS.get(tls[3]):
            kw.update(tls_state=_TLS[tls[3]], tls_dist_m=max(0.0, tls[2]), tls_id=f"{tls[0]}:{tls[1]}")
        lines = self.path.stop_lines
        # the lines more than 1 m behind are skipped (they are sorted by arc position)
        for i in range(bisect.bisect_left(self.path.stop_s, s_front - 1.0), len(lines)):
            line = lines[i]
            if i in self._passed_signs:
                continue
            if line.s_m - s_front > 300.0:
                break
            kind = _SIGN_OF_STATE.get(line.state)
            if kind:
                dist = max(0.0, line.s_m - s_front)
                kw.update(sign_kind=kind, sign_dist_m=dist, sign_id=line.junction,
                          junction_conflict=self._conflict(sim, dist))  # fmt: skip
                break
        adas = sim.outputs.get("adas_displays", {})
        self.percept = Percept(
            t_s=w.t_s, speed_mps=st.speed_mps, x_m=cx, y_m=cy, yaw_rad=st.yaw_rad, accel_mps2=st.accel_mps2,
            yaw_rate_rps=st.yaw_rate_rps, path_xy_m=self.path.window(s_c - PREVIEW_BEHIND_M, s_c + PREVIEW_AHEAD_M),
            speed_limit_mps=limit, next_speed_limit_mps=next_limit, next_speed_limit_dist_m=next_dist,
            route_end_dist_m=max(0.0, self.path.length_m - s_front), **kw, **adas,
        )  # fmt: skip
        self.controls = self.driver.act(self.percept, sim.step_s)

    def _keep_sumo_route(self, sim, slot: int, s_front: float) -> bool:
        """Whether SUMO holds the ego's planned route ahead of it; gives SUMO the next stretch of it when the
        held one runs short or SUMO has replaced it.

        Off its path the ego's pose may be mapped onto any lane (the driver may leave its route), and SUMO
        then replaces the route with the one edge it mapped to. Left so, the twin would carry that one-edge
        route for the rest of the run: SUMO's next light and right of way for the ego, and its foes' view
        of where the ego goes, would all end at the next junction."""
        route = sim.ego_route
        k = self.path.edge_index(s_front)
        end = self._sumo_route_end
        held = sim.bridge.ego_edges_left() == (len(route) if end is None else end) - k
        if (
            held
            and end is not None
            and (end == len(route) or self.path.limit_s[end] - s_front > 0.5 * SUMO_ROUTE_AHEAD_M)
        ):
            return True
        code = sim.world.edge_code[slot]
        if code < 0 or sim.world.edge_names[code] != route[k]:
            return held  # in a junction, or off the route: SUMO's route cannot start here
        end = self.path.edge_index(s_front + SUMO_ROUTE_AHEAD_M) + 1
        ev = sim.bridge.set_ego_route(route[k:end])
        if ev:
            sim.events.append(ev)
            return False
        self._sumo_route_end = end
        self._tls_cache = None
        return True

    def _next_tls(self, sim, s_front: float):
        """SUMO's next light on the ego's way (a costly lookup): every step when it is near, otherwise once
        a second, its distance carried forward with the ego's progress in between."""
        cached = self._tls_cache
        if cached is not None:
            tls, s_read, step = cached
            moved = s_front - s_read
            if tls and tls[2] - moved > TLS_NEAR_M and (sim.world.step - step) * sim.step_s < TLS_REFRESH_S:
                return (tls[0], tls[1], tls[2] - moved, tls[3])
        tls = sim.bridge.next_tls(EGO_ID)
        self._tls_cache = (tls, s_front, sim.world.step)
        return tls

    def _check_red_light(self, sim, tls) -> None:
        """The ego crossed a stop line at red: the light it was about to reach is gone while it was red."""
        last = self._last_tls
        self._last_tls = tls
        if last and last[2] < 5.0 and _TLS.get(last[3]) == "r" and (not tls or tls[:2] != last[:2]):
            from cosim.sumo_bridge.bridge import SumoEvent

            sim.events.append(SumoEvent("red_light_violation", EGO_ID, f"{last[0]} link {last[1]}", last[2]))

    def _leader_on_path(self, w, ego_slot: int, cx: float, cy: float, s_front: float) -> dict:
        """The nearest vehicle whose rear is on the ego's own path ahead: what a driver sees in front of
        them, whichever SUMO lane it is on (a car the ego is about to change lanes behind, one in a bend)."""
        live, _ = w.live()
        near = live[np.hypot(w.x_m[live] - cx, w.y_m[live] - cy) < PREVIEW_AHEAD_M + 10.0]
        idx = near[near != ego_slot]
        if idx.size == 0:
            return {}
        heading = np.radians(w.heading_deg[idx])  # World.heading_unit, for these vehicles only
        length = w.length_m[idx]
        rear_x = w.x_m[idx] - np.sin(heading) * length
        rear_y = w.y_m[idx] - np.cos(heading) * length
        half = PATH_HALF_WIDTH_M + 0.5 * (w.width_m[idx].sum() / idx.size)  # = .mean(), without its overhead
        rows, s_rear = self.path.vehicles_on_path(
            rear_x, rear_y, s_front - 2.0, s_front + PREVIEW_AHEAD_M, half
        )
        if rows.size == 0:
            return {}
        k = int(np.argmin(s_rear))
        slot = int(idx[rows[k]])
        return {"leader_present": True, "leader_id": w.ids[slot], "leader_gap_m": max(0.0, float(s_rear[k] - s_front)),
                "leader_speed_mps": float(w.speed_mps[slot])}  # fmt: skip

    @staticmethod
    def _conflict(sim, sign_dist_m: float) -> bool:
        """A vehicle the ego must yield to approaches the signed junction from within 200 m (paper IV.B)."""
        if sign_dist_m > 80.0:  # decided on the approach, not from afar
            return False
        return any(d < CONFLICT_RADIUS_M for _, d in sim.bridge.yield_foes(EGO_ID, sign_dist_m + 5.0))

    def integrate(self, sim) -> None:
        if not self.started:
            return
        c = self.controls
        self.car.step(c.throttle, c.brake, c.steer, sim.step_s)

    def write_back(self, sim) -> None:
        if not self.started:
            return
        st = self.car.state()
        x, y, angle = st.to_sumo(self.origin)
        p = self.percept
        slot = sim.world.slot_of.get(EGO_ID)
        # on its own path and mapped to a lane by SUMO: no need to search the network for the road
        suspicious = (
            p is None or abs(p.lateral_error_m) > ON_PATH_M or slot is None or sim.world.edge_code[slot] < 0
        )
        ev = sim.bridge.write_ego(x, y, angle, st.speed_mps, verify_on_road=suspicious,
                                  on_route=self._on_sumo_route and not suspicious)  # fmt: skip
        if ev:
            sim.events.append(ev)
        sim.outputs["ego_log"] = {
            "throttle": round(self.controls.throttle, 4), "brake": round(self.controls.brake, 4),
            "steer": round(self.controls.steer, 4), "physics_speed_mps": round(st.speed_mps, 4),
            "path_offset_m": round(p.lateral_error_m, 4) if p else None,
            "leader_id": p.leader_id if p else None,
            "leader_gap_m": round(p.leader_gap_m, 3) if p and p.leader_present else None,
            "tls_state": p.tls_state if p else None,
            "sign": p.sign_kind if p else None,
            "sign_dist_m": round(p.sign_dist_m, 2) if p and p.sign_kind else None,
            "junction_conflict": bool(p.junction_conflict) if p else False,
            "driver_mode": getattr(getattr(self.driver, "debug", None), "mode", ""),
        }  # fmt: skip

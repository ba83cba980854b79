"""Traffic kept around the ego (paper V.A), for scenarios built with ``demand.area: around_ego``.

The paper's generator creates SCVs at road nodes within +/-45 deg ahead of the user's vehicle and lets
them drive a routed path to a removal point. Here, once per second:

- the target is the density preset times the lane-km within ``radius_m`` of the ego;
- SCVs farther than ``radius_m`` (plus a margin, so a vehicle on the boundary does not flicker) are
  removed, and so are insertions SUMO could not place within ``PENDING_TIMEOUT_S``;
- the shortfall is generated at spots on spawn edges between ``spawn_min_m`` and ``radius_m`` ahead of
  the ego (within ``SECTOR_DEG`` of its heading; anywhere in that ring when no spot lies ahead), each on
  a route from the scenario's pool, only at spots whose surroundings are below the target density, and
  while the ego stands no faster than the target count per ``REFILL_S``. At the start the whole disc
  is filled at once, under the same rule: the target may not all be placed, since cars start only on
  the pool's origin streets while the target counts every lane-km of the disc.

Only what lies within radio range of the ego is simulated, so an experiment pays for a few hundred
vehicles instead of a town's worth while the ego sees and hears the same traffic density.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Protocol
from xml.etree import ElementTree as ET

import numpy as np
import shapely

from cosim.scenario.demand import POOL_ROUTE_PREFIX, DemandParams, is_spawn_edge
from cosim.world import EGO_ID, LEAD_ID, World

UPDATE_EVERY_S = 1.0
SECTOR_DEG = 45.0  # the paper's generation angle either side of the heading
REMOVE_MARGIN_M = 50.0
PENDING_TIMEOUT_S = 10.0
SAMPLE_STEP_M = 20.0  # lane-km is counted on points this far apart along each edge
SPAWN_END_CLEAR_M = 5.0  # spawn spots keep this far from both ends of their edge [m]
START_CLEAR_M = 60.0  # the first fill leaves this much room where the lead and the ego depart [m]
REFILL_S = 120.0  # while the ego stands, generation is limited to the target count per this time [s]
MOVING_MPS = 3.0  # below this the ego counts as standing: new SCVs may start anywhere in the ring
LOCAL_M = 100.0  # a spot whose surroundings already hold the target density gets no new vehicle [m]


class TrafficBridge(Protocol):
    """What the generator asks SUMO (``cosim.sumo_bridge.SumoBridge`` provides it)."""

    def remove_vehicle(self, vid: str) -> None: ...

    def add_scv(self, vid: str, route_id: str, depart_pos_m: float) -> None: ...


class TrafficAroundEgo:
    """Ports: its demand parameters, the drivable edges (the read-only network view's edges), the
    scenario's routes file (its pool routes), where the ego starts, its random stream (``cosim.seeds``
    "traffic"), the step length and SUMO's insertion and removal (``bridge``); ``step`` reads the snapshot.
    ``generated`` / ``removed`` count the SCVs it inserted and took out."""

    def __init__(self, params: DemandParams, drivable_edges: list, routes_file: str | Path, *,
                 start_xy: tuple[float, float], rng: np.random.Generator, step_s: float,
                 bridge: TrafficBridge):  # fmt: skip
        self.params = params
        self.bridge = bridge
        self.rng = rng
        self.step_s = step_s
        self.every = max(1, round(UPDATE_EVERY_S / step_s))
        self._lane_km_points(drivable_edges)
        self._pool(drivable_edges, routes_file)
        self.start_xy = (float(start_xy[0]), float(start_xy[1]))
        self.pending: dict[str, int] = {}  # inserted, not yet departed -> step of insertion
        self.next_id = 0
        self.filled = False
        self.credit = 0.0  # vehicles that may still be generated (see REFILL_S)
        self.generated = 0
        self.removed = 0

    # -- geometry, once --------------------------------------------------------------------------------
    def _lane_km_points(self, comp: list) -> None:
        """Points along every drivable edge weighted by the lane-km they stand for."""
        xs, ys, ws = [], [], []
        for e in comp:
            lanes = sum(1 for lane in e.getLanes() if lane.allows("passenger"))
            shape = np.asarray(e.getShape(), dtype=np.float64)[:, :2]
            seg = np.hypot(*np.diff(shape, axis=0).T)
            n = max(1, int(math.ceil(seg.sum() / SAMPLE_STEP_M)))
            cum = np.concatenate([[0.0], np.cumsum(seg)])
            at = (np.arange(n) + 0.5) * cum[-1] / n
            xs.append(np.interp(at, cum, shape[:, 0]))
            ys.append(np.interp(at, cum, shape[:, 1]))
            ws.append(np.full(n, lanes * cum[-1] / n / 1000.0))
        self.pt_x, self.pt_y, self.pt_w = (np.concatenate(a) for a in (xs, ys, ws))

    def _pool(self, comp: list, routes_file: str | Path) -> None:
        """The scenario's pool routes grouped by origin edge, and the spawn spots along those edges."""
        by_origin: dict[str, list[str]] = {}
        for el in ET.parse(routes_file).getroot().iter("route"):
            rid = el.get("id", "")
            if rid.startswith(POOL_ROUTE_PREFIX):
                by_origin.setdefault(el.get("edges").split()[0], []).append(rid)
        edges = {e.getID(): e for e in comp if is_spawn_edge(e)}
        self.origins = sorted(o for o in by_origin if o in edges)
        if not self.origins:
            raise ValueError("the scenario has no route pool: build it with demand.area: around_ego")
        self.origin_routes = [by_origin[o] for o in self.origins]
        # spawn spots every SAMPLE_STEP_M along the origin edges: a new SCV appears at a spot in the ring
        # ahead, not somewhere on an edge that may reach right up to the ego
        idx, pos, xs, ys = [], [], [], []
        for i, o in enumerate(self.origins):
            shape = np.asarray(edges[o].getShape(), dtype=np.float64)[:, :2]
            cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(shape, axis=0).T))])
            at = np.arange(
                SPAWN_END_CLEAR_M, max(cum[-1] - SPAWN_END_CLEAR_M, SPAWN_END_CLEAR_M + 1e-9), SAMPLE_STEP_M
            )
            idx.append(np.full(at.size, i))
            # SUMO's lane positions run along the lane's length, which may differ slightly from the shape's
            pos.append(at * edges[o].getLength() / cum[-1])
            xs.append(np.interp(at, cum, shape[:, 0]))
            ys.append(np.interp(at, cum, shape[:, 1]))
        self.spot_origin, self.spot_pos = np.concatenate(idx), np.concatenate(pos)
        self.spot_xy = np.column_stack([np.concatenate(xs), np.concatenate(ys)])
        # a spot stands for SAMPLE_STEP_M of every lane of its edge
        self.spot_weight = np.array([len(edges[self.origins[i]].getLanes()) for i in self.spot_origin], float)
        # vehicles the target density puts within LOCAL_M of each spot
        tree = shapely.STRtree(shapely.points(self.pt_x, self.pt_y))
        spot, pt = tree.query(shapely.points(self.spot_xy), predicate="dwithin", distance=LOCAL_M)
        lane_km = np.bincount(spot, weights=self.pt_w[pt], minlength=len(self.spot_xy))
        self.spot_capacity = self.params.per_lane_km * lane_km

    # -- per update ------------------------------------------------------------------------------------
    def _centre(self, w: World) -> tuple[float, float, float | None]:
        """The ego's position and heading [deg] (None while it stands or before it departs)."""
        slot = w.slot_of.get(EGO_ID)
        if slot is None:
            return (*self.start_xy, None)
        # a standing ego has no "ahead": feeding one sector would pour a stream of cars past it
        moving = w.speed_mps[slot] >= MOVING_MPS
        return float(w.x_m[slot]), float(w.y_m[slot]), float(w.heading_deg[slot]) if moving else None

    def target(self, x: float, y: float) -> int:
        near = np.hypot(self.pt_x - x, self.pt_y - y) <= self.params.radius_m
        return round(self.params.per_lane_km * float(self.pt_w[near].sum()))

    def step(self, w: World) -> None:
        """Once per UPDATE_EVERY_S (every step until the first fill): remove, then generate."""
        if w.step % self.every and self.filled:
            return
        x, y, heading = self._centre(w)
        for vid in [v for v in self.pending if v in w.slot_of]:
            del self.pending[vid]
        # out of range: removed (the paper's removal point), as are insertions that never found room
        scv = w.valid & ~w.is_ego
        lead = w.slot_of.get(LEAD_ID)
        if lead is not None:
            scv[lead] = False
        dist = np.hypot(w.x_m - x, w.y_m - y)
        gone = [w.ids[s] for s in np.flatnonzero(scv & (dist > self.params.radius_m + REMOVE_MARGIN_M))]
        stale = [v for v, s in self.pending.items() if (w.step - s) * self.step_s > PENDING_TIMEOUT_S]
        for vid in gone + stale:
            self.bridge.remove_vehicle(vid)
            self.pending.pop(vid, None)
        self.removed += len(gone) + len(stale)
        present = int((scv & (dist <= self.params.radius_m)).sum()) + len(self.pending)
        target = self.target(x, y)
        missing = target - present
        slow = self.filled and heading is None  # a standing ego: refill slowly, or the ring ahead of a
        if slow:  # queue pours a stream of fresh cars past it that the queue can never merge into
            self.credit = min(self.credit + target * self.every * self.step_s / REFILL_S, max(missing, 1))
            missing = min(missing, int(self.credit))
        if missing > 0:
            made = self._generate(w, x, y, heading, missing)
            self.credit -= made if slow else 0
        self.filled = True

    def _generate(self, w: World, x: float, y: float, heading: float | None, n: int) -> int:
        """Insert up to ``n`` SCVs; returns how many."""
        p = self.params
        dx, dy = self.spot_xy[:, 0] - x, self.spot_xy[:, 1] - y
        dist = np.hypot(dx, dy)
        if not self.filled:  # the first fill: the whole disc except where the lead and the ego start
            from_start = np.hypot(
                self.spot_xy[:, 0] - self.start_xy[0], self.spot_xy[:, 1] - self.start_xy[1]
            )
            ok = (dist <= p.radius_m) & (from_start > START_CLEAR_M)
        else:
            ring = (dist >= p.spawn_min_m) & (dist <= p.radius_m)
            ok = ring
            if heading is not None:
                bearing = np.degrees(np.arctan2(dx, dy))  # compass, like SUMO's angle
                off = np.abs((bearing - heading + 180.0) % 360.0 - 180.0)
                ahead = ring & (off <= SECTOR_DEG)
                ok = ahead if ahead.any() else ring
        idx = np.flatnonzero(ok)
        if idx.size == 0:
            return 0
        # distinct spots (two cars cannot start at one place) in a random order weighted by the lanes they
        # stand for, each taken only while its surroundings hold less than the target density, counting the
        # cars there and the ones placed before it. The first fill, spread over all spots at once, put 54
        # cars on the 70 spots of Krems' start: 38 per lane-km on the streets they stood on, five times the
        # target, all starting at once towards the same merges
        cars = w.valid & ~w.is_ego
        cand = self.spot_xy[idx]
        around = (np.hypot(cand[:, :1] - w.x_m[cars], cand[:, 1:] - w.y_m[cars]) <= LOCAL_M).sum(axis=1)
        weight = self.spot_weight[idx]
        order = self.rng.choice(idx.size, size=idx.size, replace=False, p=weight / weight.sum())
        made = 0
        for j in order:
            if made == n:
                break
            k = idx[j]
            if around[j] >= self.spot_capacity[k]:
                continue
            around[np.hypot(cand[:, 0] - cand[j, 0], cand[:, 1] - cand[j, 1]) <= LOCAL_M] += 1
            # from standstill, like a car pulling out (at speed, SUMO refuses about half of the insertions)
            routes = self.origin_routes[self.spot_origin[k]]
            rid = routes[int(self.rng.integers(len(routes)))]
            vid = f"scv{self.next_id}"
            self.next_id += 1
            self.bridge.add_scv(vid, rid, self.spot_pos[k])
            self.pending[vid] = w.step
            made += 1
        self.generated += made
        return made

    def close(self) -> None:
        pass

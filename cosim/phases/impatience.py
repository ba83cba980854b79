"""A car waiting at the head of its lane keeps growing impatient while it creeps (SUMO restarts the clock).

SUMO lets a driver waiting to enter a junction accept gaps that make priority traffic brake, the more the
longer it has waited: impatience = waiting time / ``--time-to-impatience``
(sumo.dlr.de/docs/Definition_of_Vehicles,_Vehicle_Types,_and_Routes.html#impatience;
MSBaseVehicle::getImpatience). Its waiting time, though, restarts whenever the car moves faster than
0.1 m/s. A gap in the priority stream that opens for one step and closes again makes the queue head roll
2 cm at 0.2 m/s, and it is patient again: at a merge into a steady stream it never gets impatient and
stands for minutes. Plain SUMO, Monaco (the drive benchmark's seed 2), Rue Suffren Raymond into Boulevard
Albert 1er (25193333): the head stood 240 s with its waiting time never above 29 s, and the participant
and the lead stood behind it for 180 s; with impatience 1 it merged within 3 s.

Here the wait is clocked as the time a car has stood or crept (below ``CREEP_MPS``) within ``HEAD_M`` of
the end of the same lane, and handed to SUMO as its impatience (libsumo ``setImpatience``: a per-vehicle
offset that SUMO clears when the car drives off). While the car stands, SUMO's clock runs with this one,
so the value is handed over again only after SUMO has cleared it (the car rolled faster than
``HALTING_MPS``). A car that is never held up keeps SUMO's own impatience; the participant's twin is
cosim's (``cosim.driver`` has its own gap acceptance).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from cosim.world import World

# a queue head stands at most jmStoplineGap (6 m at a light, cosim.scenario.behaviour) before the end of its
# lane; the car behind it at least one car length and a minimum gap (5 + 2.5 m) farther
HEAD_M = 7.5
# SUMO counts a car as waiting below this speed (SUMO_const_haltingSpeed); faster, it clears the value set
HALTING_MPS = 0.1
# a creep towards a gap that closes again stays below this
CREEP_MPS = 1.0
# shorter waits are left to SUMO's own clock: no call
MIN_WAIT_S = 5.0


class ImpatienceBridge(Protocol):
    def lane_end(self, edge_id: str, lane_index: int) -> tuple[float, float]: ...

    def set_impatience(self, vid: str, impatience: float) -> None: ...


class QueueHeadImpatience:
    """Ports: the bridge (lane ends, SUMO's per-vehicle impatience), SUMO's ``time_to_impatience_s`` and
    the step length. ``step`` reads the snapshot once per step; ``raised`` counts the impatience calls."""

    def __init__(self, bridge: ImpatienceBridge, *, time_to_impatience_s: float, step_s: float):
        self.bridge = bridge
        self.time_to_impatience_s = time_to_impatience_s
        self.step_s = step_s
        self.wait_s = np.zeros(0)  # per slot: the clock above
        self.code = np.zeros(0, np.int64)  # per slot: edge code * 64 + lane index it was clocked on
        self.synced = np.zeros(0, dtype=bool)  # per slot: SUMO holds the impatience handed over last
        self._end_x = np.zeros(0)  # per lane key: its end [m] (nan: not looked up yet)
        self._end_y = np.zeros(0)
        self.raised = 0

    def _lane_ends(self, w: World, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """End points of lanes by key (edge code * 64 + lane index); internal lanes end at inf."""
        need = int(keys.max()) + 1 if keys.size else 0
        if need > self._end_x.size:
            grow = max(need, 2 * self._end_x.size)
            self._end_x = np.concatenate([self._end_x, np.full(grow - self._end_x.size, np.nan)])
            self._end_y = np.concatenate([self._end_y, np.full(grow - self._end_y.size, np.nan)])
        for key in np.unique(keys[np.isnan(self._end_x[keys])]).tolist():
            edge = w.edge_names[key >> 6]
            # a car inside a junction has entered it: no yield line ahead on this lane
            end = (np.inf, np.inf) if edge.startswith(":") else self.bridge.lane_end(edge, key & 63)
            self._end_x[key], self._end_y[key] = end
        return self._end_x[keys], self._end_y[keys]

    def step(self, w: World) -> None:
        if self.wait_s.size < w.capacity:
            self.wait_s = np.concatenate([self.wait_s, np.zeros(w.capacity - self.wait_s.size)])
            self.code = np.concatenate([self.code, np.full(w.capacity - self.code.size, -1, np.int64)])
            self.synced = np.concatenate([self.synced, np.zeros(w.capacity - self.synced.size, dtype=bool)])
        slots, ids = w.live()
        on_lane = (w.edge_code[slots] >= 0) & (w.lane_index[slots] >= 0) & ~w.is_ego[slots]
        slow = on_lane & (w.speed_mps[slots] < CREEP_MPS)
        key = w.edge_code[slots].astype(np.int64) * 64 + w.lane_index[slots]
        head = np.zeros(slots.size, dtype=bool)
        if slow.any():
            ex, ey = self._lane_ends(w, key[slow])
            head[slow] = np.hypot(w.x_m[slots[slow]] - ex, w.y_m[slots[slow]] - ey) <= HEAD_M
        same = (key == self.code[slots]) & (w.depart_step[slots] != w.step)
        self.wait_s[slots] = np.where(head & same, self.wait_s[slots] + self.step_s, 0.0)
        self.code[slots] = np.where(head, key, -1)
        synced = self.synced[slots] & head & same & (w.speed_mps[slots] < HALTING_MPS)
        due = (self.wait_s[slots] >= MIN_WAIT_S) & ~synced
        for i in np.flatnonzero(due).tolist():
            self.bridge.set_impatience(
                ids[i], min(1.0, float(self.wait_s[slots[i]]) / self.time_to_impatience_s)
            )
            self.raised += 1
        self.synced[slots] = synced | due

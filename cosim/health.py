"""Every run's own health check: did the drive that the results stand on actually happen?

``DriveHealth`` records a few numbers per step (the ego's presence and speed, whom it follows, whether it
waits at a red light) and the traffic events, and reports for the whole run or any time window (an
experiment phase):

- ``ego_present_at_s``: when the ego first was in the simulation;
- ``ego_distance_m``, ``longest_standstill_s`` (and the longest outside red lights; creeping up a queue by
  less than ``CREEP_M`` does not end a standstill), ``stalls``: standstills longer than ``STALL_S`` (a light
  cycle) that were not at a red light, each also logged as an ``ego_stall`` event naming what the ego
  waited for;
- ``following_share``: share of the ego's states with a vehicle ahead on its path within ``FOLLOW_M``
  (moving or queued behind it); ``lead_leader_share``: share in which that vehicle is the lead car;
  ``cut_ins``: other vehicles that came between the lead and the ego; ``lead_paced_share``: share in which
  the ego set the lead's pace (``cosim.phases.lead``: it waited, or a speed cap for the ego held it below
  its lane's limit): there the gap the ego keeps is partly the lead's doing, not the driver's, so an analysis of
  time gaps can leave those samples out (timegap.csv's ``lead_paced``);
- ``collisions`` (any vehicle), ``ego_collisions``, ``teleports`` and ``teleport_share`` of the vehicles
  that departed;
- ``ego_off_road`` (times the ego left the road: ``cosim.sumo_bridge`` reports it when the ego's pose stays
  off every lane) and ``off_road_s``, the time it spent off the road: the car went where no traffic, sign
  or light reaches it, so the drive has stopped being the task.

``status`` is ``degraded`` with the reasons in ``problems`` whenever one of them misses what a drive the
results can stand on needs (the thresholds below), or when the ego reached the end of a route that could not
be extended (``ROUTE_END_M``); a run never reports ``ok`` with an empty drive.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from cosim.world import EGO_ID, LEAD_ID, SumoEvent, World

STALL_S = 90.0  # a standstill outside red lights longer than this (a light cycle) is a stall [s]
MAX_STANDSTILL_S = 120.0  # a longer standstill degrades the drive [s]
FOLLOW_M = 100.0  # a vehicle ahead on the ego's path within this gap is being followed [m]
STOPPED_MPS = 0.1  # [m/s]
# a standstill goes on while the ego creeps up less than this (a queue closing up, a car length): split at
# every creep, a 78-s wait on Helsinki (seed 1) was reported as 39.7 s [m]
CREEP_M = 5.0
MIN_MEAN_SPEED_MPS = 2.0  # a drive slower than this on average (7 km/h) did not really happen [m/s]
MIN_FOLLOWING_SHARE = 0.8  # with a lead car: the following task needs at least this share ...
MIN_LEAD_LEADER_SHARE = 0.9  # ... and the lead must be the direct leader at least this often
MAX_TELEPORT_SHARE = 0.01  # of the vehicles that departed
# longer off the road than this degrades the drive [s]: a corner cut short leaves every lane for a moment
# (Helsinki, seed 1: 0.3 s reported, the car 2.2 m off the lane's centre line when SUMO had it again), 20 m
# off the road at town speed is no longer the task
MAX_OFF_ROAD_S = 2.0
PRESENT_WITHIN_S = 1.0  # the ego is in the simulation this soon after its departure time [s]
MIN_WINDOW_S = 30.0  # shorter windows are not judged on distance and shares [s]
# a ``route_not_extended`` event with less than this left ahead of the ego: it reached the end of its route
# (a map whose every way on turns round, e.g. one junction cut out of a town) [m]
ROUTE_END_M = 10.0


def involves_ego(vehicle: str, detail: str) -> bool:
    """Whether an event is the ego's: it is the vehicle, or a collision's victim (detail "with ego ...")."""
    return vehicle == EGO_ID or detail.startswith(f"with {EGO_ID} ")


class DriveHealth:
    """Ports: the run's ego config (whether there is an ego, MuJoCo or SUMO, with a lead, when it departs)
    and the step length; ``step`` reads the snapshot, the step's events and the ego driver's percept, and
    returns the events it adds (an ``ego_stall``)."""

    def __init__(self, ego, step_s: float):
        """``ego``: a ``cosim.runconfig.EgoConfig`` (enabled, physics, lead_vehicle, depart_s are read)."""
        self.step_s = step_s
        # whom the ego follows is known from its driver's percept (a MuJoCo ego); a plain SUMO ego has none
        self.sees_leader = bool(ego.enabled and ego.physics == "mujoco")
        self.has_lead = self.sees_leader and bool(ego.lead_vehicle)
        self.ego_expected = bool(ego.enabled)
        self.depart_s = float(ego.depart_s)
        self.t: list[float] = []  # per step with the ego present
        self.speed: list[float] = []
        self.following: list[bool] = []
        self.lead_leader: list[bool] = []
        self.lead_paced: list[bool] = []
        self.at_red: list[bool] = []
        self.off_road: list[bool] = []
        self._is_off_road = False
        self.all_t: list[float] = []  # per step
        self.departed: list[int] = []
        self.events: list[tuple[float, str, bool]] = []  # (t, kind, whether the ego is involved)
        self.ego_present_at_s: float | None = None
        self._still_since: float | None = None
        self._crept_m = 0.0  # since the standstill began [m]
        self._stall_logged = False

    def step(self, w: World, events: list[SumoEvent], percept=None, driver_mode: Callable[[], str] = lambda: "",
             lead_is_leader: bool | None = None, lead_paced: bool = False) -> list[SumoEvent]:  # fmt: skip
        """Record the step. ``percept``: the ego driver's ``cosim.driver.Percept`` of the step (None without
        a MuJoCo ego); ``driver_mode``: what the driver is doing, asked only to name a stall;
        ``lead_is_leader``: whether the ego follows the lead (``LeadVehicle.lead_is_leader``: also with a car
        beside the lead as its nearest leader; default: the percept's leader is the lead); ``lead_paced``:
        whether the ego set the lead's pace this step (``LeadVehicle.paced``). Returns the
        events to add to the step's (an ``ego_stall`` once a standstill passes STALL_S)."""
        t = float(w.t_s)
        self.all_t.append(t)
        self.departed.append(int(np.count_nonzero(w.depart_step[w.valid] == w.step)))
        for ev in events:
            if ev.kind in ("collision", "teleport", "lead_cut_in"):
                self.events.append((t, ev.kind, involves_ego(ev.vehicle, ev.detail)))
            elif ev.kind == "route_not_extended" and ev.value is not None and ev.value < ROUTE_END_M:
                self.events.append((t, "route_end", True))
            elif ev.kind in ("ego_off_road", "ego_on_road"):
                self._is_off_road = ev.kind == "ego_off_road"
                if self._is_off_road:
                    self.events.append((t, ev.kind, True))
        ego = w.slot_of.get(EGO_ID)
        if ego is None:
            return []
        if self.ego_present_at_s is None:
            self.ego_present_at_s = t
        speed = float(w.speed_mps[ego])
        leader = percept.leader_id if percept is not None and percept.leader_present else None
        red = percept is not None and percept.tls_state == "r" and percept.tls_dist_m < 60.0
        self.t.append(t)
        self.speed.append(speed)
        self.following.append(leader is not None and percept.leader_gap_m <= FOLLOW_M)
        self.lead_leader.append(leader == LEAD_ID if lead_is_leader is None else lead_is_leader)
        self.lead_paced.append(bool(lead_paced))
        self.at_red.append(red)
        self.off_road.append(self._is_off_road)
        stall = self._watch_stall(t, speed, red, percept, driver_mode)
        if stall is None:
            return []
        self.events.append((t, stall.kind, True))  # counted here: the caller logs it after this step
        return [stall]

    def _watch_stall(self, t: float, speed: float, red: bool, percept, driver_mode) -> SumoEvent | None:
        """An ``ego_stall`` event, once, when a standstill outside red lights (creeps of less than CREEP_M
        each included, the rule of ``_standing``) passes STALL_S."""
        if self._still_since is not None:
            self._crept_m = self._crept_m + speed * self.step_s if speed >= STOPPED_MPS else 0.0
        if red or (speed >= STOPPED_MPS and (self._still_since is None or self._crept_m > CREEP_M)):
            self._still_since, self._stall_logged = None, False
            return None
        if self._still_since is None:
            self._still_since, self._crept_m = t, 0.0
        if not self._stall_logged and t - self._still_since > STALL_S:
            self._stall_logged = True
            what = [f"driver: {driver_mode() or '?'}"]
            if percept is not None and percept.leader_present:
                what.append(f"behind {percept.leader_id} at {percept.leader_gap_m:.0f} m")
            if percept is not None and percept.sign_kind:
                what.append(
                    f"{percept.sign_kind} line {percept.sign_dist_m:.0f} m ahead at {percept.sign_id}"
                )
            return SumoEvent("ego_stall", EGO_ID, f"standing {STALL_S:.0f} s: " + ", ".join(what),
                             t - self._still_since)  # fmt: skip
        return None

    def close(self) -> None:
        pass

    def report(self, t0: float = -math.inf, t1: float = math.inf) -> dict:
        """The health of the window [t0, t1] of the run (the whole run by default)."""
        t = np.asarray(self.t)
        m = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
        all_t = np.asarray(self.all_t)
        window_s = float(min(t1, all_t[-1]) - max(t0, all_t[0])) if all_t.size else 0.0
        step_s = self.step_s
        speed = np.asarray(self.speed)[m]
        still = _standing(speed, step_s)
        red = np.asarray(self.at_red, dtype=bool)[m]
        events = [(k, v) for te, k, v in self.events if t0 - 1e-9 <= te <= t1 + 1e-9]
        count = {
            k: sum(1 for kind, _ in events if kind == k)
            for k in ("collision", "teleport", "lead_cut_in", "ego_stall", "route_end", "ego_off_road")
        }
        departed = (
            int(np.asarray(self.departed)[(all_t >= t0 - 1e-9) & (all_t <= t1 + 1e-9)].sum())
            if all_t.size
            else 0
        )
        rep = {
            "window_s": round(max(window_s, 0.0), 1),
            "ego_present_at_s": self.ego_present_at_s,
            "ego_states": int(m.sum()),
            "ego_distance_m": round(float(speed.sum() * step_s), 1),
            "longest_standstill_s": round(_longest_run(still) * step_s, 1),
            "longest_standstill_not_red_s": round(_longest_run(still & ~red) * step_s, 1),
            "stalls": count["ego_stall"],
            "following_share": _share(np.asarray(self.following, dtype=bool)[m])
            if self.sees_leader
            else None,
            "lead_leader_share": _share(np.asarray(self.lead_leader, dtype=bool)[m])
            if self.has_lead
            else None,
            "lead_paced_share": _share(np.asarray(self.lead_paced, dtype=bool)[m]) if self.has_lead else None,
            "cut_ins": count["lead_cut_in"] if self.has_lead else None,
            "collisions": count["collision"],
            "ego_collisions": sum(1 for kind, with_ego in events if kind == "collision" and with_ego),
            "teleports": count["teleport"],
            "vehicles_departed": departed,
            "teleport_share": round(count["teleport"] / departed, 4) if departed else 0.0,
            "ego_off_road": count["ego_off_road"],
            "off_road_s": round(float(np.asarray(self.off_road, dtype=bool)[m].sum()) * step_s, 1),
        }
        rep["problems"] = self._problems(rep, t0, route_ended=count["route_end"] > 0)
        rep["status"] = "degraded" if rep["problems"] else "ok"
        return rep

    def _problems(self, rep: dict, t0: float, route_ended: bool = False) -> list[str]:
        if not self.ego_expected:
            return []
        out = []
        if rep["ego_states"] == 0:
            return ["the ego never drove in this window"]
        if t0 == -math.inf and rep["ego_present_at_s"] > self.depart_s + PRESENT_WITHIN_S + 1e-9:
            out.append(f"the ego entered the simulation only at {rep['ego_present_at_s']:.1f} s")
        judged = rep["window_s"] >= MIN_WINDOW_S
        if judged and rep["ego_distance_m"] < MIN_MEAN_SPEED_MPS * rep["window_s"]:
            out.append(f"the ego drove only {rep['ego_distance_m']:.0f} m in {rep['window_s']:.0f} s")
        if rep["longest_standstill_s"] > MAX_STANDSTILL_S:
            out.append(f"the ego stood still for {rep['longest_standstill_s']:.0f} s")
        if rep["stalls"]:
            out.append(f"{rep['stalls']} stall(s) outside red lights (see the ego_stall events)")
        if route_ended:
            out.append(
                "the ego reached the end of its route: the map has no way on from there without turning "
                "round (see the route_not_extended events)"
            )
        if judged and self.has_lead:
            if rep["following_share"] < MIN_FOLLOWING_SHARE:
                out.append(f"following only {rep['following_share']:.0%} of the time")
            if rep["lead_leader_share"] < MIN_LEAD_LEADER_SHARE:
                out.append(
                    f"the lead car was the ego's leader only {rep['lead_leader_share']:.0%} of the time"
                )
        if rep["off_road_s"] > MAX_OFF_ROAD_S:
            out.append(
                f"the ego was off the road for {rep['off_road_s']:.1f} s (see the ego_off_road events)"
            )
        if rep["ego_collisions"]:
            out.append(f"{rep['ego_collisions']} collision(s) of the ego")
        if rep["collisions"] - rep["ego_collisions"]:
            out.append(f"{rep['collisions'] - rep['ego_collisions']} collision(s) between other vehicles")
        if rep["teleport_share"] > MAX_TELEPORT_SHARE:
            out.append(f"{rep['teleports']} teleports ({rep['teleport_share']:.1%} of the vehicles)")
        return out


def _share(flags: np.ndarray) -> float:
    return round(float(flags.mean()), 3) if flags.size else 0.0


def _standing(speed: np.ndarray, step_s: float) -> np.ndarray:
    """Per step, whether the ego stands: below STOPPED_MPS, or creeping between two such steps by less than
    CREEP_M in all."""
    still = speed < STOPPED_MPS
    if not still.any():
        return still
    travelled = np.cumsum(speed * step_s)
    idx = np.flatnonzero(still)
    # a creep: the steps between two standing ones, shorter than CREEP_M
    creep = (np.diff(idx) > 1) & (travelled[idx[1:] - 1] - travelled[idx[:-1]] < CREEP_M)
    for a, b in zip(idx[:-1][creep].tolist(), idx[1:][creep].tolist(), strict=True):
        still[a:b] = True
    return still


def _longest_run(flags: np.ndarray) -> int:
    """Length of the longest run of ones."""
    if not flags.size or not flags.any():
        return 0
    padded = np.concatenate([[0], flags.astype(np.int8), [0]])
    edges = np.flatnonzero(np.diff(padded))
    return int((edges[1::2] - edges[0::2]).max())

"""The lead vehicle of the following task (paper VII.C): a SUMO car on the ego's route that drives like a
considerate human leader, so the participant spends the drive following it.

- It starts 20 m ahead of the ego at the first step (``Simulation._place_ego``) and keeps to the ego's
  route, which ``cosim.phases.route`` extends for both as they drive.
- It drives in the lanes the ego's route path takes (``RoutePath.lane_on``: on the pass of the edge nearest
  it), not in SUMO's own choice; it stops behind the last car of a queue in that lane rather than drive
  past the queue, and standing short of that lane beside a queue or the ego, it noses in.
- It drives a little below the limit (``sumo_bridge.LEAD_SPEED_FACTOR``) and never lets the gap along
  the route grow beyond an allowance: ``ALLOWANCE_S`` at the ego's recent top speed, at least
  ``ALLOWANCE_MIN_M`` and at most ``wait_beyond_m`` (all of ``wait_beyond_m`` while the ego stands). Its
  speed is capped at the ego's plus (allowance - gap) / ``CLOSE_TIME_S``, so beyond that gap it drives
  slower than the ego, and stands while the ego stands (after a red light that stopped only the ego,
  behind a slow participant).
- At a line where it must yield (stop or give-way sign, minor road, priority to the right, roundabout
  entry, a permissive green for a left turn) it waits until the ego has closed up behind it (or as far as
  a car between them lets it) and the
  priority traffic leaves a gap for both: the critical gap of the movement plus, when the ego is the car
  right behind it, the follow-up headway the ego needs behind it (HCM 2010,
  ``cosim.driver.gap_acceptance``; shrinking with the waiting time as the ego's own does). After
  ``YIELD_TOGETHER_S`` it takes a gap for itself alone and waits for the ego beyond the line.
- At a light it does not run away through a green that will stop the ego: approaching one, it reckons
  whether the ego, at its present speed (queued right behind it: speeding up when it goes, after the
  start-up lost time), reaches the stop line before the green ends (the programme says when; an actuated
  green at its longest while the pair holds it, see ``_light_cap``), again every step while it can still
  stop or stands at the line; if not, it stops at the line itself and both wait for the next green.
- A vehicle that comes between the lead and the ego (a cut-in) is logged as a ``lead_cut_in`` event. If it
  is still there ``DIVERT_AFTER_S`` later and its route would keep it on the lead's way, it turns off at the
  next junction it can (``cut_in_diverted``), as a car in front of a confederate lead would eventually do:
  otherwise one cut-in costs the rest of the drive its following task (seen on Krems: 400 s behind one
  SCV that shared the lead's route). Meanwhile the lead keeps that car within ``wait_beyond_m`` and the
  ego within ``BETWEEN_ALLOWANCE`` times that: waiting for the ego at ``wait_beyond_m`` would make it
  crawl and hold the car (and the ego) back, keeping only the car close would lose the ego.
- Cars still between them after ``LET_PAST_AFTER_S`` are let past: the lead pulls over at the roadside
  (``lead_let_past``; SUMO takes it off the lane, the cars behind drive by), waits there while the ego
  stands far back, and gets back in ahead of the ego once no car is left between them (``lead_rejoined``).
  Standing there it is the nearest car on the ego's way, so the participant stops behind it rather than
  pass it.

Its speed is only ever capped (SUMO's car following, right of way and lights still hold it back).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

import numpy as np

from cosim.driver import Percept
from cosim.driver.gap_acceptance import critical_gap_s, follow_up_s, movement_of
from cosim.driver.route import RoutePath
from cosim.phases.courtesy import COURTESY_AFTER_S, CourtesyYield
from cosim.phases.ego import PATH_HALF_WIDTH_M, FoesBridge, priority_gap_s, pull_away_arrival
from cosim.world import EGO_ID, LEAD_ID, SumoEvent, World

CLOSE_TIME_S = 5.0  # the lead closes a gap beyond its allowance (below) in about this time [s]
# while the ego drives, the gap the lead lets grow is this time at the ego's speed, at least ALLOWANCE_MIN_M
# and at most wait_beyond_m: a considerate leader judges the follower's lag in seconds, not metres. With
# wait_beyond_m alone, an ego creeping through a turn at 3 m/s had a 13-s gap behind the lead, and two cars
# from the other approach merged in between them (Munich, experiment P1 system_B: lead as leader 0.76).
# A standing ego still gets wait_beyond_m: a lead held within ALLOWANCE_MIN_M of an ego stopped at a red would
# stand in the junction beyond it [s]
ALLOWANCE_S = 3.0
ALLOWANCE_MIN_M = 15.0
# ... at the ego's recent top speed, which falls at most this fast: reckoned at its speed of the moment, the
# allowance would shrink whenever the ego brakes and the lead would brake with it, a loop that only ever
# slows the pair down [m/s^2]
ALLOWANCE_SPEED_DECAY_MPS2 = 0.5
YIELD_HOLD_M = 30.0  # the lead is held at a yield line this close to it ... [m]
EGO_CLOSE_M = 15.0  # ... until the ego is at most this far behind it [m]
LIGHT_DECIDE_M = 70.0  # the lead decides whether to stop for the ego's sake this far before a light [m]
LIGHT_MARGIN_S = 1.5  # an approaching ego must reach the stop line this long before the green ends [s]
# ... at its present speed; queued behind the lead (within EGO_CLOSE_M, or behind a car between them that
# is) it goes when the lead goes: speeding up (EGO_PULL_AWAY_MPS2), after the start-up lost time when it stands
# (HCM 2010, ch. 31: 2 s). Reckoned at its present speed, a standing ego never made any green, and the lead
# stood at its line through green after green (Munich seed 2: 96 s, a car between them)
START_UP_LOST_S = 2.0
# a queue discharging at a green goes on into the amber: HCM 2010 (ch. 31) extends the effective green by
# this much beyond the green. A queued ego is reckoned against it, not with LIGHT_MARGIN_S: asked to make the
# green with a margin, the lead standing at its line with the ego 1.7 m behind found a 6-s protected green
# too short, cycle after cycle (Munich, experiment P1: 120 s, a permissive green before it too busy) [s]
EXTENSION_OF_GREEN_S = 2.0
DETECTOR_CARS_MAX = 8  # the cars ahead of the lead reckoned with as they cross a light's detector
STOP_DECEL_MPS2 = 2.0  # the lead's planned deceleration when it stops for the ego at a green [m/s^2]
STOP_BEFORE_M = 1.0  # it stops this far before the stop line [m]
# SUMO link states where the lead must yield: stop, all-way stop, right-before-left, minor, and a permissive
# green (g: a left turn through oncoming traffic), where the lead going alone let the oncoming stream in
# between it and the ego
YIELD_STATES = "sw=mg"
LEAD_FOLLOWER_GAP_FACTOR = 1.2  # the follow-up headway the lead leaves the ego: a cautious participant's
# ... for this long at a yield line; then it takes a gap for itself alone and waits for the ego beyond the
# junction. Priority traffic is seen 200 m out (paper IV.B), and a busy stream seldom leaves a gap for two
# (HCM: t_c + t_f, 7.5-10 s): the lead stood 120 s at Monaco -166149542#0 with the participant behind it [s]
YIELD_TOGETHER_S = 30.0
LANE_HOLD_S = 1.0  # the lead is told the ego's lane every step, for this long [s]
# while cars are between the lead and the ego, the lead keeps the car behind it within wait_beyond_m and the
# ego within this many times wait_beyond_m: room for the cars between (waiting for the ego at wait_beyond_m
# made the lead crawl and hold the car between, and so the ego, back), yet the lead never leaves the ego
# behind for good (keeping only its own follower close, it lost the ego on Helsinki after two cut-ins)
BETWEEN_ALLOWANCE = 2.0
DIVERT_AFTER_S = 5.0  # a vehicle between the lead and the ego this long is sent off the lead's way [s]
DIVERT_AHEAD_M = 40.0  # ... at a junction at least this far ahead of it, room to pick its lane [m]
DIVERT_RETRY_S = 5.0  # when no junction offers a way out yet, ask again after this long [s]
# ... off the lead's way this far ahead of the lead: a long route comes back to its roads (15 km in the
# experiment), and kept off the whole of it, the car found no exit but beyond a light where it stood ahead of
# the ego for a whole red (Helsinki P1: straight on at 194850767#2 was the lead's way 2 km later) [m]
DIVERT_KEEP_OFF_M = 500.0
BETWEEN_MAX_CARS = 4  # the cars between the lead and the ego sent off, from the ego's leader on
# one vehicle is one cut-in: the ego's leader may flip between it and the lead while it stays between them
# (beside the ego in the lane the ego moves into, then ahead of it) [s]
CUT_IN_ONCE_S = 60.0
CROSSING_DEG = 45.0  # a vehicle heading this far off the ego's heading crosses its way [deg]
STAND_MPS = 0.5  # the lead stands below this speed [m/s]
# a speed cap within this of the lead's speed (or below it) is what holds the lead back [m/s]
PACED_MARGIN_MPS = 0.5
# the lead standing this long short of the lane its way goes on noses in when the car that would follow it
# there is the ego or drives slower than LANE_FORCE_FOLLOWER_MPS (a queue) [s]
LANE_FORCE_AFTER_S = 5.0
LANE_FORCE_FOLLOWER_MPS = 2.0
# a car between the lead and the ego this long: the lead pulls over at the roadside, lets the cars between
# pass and drives on ahead of the ego, as a confederate lead does. Sent off at the next junction
# (``_divert_cut_in``), a car stayed between them up to the junction its route allowed, 20 s on Monaco
# 166009792#2; and a red that stopped only the ego let a stream of cars from the cross street in between
# them (Krems 71582001: 75 s, lead as leader 0.25). After 6 s, each cut-in still cost the following task
# 10-15 s (Monaco baseline 0.77) [s]
LET_PAST_AFTER_S = 3.0
# ... while the ego stands (a red that stopped only the ego: the cars turning in ahead of it keep coming, and
# the farther the lead has moved on with them, the longer each takes to pass it) [s]
LET_PAST_STANDING_AFTER_S = 2.0
PULL_OVER_SPARE_M = 5.0  # the lead stands at the roadside this far beyond its braking distance [m]
PULL_OVER_CLEAR_M = 15.0  # ... and at least this far short of the lane's end: not at a junction's line [m]
# ... on a road of at most this many lanes: the participant stops behind the lead at the roadside beside up to
# three lanes (ego.LEAD_AT_ROADSIDE_M); beside Berlin's six-lane Grosser Stern it stood 19 m off the ego's lane,
# the ego drove past, and the lead stood 58 s
PULL_OVER_MAX_LANES = 3
# the lead gets back in only with the ego standing or this far back: a headway [s], a comfortable stop [m/s^2]
# and room to spare [m] (SUMO re-inserts it only where the car behind can stop)
REJOIN_HEADWAY_S = 1.0
REJOIN_EGO_DECEL_MPS2 = 3.0
REJOIN_SPARE_M = 5.0


def _closing_cap(v_behind: float, gap_m: float, limit_m: float) -> float:
    """Speed that lets a car ``gap_m`` behind at ``v_behind`` close to ``limit_m`` in about CLOSE_TIME_S."""
    return max(0.0, v_behind + (limit_m - gap_m) / CLOSE_TIME_S)


class LeadBridge(FoesBridge, Protocol):
    """What the lead asks SUMO and tells it (``cosim.sumo_bridge.SumoBridge`` provides it)."""

    def cap_speed(self, vid: str, speed_mps: float | None) -> None: ...

    def lane_speed_limit(self, vid: str) -> float: ...

    def next_tls(self, vid: str, within_m: float = math.inf) -> tuple[str, int, float, str] | None: ...

    def tls_green_left_s(self, tls_id: str, link_index: int) -> tuple[float, float]: ...

    def tls_max_gap_s(self, tls_id: str) -> float: ...

    def tls_detection(self, tls_id: str, link_index: int) -> tuple[float, float] | None: ...

    def next_link(self, vid: str, within_m: float = math.inf) -> tuple[str, float, str] | None: ...

    def follower(self, vid: str, distance_m: float) -> tuple[str, float] | None: ...

    def leader(self, vid: str, distance_m: float = 200.0) -> tuple[str, float] | None: ...

    def route_ahead(self, vid: str, within_m: float = math.inf) -> list[str]: ...

    def divert(self, vid: str, keep_off: set[str], min_ahead_m: float) -> str | None: ...

    def keep_lane(self, vid: str, lane_index: int, duration_s: float, force: bool = False) -> None: ...

    def follower_beside(self, vid: str, left: bool) -> tuple[str, float, float] | None: ...

    def pull_over(
        self, vid: str, ahead_m: float, clear_of_end_m: float, max_lanes: int | None = None
    ) -> str | None: ...

    def parked(self, vid: str) -> bool: ...

    def rejoin(self, vid: str) -> None: ...

    def leader_beside(self, vid: str, left: bool) -> tuple[str, float, float] | None: ...


class EgoOnPath(Protocol):
    """What the lead reads of the ego's phase (``cosim.phases.ego.EgoController``): where its front bumper
    is on its route path, that path, what its driver perceives (the ego's leader) and the priority car that
    lets the pair in at a yield line."""

    s_front_m: float | None
    path: RoutePath
    percept: Percept | None
    courtesy: CourtesyYield
    lead_at_roadside: bool  # the lead sets it while it stands at the roadside


class LeadVehicle:
    """Ports: how far behind it lets the ego fall (``wait_beyond_m``), SUMO's operations for the lead
    (``bridge``), the ego's phase (``ego``: None when SUMO drives the ego; the gap is then a straight line
    and no cut-in is seen) and ``emit`` for its events of the step; ``step`` reads the snapshot."""

    def __init__(self, wait_beyond_m: float, *, bridge: LeadBridge, ego: EgoOnPath | None,
                 emit: Callable[[SumoEvent], None]):  # fmt: skip
        self.bridge = bridge
        self.ego = ego
        self.emit = emit
        self.wait_beyond_m = wait_beyond_m
        self.waiting = False  # the lead slows down or stands for the ego
        # the lead's pace is the ego's doing: it waits, or a speed cap for the ego (or a car between them) is
        # what holds it back: the gap the ego keeps then is partly the lead's making
        self.paced = False
        self.cut_ins = 0
        self.lead_is_leader = False  # the ego follows the lead this step (see _log_cut_in)
        self.gap_m = math.nan  # along the route, the lead's rear to the ego's front [m]
        self._capped = False
        self._light: tuple | None = None  # (tls id, link index, state) of the light decided on ...
        self._stop_at_light = False  # ... and whether the lead stops there for the ego
        self._lead_s: float | None = None  # the lead's rear on the ego's route path [m]
        self._ego_leader: str | None = None
        self._yield_wait: tuple | None = None  # (last distance to the yield line, when the lead came near it)
        self._between: tuple[str, float] | None = None  # (vehicle between the lead and the ego, since when)
        self._between_since: dict[str, float] = {}  # every car between them (ego's leader on) -> since when
        self._divert_asked: dict[str, float] = {}  # vehicle -> when it was last asked to turn off
        self._cut_in_seen: dict[str, float] = {}  # vehicle -> when its cut-in was counted
        self._stuck_since: float | None = None  # the lead stands in another lane than its way's, since when
        self._forcing = False  # ... and noses into that lane
        self._lane: int | None = None  # the lane of its edge the lead's way takes (None: off the ego's route)
        self._pulled_over: str | None = None  # the lane beside which the lead stands to let cars pass
        self._rejoining = False  # ... and, told to rejoin, it has not driven off yet (maybe not on a lane)
        self.let_past = 0  # times the lead pulled over for cars between it and the ego
        self._ego_top_speed = (0.0, 0.0)  # (when, the ego's recent top speed [m/s]) for the allowance

    def step(self, w: World) -> None:
        self.lead_is_leader = False
        lead, ego = w.slot_of.get(LEAD_ID), w.slot_of.get(EGO_ID)
        if lead is None or ego is None:
            self.waiting = self.paced = False
            return
        self.gap_m = self._gap(w, lead, ego)
        if self._rejoining and float(w.speed_mps[lead]) > STAND_MPS:  # back on its lane, driving
            self._rejoining = False
            self.ego.lead_at_roadside = False
        if self._pulled_over is not None or self._rejoining:
            self._log_cut_in(w)
            if self._pulled_over is not None:
                self._rejoin_when_clear(w, lead, ego)
            return
        self._keep_to_the_egos_lane(w, lead)
        self._log_cut_in(w)
        self._divert_cut_in(w)
        if self._let_cars_past(w, lead):
            return
        v_ego = float(w.speed_mps[ego])
        caps = []
        ego_limit_m = self._allowance_m(w.t_s, v_ego)  # every step: it keeps the ego's top speed up to date
        if self._between is not None:  # the ego follows the car between them, the lead keeps that car close
            ego_limit_m = self.wait_beyond_m * BETWEEN_ALLOWANCE
        if self.wait_beyond_m > 0:
            caps.append(_closing_cap(v_ego, self.gap_m, ego_limit_m))
            between = self._car_between(w)
            if between is not None:
                caps.append(_closing_cap(*between, self.wait_beyond_m))
        holds = [
            c
            for c in (self._light_cap(w, v_ego), self._yield_cap(w), self._queue_cap(w, lead))
            if c is not None
        ]
        self.waiting = bool(holds) or (self.wait_beyond_m > 0 and self.gap_m > ego_limit_m)
        cap = min(caps + holds) if caps or holds else math.inf
        limit = self.bridge.lane_speed_limit(LEAD_ID)
        # held back: the cap is what sets its speed (not a car ahead of it, a bend or its lane's limit)
        self.paced = self.waiting or cap < min(limit, float(w.speed_mps[lead]) + PACED_MARGIN_MPS)
        if cap < limit:
            self.bridge.cap_speed(LEAD_ID, cap)
            self._capped = True
        elif self._capped:
            self.bridge.cap_speed(LEAD_ID, None)
            self._capped = False

    def _allowance_m(self, t: float, v_ego: float) -> float:
        """How far the ego may fall behind before the lead waits for it [m] (ALLOWANCE_S); updates the ego's
        recent top speed with its speed ``v_ego`` at time ``t``."""
        t_last, v_top = self._ego_top_speed
        v_top = max(v_ego, v_top - ALLOWANCE_SPEED_DECAY_MPS2 * (t - t_last))
        self._ego_top_speed = (t, v_top)
        if v_ego < STAND_MPS:
            return self.wait_beyond_m
        return min(self.wait_beyond_m, max(ALLOWANCE_MIN_M, v_top * ALLOWANCE_S))

    def _keep_to_the_egos_lane(self, w: World, lead: int) -> None:
        """Drive in the lane the ego's path takes on this edge: SUMO's own lane choice (its strategic look
        ahead, overtaking, keeping right) put the lead in another lane than the ego on multi-lane roads,
        where the ego passed it while it waited at a line (Helsinki, experiment: the lead was the ego's
        leader in 0-31 % of each phase)."""
        self._lane = None
        path = self.ego.path if self.ego is not None else None
        code = int(w.edge_code[lead])
        if path is None or code < 0:
            return
        near_s = self._lead_s if self._lead_s is not None else self.ego.s_front_m
        lane = path.lane_on(w.edge_names[code], near_s or 0.0)
        if lane is None:
            return
        self._lane = lane
        self.bridge.keep_lane(LEAD_ID, lane, LANE_HOLD_S, force=self._nose_in(w, lead, lane))

    def _queue_cap(self, w: World, lead: int) -> float | None:
        """Speed cap that stops the lead, in another lane than its way's, behind the last car of a queue in
        that lane (crawling below LANE_FORCE_FOLLOWER_MPS), so it moves over behind it, else None. SUMO's own
        lane change drove it on past the queue to nose in at its head, and the ego, on its path in that
        lane, stayed behind the queue (Helsinki seed 1: 30 s behind a car that came between)."""
        here, lane = int(w.lane_index[lead]), self._lane
        if lane is None or here == lane:
            return None
        ahead = self.bridge.leader_beside(LEAD_ID, left=lane > here)
        if ahead is None or ahead[1] < 0.0 or ahead[2] > LANE_FORCE_FOLLOWER_MPS:
            return None  # no queue there, or the lead is beside it already (it noses in: _nose_in)
        return math.sqrt(2.0 * STOP_DECEL_MPS2 * max(0.0, ahead[1] - STOP_BEFORE_M))

    def _nose_in(self, w: World, lead: int, lane: int) -> bool:
        """Whether the lead, standing short of the lane its way goes on, should move over into a gap SUMO
        finds too small: after LANE_FORCE_AFTER_S when the car that would follow it there crawls (a queue,
        which gives no gap by itself) or is the ego (its driver follows the lead). At the end of a lane
        SUMO's own lane change waited 135 s beside a queue that streamed at every green (Munich seed 1)."""
        here = int(w.lane_index[lead])
        if here == lane or float(w.speed_mps[lead]) > STAND_MPS:
            self._stuck_since, self._forcing = None, False
            return False
        t = w.t_s
        if self._stuck_since is None:
            self._stuck_since = t
        if t - self._stuck_since < LANE_FORCE_AFTER_S:
            return False
        behind = self.bridge.follower_beside(LEAD_ID, left=lane > here)
        if behind is not None and behind[0] != EGO_ID and behind[2] > LANE_FORCE_FOLLOWER_MPS:
            return False
        if not self._forcing:
            ahead_of = behind[0] if behind is not None else "nobody"
            self.emit(SumoEvent("lead_nosed_in", LEAD_ID, f"into lane {lane}, ahead of {ahead_of}"))
        self._forcing = True
        return True

    def _ego_queued_behind(self) -> bool:
        """Whether the ego is right behind the lead (within EGO_CLOSE_M), or as close as it can be with cars
        between them: the car behind the lead within EGO_CLOSE_M of it, the ego within EGO_CLOSE_M of the car
        ahead of it. Waiting for the ego to close up to EGO_CLOSE_M past a car between, the lead stood at a
        line for good (Munich seed 2: 60 s and on, the ego 17 m behind, scv239 between them)."""
        if self.gap_m <= EGO_CLOSE_M:
            return True
        percept = getattr(self.ego, "percept", None)
        if self._between is None or percept is None or not percept.leader_present:
            return False
        if percept.leader_gap_m > EGO_CLOSE_M:
            return False
        return self.bridge.follower(LEAD_ID, EGO_CLOSE_M) is not None

    def _ego_follows_next(self) -> bool:
        """Whether the ego, not another car, goes through a gap right after the lead: no car is behind the
        lead within EGO_CLOSE_M in its lane but the ego. A gap for two is for the participant; with other cars
        queued behind the lead they take the next gap whatever the lead waits for (Munich seed 2: the lead
        stood 25 s at a permissive green for a gap for two, three cars behind it in the turning lane, the
        ego in another lane unable to get in behind them until they moved)."""
        behind = self.bridge.follower(LEAD_ID, EGO_CLOSE_M)
        return behind is None or behind[0] == EGO_ID

    def _car_between(self, w: World) -> tuple[float, float] | None:
        """(speed [m/s], gap [m]) of the car right behind the lead while a car is between it and the ego."""
        if self._between is None:
            return None
        follower = self.bridge.follower(LEAD_ID, self.wait_beyond_m * 3)
        slot = w.slot_of.get(follower[0]) if follower else None
        return (float(w.speed_mps[slot]), follower[1]) if slot is not None else None

    def _gap(self, w: World, lead: int, ego: int) -> float:
        """Bumper gap along the ego's route path (straight line when the ego has no path)."""
        ux, uy = w.heading_unit()
        rear_x = float(w.x_m[lead] - ux[lead] * w.length_m[lead])
        rear_y = float(w.y_m[lead] - uy[lead] * w.length_m[lead])
        controller = self.ego
        if controller is None or controller.s_front_m is None:
            return math.hypot(rear_x - w.x_m[ego], rear_y - w.y_m[ego])
        near = self._lead_s if self._lead_s is not None else controller.s_front_m
        self._lead_s, _ = controller.path.project(rear_x, rear_y, near_s=near)
        return self._lead_s - controller.s_front_m

    def _light_cap(self, w: World, v_ego: float) -> float | None:
        """Speed cap that stops the lead at a green light the ego would not get through, else None."""
        tls = self.bridge.next_tls(LEAD_ID, within_m=LIGHT_DECIDE_M)
        if not tls:
            return None
        tls_id, link, dist, state = tls
        if not self.gap_m > 0:  # the ego is beside or ahead of the lead: nothing to wait for
            self._light = None
            return None
        green = state in "Gg"
        if (tls_id, link, green) != self._light:  # a new light, or this one turned green / ended its green
            self._light = (tls_id, link, green)
            self._stop_at_light = False
        v_lead = float(w.speed_mps[w.slot_of[LEAD_ID]])
        standing = v_lead < STAND_MPS  # at its line: SUMO stops it a hair closer than STOP_BEFORE_M
        can_stop = standing or dist - STOP_BEFORE_M >= v_lead * v_lead / (2.0 * STOP_DECEL_MPS2)
        if green and can_stop and (not self._stop_at_light or standing):
            # decided again every step while the lead can still stop: an ego that slows down (a curve, a
            # car pulling out) may no longer make the green the lead would still get through; and while it
            # stands at the line: the ego may have closed up behind it
            queued = self._ego_queued_behind()
            if queued:
                ego_s = self._ego_pulls_up_s(w, v_ego, dist)
            else:
                ego_s = self._ego_to_line_m(w, dist) / max(v_ego, 1.0)
            green_left = self._green_left_for_the_pair(w, tls_id, link, v_lead, v_ego, dist, queued)
            if queued:
                self._stop_at_light = ego_s > green_left + EXTENSION_OF_GREEN_S
            else:
                self._stop_at_light = ego_s + LIGHT_MARGIN_S > green_left
        if not self._stop_at_light or state in "rRuyY":  # red or amber: SUMO stops the lead by itself
            return None
        return math.sqrt(2.0 * STOP_DECEL_MPS2 * max(0.0, dist - STOP_BEFORE_M))

    def _green_left_for_the_pair(self, w: World, tls_id: str, link: int, v_lead: float, v_ego: float,
                                 lead_dist_m: float, queued: bool) -> float:  # fmt: skip
        """How long the green at the lead's light lasts for the pair [s]. A gap-actuated green ends between
        its earliest and its latest end (``tls_green_left_s``): SUMO extends it at each check while a vehicle
        has crossed a green lane's detector within max-gap (``tls_detection``). Reckoned to its earliest
        end, a green in extension ended "now" every step, and the lead stood at its line, a queue standing on
        the detector holding the green, until its longest ran out (Krems 71582001: 50 s, then a whole red).
        Reckoned to its latest whenever the ego followed within max-gap, the lead, standing at its line,
        went for an ego 16 m behind at 7 m/s still 6 m short of the detector: the green ended 0.6 s later,
        and the lead went through alone at the amber (Helsinki 25345665, drive benchmark P2 system_A).
        So the detector's last vehicle holds the green max-gap after it, the cars ahead of the lead, the lead
        and then the ego crossing it before that runs out hold it on (to its latest: the cars behind keep
        coming), and past the detector the ego holds nothing. A light without detectors of its own: the
        platoon rule (the ego queued behind the lead or following within max-gap)."""
        earliest, latest = self.bridge.tls_green_left_s(tls_id, link)
        max_gap = self.bridge.tls_max_gap_s(tls_id)
        detection = self.bridge.tls_detection(tls_id, link)
        if detection is None:
            return latest if queued or self.gap_m <= max_gap * max(v_ego, 1.0) else earliest
        detector_m, since_s = detection  # the detector's distance before the line, its last vehicle
        if since_s <= 0.0:  # a car on a detector (a queue standing on it) holds the green
            return latest
        held_s = max(earliest, max_gap - since_s)
        lead_to_detector_m = lead_dist_m - detector_m
        if lead_to_detector_m > 0.0:  # the cars ahead of it, then the lead, cross the detector
            crossing = [*self._cars_to_detector(w, lead_to_detector_m), (lead_to_detector_m, v_lead)]
            for to_detector_m, v in crossing:
                at_s = to_detector_m / max(v, 1.0)
                if at_s > held_s:
                    return held_s
                held_s = at_s + max_gap
        ego_to_detector_m = self._ego_to_line_m(w, lead_dist_m) - detector_m
        if ego_to_detector_m <= 0.0:
            return held_s
        if queued:
            ego_at_s = self._ego_pulls_up_s(w, v_ego, lead_dist_m, short_of_line_m=detector_m)
        else:
            ego_at_s = ego_to_detector_m / max(v_ego, 1.0)
        return latest if ego_at_s <= held_s else held_s

    def _cars_to_detector(self, w: World, lead_to_detector_m: float) -> list[tuple[float, float]]:
        """(front's distance to the detector [m], speed [m/s]) of the cars ahead of the lead in its lane that
        have yet to cross the detector ``lead_to_detector_m`` ahead of its front, nearest the detector first:
        a queue discharging ahead of the lead holds the green for it."""
        found: list[tuple[float, float]] = []
        vid, ahead_m = LEAD_ID, 0.0
        while len(found) < DETECTOR_CARS_MAX:
            nxt = self.bridge.leader(vid, lead_to_detector_m - ahead_m)
            slot = w.slot_of.get(nxt[0]) if nxt is not None else None
            if slot is None:
                break
            ahead_m += nxt[1] + float(w.length_m[slot])
            if ahead_m >= lead_to_detector_m:
                break
            found.append((lead_to_detector_m - ahead_m, float(w.speed_mps[slot])))
            vid = nxt[0]
        return found[::-1]

    def _ego_to_line_m(self, w: World, lead_dist_m: float) -> float:
        """The ego's front to the stop line ``lead_dist_m`` ahead of the lead [m]."""
        return lead_dist_m + float(w.length_m[w.slot_of[LEAD_ID]]) + max(self.gap_m, 0.0)

    def _ego_pulls_up_s(
        self, w: World, v_ego: float, lead_dist_m: float, short_of_line_m: float = 0.0
    ) -> float:
        """When the ego, queued behind the lead, reaches the stop line ``lead_dist_m`` ahead of the lead (or
        a point ``short_of_line_m`` before it) if it goes now [s]: speeding up (EGO_PULL_AWAY_MPS2), after the
        start-up lost time when it stands."""
        limit = max(v_ego, self.bridge.lane_speed_limit(LEAD_ID))
        lost = START_UP_LOST_S if v_ego < STAND_MPS else 0.0
        ego_m = self._ego_to_line_m(w, lead_dist_m) - short_of_line_m
        return lost + pull_away_arrival(v_ego, limit, ego_m)[0]

    def _yield_cap(self, w: World) -> float | None:
        """Speed cap that holds the lead at a yield line until the ego is right behind it and the gap in the
        priority traffic suits both, else None."""
        link = self.bridge.next_link(LEAD_ID, YIELD_HOLD_M)  # farther: no hold (and no costly question)
        if link is None:
            self._yield_wait = None
            return None
        state, dist, direction = link
        if state not in YIELD_STATES or dist > YIELD_HOLD_M:
            self._yield_wait = None
            return None
        t = w.t_s
        if self._yield_wait is None or dist > self._yield_wait[0] + 5.0:  # a new line (distances grew)
            self._yield_wait = (dist, t)
        waited = t - self._yield_wait[1]
        self._yield_wait = (dist, self._yield_wait[1])
        movement = movement_of(direction)
        needed = critical_gap_s(movement, waited)
        if waited < YIELD_TOGETHER_S and self._ego_follows_next():
            # the ego goes through the same gap, a follow-up headway behind the lead but not before it has
            # pulled up to the line: queued up to EGO_CLOSE_M back and standing, it needs the start-up lost
            # time and several seconds more than a follow-up headway to get there
            follow_up = follow_up_s(movement, LEAD_FOLLOWER_GAP_FACTOR)
            v_ego = float(w.speed_mps[w.slot_of[EGO_ID]])
            needed = max(needed, self._ego_pulls_up_s(w, v_ego, dist)) + follow_up
        courtesy = self.ego.courtesy if self.ego is not None else None
        if (
            courtesy is not None
            and waited >= COURTESY_AFTER_S
            and self._lead_s is not None
            and self._ego_queued_behind()
        ):
            line_s = self._lead_s + float(w.length_m[w.slot_of[LEAD_ID]]) + dist
            courtesy.ask(w, LEAD_ID, dist, line_s, "its line", self.ego.path.junction_end(line_s))
        stopping_for = (courtesy.car,) if courtesy is not None else ()
        if (
            self._ego_queued_behind()
            and priority_gap_s(w, self.bridge, LEAD_ID, dist, stopping_for) >= needed
        ):
            return None
        return math.sqrt(2.0 * STOP_DECEL_MPS2 * max(0.0, dist - STOP_BEFORE_M))

    def _log_cut_in(self, w: World) -> None:
        """Another vehicle has become the ego's leader while the lead is still ahead of it: in place of the
        lead, or of a car that had come between them (a second car in ahead of the first is a cut-in too:
        counting only changes from the lead, four cars taking a lane-change gap counted as one). A car
        crossing the ego's way is not between them: the ego sees it ahead for a moment as it passes (Krems
        seed 2, at a stop sign: 16 crossing cars, each the ego's leader for 0.4 s). Nor is a car beside the
        lead (``_beside_lead``): the ego still follows the lead, and ``lead_is_leader`` says so."""
        t = w.t_s
        percept = getattr(self.ego, "percept", None)
        leader = percept.leader_id if percept is not None and percept.leader_present else None
        if leader not in (None, LEAD_ID) and self.gap_m > 0 and self._beside_lead(w, leader):
            leader = LEAD_ID
        self.lead_is_leader = leader == LEAD_ID
        if leader is not None and self._crosses(w, leader):
            return
        was_between = self._ego_leader == LEAD_ID or self._ego_leader in self._cut_in_seen
        if (was_between and leader not in (None, LEAD_ID, self._ego_leader) and self.gap_m > 0
                and t - self._cut_in_seen.get(leader, -math.inf) > CUT_IN_ONCE_S):  # fmt: skip
            self._cut_in_seen[leader] = t
            self.cut_ins += 1
            self.emit(SumoEvent("lead_cut_in", leader, f"between the lead and the ego ({self.gap_m:.0f} m)",
                                self.gap_m))  # fmt: skip
        self._ego_leader = leader

    def _beside_lead(self, w: World, vid: str) -> bool:
        """Whether ``vid``, the ego's leader, is beside the lead rather than between it and the ego: its
        front is past the lead's rear along the ego's path, so no car fits between the lead and the ego
        (Helsinki seed 1, at a red: scv7 stood in the next lane beside the lead, its rear angled into the
        ego's path; it was the ego's leader at 0-1 m for 20 s and counted as two cut-ins)."""
        slot = w.slot_of.get(vid)
        controller = self.ego
        if slot is None or controller is None or controller.s_front_m is None or self._lead_s is None:
            return False
        front_s, _ = controller.path.project(float(w.x_m[slot]), float(w.y_m[slot]), near_s=self._lead_s)
        return front_s > self._lead_s

    def _crosses(self, w: World, vid: str) -> bool:
        """Whether ``vid`` heads across the ego's way: more than CROSSING_DEG off the direction of the ego's
        path where it is (off the ego's heading without a path). Against the ego's own heading, the cars
        beyond a turn the ego waited at all crossed its way: a red light's 75 s of cars turning in between the
        ego and the lead beyond the junction went unseen (Krems 71582001)."""
        slot, ego = w.slot_of.get(vid), w.slot_of.get(EGO_ID)
        if slot is None or ego is None:
            return False
        heading = float(w.heading_deg[slot])
        controller = self.ego
        if controller is not None and controller.s_front_m is not None:
            s, _ = controller.path.project(
                float(w.x_m[slot]), float(w.y_m[slot]), near_s=controller.s_front_m
            )
            dx, dy = controller.path.direction_at(np.array([s]))
            way = math.degrees(math.atan2(float(dx[0]), float(dy[0])))  # SUMO angle: 0 = +y, 90 = +x
        else:
            way = float(w.heading_deg[ego])
        off = abs((heading - way + 180.0) % 360.0 - 180.0)
        return off > CROSSING_DEG

    def _divert_cut_in(self, w: World) -> None:
        """Send the vehicles that have stayed between the lead and the ego off the lead's way: the ego's
        leader and the cars ahead of it up to the lead (Monaco -166149542#0: three priority cars came in
        while the participant waited at the line; sending only the nearest off, the other two stayed
        between them for the rest of the phase)."""
        leader = self._ego_leader
        if leader in (None, LEAD_ID) or not self.gap_m > 0:
            self._between = None
            self._between_since.clear()
            return
        t = w.t_s
        if self._between is None or self._between[0] != leader:
            self._between = (leader, t)
        chain, room = [leader], self.gap_m  # cars ahead of the ego's leader, no farther than the lead
        while len(chain) < BETWEEN_MAX_CARS and room > 0:
            ahead = self.bridge.leader(chain[-1], room)
            if ahead is None or ahead[0] in (LEAD_ID, EGO_ID) or ahead[0] in chain:
                break
            chain.append(ahead[0])
            room -= ahead[1]
        self._between_since = {vid: self._between_since.get(vid, t) for vid in chain}
        keep_off = None
        for vid, since in self._between_since.items():
            asked = self._divert_asked.get(vid)
            if t - since < DIVERT_AFTER_S or (asked is not None and t - asked < DIVERT_RETRY_S):
                continue
            self._divert_asked[vid] = t
            if keep_off is None:
                keep_off = set(self.bridge.route_ahead(LEAD_ID, DIVERT_KEEP_OFF_M))
            exit_edge = self.bridge.divert(vid, keep_off, DIVERT_AHEAD_M)
            if exit_edge is not None:
                self._divert_asked[vid] = math.inf  # done: it leaves the lead's way at its next junction
                self.emit(
                    SumoEvent("cut_in_diverted", vid, f"turns off onto {exit_edge}, off the lead's way")
                )

    def _let_cars_past(self, w: World, lead: int) -> bool:
        """Pull over at the roadside when cars have been between the lead and the ego for LET_PAST_AFTER_S
        (LET_PAST_STANDING_AFTER_S while the ego stands); True when the lead now heads for its roadside stop."""
        ego_stands = float(w.speed_mps[w.slot_of[EGO_ID]]) < STAND_MPS
        after = LET_PAST_STANDING_AFTER_S if ego_stands else LET_PAST_AFTER_S
        if not self._between_since or w.t_s - min(self._between_since.values()) < after:
            return False
        v = float(w.speed_mps[lead])
        lane = self.bridge.pull_over(LEAD_ID, v * v / (2.0 * STOP_DECEL_MPS2) + PULL_OVER_SPARE_M,
                                     PULL_OVER_CLEAR_M, PULL_OVER_MAX_LANES)  # fmt: skip
        if lane is None:  # in a junction, near the end of its lane, on a wide road: again on the next step
            return False
        if self._capped:  # a lingering cap would hold it short of its stop
            self.bridge.cap_speed(LEAD_ID, None)
            self._capped = False
        self._pulled_over = lane
        if self.ego is not None:
            self.ego.lead_at_roadside = True
        self.let_past += 1
        self.waiting = self.paced = True
        cars = len(self._between_since)
        self.emit(SumoEvent("lead_let_past", LEAD_ID, f"pulls over beside {lane} for {cars} car(s) between it "
                            f"and the ego ({self.gap_m:.0f} m)", self.gap_m))  # fmt: skip
        return True

    def _rejoin_when_clear(self, w: World, lead: int, ego: int) -> None:
        """Back onto its lane once the lead stands at the roadside, no car is left between it and the ego,
        and the ego comes on far enough back for SUMO to let the lead in ahead of it (``_room_to_rejoin``).
        Until the lead drives again the participant treats it as the car ahead
        (``EgoController.lead_at_roadside``) and stops short of it: told to rejoin with the ego 6 m behind at
        7 m/s, SUMO kept the lead off the road until the ego had passed it (Monaco, experiment P1)."""
        if not self.bridge.parked(LEAD_ID):
            return  # still on its way to the roadside stop
        if not self._room_to_rejoin(float(w.speed_mps[ego])) or self._cars_between(w, lead, ego):
            return
        self.bridge.rejoin(LEAD_ID)
        self._pulled_over, self._rejoining = None, True
        self._between, self._ego_leader = None, LEAD_ID
        self._between_since.clear()
        self.emit(SumoEvent("lead_rejoined", LEAD_ID, f"ahead of the ego ({self.gap_m:.0f} m)", self.gap_m))

    def _room_to_rejoin(self, v_ego: float) -> bool:
        """Whether the ego comes on (drives, or stands within ``wait_beyond_m``) with room for the lead to
        get back in ahead of it: standing, or far enough back to stop behind a car pulling out
        (REJOIN_HEADWAY_S, then braking at REJOIN_EGO_DECEL_MPS2, REJOIN_SPARE_M to spare)."""
        if v_ego <= STAND_MPS:
            return self.gap_m <= self.wait_beyond_m
        room = v_ego * REJOIN_HEADWAY_S + v_ego * v_ego / (2.0 * REJOIN_EGO_DECEL_MPS2) + REJOIN_SPARE_M
        return self.gap_m >= room

    def _cars_between(self, w: World, lead: int, ego: int) -> bool:
        """Whether a vehicle heading the ego's way is on its path between its front and a little beyond the
        lead's front (room for the lead to get back in)."""
        controller = self.ego
        if controller is None or controller.s_front_m is None or self._lead_s is None:
            return False
        live, _ = w.live()
        others = live[(live != lead) & (live != ego)]
        if others.size == 0:
            return False
        ux, uy = w.heading_unit()
        rear_x = w.x_m[others] - ux[others] * w.length_m[others]
        rear_y = w.y_m[others] - uy[others] * w.length_m[others]
        lead_front = self._lead_s + float(w.length_m[lead])
        half = PATH_HALF_WIDTH_M + 0.5 * float(w.width_m[others].mean())  # the ego's leader on its path
        rows, s = controller.path.vehicles_on_path(
            rear_x, rear_y, controller.s_front_m - 1.0, lead_front + PULL_OVER_SPARE_M, half
        )
        if rows.size == 0:
            return False
        dx, dy = controller.path.direction_at(s)
        along = ux[others[rows]] * dx + uy[others[rows]] * dy
        on_road = controller.path.on_its_roads(w.edges_of(others[rows]), s)
        return bool(((along > math.cos(math.radians(CROSSING_DEG))) & on_road).any())

    def close(self) -> None:
        pass

"""The lead vehicle of the following task as a phase with fake ports: a World, a fake bridge answering
what the lead asks SUMO, a fake ego phase (its path and percept) and a list for its events (no SUMO, no
MuJoCo)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from cosim.driver.route import RoutePath
from cosim.phases.courtesy import COURTESY_AFTER_S, CourtesyYield
from cosim.phases.ego import priority_gap_s
from cosim.phases.lead import (
    DIVERT_KEEP_OFF_M,
    LANE_FORCE_AFTER_S,
    LET_PAST_AFTER_S,
    STOP_DECEL_MPS2,
    YIELD_TOGETHER_S,
    LeadVehicle,
)
from cosim.world import EGO_ID, LEAD_ID, World


class FakeBridge:
    """What the lead asks SUMO, answered from fields the test sets."""

    def __init__(self):
        self.caps: list[float | None] = []
        self.other_caps: dict[str, float | None] = {}
        self.tls = None  # (id, link, dist, state)
        self.green_left_s = math.inf
        self.detection: tuple[float, float] | None = None  # (detector before the line [m], since a car [s])
        self.link = None  # (state, dist, direction)
        self.foes: list[tuple[str, float, float, float, bool]] = []
        self.diverted: list[tuple[str, set]] = []
        self.exit_edge: str | None = "side"
        self.lanes: list[int] = []  # lanes the lead was told to keep to ...
        self.forced: list[bool] = []  # ... and whether into a gap SUMO finds too small
        self.beside: tuple[str, float, float] | None = None  # the car behind the lead in the lane it moves to
        self.ahead_beside: tuple[str, float, float] | None = None  # ... and the car ahead of it there
        self.behind: tuple[str, float] | None = None  # the car behind the lead in its lane (id, gap)
        self.leaders: dict[str, tuple[str, float]] = {}  # vehicle -> (its leader, gap) in its lane
        self.roadside: str | None = None  # the lane the lead pulls over beside (None: no room there)
        self.pulled_over: list[float] = []  # how far ahead it was asked to stand at the roadside
        self.standing_beside = False  # it stands at the roadside
        self.rejoined = 0

    def cap_speed(self, vid, speed):
        if vid != LEAD_ID:  # a priority car letting the pair in (CourtesyYield)
            self.other_caps[vid] = speed
            return
        self.caps.append(speed)

    def lane_speed_limit(self, vid):
        return 13.0

    def next_tls(self, vid, within_m=float("inf")):
        return self.tls if self.tls and self.tls[2] <= within_m else None

    def tls_green_left_s(self, tls_id, link):
        g = self.green_left_s  # a fixed programme's end, or an actuated green's (earliest, latest)
        return g if isinstance(g, tuple) else (g, g)

    def tls_max_gap_s(self, tls_id):
        return 3.0

    def tls_detection(self, tls_id, link):
        return self.detection

    def next_link(self, vid, within_m=math.inf):
        return self.link if self.link is None or self.link[1] <= within_m else None

    def yield_foes(self, vid, lookahead_m):
        return self.foes

    def junction_ahead(self, vid):  # every priority car far from its line: a spot short of the conflict
        return (1000.0, 10.0)

    def route_ahead(self, vid, within_m=math.inf):
        assert vid == LEAD_ID
        self.route_within_m = within_m
        return ["a", "b", "c"]

    def follower(self, vid, distance_m):
        return self.behind if self.behind is not None and self.behind[1] <= distance_m else None

    def leader(self, vid, distance_m=200.0):
        return self.leaders.get(vid)

    def divert(self, vid, keep_off, min_ahead_m):
        self.diverted.append((vid, keep_off))
        return self.exit_edge

    def keep_lane(self, vid, lane_index, duration_s, force=False):
        assert vid == LEAD_ID
        self.lanes.append(lane_index)
        self.forced.append(force)

    def follower_beside(self, vid, left):
        return self.beside

    def leader_beside(self, vid, left):
        return self.ahead_beside

    def pull_over(self, vid, ahead_m, clear_of_end_m, max_lanes=None):
        assert vid == LEAD_ID
        if self.roadside is not None:
            self.pulled_over.append(ahead_m)
        return self.roadside

    def parked(self, vid):
        return self.standing_beside

    def rejoin(self, vid):
        self.rejoined += 1
        self.standing_beside = False


class FakeEgo:
    """What the lead reads of the ego's phase: its front bumper on its route path (None: no path, the gap is
    a straight line), the path and its driver's percept (the ego's leader)."""

    def __init__(self, courtesy, s_front_m=None, path=None):
        self.s_front_m, self.path = s_front_m, path
        self.percept = None
        self.courtesy = courtesy
        self.lead_at_roadside = False

    def sees(self, leader):
        self.percept = SimpleNamespace(leader_present=leader is not None, leader_id=leader)


def fake_sim(gap_m: float, ego_speed: float):
    """Lead and ego on a straight road heading north (SUMO angle 0), the lead's rear ``gap_m`` ahead; the
    ports the lead is given (``bridge``, ``ego``, ``events`` for ``emit``) beside the snapshot."""
    w = World(capacity=8)
    for vid, y in ((EGO_ID, 0.0), (LEAD_ID, gap_m + 5.0)):
        s = w.add(vid, is_ego=vid == EGO_ID)
        w.x_m[s], w.y_m[s], w.heading_deg[s], w.length_m[s] = 0.0, y, 0.0, 5.0
    w.speed_mps[w.slot_of[EGO_ID]] = ego_speed
    bridge, events = FakeBridge(), []
    ego = FakeEgo(CourtesyYield(bridge=bridge, step_s=0.1, emit=events.append))
    return SimpleNamespace(world=w, bridge=bridge, ego=ego, events=events)


def _lead(sim, wait_beyond_m: float = 40.0) -> LeadVehicle:
    return LeadVehicle(wait_beyond_m, bridge=sim.bridge, ego=sim.ego, emit=sim.events.append)


def test_the_lead_waits_for_a_lagging_ego_and_stands_while_it_stands():
    sim = fake_sim(gap_m=80.0, ego_speed=6.0)
    lead = _lead(sim)
    lead.step(sim.world)
    assert lead.gap_m == pytest.approx(80.0)
    assert sim.bridge.caps[-1] < 6.0 and lead.waiting  # slower than the ego: it closes up
    sim.world.speed_mps[sim.world.slot_of[EGO_ID]] = 0.0
    lead.step(sim.world)
    assert sim.bridge.caps[-1] == 0.0  # the ego stands (a red light behind the lead): so does the lead


def test_the_lead_lets_a_slow_ego_fall_behind_by_seconds_not_metres():
    """Munich P1 system_B: the ego crept through a turn at 3 m/s, the lead drew 22-24 m ahead (within the
    40-m allowance, 8 s at that speed) and two cars merged in between them. The allowance is ALLOWANCE_S
    at the ego's speed (at least ALLOWANCE_MIN_M): 15 m at 3 m/s, so 25 m ahead the lead slows down."""
    sim = fake_sim(gap_m=25.0, ego_speed=3.0)
    lead = _lead(sim)
    lead.step(sim.world)
    assert lead.waiting and sim.bridge.caps[-1] == pytest.approx(3.0 + (15.0 - 25.0) / 5.0)
    # at 10 m/s the same 25 m is 2.5 s: within the 30-m allowance, the lead drives on
    sim = fake_sim(gap_m=25.0, ego_speed=10.0)
    lead = _lead(sim)
    lead.step(sim.world)
    assert not lead.waiting and sim.bridge.caps[-1] == pytest.approx(10.0 + (30.0 - 25.0) / 5.0)


def test_the_lead_is_paced_by_the_ego_while_a_cap_for_it_holds_the_lead_back():
    """Not waiting yet, the lead held at 11 m/s on a 13-m/s lane so that an ego at 10 m/s 25 m behind keeps
    up: the ego sets its pace (the gap the ego keeps is partly the lead's doing, timegap.csv's lead_paced).
    Behind a slower car (8 m/s) the same cap holds nothing back; an ego that keeps up by itself leaves the
    lead free."""
    for lead_speed, paced in ((11.0, True), (8.0, False)):
        sim = fake_sim(gap_m=25.0, ego_speed=10.0)
        sim.world.speed_mps[sim.world.slot_of[LEAD_ID]] = lead_speed
        lead = _lead(sim)
        lead.step(sim.world)
        assert not lead.waiting and lead.paced == paced and sim.bridge.caps[-1] == pytest.approx(11.0)
    sim = fake_sim(gap_m=20.0, ego_speed=12.0)  # cap 12 + (36 - 20) / 5 = 15.2 m/s, above the lane's 13
    sim.world.speed_mps[sim.world.slot_of[LEAD_ID]] = 13.0
    lead = _lead(sim)
    lead.step(sim.world)
    assert not lead.waiting and not lead.paced
    sim = fake_sim(gap_m=80.0, ego_speed=6.0)  # waiting is pacing
    lead = _lead(sim)
    lead.step(sim.world)
    assert lead.waiting and lead.paced


def test_an_ego_braking_behind_the_lead_does_not_make_it_brake_too():
    """Reckoned at the ego's speed of the moment, the allowance would shrink as the ego brakes, the lead
    brake for it, and so on down. It follows the ego's recent top speed, which falls at
    ALLOWANCE_SPEED_DECAY_MPS2."""
    sim = fake_sim(gap_m=25.0, ego_speed=10.0)
    lead = _lead(sim)
    lead.step(sim.world)
    sim.world.t_s, sim.world.speed_mps[sim.world.slot_of[EGO_ID]] = 1.0, 4.0
    lead.step(sim.world)
    allowance = 3.0 * (10.0 - 0.5 * 1.0)  # 28.5 m, not the 15 m of an ego at 4 m/s
    assert not lead.waiting and sim.bridge.caps[-1] == pytest.approx(4.0 + (allowance - 25.0) / 5.0)
    sim.world.t_s = 30.0  # 29 s later at 4 m/s it is a slow ego
    lead.step(sim.world)
    assert lead.waiting and sim.bridge.caps[-1] == pytest.approx(4.0 + (15.0 - 25.0) / 5.0)


def test_a_standing_ego_lets_the_lead_clear_the_junction_ahead():
    """Held within ALLOWANCE_MIN_M of an ego stopped at a red, the lead would stand in the junction beyond
    the line: while the ego stands, the lead may draw ahead to wait_beyond_m."""
    sim = fake_sim(gap_m=25.0, ego_speed=0.0)
    lead = _lead(sim)
    lead.step(sim.world)
    assert not lead.waiting and sim.bridge.caps[-1] == pytest.approx((40.0 - 25.0) / 5.0)


def test_the_lead_drives_freely_when_the_ego_follows_closely():
    sim = fake_sim(gap_m=15.0, ego_speed=10.0)
    lead = _lead(sim)
    lead.step(sim.world)
    assert not lead.waiting and sim.bridge.caps == []  # its cap is above the limit: nothing to tell SUMO


def test_the_lead_stops_at_a_green_the_ego_would_miss():
    sim = fake_sim(gap_m=20.0, ego_speed=8.0)
    sim.bridge.tls, sim.bridge.green_left_s = ("J", 0, 40.0, "G"), 3.0  # the ego needs (40+5+20)/8 ~ 8 s
    lead = _lead(sim)
    lead.step(sim.world)
    assert lead.waiting and sim.bridge.caps[-1] <= math.sqrt(2 * 2.0 * 39.0)  # braking for the line
    sim2 = fake_sim(gap_m=20.0, ego_speed=8.0)
    sim2.bridge.tls, sim2.bridge.green_left_s = ("J", 0, 40.0, "G"), 30.0  # long green: both get through
    lead2 = _lead(sim2)
    lead2.step(sim2.world)
    assert not lead2.waiting


def test_the_lead_decides_again_when_the_ego_slows_down_before_a_green():
    sim = fake_sim(gap_m=20.0, ego_speed=8.0)
    sim.world.speed_mps[sim.world.slot_of[LEAD_ID]] = 8.0
    sim.bridge.tls, sim.bridge.green_left_s = ("J", 0, 60.0, "G"), 15.0  # (60+5+20)/8 + 1.5 ~ 12 s: go
    lead = _lead(sim)
    lead.step(sim.world)
    assert not lead.waiting
    # the ego brakes for a curve: (55+5+20)/4 + 1.5 = 21.5 s > the 14 s of green left; the lead (8 m/s,
    # 16 m to stop at 2 m/s^2) can still stop 55 m before the line, so it does
    sim.world.speed_mps[sim.world.slot_of[EGO_ID]] = 4.0
    sim.bridge.tls, sim.bridge.green_left_s = ("J", 0, 55.0, "G"), 14.0
    lead.step(sim.world)
    assert lead.waiting
    # past the point where it could stop comfortably it goes on whatever the ego does
    sim2 = fake_sim(gap_m=20.0, ego_speed=8.0)
    sim2.world.speed_mps[sim2.world.slot_of[LEAD_ID]] = 12.0
    sim2.bridge.tls, sim2.bridge.green_left_s = ("J", 0, 60.0, "G"), 15.0
    lead2 = _lead(sim2)
    lead2.step(sim2.world)
    sim2.world.speed_mps[sim2.world.slot_of[EGO_ID]] = 2.0
    sim2.bridge.tls, sim2.bridge.green_left_s = ("J", 0, 30.0, "G"), 12.0  # 36 m needed to stop from 12 m/s
    lead2.step(sim2.world)
    assert not lead2.waiting


def test_the_lead_standing_at_a_green_goes_when_the_ego_queued_behind_it_makes_the_green_from_rest():
    """Munich seed 2: the lead stood at its line for the ego, a car between them; reckoned at the ego's
    present speed (0) no green was ever long enough, and the lead stood through green after green. Queued
    behind the lead, the ego goes when it goes: start-up lost time 2 s + 15 m speeding up at 1.5 m/s^2
    (4.5 s) = 6.5 s, within the green and the 2 s a discharging queue goes on into the amber (HCM: Munich P1,
    a 6-s protected green, the ego 1.7 m behind: asked for a 1.5-s margin instead, the lead stood at its
    line cycle after cycle)."""
    for green_left_s, waits in ((12.0, False), (6.0, False), (4.0, True)):
        assert _standing_at_a_green_with_the_ego_queued(green_left_s).waiting == waits, green_left_s


def _standing_at_a_green_with_the_ego_queued(green_left_s, detection=None, gap_m=10.0, ego_speed=0.0):
    """The lead after one step standing at its line, where it had stopped for the ego, at a green with
    ``green_left_s`` to go (or (earliest, latest)), the ego queued 10 m behind it (or ``gap_m`` at
    ``ego_speed``); ``detection``: the light's detector (distance before the line, time since a car)."""
    sim = fake_sim(gap_m=gap_m, ego_speed=ego_speed)
    sim.world.speed_mps[sim.world.slot_of[LEAD_ID]] = 0.0
    # standing where SUMO stopped it for its cap: a hair short of STOP_BEFORE_M (Krems: 0.994 m)
    sim.bridge.tls, sim.bridge.green_left_s = ("J", 0, 0.994, "G"), green_left_s
    sim.bridge.detection = detection
    lead = _lead(sim)
    lead._stop_at_light, lead._light = True, ("J", 0, True)
    lead.step(sim.world)
    return lead


def test_at_an_actuated_green_the_lead_counts_on_its_extension_only_while_its_platoon_holds_it():
    """Krems 71582001 (experiment P3): a gap-actuated green in extension ends at SUMO's next check, 0-4 s
    ahead, every step, until its maxDur. Reckoned to that earliest end, the lead stood at the line with the
    ego queued behind it (a car between them) through the 50-s green, its own queue holding it green. Queued
    behind the lead, or following within the light's max-gap (3 s), the ego keeps it green to its longest;
    farther back it may not."""
    extension = (0.5, 26.0)  # (earliest, latest) end of the green [s]
    assert not _standing_at_a_green_with_the_ego_queued(extension).waiting  # the ego queued behind it: go
    for gap_m, waits in ((20.0, False), (60.0, True)):  # 2.5 s behind at 8 m/s: within max-gap; 7.5 s: not
        sim = fake_sim(gap_m=gap_m, ego_speed=8.0)
        sim.world.speed_mps[sim.world.slot_of[LEAD_ID]] = 8.0
        sim.bridge.tls, sim.bridge.green_left_s = ("J", 0, 40.0, "G"), extension
        lead = _lead(sim)
        lead.step(sim.world)
        assert lead.waiting == waits, gap_m


def test_at_an_actuated_green_the_lead_reckons_with_the_detector_that_extends_it():
    """Helsinki 25345665 (drive benchmark, P2 system_A): the lead stood at its line for the ego, 16.8 m
    behind at 7 m/s, and went, counting on the ego to hold the actuated green; the ego was still 6 m short of
    the detector (16.7 m before the line) when the green gapped out 0.6 s later (its last car 3 s before),
    and the lead went through alone at the amber. A car on a detector, or the ego crossing it before the
    green's next check, holds it; a queue standing between the detector and the line does not."""
    extension, detector_m = (0.6, 43.6), 16.66

    def waits(since_s, gap_m=16.8, ego_speed=7.0):
        detection = (detector_m, since_s)
        return _standing_at_a_green_with_the_ego_queued(extension, detection, gap_m, ego_speed).waiting

    assert waits(since_s=3.03)  # the ego reaches the detector in 0.9 s, after the green's check at 0.6 s
    assert not waits(since_s=0.5)  # the last car holds it 2.5 s: the ego crosses the detector in time
    assert not waits(since_s=0.0)  # a car on a detector holds it
    # queued 10 m behind the lead and standing, both between the detector and the line: nothing holds it ...
    assert waits(since_s=5.0, gap_m=10.0, ego_speed=0.0)
    # ... unless the queue behind them stands on the detector (Krems 71582001: 50 s of green)
    assert not waits(since_s=0.0, gap_m=10.0, ego_speed=0.0)


def test_approaching_an_actuated_green_the_lead_counts_on_the_cars_ahead_of_it_to_hold_it():
    """A car ahead of the lead crosses the detector first and holds the green for the lead, and the lead
    for the ego; alone, the lead reaches the detector after the green's next check and stops for the ego."""
    outcomes = []
    for car_ahead in (False, True):
        sim = fake_sim(gap_m=15.0, ego_speed=8.0)
        sim.world.speed_mps[sim.world.slot_of[LEAD_ID]] = 8.0
        # 40 m before the line; the detector 16.66 m before it, its last car 1 s ago: held 2 s; the lead
        # reaches it in 2.9 s, the ego (40 + 5 + 15 - 16.66 m at 8 m/s) in 5.4 s
        sim.bridge.tls, sim.bridge.green_left_s = ("J", 0, 40.0, "G"), (0.5, 30.0)
        sim.bridge.detection = (16.66, 1.0)
        if car_ahead:  # 10 m ahead of the lead at 8 m/s: 8.3 m short of the detector, there in 1 s
            s = sim.world.add("ahead")
            sim.world.length_m[s], sim.world.speed_mps[s] = 5.0, 8.0
            sim.bridge.leaders[LEAD_ID] = ("ahead", 10.0)
        lead = _lead(sim)
        lead.step(sim.world)
        outcomes.append(lead.waiting)
    assert outcomes == [True, False]


def test_the_lead_holds_at_a_give_way_line_until_the_ego_is_close_and_the_gap_suits_both():
    sim = fake_sim(gap_m=25.0, ego_speed=5.0)
    sim.bridge.link = ("m", 10.0, "s")
    lead = _lead(sim)
    lead.step(sim.world)
    assert lead.waiting  # the ego is 25 m behind: wait for it at the line
    sim3 = fake_sim(gap_m=8.0, ego_speed=3.0)
    sim3.bridge.link = ("m", 10.0, "s")
    sim3.world.add("foe")
    sim3.world.speed_mps[sim3.world.slot_of["foe"]] = 10.0
    sim3.bridge.foes = [("foe", 10.0, 80.0, 0.0, False)]  # arrives in 8 s: < t_c + t_f = 6.5 + 4.8 s
    lead3 = _lead(sim3)
    lead3.step(sim3.world)
    assert lead3.waiting
    sim3.bridge.foes = [("foe", 10.0, 150.0, 0.0, False)]  # 15 s: room for both
    lead3.step(sim3.world)
    assert not lead3.waiting


def test_the_gap_for_two_counts_from_when_the_ego_has_pulled_up_to_the_line():
    """The lead goes with the ego queued behind it only when the gap lasts until the ego has pulled up to
    the line (start-up lost time, speeding up) and a follow-up headway more: counted from the lead alone,
    an ego standing 14 m back would reach the line with less than its follow-up headway left."""
    waiting = {}
    for ego_gap_m in (2.0, 14.0):
        sim = fake_sim(gap_m=ego_gap_m, ego_speed=0.0)
        sim.bridge.link = ("m", 1.0, "r")  # a right turn from a minor road: t_c 6.2 s, t_f 3.3 s
        sim.world.add("foe")
        sim.world.speed_mps[sim.world.slot_of["foe"]] = 10.0
        sim.bridge.foes = [("foe", 1.0, 105.0, 0.0, False)]  # arrives in 10.5 s: > t_c + 1.2 t_f (10.2 s)
        lead = _lead(sim)
        lead.step(sim.world)
        waiting[ego_gap_m] = lead.waiting
    # 2 m behind, the ego is at the line in 5.3 s (2 s start-up, 8 m at 1.5 m/s^2), within t_c: the lead
    # goes; 14 m behind, in 7.2 s, and 7.2 + 4.0 s is more than the gap: the lead waits
    assert waiting == {2.0: False, 14.0: True}


def test_after_waiting_with_the_ego_behind_it_a_priority_car_lets_the_pair_in():
    """Monaco -166149542#0 (experiment, every participant): a stream that never left a gap for two held
    the lead and the ego 30 s; the lead then went alone and the priority cars turning in came between. After
    COURTESY_AFTER_S a priority car that can stop comfortably stops short of the junction (CourtesyYield);
    standing, it is no foe, and the lead goes with the ego behind it."""
    sim = fake_sim(gap_m=2.0, ego_speed=0.0)
    sim.ego.path, sim.ego.s_front_m = RoutePath([(0.0, -20.0), (0.0, 200.0)]), 20.0  # the ego's front at y=0
    sim.bridge.link = ("m", 1.0, "s")
    c = sim.world.add("c")
    sim.world.speed_mps[c] = 12.0
    sim.bridge.foes = [("c", 1.0, 60.0, 0.0, False)]  # arrives in 5 s: < t_c (6.5 s)
    lead = _lead(sim)
    lead.step(sim.world)
    assert lead.waiting and sim.events == []
    sim.world.t_s = COURTESY_AFTER_S
    lead.step(sim.world)
    assert [(e.kind, e.vehicle) for e in sim.events] == [("courtesy_yield", "c")] and lead.waiting
    assert sim.bridge.other_caps["c"] is not None  # it is brought to a stop short of the junction ...
    sim.world.speed_mps[c] = 0.0  # ... and stands
    sim.world.t_s += 0.1
    lead.step(sim.world)
    assert not lead.waiting


def test_after_waiting_at_a_give_way_line_the_lead_takes_a_gap_for_itself_alone():
    """Monaco -166149542#0 (experiment P1): with priority traffic seen 200 m out, a busy stream never left a
    gap for two (t_c + 1.2 t_f) and the lead stood 120 s at the line with the participant behind it. After
    YIELD_TOGETHER_S it needs only its own critical gap; the participant follows with its own."""
    sim = fake_sim(gap_m=2.0, ego_speed=0.0)
    sim.bridge.link = ("m", 1.0, "s")
    sim.world.add("foe")
    sim.world.speed_mps[sim.world.slot_of["foe"]] = 10.0
    sim.bridge.foes = [("foe", 1.0, 70.0, 0.0, False)]  # arrives in 7 s: > t_c (6.5 s), < t_c + 1.2 t_f
    lead = _lead(sim)
    lead.step(sim.world)
    assert lead.waiting
    sim.world.t_s = YIELD_TOGETHER_S - 1.0
    lead.step(sim.world)
    assert lead.waiting  # together, the gap must be t_c + 1.2 t_f however long they waited
    sim.world.t_s = YIELD_TOGETHER_S + 0.1
    lead.step(sim.world)
    assert not lead.waiting


def test_the_lead_at_a_give_way_line_goes_when_the_ego_is_queued_behind_a_car_between_them():
    """Munich seed 2: a car came between the lead and the ego; the lead waited at a line for the ego to close
    up to 15 m, which the car between did not let it do, and all three stood there for good. The ego 3 m
    behind that car, itself 2 m behind the lead: the ego is as close as it can be, and the lead goes."""
    sim = fake_sim(gap_m=17.0, ego_speed=0.0)
    sim.bridge.link = ("=", 1.0, "s")
    lead = _lead(sim)
    sim.ego.sees(LEAD_ID)
    lead.step(sim.world)
    assert lead.waiting  # the ego 17 m behind, nobody between: it waits for the ego to close up
    sim.world.t_s = 0.1
    sim.ego.sees("scv239")
    sim.ego.percept.leader_gap_m = 3.0
    sim.bridge.behind = ("scv239", 2.0)
    lead.step(sim.world)
    assert not lead.waiting


def test_a_cut_in_is_logged_when_another_vehicle_becomes_the_ego_leader():
    sim = fake_sim(gap_m=20.0, ego_speed=8.0)
    lead = _lead(sim)
    sim.ego.sees(LEAD_ID)
    lead.step(sim.world)
    sim.ego.sees("scv7")
    lead.step(sim.world)
    assert (
        lead.cut_ins == 1
        and [e.kind for e in sim.events] == ["lead_cut_in"]
        and sim.events[0].vehicle == "scv7"
    )
    for k, seen in enumerate([LEAD_ID, "scv7", LEAD_ID, "scv7", LEAD_ID, "scv8"]):  # the ego's leader flips
        sim.world.t_s = 1.0 + k
        sim.ego.sees(seen)
        lead.step(sim.world)
    assert lead.cut_ins == 2 and [e.vehicle for e in sim.events] == ["scv7", "scv8"]  # scv7 counted once


def test_cars_that_come_in_one_ahead_of_the_other_are_each_a_cut_in():
    """While the ego waits to change lanes, the stream fills the gap behind the lead: scv1, then scv2 in
    front of it, ... each came between the lead and the ego. A car the ego merely catches up with in the
    meantime (the lead out of sight, no car between) is not."""
    sim = fake_sim(gap_m=40.0, ego_speed=2.0)
    lead = _lead(sim)
    for k, seen in enumerate([LEAD_ID, "scv1", "scv2", "scv3", "scv2", None, "scv9"]):
        sim.world.t_s = float(k)
        sim.ego.sees(seen)
        lead.step(sim.world)
    assert [e.vehicle for e in sim.events if e.kind == "lead_cut_in"] == ["scv1", "scv2", "scv3"]


def test_a_car_crossing_the_egos_way_is_not_a_cut_in():
    """Waiting at a stop sign, the ego sees each car crossing the junction ahead as its leader for a moment
    (Krems seed 2: 16 of them); they are not between the lead and the ego."""
    sim = fake_sim(gap_m=40.0, ego_speed=0.0)
    w = sim.world
    for k, heading in enumerate((90.0, 270.0, 30.0)):  # two crossing, one merging into the ego's way
        car = w.add(f"x{k}")
        w.heading_deg[car] = heading
    lead = _lead(sim)
    for k, seen in enumerate([LEAD_ID, "x0", LEAD_ID, "x1", LEAD_ID, "x2"]):
        w.t_s = float(k)
        sim.ego.sees(seen)
        lead.step(w)
    assert [e.vehicle for e in sim.events if e.kind == "lead_cut_in"] == ["x2"]


@pytest.mark.parametrize("front_y, between", [(4.0, False), (-1.0, True)])
def test_a_car_beside_the_lead_is_not_between_it_and_the_ego(front_y, between):
    """Helsinki seed 1, at a red: scv7 stood in the next lane beside the lead, its rear angled into the ego's
    path, and was the ego's leader at 0-1 m for 20 s: the ego still follows the lead (no car fits between
    them), no cut-in. The same car with its front behind the lead's rear is between them."""
    sim = fake_sim(gap_m=6.0, ego_speed=0.0)  # the lead's rear 6 m ahead of the ego's front (y = 0)
    # scv7 in the next lane, its nose turned out (rear 0.8 m off the ego's path), front at y = 6 + front_y
    w = sim.world
    car = w.add("scv7")
    w.x_m[car], w.y_m[car], w.heading_deg[car], w.length_m[car] = 2.5, front_y + 6.0, 20.0, 5.0
    sim.ego.path, sim.ego.s_front_m = RoutePath([(0.0, -20.0), (0.0, 200.0)]), 20.0
    lead = _lead(sim)
    sim.ego.sees(LEAD_ID)
    lead.step(w)
    assert lead.lead_is_leader
    w.t_s = 1.0
    sim.ego.sees("scv7")
    lead.step(w)
    assert lead.lead_is_leader is not between
    assert [e.vehicle for e in sim.events if e.kind == "lead_cut_in"] == (["scv7"] if between else [])


def test_every_car_between_the_lead_and_the_ego_is_sent_off_not_only_the_egos_leader():
    """Monaco -166149542#0: three priority cars came in while the participant waited at the line; sending
    only its leader off, the two ahead of it stayed between the lead and the ego for the rest of the phase."""
    sim = fake_sim(gap_m=40.0, ego_speed=8.0)
    lead = _lead(sim)
    sim.ego.sees(LEAD_ID)
    lead.step(sim.world)
    sim.ego.sees("scv1")
    sim.bridge.leaders = {"scv1": ("scv2", 5.0), "scv2": ("scv3", 5.0), "scv3": (LEAD_ID, 5.0)}
    for k in range(1, 60):  # 5.9 s with them between
        sim.world.t_s = k * 0.1
        lead.step(sim.world)
    assert sorted(v for v, _ in sim.bridge.diverted) == ["scv1", "scv2", "scv3"]
    assert sorted(e.vehicle for e in sim.events if e.kind == "cut_in_diverted") == ["scv1", "scv2", "scv3"]


def test_a_vehicle_that_stays_between_the_lead_and_the_ego_is_sent_off_the_leads_way():
    sim = fake_sim(gap_m=20.0, ego_speed=8.0)
    lead = _lead(sim)
    sim.ego.sees(LEAD_ID)
    lead.step(sim.world)
    sim.ego.sees("scv7")
    sim.bridge.exit_edge = None  # no junction offers a way out yet
    for k in range(1, 100):  # 9.9 s with scv7 between them
        sim.world.t_s = k * 0.1
        lead.step(sim.world)
    # asked first after DIVERT_AFTER_S (5 s), again DIVERT_RETRY_S later, never every step
    assert [v for v, _ in sim.bridge.diverted] == ["scv7"] and sim.bridge.diverted[0][1] == {"a", "b", "c"}
    # kept off the lead's way near ahead only: a long route comes back to its roads (Helsinki P1)
    assert sim.bridge.route_within_m == DIVERT_KEEP_OFF_M
    sim.bridge.exit_edge = "side"
    for k in range(100, 200):
        sim.world.t_s = k * 0.1
        lead.step(sim.world)
    assert len(sim.bridge.diverted) == 2  # the second ask turned it off; it is not asked again
    assert [e.kind for e in sim.events] == ["lead_cut_in", "cut_in_diverted"]
    # the lead back as the ego's leader: nothing more happens
    sim.ego.sees(LEAD_ID)
    lead.step(sim.world)
    assert len(sim.bridge.diverted) == 2


def test_a_standing_foe_counts_unless_something_holds_it_back():
    sim = fake_sim(gap_m=20.0, ego_speed=0.0)
    foe = sim.world.add("foe", is_ego=False)
    sim.world.speed_mps[foe] = 0.0
    # first in line at an open link after a whole red: it may start now, 10 m from the conflict
    sim.bridge.foes = [("foe", 5.0, 10.0, 40.0, False)]
    assert priority_gap_s(sim.world, sim.bridge, LEAD_ID, 5.0) < 4.0
    # queued behind another car (or at a closed link): waiting itself, it does not count
    sim.bridge.foes = [("foe", 5.0, 10.0, 40.0, True)]
    assert priority_gap_s(sim.world, sim.bridge, LEAD_ID, 5.0) == math.inf
    # held back but only just stopped: still counts (it may be rolling up to its queue)
    sim.bridge.foes = [("foe", 5.0, 10.0, 1.0, True)]
    assert priority_gap_s(sim.world, sim.bridge, LEAD_ID, 5.0) < 4.0


def _scv7_right_behind_the_lead(sim) -> None:
    """scv7 at 10 m/s, 12 m behind the lead (the bridge's answer for the lead's follower)."""
    sim.world.speed_mps[sim.world.add("scv7", is_ego=False)] = 10.0
    sim.bridge.follower = lambda vid, d: ("scv7", 12.0)


def test_with_a_car_between_them_the_lead_keeps_that_car_close_instead_of_crawling():
    sim = fake_sim(gap_m=60.0, ego_speed=3.0)
    _scv7_right_behind_the_lead(sim)
    lead = _lead(sim)
    sim.ego.sees(LEAD_ID)
    lead.step(sim.world)
    assert sim.bridge.caps[-1] == 0.0  # 3 + (40 - 60) / 5 < 0: the lead stands for the lagging ego
    sim.ego.sees("scv7")
    lead.step(sim.world)
    # the car behind the lead allows 10 + (40 - 12) / 5 = 15.6 m/s; the ego, 60 m behind with a car between
    # (allowed 2 x 40 m), 3 + (80 - 60) / 5 = 7 m/s: the lead eases off, it does not stand
    assert sim.bridge.caps[-1] == pytest.approx(7.0)


def test_with_a_car_between_them_the_lead_still_waits_for_an_ego_left_far_behind():
    """Keeping only the car behind it close, the lead lost the ego for good after two cut-ins (Helsinki)."""
    sim = fake_sim(gap_m=120.0, ego_speed=8.0)
    _scv7_right_behind_the_lead(sim)
    lead = _lead(sim)
    sim.ego.sees(LEAD_ID)
    lead.step(sim.world)
    sim.ego.sees("scv7")
    lead.step(sim.world)
    assert sim.bridge.caps[-1] < 8.0 and lead.waiting  # 8 + (80 - 120) / 5 = 0: slower than the ego


def test_the_gap_is_measured_along_the_egos_route_path():
    # the route turns right 100 m ahead of the ego's front bumper; the lead is 50 m into the new road
    path = RoutePath([(0.0, -20.0), (0.0, 100.0), (100.0, 100.0)])
    sim = fake_sim(gap_m=0.0, ego_speed=10.0)
    w = sim.world
    lead_slot = w.slot_of[LEAD_ID]
    w.x_m[lead_slot], w.y_m[lead_slot], w.heading_deg[lead_slot] = 50.0, 100.0, 90.0  # heading east
    sim.ego.path, sim.ego.s_front_m = path, 20.0  # the ego's front bumper at (0, 0)
    lead = _lead(sim)
    lead.step(w)
    assert lead.gap_m == pytest.approx(100.0 + 45.0)  # along the path, not the straight 110 m
    assert lead.waiting and sim.bridge.caps  # beyond wait_beyond_m: it slows for the ego
    sim.ego.path, sim.ego.s_front_m = None, None
    straight = _lead(sim)
    straight.step(w)
    assert straight.gap_m == pytest.approx(math.hypot(45.0, 100.0))


def test_nothing_happens_until_both_are_in_and_close_is_safe():
    sim = fake_sim(gap_m=80.0, ego_speed=6.0)
    sim.world.remove(LEAD_ID)
    lead = _lead(sim)
    lead.step(sim.world)
    assert sim.bridge.caps == [] and sim.events == [] and math.isnan(lead.gap_m)
    lead.close()


def test_the_lead_keeps_to_the_lane_the_egos_path_takes():
    """On a multi-lane road the lead drives in the ego's lane, not wherever SUMO's lane choice puts it."""
    sim = fake_sim(gap_m=20.0, ego_speed=8.0)
    w = sim.world
    sim.ego.s_front_m = 0.0
    sim.ego.path = RoutePath([(0.0, -10.0), (0.0, 200.0)], edge_lanes=[(0.0, 210.0, "b", 1)])
    lead = _lead(sim)
    w.edge_code[w.slot_of[LEAD_ID]] = w.intern_edge("a")  # an edge the path does not name: left alone
    lead.step(w)
    assert sim.bridge.lanes == []
    w.edge_code[w.slot_of[LEAD_ID]] = w.intern_edge("b")
    lead.step(w)
    assert sim.bridge.lanes == [1]


def _stuck_in_lane_0(beside):
    """The lead stands in lane 0 of edge b where the ego's path takes lane 1; ``beside``: the car behind it
    there (id, gap, speed)."""
    sim = fake_sim(gap_m=20.0, ego_speed=0.0)
    w = sim.world
    sim.ego.s_front_m = 10.0
    sim.ego.path = RoutePath([(0.0, -10.0), (0.0, 200.0)], edge_lanes=[(0.0, 210.0, "b", 1)])
    sim.bridge.beside = beside
    lead = _lead(sim)
    w.edge_code[w.slot_of[LEAD_ID]] = w.intern_edge("b")
    return sim, lead


@pytest.mark.parametrize("beside", [None, ("scv1", 1.5, 0.0), (EGO_ID, 2.0, 6.0)])
def test_the_lead_standing_in_the_wrong_lane_noses_into_a_queue_or_in_front_of_the_ego(beside):
    """Standing short of the lane its way goes on, the lead waits LANE_FORCE_AFTER_S for SUMO's lane change,
    then moves over into a gap too small for SUMO: beside a standing queue, or in front of the ego, whose
    driver follows it. It says so once."""
    sim, lead = _stuck_in_lane_0(beside)
    for k in range(int(LANE_FORCE_AFTER_S / 0.1) + 3):
        sim.world.t_s = k * 0.1
        lead.step(sim.world)
    assert sim.bridge.lanes[-1] == 1
    assert not sim.bridge.forced[0] and sim.bridge.forced[-1]
    assert [e.kind for e in sim.events] == ["lead_nosed_in"]


def test_the_lead_does_not_nose_in_front_of_a_moving_car():
    sim, lead = _stuck_in_lane_0(("scv1", 3.0, 8.0))
    for k in range(int(LANE_FORCE_AFTER_S / 0.1) * 2):
        sim.world.t_s = k * 0.1
        lead.step(sim.world)
    assert not any(sim.bridge.forced) and sim.events == []


def test_the_lead_in_the_wrong_lane_stops_behind_a_queue_in_its_lane_instead_of_passing_it():
    """Helsinki seed 1: a queue stood at a red light in the lane the lead's way takes; SUMO's lane change
    drove it on past the queue to its head, and the ego, on its path in that lane, stayed behind the queue.
    The lead stops short of the queue's last car (and moves over behind it); a moving lane, or a queue it
    is already beside, does not stop it."""
    sim, lead = _stuck_in_lane_0(None)
    sim.world.speed_mps[sim.world.slot_of[LEAD_ID]] = 8.0
    sim.world.speed_mps[sim.world.slot_of[EGO_ID]] = 8.0
    sim.bridge.ahead_beside = ("scv1", 20.0, 0.0)  # the queue's last car, its rear 20 m ahead
    lead.step(sim.world)
    assert lead.waiting and sim.bridge.caps[-1] == pytest.approx(math.sqrt(2 * 2.0 * 19.0))
    for ahead in (("scv1", 20.0, 8.0), ("scv1", -2.0, 0.0), None):
        sim.bridge.ahead_beside = ahead
        lead.step(sim.world)
        assert not lead.waiting, ahead


def test_the_lead_does_not_hold_at_a_green_for_an_ego_that_has_passed_it():
    """The ego overtook the lead in another lane (the lead had stopped for it at a green): waiting there
    for it would only hold the lead (Munich seed 1, the lead stood through the green)."""
    sim = fake_sim(gap_m=30.0, ego_speed=8.0)
    sim.bridge.tls, sim.bridge.green_left_s = ("J", 0, 40.0, "G"), 3.0
    sim.ego.path, sim.ego.s_front_m = RoutePath([(0.0, -10.0), (0.0, 300.0)]), 10.0  # the ego's front at y=0
    lead = _lead(sim)
    lead.step(sim.world)
    assert lead.waiting and lead.gap_m == pytest.approx(30.0)
    sim.ego.s_front_m = 70.0  # now 25 m ahead of the lead's front
    lead.step(sim.world)
    assert not lead.waiting and sim.bridge.caps[-1] is None


def test_the_lead_waits_for_a_gap_for_two_only_when_the_ego_is_the_car_behind_it():
    """Munich seed 2: at a permissive green the lead waited 25 s for a gap for itself and the participant,
    three cars queued behind it in the turning lane and the participant in the next lane, which could not
    get in behind them until they moved. A car behind the lead takes the next gap whatever the lead waits
    for: the lead needs only its own critical gap."""
    sim = fake_sim(gap_m=12.0, ego_speed=0.0)  # along the path, the ego is close (in the lane beside)
    sim.bridge.link = ("g", 1.0, "l")
    sim.world.add("foe")
    sim.world.speed_mps[sim.world.slot_of["foe"]] = 10.0
    sim.bridge.foes = [("foe", 1.0, 80.0, 0.0, False)]  # arrives in 8 s: > t_c of a left turn, < t_c + t_f
    lead = _lead(sim)
    lead.step(sim.world)
    assert lead.waiting  # nobody behind it but the ego: a gap for two
    sim.bridge.behind = ("scv161", 2.0)
    sim.world.t_s = 0.1
    lead.step(sim.world)
    assert not lead.waiting
    sim.bridge.behind = (EGO_ID, 2.0)
    sim.world.t_s = 0.2
    lead.step(sim.world)
    assert lead.waiting


def _car(w: World, vid: str, x: float, y: float, heading: float = 0.0) -> int:
    slot = w.add(vid)
    w.x_m[slot], w.y_m[slot], w.heading_deg[slot], w.length_m[slot], w.width_m[slot] = x, y, heading, 5.0, 1.8
    return slot


def test_the_lead_pulls_over_for_a_car_that_stays_between_and_rejoins_ahead_of_the_ego():
    """A car that came in between the lead and the ego and stays there (its route on the lead's way, no
    junction to send it off: Monaco 166009792#2, 20 s) is let past: the lead stands at the roadside beyond
    its braking distance, and gets back in once the car has passed it and the ego comes on."""
    sim = fake_sim(gap_m=40.0, ego_speed=10.0)  # ego front at y = 0, lead's rear at y = 40
    w = sim.world
    w.speed_mps[w.slot_of[LEAD_ID]] = 10.0
    sim.ego.path, sim.ego.s_front_m = RoutePath([(0.0, -20.0), (0.0, 400.0)]), 20.0
    car = _car(w, "scv7", 0.0, 25.0)  # between them, in their lane
    sim.bridge.roadside, sim.bridge.exit_edge = "e_0", None
    lead = _lead(sim)
    sim.ego.sees(LEAD_ID)
    lead.step(w)
    sim.ego.sees("scv7")
    k = 1
    while not sim.bridge.pulled_over:
        w.t_s = k * 0.1
        lead.step(w)
        k += 1
    assert w.t_s == pytest.approx(0.1 + LET_PAST_AFTER_S, abs=0.15)
    assert sim.bridge.pulled_over[0] >= 10.0**2 / (2.0 * STOP_DECEL_MPS2)  # it can stop there comfortably
    assert [e.kind for e in sim.events] == ["lead_cut_in", "lead_let_past"] and lead.let_past == 1
    assert sim.bridge.caps[-1] is None  # no cap of its own holds it short of the roadside stop
    assert sim.ego.lead_at_roadside  # the participant keeps behind it there, whichever lane it is beside
    sim.bridge.standing_beside = True
    w.speed_mps[w.slot_of[LEAD_ID]] = 0.0
    lead.step(w)
    assert sim.bridge.rejoined == 0  # the car is still between them
    w.y_m[car] = 56.0  # past the lead (its front at y = 45): the car's rear 6 m beyond it, room to get in
    sim.ego.sees(LEAD_ID)  # the lead at the roadside is the nearest car on the ego's way
    lead.step(w)
    assert sim.bridge.rejoined == 1 and sim.events[-1].kind == "lead_rejoined"
    assert sim.ego.lead_at_roadside  # the participant keeps behind it until it drives again ...
    lead.step(w)
    w.speed_mps[w.slot_of[LEAD_ID]] = 3.0
    lead.step(w)
    assert not sim.ego.lead_at_roadside  # ... on its lane
    lead.step(w)  # back to following-task duty: no second rejoin, no new let-past
    assert sim.bridge.rejoined == 1 and lead.let_past == 1


def _at_the_roadside_with_no_car_left_between(gap_m: float, ego_speed: float):
    """A car between the lead and the ego on a straight road until the lead has pulled over for it; then it
    has passed and gone on, the lead stands at the roadside, the ego sees it ahead."""
    sim = fake_sim(gap_m=gap_m, ego_speed=ego_speed)
    w = sim.world
    sim.ego.path, sim.ego.s_front_m = RoutePath([(0.0, -20.0), (0.0, 400.0)]), 20.0
    _car(w, "scv3", 0.0, 0.5 * gap_m)
    sim.bridge.roadside, sim.bridge.exit_edge = "e_0", None
    lead = _lead(sim)
    sim.ego.sees(LEAD_ID)
    lead.step(w)
    sim.ego.sees("scv3")
    for k in range(1, 40):
        w.t_s = k * 0.1
        lead.step(w)
    assert lead.let_past == 1
    w.remove("scv3")
    sim.bridge.standing_beside = True
    sim.ego.sees(LEAD_ID)
    return sim, lead


def test_the_lead_at_the_roadside_gets_back_in_only_with_room_in_front_of_the_ego():
    """Told to rejoin with the ego 6 m behind at 7 m/s, SUMO kept the lead off the road until the ego had
    passed it (Monaco, experiment P1): it goes only with the ego standing close behind or far enough back
    to stop behind it."""
    sim, lead = _at_the_roadside_with_no_car_left_between(gap_m=20.0, ego_speed=10.0)  # too close at 10 m/s
    lead.step(sim.world)
    assert sim.bridge.rejoined == 0
    sim.world.speed_mps[sim.world.slot_of[EGO_ID]] = 0.0  # it has stopped behind the lead
    lead.step(sim.world)
    assert sim.bridge.rejoined == 1


def test_at_the_roadside_the_lead_waits_there_while_the_ego_stands_far_back():
    """A red that stopped only the ego (Krems 71582001: 75 s): the lead stays at the roadside, where the cars
    turning in pass it, and drives on when the ego does."""
    sim, lead = _at_the_roadside_with_no_car_left_between(gap_m=70.0, ego_speed=0.0)
    lead.step(sim.world)
    assert sim.bridge.rejoined == 0  # clear, but the ego stands 70 m back
    sim.world.speed_mps[sim.world.slot_of[EGO_ID]] = 3.0
    lead.step(sim.world)
    assert sim.bridge.rejoined == 1


def test_a_car_on_the_egos_way_beyond_a_turn_is_between_even_when_it_heads_across_the_ego():
    """Standing at a red before a left turn, the ego faces north while the cars that turn in ahead of it from
    the cross street drive west along its path: they come between it and the lead (Krems 71582001). A car
    crossing the path there (heading north across the westbound road) does not."""
    path = RoutePath([(0.0, -20.0), (0.0, 10.0), (-300.0, 10.0)])  # north, then left (west) at y = 10
    sim = fake_sim(gap_m=0.0, ego_speed=0.0)
    w = sim.world
    lead_slot = w.slot_of[LEAD_ID]
    w.x_m[lead_slot], w.y_m[lead_slot], w.heading_deg[lead_slot] = -80.0, 10.0, 270.0
    sim.ego.path, sim.ego.s_front_m = path, 20.0  # the ego's front at (0, 0), at its line
    _car(w, "turned_in", -40.0, 10.0, heading=270.0)
    _car(w, "crossing", -20.0, 12.0, heading=0.0)
    lead = _lead(sim)
    for k, seen in enumerate([LEAD_ID, "crossing", LEAD_ID, "turned_in"]):
        w.t_s = float(k)
        sim.ego.sees(seen)
        lead.step(w)
    assert [e.vehicle for e in sim.events if e.kind == "lead_cut_in"] == ["turned_in"]

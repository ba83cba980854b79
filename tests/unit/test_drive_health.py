"""The lead vehicle's rules and the drive health, with fake ports (no SUMO, no MuJoCo)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from cosim.health import DriveHealth
from cosim.phases.lead import LeadVehicle
from cosim.sumo_bridge.bridge import EGO_ID, LEAD_ID, SumoEvent
from cosim.world import World


class FakeBridge:
    """What the lead asks SUMO, answered from fields the test sets."""

    def __init__(self):
        self.caps: list[float | None] = []
        self.tls = None  # (id, link, dist, state)
        self.green_left_s = math.inf
        self.link = None  # (state, dist, direction)
        self.foes: list[tuple[str, float, float, float, bool]] = []
        self.diverted: list[tuple[str, set]] = []
        self.exit_edge: str | None = "side"

    def cap_speed(self, vid, speed):
        assert vid == LEAD_ID
        self.caps.append(speed)

    def lane_speed_limit(self, vid):
        return 13.0

    def next_tls(self, vid):
        return self.tls

    def tls_green_left_s(self, tls_id, link):
        return self.green_left_s

    def next_link(self, vid):
        return self.link

    def yield_foes(self, vid, lookahead_m):
        return self.foes

    def route_ahead(self, vid):
        assert vid == LEAD_ID
        return ["a", "b", "c"]

    def follower(self, vid, distance_m):
        return None

    def divert(self, vid, keep_off, min_ahead_m):
        self.diverted.append((vid, keep_off))
        return self.exit_edge


def fake_sim(gap_m: float, ego_speed: float):
    """Lead and ego on a straight road heading north (SUMO angle 0), the lead's rear ``gap_m`` ahead."""
    w = World(capacity=8)
    for vid, y in ((EGO_ID, 0.0), (LEAD_ID, gap_m + 5.0)):
        s = w.add(vid, is_ego=vid == EGO_ID)
        w.x_m[s], w.y_m[s], w.heading_deg[s], w.length_m[s] = 0.0, y, 0.0, 5.0
    w.speed_mps[w.slot_of[EGO_ID]] = ego_speed
    sim = SimpleNamespace(world=w, bridge=FakeBridge(), ego=None, events=[], step_s=0.1, hooks=[])
    sim.add_hook = lambda phase, fn: sim.hooks.append((phase, fn))
    return sim


def test_the_lead_waits_for_a_lagging_ego_and_stands_while_it_stands():
    sim = fake_sim(gap_m=80.0, ego_speed=6.0)
    lead = LeadVehicle(sim, wait_beyond_m=40.0)
    lead.step(sim)
    assert lead.gap_m == pytest.approx(80.0)
    assert sim.bridge.caps[-1] < 6.0 and lead.waiting  # slower than the ego: it closes up
    sim.world.speed_mps[sim.world.slot_of[EGO_ID]] = 0.0
    lead.step(sim)
    assert sim.bridge.caps[-1] == 0.0  # the ego stands (a red light behind the lead): so does the lead


def test_the_lead_drives_freely_when_the_ego_follows_closely():
    sim = fake_sim(gap_m=15.0, ego_speed=10.0)
    lead = LeadVehicle(sim, wait_beyond_m=40.0)
    lead.step(sim)
    assert not lead.waiting and sim.bridge.caps == []  # its cap is above the limit: nothing to tell SUMO


def test_the_lead_stops_at_a_green_the_ego_would_miss():
    sim = fake_sim(gap_m=30.0, ego_speed=8.0)
    sim.bridge.tls, sim.bridge.green_left_s = ("J", 0, 40.0, "G"), 3.0  # the ego needs (40+5+30)/8 ~ 9 s
    lead = LeadVehicle(sim, wait_beyond_m=40.0)
    lead.step(sim)
    assert lead.waiting and sim.bridge.caps[-1] <= math.sqrt(2 * 2.0 * 39.0)  # braking for the line
    sim2 = fake_sim(gap_m=30.0, ego_speed=8.0)
    sim2.bridge.tls, sim2.bridge.green_left_s = ("J", 0, 40.0, "G"), 30.0  # long green: both get through
    lead2 = LeadVehicle(sim2, wait_beyond_m=40.0)
    lead2.step(sim2)
    assert not lead2.waiting


def test_the_lead_decides_again_when_the_ego_slows_down_before_a_green():
    sim = fake_sim(gap_m=30.0, ego_speed=8.0)
    sim.world.speed_mps[sim.world.slot_of[LEAD_ID]] = 8.0
    sim.bridge.tls, sim.bridge.green_left_s = ("J", 0, 60.0, "G"), 15.0  # (60+5+30)/8 + 1.5 ~ 13 s: go
    lead = LeadVehicle(sim, wait_beyond_m=40.0)
    lead.step(sim)
    assert not lead.waiting
    # the ego brakes for a curve: (55+5+30)/4 + 1.5 = 24 s > the 14 s of green left; the lead (8 m/s,
    # 16 m to stop at 2 m/s^2) can still stop 55 m before the line, so it does
    sim.world.speed_mps[sim.world.slot_of[EGO_ID]] = 4.0
    sim.bridge.tls, sim.bridge.green_left_s = ("J", 0, 55.0, "G"), 14.0
    lead.step(sim)
    assert lead.waiting
    # past the point where it could stop comfortably it goes on whatever the ego does
    sim2 = fake_sim(gap_m=30.0, ego_speed=8.0)
    sim2.world.speed_mps[sim2.world.slot_of[LEAD_ID]] = 12.0
    sim2.bridge.tls, sim2.bridge.green_left_s = ("J", 0, 60.0, "G"), 15.0
    lead2 = LeadVehicle(sim2, wait_beyond_m=40.0)
    lead2.step(sim2)
    sim2.world.speed_mps[sim2.world.slot_of[EGO_ID]] = 2.0
    sim2.bridge.tls, sim2.bridge.green_left_s = ("J", 0, 30.0, "G"), 12.0  # 36 m needed to stop from 12 m/s
    lead2.step(sim2)
    assert not lead2.waiting


def test_the_lead_holds_at_a_give_way_line_until_the_ego_is_close_and_the_gap_suits_both():
    sim = fake_sim(gap_m=25.0, ego_speed=5.0)
    sim.bridge.link = ("m", 10.0, "s")
    lead = LeadVehicle(sim, wait_beyond_m=40.0)
    lead.step(sim)
    assert lead.waiting  # the ego is 25 m behind: wait for it at the line
    sim3 = fake_sim(gap_m=8.0, ego_speed=3.0)
    sim3.bridge.link = ("m", 10.0, "s")
    sim3.world.add("foe")
    sim3.world.speed_mps[sim3.world.slot_of["foe"]] = 10.0
    sim3.bridge.foes = [("foe", 10.0, 80.0, 0.0, False)]  # arrives in 8 s: < t_c + t_f = 6.5 + 4.8 s
    lead3 = LeadVehicle(sim3, wait_beyond_m=40.0)
    lead3.step(sim3)
    assert lead3.waiting
    sim3.bridge.foes = [("foe", 10.0, 150.0, 0.0, False)]  # 15 s: room for both
    lead3.step(sim3)
    assert not lead3.waiting


def test_a_cut_in_is_logged_when_another_vehicle_becomes_the_ego_leader():
    sim = fake_sim(gap_m=20.0, ego_speed=8.0)
    lead = LeadVehicle(sim, wait_beyond_m=40.0)
    sim.ego = SimpleNamespace(s_front_m=None, percept=SimpleNamespace(leader_present=True, leader_id=LEAD_ID))
    lead.step(sim)
    sim.ego.percept = SimpleNamespace(leader_present=True, leader_id="scv7")
    lead.step(sim)
    assert (
        lead.cut_ins == 1
        and [e.kind for e in sim.events] == ["lead_cut_in"]
        and sim.events[0].vehicle == "scv7"
    )


def test_a_vehicle_that_stays_between_the_lead_and_the_ego_is_sent_off_the_leads_way():
    sim = fake_sim(gap_m=20.0, ego_speed=8.0)
    lead = LeadVehicle(sim, wait_beyond_m=40.0)
    sim.ego = SimpleNamespace(s_front_m=None, percept=SimpleNamespace(leader_present=True, leader_id=LEAD_ID))
    lead.step(sim)
    sim.ego.percept = SimpleNamespace(leader_present=True, leader_id="scv7")
    sim.bridge.exit_edge = None  # no junction offers a way out yet
    for k in range(1, 100):  # 9.9 s with scv7 between them
        sim.world.t_s = k * 0.1
        lead.step(sim)
    # asked first after DIVERT_AFTER_S (5 s), again DIVERT_RETRY_S later, never every step
    assert [v for v, _ in sim.bridge.diverted] == ["scv7"] and sim.bridge.diverted[0][1] == {"a", "b", "c"}
    sim.bridge.exit_edge = "side"
    for k in range(100, 200):
        sim.world.t_s = k * 0.1
        lead.step(sim)
    assert len(sim.bridge.diverted) == 2  # the second ask turned it off; it is not asked again
    assert [e.kind for e in sim.events] == ["lead_cut_in", "cut_in_diverted"]
    # the lead back as the ego's leader: nothing more happens
    sim.ego.percept = SimpleNamespace(leader_present=True, leader_id=LEAD_ID)
    lead.step(sim)
    assert len(sim.bridge.diverted) == 2


def _health_sim(lead: bool = True):
    w = World(capacity=8)
    config = SimpleNamespace(
        ego=SimpleNamespace(enabled=True, lead_vehicle=lead, depart_s=0.0, physics="mujoco")
    )
    sim = SimpleNamespace(world=w, config=config, ego=None, events=[], step_s=0.1, hooks=[])
    sim.add_hook = lambda phase, fn: sim.hooks.append((phase, fn))
    return sim


def _step(sim, health, t, speed, leader=None, gap=20.0, events=()):
    w = sim.world
    w.step += 1
    w.t_s = t
    if EGO_ID not in w.slot_of:
        w.add(EGO_ID, is_ego=True)
    w.speed_mps[w.slot_of[EGO_ID]] = speed
    sim.ego = SimpleNamespace(percept=SimpleNamespace(leader_present=leader is not None, leader_id=leader,
                                                      leader_gap_m=gap, tls_state=None, tls_dist_m=math.inf,
                                                      sign_kind=None),
                              driver=SimpleNamespace(debug=SimpleNamespace(mode="leader")))  # fmt: skip
    sim.events = list(events)
    sim.events += health.step(w, sim.events, sim.ego.percept, lambda: sim.ego.driver.debug.mode)


def test_health_of_a_good_drive_is_ok_and_of_a_stalled_one_degraded():
    sim = _health_sim()
    health = DriveHealth(sim.config.ego, sim.step_s)
    for k in range(1, 601):  # 60 s at 10 m/s behind the lead
        _step(sim, health, k * 0.1, 10.0, LEAD_ID)
    rep = health.report()
    assert rep["status"] == "ok", rep["problems"]
    assert rep["ego_present_at_s"] == pytest.approx(0.1) and rep["ego_distance_m"] == pytest.approx(600.0)
    assert rep["following_share"] == 1.0 and rep["lead_leader_share"] == 1.0

    sim = _health_sim()
    health = DriveHealth(sim.config.ego, sim.step_s)
    for k in range(1, 1501):  # 150 s standing behind another car
        _step(sim, health, k * 0.1, 0.0, "scv1")
    rep = health.report()
    assert rep["status"] == "degraded" and rep["stalls"] == 0  # the stall event is counted once logged ...
    assert any(e.kind == "ego_stall" for e in sim.events) or rep["longest_standstill_s"] > 120.0
    assert "the ego stood still for 150 s" in rep["problems"]
    assert any("leader only 0%" in p for p in rep["problems"])


def test_health_windows_and_collisions():
    sim = _health_sim(lead=False)
    health = DriveHealth(sim.config.ego, sim.step_s)
    for k in range(1, 601):
        ev = [SumoEvent("collision", "scv1", "with scv2 (junction) on :J_0")] if k == 300 else []
        _step(sim, health, k * 0.1, 5.0, None, events=ev)
    assert health.report(0.0, 20.0)["status"] == "ok"
    late = health.report(20.0, 60.0)
    assert late["collisions"] == 1 and late["ego_collisions"] == 0 and late["status"] == "degraded"


def test_health_says_so_when_the_ego_never_drove():
    sim = _health_sim()
    health = DriveHealth(sim.config.ego, sim.step_s)
    sim.world.step, sim.world.t_s = 1, 0.1
    assert health.step(sim.world, []) == []
    rep = health.report()
    assert rep["status"] == "degraded" and rep["problems"] == ["the ego never drove in this window"]


def test_a_standing_foe_counts_unless_something_holds_it_back():
    from cosim.phases.ego import priority_gap_s

    sim = fake_sim(gap_m=20.0, ego_speed=0.0)
    foe = sim.world.add("foe", is_ego=False)
    sim.world.speed_mps[foe] = 0.0
    # first in line at an open link after a whole red: it may start now, 10 m from the conflict
    sim.bridge.foes = [("foe", 5.0, 10.0, 40.0, False)]
    assert priority_gap_s(sim, LEAD_ID, 5.0) < 4.0
    # queued behind another car (or at a closed link): waiting itself, it does not count
    sim.bridge.foes = [("foe", 5.0, 10.0, 40.0, True)]
    assert priority_gap_s(sim, LEAD_ID, 5.0) == math.inf
    # held back but only just stopped: still counts (it may be rolling up to its queue)
    sim.bridge.foes = [("foe", 5.0, 10.0, 1.0, True)]
    assert priority_gap_s(sim, LEAD_ID, 5.0) < 4.0


def test_with_a_car_between_them_the_lead_keeps_that_car_close_instead_of_crawling():
    sim = fake_sim(gap_m=60.0, ego_speed=3.0)
    scv = sim.world.add("scv7", is_ego=False)
    sim.world.speed_mps[scv] = 10.0
    lead = LeadVehicle(sim, wait_beyond_m=40.0)
    sim.ego = SimpleNamespace(s_front_m=None, percept=SimpleNamespace(leader_present=True, leader_id=LEAD_ID))
    lead.step(sim)
    assert sim.bridge.caps[-1] == 0.0  # 3 + (40 - 60) / 5 < 0: the lead stands for the lagging ego
    sim.ego.percept = SimpleNamespace(leader_present=True, leader_id="scv7")
    sim.bridge.follower = lambda vid, d: ("scv7", 12.0)  # right behind the lead at 10 m/s
    lead.step(sim)
    assert sim.bridge.caps[-1] is None  # 10 + (40 - 12) / 5 = 15.6 m/s: above the limit, not capped


def test_a_collision_is_the_egos_whether_it_hit_or_was_hit():
    from cosim.health import involves_ego

    assert involves_ego(EGO_ID, "with scv3 (junction) on :j_0_0")
    assert involves_ego("scv822", f"with {EGO_ID} (junction) on :456774382_3_0")  # the summary missed this one
    assert not involves_ego("scv1", "with scv2 (junction) on :j_0_0")
    assert not involves_ego("scv1", "with ego2 (front) on e_0")

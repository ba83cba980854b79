"""The run's health record as a phase with fake ports: its ego config, a World, the step's events and a
percept written by the test (no SUMO, no MuJoCo)."""

from __future__ import annotations

import math
from types import SimpleNamespace

from cosim.health import STALL_S, DriveHealth
from cosim.runconfig import EgoConfig
from cosim.world import EGO_ID, LEAD_ID, SumoEvent, World


def _percept(leader=LEAD_ID, tls="g"):
    return SimpleNamespace(leader_present=leader is not None, leader_id=leader, leader_gap_m=12.0, tls_state=tls,
                           tls_dist_m=30.0, sign_kind="stop", sign_dist_m=4.0, sign_id="J7")  # fmt: skip


def _drive(health, w, seconds, speed, percept, asked, events_at=None):
    out = []
    for _ in range(round(seconds / 0.1)):
        w.step += 1
        w.t_s = round(w.step * 0.1, 6)
        w.speed_mps[w.slot_of[EGO_ID]] = speed
        events = list(events_at.get(w.step, [])) if events_at else []

        def mode():
            asked.append(w.t_s)
            return "stop_line"

        out += health.step(w, events, percept, mode)
    return out


def test_a_long_standstill_outside_red_is_reported_once_with_what_the_ego_waited_for():
    health = DriveHealth(EgoConfig(), 0.1)
    w = World(capacity=4)
    w.add(EGO_ID, is_ego=True)
    asked: list[float] = []
    added = _drive(health, w, 30.0, 10.0, _percept(), asked)
    assert added == [] and asked == []  # the driver's mode is asked only to name a stall
    added = _drive(health, w, STALL_S + 10.0, 0.0, _percept(), asked)
    assert [e.kind for e in added] == ["ego_stall"] and len(asked) == 1
    assert added[0].vehicle == EGO_ID and added[0].value > STALL_S
    assert "driver: stop_line" in added[0].detail and f"behind {LEAD_ID} at 12 m" in added[0].detail
    assert "stop line 4 m ahead at J7" in added[0].detail
    # at a red light a standstill is no stall
    assert _drive(health, w, STALL_S + 10.0, 0.0, _percept(tls="r"), asked) == []
    health.close()


def test_events_counted_and_a_sumo_ego_has_no_following_shares():
    health = DriveHealth(EgoConfig(physics="sumo"), 0.1)
    w = World(capacity=4)
    w.add(EGO_ID, is_ego=True)
    crash = SumoEvent("collision", "scv3", f"with {EGO_ID} (junction) on :j_0")
    _drive(health, w, 40.0, 8.0, None, [], events_at={5: [crash], 6: [SumoEvent("teleport", "scv4")]})
    rep = health.report()
    assert rep["following_share"] is None and rep["lead_leader_share"] is None and rep["cut_ins"] is None
    assert rep["collisions"] == 1 and rep["ego_collisions"] == 1 and rep["teleports"] == 1
    assert rep["ego_distance_m"] == 320.0 and rep["window_s"] == 39.9
    assert rep["status"] == "degraded" and "1 collision(s) of the ego" in rep["problems"]
    assert math.isclose(health.report(10.0, 40.0)["ego_distance_m"], 240.8)


def test_the_lead_share_takes_the_leads_word_on_whom_the_ego_follows():
    """With a lead car the share counts the steps ``LeadVehicle.lead_is_leader`` says the ego follows it
    (a car beside the lead as the percept's nearest leader included); without that word, the percept's."""
    health = DriveHealth(EgoConfig(), 0.1)
    w = World(capacity=4)
    w.add(EGO_ID, is_ego=True)
    beside = _percept(leader="scv7")
    for step, says in enumerate([True] * 300 + [False] * 100):
        w.step, w.t_s = step + 1, round((step + 1) * 0.1, 6)
        w.speed_mps[w.slot_of[EGO_ID]] = 8.0
        health.step(w, [], beside, lead_is_leader=says)
    assert health.report()["lead_leader_share"] == 0.75
    alone = DriveHealth(EgoConfig(), 0.1)
    _drive(alone, w, 40.0, 8.0, beside, [])
    assert alone.report()["lead_leader_share"] == 0.0


def test_time_off_the_road_is_counted_and_only_a_real_excursion_degrades_the_drive():
    """``cosim.sumo_bridge`` reports ``ego_off_road`` when the ego's pose stays off every lane and
    ``ego_on_road`` when it is back: a corner cut short (0.3 s) is counted, not judged; seconds off the
    road are no longer the task."""
    health = DriveHealth(EgoConfig(), 0.1)
    w = World(capacity=4)
    w.add(EGO_ID, is_ego=True)
    off, on = SumoEvent("ego_off_road", EGO_ID), SumoEvent("ego_on_road", EGO_ID)
    _drive(health, w, 40.0, 8.0, _percept(), [], events_at={100: [off], 103: [on], 300: [off], 330: [on]})
    rep = health.report()
    assert rep["ego_off_road"] == 2 and math.isclose(rep["off_road_s"], 3.3)
    assert rep["status"] == "degraded" and any("off the road for 3.3 s" in p for p in rep["problems"])
    brief = health.report(0.0, 20.0)  # only the corner cut short
    assert brief["ego_off_road"] == 1 and math.isclose(brief["off_road_s"], 0.3)
    assert not any("off the road" in p for p in brief["problems"])

"""The drive health over simulated drives (the ego's percept and events written by the test; no SUMO, no
MuJoCo). The lead's rules are tests/unit/phases/test_lead_phase.py."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from cosim.health import DriveHealth
from cosim.world import EGO_ID, LEAD_ID, SumoEvent, World


def _health_sim(lead: bool = True):
    w = World(capacity=8)
    config = SimpleNamespace(
        ego=SimpleNamespace(enabled=True, lead_vehicle=lead, depart_s=0.0, physics="mujoco")
    )
    sim = SimpleNamespace(world=w, config=config, ego=None, events=[], step_s=0.1, hooks=[])
    sim.add_hook = lambda phase, fn: sim.hooks.append((phase, fn))
    return sim


def _step(sim, health, t, speed, leader=None, gap=20.0, events=(), lead_paced=False):
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
    sim.events += health.step(
        w, sim.events, sim.ego.percept, lambda: sim.ego.driver.debug.mode, lead_paced=lead_paced
    )


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
    logged = []
    for k in range(1, 1501):  # 150 s standing behind another car
        _step(sim, health, k * 0.1, 0.0, "scv1")
        logged += sim.events
    rep = health.report()
    # the stall is logged once (ego_stall) and counted in the report (before, only an ego_stall passed back in
    # with a later step's events counted, which no caller did: every report said 0 stalls)
    assert sum(e.kind == "ego_stall" for e in logged) == 1 and rep["stalls"] == 1
    assert "1 stall(s) outside red lights (see the ego_stall events)" in rep["problems"]
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


def test_a_collision_is_the_egos_whether_it_hit_or_was_hit():
    from cosim.health import involves_ego

    assert involves_ego(EGO_ID, "with scv3 (junction) on :j_0_0")
    assert involves_ego(
        "scv822", f"with {EGO_ID} (junction) on :456774382_3_0"
    )  # the summary missed this one
    assert not involves_ego("scv1", "with scv2 (junction) on :j_0_0")
    assert not involves_ego("scv1", "with ego2 (front) on e_0")


def test_the_experiment_summary_shows_each_phases_distance_and_why_it_degraded():
    """summary.md, not only the warning lines on stderr, names a degraded phase and why (issue 15.6)."""
    from cosim.experiment.runner import degraded_phases, summary_markdown

    def phase(name, distance, problems):
        health = {
            "ego_distance_m": distance,
            "problems": problems,
            "status": "degraded" if problems else "ok",
        }
        return {"phase": name, "system": "none", "health": health}

    short = "the ego drove only 163 m in 300 s"
    summary = {"experiment": "x", "wall_s": 1.0, "jobs": 1, "simulated_s": 600.0, "across": [],
               "participants": [{"participant": "P4", "profile": "occasional_driver", "order": ["baseline", "system_A"],
                                 "phases": [phase("baseline", 1127.4, []), phase("system_A", 163.2, [short]),
                                            {"phase": "system_B", "system": "B", "health": None}]}]}  # fmt: skip
    rows = [line for line in summary_markdown(summary).splitlines() if line.startswith("| ")]
    assert rows[0].endswith("| distance [m] | drive health |")
    assert rows[1].endswith("| 1127 | ok |")
    assert rows[2].endswith(f"| 163 | degraded: {short} |")
    assert rows[3].endswith("| – | no data |")
    assert degraded_phases(summary) == [f"P4 system_A: {short}", "P4 system_B: no data"]


def test_creeping_up_a_queue_does_not_end_a_standstill():
    """Helsinki seed 1: a 78-s wait in a queue that closed up twice at 0.6 m/s was reported as 39.7 s, so a
    drive could stand for minutes and pass the 120-s check. Creeps shorter than CREEP_M (a car length) are
    part of the standstill; driving on ends it."""
    from cosim.health import CREEP_M

    def drive(gap_speed_mps: float, gap_s: float, creeps: int = 1):
        sim = _health_sim(lead=False)
        health = DriveHealth(sim.config.ego, sim.step_s)
        t, events = 0.0, []
        legs = [(0.0, 50.0)] + [(gap_speed_mps, gap_s), (0.0, 50.0 / creeps)] * creeps
        for speed, seconds in legs:
            for _ in range(round(seconds / sim.step_s)):
                t += sim.step_s
                _step(sim, health, t, speed, "scv1")
                events += sim.events
        return health.report(), events

    rep, events = drive(0.6, 2.0)  # 1.2 m: the queue closes up
    assert 0.6 * 2.0 < CREEP_M and rep["longest_standstill_s"] == pytest.approx(102.0, abs=0.2)
    assert sum(e.kind == "ego_stall" for e in events) == 1  # one stall, past STALL_S across the creep
    # the report and the ego_stall event judge each creep alone: four creeps of 2 m (8 m in all) are one
    # standstill of 108 s for both
    rep, events = drive(1.0, 2.0, creeps=4)
    assert 2.0 < CREEP_M < 8.0 and rep["longest_standstill_s"] == pytest.approx(108.0, abs=0.2)
    assert sum(e.kind == "ego_stall" for e in events) == 1
    rep, events = drive(5.0, 4.0)  # 20 m: it drove on
    assert rep["longest_standstill_s"] == pytest.approx(50.0, abs=0.2)
    assert not any(e.kind == "ego_stall" for e in events)


def test_health_names_a_route_that_ran_out():
    """One junction cut out of a town (CommonRoad's garching_intersection.osm): every way on turns round, so
    the route cannot be extended and the ego stands at its end; the report says why, not only how little it
    drove. A failed extension with road still ahead is not a problem."""
    sim = _health_sim()
    health = DriveHealth(sim.config.ego, sim.step_s)
    for k in range(1, 601):
        left = max(0.5, 120.0 - k * 0.1 * 10.0)
        events = [SumoEvent("route_not_extended", EGO_ID, f"{left:.0f} m left", left)] if k % 100 == 1 else []
        _step(sim, health, k * 0.1, 10.0 if left > 0.5 else 0.0, LEAD_ID, events=events)
    assert any("end of its route" in p for p in health.report()["problems"])
    assert not any(
        "end of its route" in p for p in health.report(0.0, 12.0)["problems"]
    )  # 119 and 19 m left then


def test_health_reports_how_much_of_a_window_the_ego_set_the_leads_pace():
    """The gap the ego keeps while the lead waits for it or is held back for it is partly the lead's doing:
    the share of such states is reported per window (it degrades nothing: pacing is the lead's job), and only
    with a lead car."""
    sim = _health_sim()
    health = DriveHealth(sim.config.ego, sim.step_s)
    for k in range(1, 601):  # 60 s behind the lead, paced by the ego from 45 s on
        _step(sim, health, k * 0.1, 10.0, LEAD_ID, lead_paced=k > 450)
    assert health.report()["lead_paced_share"] == pytest.approx(0.25)
    assert health.report(0.0, 45.0)["lead_paced_share"] == 0.0
    assert health.report(45.05, 60.0)["lead_paced_share"] == 1.0
    assert health.report()["status"] == "ok"
    sim = _health_sim(lead=False)
    health = DriveHealth(sim.config.ego, sim.step_s)
    _step(sim, health, 0.1, 10.0, "scv1")
    assert health.report()["lead_paced_share"] is None

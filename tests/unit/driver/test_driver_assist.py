"""How the assistance displays change the scripted driver (paper Sec. VII.C).

System A (rear display on the leader) -> sudden braking, then a larger distance.
System B (time gap shown in the car) -> regular, gradual adjustment toward the recommended gap.
"""

import numpy as np
import pytest
from driver_testsim import Leader, Route, scripted, simulate, time_gap

T_ON = 40.0  # [s] display switches on
V_LEAD = 15.0  # [m/s]


def run(drv, t_end=160.0, a_lit=None, b_level=None, b_data=True):
    """Steady following of a constant-speed leader; displays from T_ON on."""
    leader = Leader(21.0, V_LEAD)

    def extras(t, s, v):
        out = {}
        if a_lit is not None:
            out["sys_a_lit"] = a_lit(t)
        if b_level is not None and t >= T_ON:
            shown = (leader.s_rear - s) / max(v, 0.1) if b_data else None  # a perfect radio
            out.update(sys_b_gap_s=shown, sys_b_level=b_level)
        return out

    return simulate(
        drv, Route.straight(), t_end, v0_mps=V_LEAD, leader=leader, speed_limit_mps=22.0, extras=extras
    )


def lit_for(seconds):
    return lambda t: T_ON <= t < T_ON + seconds


@pytest.mark.parametrize("name", ["daily_commuter", "occasional_driver"])
def test_system_a_warning_brakes_after_the_reaction_delay_then_keeps_more_distance(name):
    base = run(scripted(name))
    drv = scripted(name, a_brake_prob=1.0)
    p = drv.profile
    a = run(drv, a_lit=lit_for(3.0))
    k0 = a.at(T_ON)
    assert np.array_equal(a.brake[:k0], base.brake[:k0])
    onset = a.t[k0 + np.argmax(a.brake[k0:] > 0.02)] - T_ON
    assert p.reaction_time_s <= onset <= p.reaction_time_s + 0.3
    # sudden: the braking pulse reaches the profile's deceleration within half a second
    window = slice(k0, a.at(T_ON + p.reaction_time_s + p.a_brake_duration_s + 0.5))
    assert a.a[window].min() <= -0.9 * p.a_brake_decel_mps2
    # then a larger distance that fades once the display is dark
    k10, k100 = a.at(T_ON + 10.0), a.at(T_ON + 100.0)
    assert a.gap[k10] > base.gap[k10] + 5.0
    assert time_gap(a)[k10] > time_gap(base)[k10] + 0.3
    assert a.gap[k100] - base.gap[k100] < 0.5 * (a.gap[k10] - base.gap[k10])
    assert np.nanmin(a.gap) > 15.0  # braking never endangers anyone here


def test_system_a_no_response_when_the_driver_ignores_it():
    base = run(scripted("daily_commuter"))
    a = run(scripted("daily_commuter", a_brake_prob=0.0), a_lit=lit_for(3.0))
    assert np.array_equal(a.throttle, base.throttle) and np.array_equal(a.brake, base.brake)


def test_system_a_held_display_keeps_the_distance_and_refractory_limits_pulses():
    drv = scripted("daily_commuter", a_brake_prob=1.0, a_refractory_s=6.0)
    # lit for 40 s: the gap addition is held, not decayed
    held = run(drv, t_end=90.0, a_lit=lit_for(40.0))
    adds = [d.a_gap_add_s for d in held.debug]
    assert adds[held.at(T_ON + 39.0)] == pytest.approx(drv.profile.a_gap_increase_s)
    # blinking every 2 s: one braking pulse per refractory period
    drv.reset()
    blink = run(drv, t_end=60.0, a_lit=lambda t: t >= T_ON and int((t - T_ON) / 1.0) % 2 == 0)
    starts = np.flatnonzero(np.diff(np.array([d.a_braking for d in blink.debug], dtype=int)) == 1)
    gaps_s = np.diff(blink.t[starts])
    assert len(starts) >= 2 and gaps_s.min() >= drv.profile.a_refractory_s - 1e-9
    assert blink.debug[-1].a_gap_add_s <= drv.profile.a_gap_max_s


@pytest.mark.parametrize("name", ["daily_commuter", "aggressive"])
def test_system_b_display_makes_the_gap_grow_gradually_toward_the_target(name):
    drv = scripted(name)
    p = drv.profile
    goal = p.desired_time_gap_s + p.b_compliance * (p.b_target_gap_s - p.desired_time_gap_s)
    base = run(scripted(name))
    b = run(drv, b_level="advisory")
    tg, k0 = time_gap(b), b.at(T_ON)
    assert tg[k0] < goal - 0.2  # started closer than the goal
    k_end = b.at(T_ON + 100.0)
    assert tg[k_end] == pytest.approx(goal, abs=0.05)  # reached the goal
    assert time_gap(base)[k_end] == pytest.approx(tg[k0], abs=0.01)  # the baseline did not move
    # gradual: half-way only after several seconds, gentle decelerations, nearly monotonic rise
    frac = (tg[k0:] - tg[k0]) / (goal - tg[k0])
    t_half = b.t[k0 + np.argmax(frac > 0.5)] - T_ON
    assert t_half > 5.0
    assert b.a[k0:].min() > -0.5
    rise = tg[b.at(T_ON + 30.0)] - tg[k0]
    assert rise > 0.6 * (goal - tg[k0])


def test_system_b_warning_level_adapts_faster_than_advisory_and_plain_display():
    t_half = {}
    for level in ("none", "advisory", "warning"):
        b = run(scripted("daily_commuter"), t_end=240.0, b_level=level)
        tg, k0 = time_gap(b), b.at(T_ON)
        goal = tg[-1] if level != "none" else 1.84
        frac = (tg[k0:] - tg[k0]) / (1.84 - tg[k0])
        assert goal == pytest.approx(1.84, abs=0.05)
        t_half[level] = b.t[k0 + np.argmax(frac > 0.5)] - T_ON
    assert t_half["warning"] < t_half["advisory"] < t_half["none"]
    assert t_half["advisory"] > 1.5 * t_half["warning"]


def test_system_b_no_data_and_far_gaps_change_nothing():
    base = run(scripted("daily_commuter"))
    no_data = run(scripted("daily_commuter"), b_level="none", b_data=False)
    assert np.array_equal(no_data.throttle, base.throttle)
    # a driver already above the goal is not pulled closer by the display (no display-induced tailgating)
    occ_base = run(scripted("occasional_driver", desired_time_gap_s=2.2))
    occ = run(scripted("occasional_driver", desired_time_gap_s=2.2), b_level="advisory")
    assert np.allclose(occ.gap, occ_base.gap)


def test_b_addition_fades_when_the_display_goes_dark():
    drv = scripted("daily_commuter")
    leader = Leader(21.0, V_LEAD)

    def extras(t, s, v):
        if T_ON <= t < T_ON + 60.0:
            return dict(sys_b_gap_s=(leader.s_rear - s) / max(v, 0.1), sys_b_level="advisory")
        return {}

    tr = simulate(
        drv, Route.straight(), 220.0, v0_mps=V_LEAD, leader=leader, speed_limit_mps=22.0, extras=extras
    )
    add_on = tr.debug[tr.at(T_ON + 59.0)].b_gap_add_s
    add_later = tr.debug[tr.at(T_ON + 60.0 + 60.0 + drv.profile.reaction_time_s)].b_gap_add_s
    assert add_on > 0.3
    assert add_later == pytest.approx(add_on * np.exp(-1.0), rel=0.05)  # b_forget_time_s = 60 s


def test_a_and_b_differ_in_character():
    """A: a sudden deceleration pulse; B: no pulse, a steady drift - the paper's Fig. 4 contrast."""
    a = run(scripted("daily_commuter", a_brake_prob=1.0), a_lit=lit_for(3.0))
    b = run(scripted("daily_commuter"), b_level="warning")
    k0 = a.at(T_ON)
    jerk_a = np.abs(np.diff(a.a[k0:])).max() / 0.1
    jerk_b = np.abs(np.diff(b.a[k0:])).max() / 0.1
    assert a.a[k0:].min() < -2.5 and b.a[k0:].min() > -0.5
    assert jerk_a > 5.0 * jerk_b

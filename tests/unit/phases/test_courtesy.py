"""A priority car lets the participant in after a long wait at a yield line (``CourtesyYield``), with fake
ports: a World and a bridge answering SUMO's right of way from a list the test sets."""

from __future__ import annotations

import math

import pytest

from cosim.phases.courtesy import (
    COURTESY_DECEL_MPS2,
    COURTESY_HOLD_S,
    LINE_SPARE_M,
    STOP_SHORT_M,
    CourtesyYield,
)
from cosim.phases.ego import priority_gap_s
from cosim.world import EGO_ID, World


class FakeBridge:
    def __init__(self):
        self.foes: list[tuple[str, float, float, float, bool]] = []
        self.caps: dict[str, float | None] = {}
        self.ahead: dict[str, tuple[float, float] | None] = {}  # (to its line, through the junction) [m]

    def yield_foes(self, vid, lookahead_m):
        return self.foes

    def junction_ahead(self, vid):
        return self.ahead.get(vid, (1000.0, 10.0))

    def cap_speed(self, vid, speed_mps):
        self.caps[vid] = speed_mps


def _setup(cars: dict[str, tuple[float, float, bool]]):
    """Priority cars: id -> (distance to the conflict [m], speed [m/s], held back)."""
    w, bridge, events = World(capacity=8), FakeBridge(), []
    for vid, (dist, speed, held) in cars.items():
        slot = w.add(vid)
        w.speed_mps[slot] = speed
        bridge.foes.append((vid, 1.0, dist, 0.0, held))
    return w, bridge, events, CourtesyYield(bridge=bridge, step_s=0.1, emit=events.append)


def test_the_nearest_car_that_can_stop_comfortably_is_asked_and_stops_short_of_the_conflict():
    # near: 14 m at 12 m/s needs 28.8 m to stop at 2.5 m/s^2 (it goes first); queued: crawls in a queue;
    # held: stands behind another; far: beyond COURTESY_LOOK_M
    w, bridge, events, courtesy = _setup({
        "near": (14.0, 12.0, False), "queued": (30.0, 0.5, False), "held": (35.0, 3.0, True),
        "chosen": (60.0, 12.0, False), "next": (75.0, 12.0, False), "far": (120.0, 12.0, False),
    })  # fmt: skip
    courtesy.ask(w, EGO_ID, 1.0, 100.0, "J")
    assert courtesy.car == "chosen"
    assert [(e.kind, e.vehicle, e.detail) for e in events] == [
        ("courtesy_yield", "chosen", "stops for the ego at J")
    ]
    # its speed follows a comfortable stop ending STOP_SHORT_M before the conflict
    driven, v = 0.0, 12.0
    slot = w.slot_of["chosen"]
    for _ in range(100):  # 10 s, within COURTESY_HOLD_S
        cap = bridge.caps["chosen"]
        assert cap <= math.sqrt(2.0 * COURTESY_DECEL_MPS2 * max(0.0, 60.0 - STOP_SHORT_M - driven)) + 1e-9
        v = min(v, cap)
        w.speed_mps[slot] = v
        driven += v * 0.1
        w.t_s = round(w.t_s + 0.1, 6)
        courtesy.hold(w, 90.0)
    assert 60.0 - STOP_SHORT_M - 1.5 < driven <= 60.0 - STOP_SHORT_M
    # standing there, it is no foe of the one it stops for; the next car still is ("near" has gone through)
    bridge.foes = [f for f in bridge.foes if f[0] in ("chosen", "next")]
    gap = priority_gap_s(w, bridge, EGO_ID, 1.0, (courtesy.car,))
    assert gap == pytest.approx(75.0 / 12.0)


def test_the_car_is_let_go_once_the_ego_is_past_the_line_or_after_the_hold_time():
    w, bridge, _, courtesy = _setup({"c": (60.0, 10.0, False)})
    courtesy.ask(w, EGO_ID, 1.0, 100.0, "J")
    courtesy.hold(w, 99.0)
    assert courtesy.car == "c" and bridge.caps["c"] is not None
    courtesy.hold(w, 100.5)  # the ego's front is past the line
    assert courtesy.car is None and bridge.caps["c"] is None
    courtesy.ask(w, EGO_ID, 1.0, 100.0, "J")
    assert courtesy.car is None  # once per line
    courtesy.ask(w, EGO_ID, 1.0, 250.0, "K")
    assert courtesy.car == "c"
    w.t_s = COURTESY_HOLD_S
    courtesy.hold(w, 0.0)
    assert courtesy.car is None and bridge.caps["c"] is None


def test_nobody_is_asked_when_no_car_can_stop_comfortably():
    w, _, events, courtesy = _setup({"near": (20.0, 14.0, False)})
    courtesy.ask(w, EGO_ID, 1.0, 100.0, "J")
    assert courtesy.car is None and events == []


def test_a_car_asked_stops_at_its_line_when_the_spot_is_in_the_junction_and_one_inside_is_not_asked():
    """A wide junction: 6 m before the conflict is 11 m past the car's line, inside the junction, where it
    would stand in the way of the other priority movements (Beatty, US-95)."""
    w, bridge, events, courtesy = _setup({"inside": (30.0, 8.0, False), "wide": (60.0, 12.0, False)})
    bridge.ahead = {"inside": None, "wide": (60.0 - 17.0, 20.0)}  # line 17 m before the conflict
    courtesy.ask(w, EGO_ID, 1.0, 100.0, "J")
    assert courtesy.car == "wide"
    # it stops at its line: 43 m less the spare, less the 1.2 m it drives in the step it is asked in
    to_line = 43.0 - LINE_SPARE_M - 12.0 * 0.1
    assert bridge.caps["wide"] == pytest.approx(math.sqrt(2.0 * COURTESY_DECEL_MPS2 * to_line))


def test_the_car_is_held_until_the_ego_is_through_the_junction_not_only_past_its_line():
    """Let go as the ego's front passed the line, the car pulled out into the ego turning left in the
    junction behind the lead (Krems 327615515, make experiment P3 system_B): it stands until the ego's rear
    is past the junction's end on its path."""
    w, bridge, _, courtesy = _setup({"c": (60.0, 10.0, False)})
    courtesy.ask(w, EGO_ID, 1.0, 100.0, "J", 112.0)  # the path leaves the junction 12 m past the line
    courtesy.hold(w, 105.0, 4.5)  # front in the junction
    assert courtesy.car == "c"
    courtesy.hold(w, 115.0, 4.5)  # front out, rear still in it
    assert courtesy.car == "c" and bridge.caps["c"] is not None
    courtesy.hold(w, 116.6, 4.5)  # through
    assert courtesy.car is None and bridge.caps["c"] is None

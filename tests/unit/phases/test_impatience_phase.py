"""Queue heads keep growing impatient while they creep (cosim.phases.impatience; no SUMO: a fake bridge).
In SUMO itself: tests/integration/test_queue_head_impatience.py."""

from __future__ import annotations

import pytest

from cosim.phases.impatience import HEAD_M, MIN_WAIT_S, QueueHeadImpatience
from cosim.world import EGO_ID, World

STEP_S = 0.1
TTI_S = 60.0


class FakeBridge:
    """One straight lane "in_0" along +x ending at x = 100 (its stop line); "out" beyond the junction."""

    def __init__(self):
        self.set: dict[str, list[float]] = {}

    def lane_end(self, edge_id, lane_index):
        return (100.0, 0.0)

    def set_impatience(self, vid, impatience):
        self.set.setdefault(vid, []).append(impatience)


def _world(cars: dict[str, float]) -> World:
    w = World(capacity=4)
    for vid in cars:
        s = w.add(vid, is_ego=vid == EGO_ID)
        w.edge_code[s] = w.intern_edge("in")
        w.lane_index[s] = 0
    return w


def _step(w: World, phase: QueueHeadImpatience, cars: dict[str, tuple[float, float]], edge: str = "in"):
    """Advance the snapshot one step: each car at (x [m], speed [m/s]) on ``edge``."""
    w.step += 1
    w.t_s = w.step * STEP_S
    for vid, (x, v) in cars.items():
        s = w.slot_of[vid]
        w.x_m[s], w.y_m[s], w.speed_mps[s] = x, 0.0, v
        w.edge_code[s] = w.intern_edge(edge)
    phase.step(w)


def test_a_head_that_creeps_grows_impatient_as_if_it_had_stood():
    bridge = FakeBridge()
    phase = QueueHeadImpatience(bridge, time_to_impatience_s=TTI_S, step_s=STEP_S)
    cars = {"head": 99.0, "second": 91.0, EGO_ID: 99.0}
    w = _world(cars)
    # 40 s at the stop line; every 3 s the head rolls 2 cm at 0.2 m/s (SUMO's own waiting time restarts)
    creeps = []
    for k in range(400):
        creep = k % 30 == 0
        _step(w, phase, {"head": (99.0 + 0.02 * (k // 30), 0.2 if creep else 0.0), "second": (91.0, 0.0),
                         EGO_ID: (99.0, 0.0)})  # fmt: skip
        if creep and k * STEP_S >= MIN_WAIT_S:
            creeps.append(k * STEP_S)
    got = bridge.set["head"]
    # handed over once the wait reaches MIN_WAIT_S, then again after each creep (SUMO cleared it), each
    # time the whole wait so far, not the seconds since the last creep
    assert got[0] == pytest.approx(MIN_WAIT_S / TTI_S, abs=0.01)
    assert got[1:] == pytest.approx([t / TTI_S for t in creeps], abs=0.01)
    # the car behind it is not at the stop line, and the participant's twin is never SUMO's to hurry
    assert "second" not in bridge.set and EGO_ID not in bridge.set
    assert 91.0 < 100.0 - HEAD_M


def test_the_clock_stops_when_the_car_drives_off_or_enters_the_junction():
    bridge = FakeBridge()
    phase = QueueHeadImpatience(bridge, time_to_impatience_s=TTI_S, step_s=STEP_S)
    w = _world({"a": 99.0})
    for _ in range(100):  # 10 s standing: handed over once, SUMO's clock runs on with it
        _step(w, phase, {"a": (99.0, 0.0)})
    n = len(bridge.set["a"])
    assert n == 1
    _step(w, phase, {"a": (99.2, 2.0)})  # drives off: no call, the clock restarts
    _step(w, phase, {"a": (99.0, 0.0)})
    assert len(bridge.set["a"]) == n
    for _ in range(30):  # on the junction's internal lane: no yield line ahead on it
        _step(w, phase, {"a": (101.0, 0.0)}, edge=":j_0")
    for _ in range(int(MIN_WAIT_S / STEP_S) - 2):  # back at a stop line: the clock starts from 0
        _step(w, phase, {"a": (99.0, 0.0)})
    assert len(bridge.set["a"]) == n
    for _ in range(5):
        _step(w, phase, {"a": (99.0, 0.0)})
    assert len(bridge.set["a"]) > n and bridge.set["a"][n] == pytest.approx(MIN_WAIT_S / TTI_S, abs=0.01)


def test_impatience_is_capped_at_one():
    bridge = FakeBridge()
    phase = QueueHeadImpatience(bridge, time_to_impatience_s=10.0, step_s=STEP_S)
    w = _world({"a": 99.0})
    for k in range(300):  # creeping every 10 s
        _step(w, phase, {"a": (99.0, 0.2 if k % 100 == 99 else 0.0)})
    assert bridge.set["a"][-1] == 1.0

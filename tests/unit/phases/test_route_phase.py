"""The ego's route: its extension on a ring road and its way round a stalled queue on a small grid of fake
edges, with a fake router and fake queues (no SUMO)."""

from __future__ import annotations

import math

import pytest

from cosim.phases import route as route_phase
from cosim.phases.route import (
    COMMIT_M,
    EXTEND_AHEAD_M,
    REPLAN_EVERY_S,
    RETRY_S,
    STALL_HEADWAY_S,
    STALL_WAIT_S,
    EgoRoute,
)
from cosim.seeds import stream
from cosim.world import LEAD_ID, World

N = 8  # an octagon: every turn 45 deg, never a hairpin


class Node:
    def __init__(self, nid: str):
        self.nid = nid

    def getID(self):
        return self.nid


class FakeEdge:
    """A straight one-way road from ``a`` to ``b`` at 10 m/s; its junction is named by where it ends."""

    def __init__(self, eid: str, a: tuple[float, float], b: tuple[float, float]):
        self.eid, self._shape, self.outgoing = eid, [a, b], []

    def getID(self):
        return self.eid

    def getLength(self):
        return math.dist(*self._shape)

    def getSpeed(self):
        return 10.0

    def getType(self):
        return "highway.residential"

    def getShape(self):
        return self._shape

    def getToNode(self):
        return Node(f"{self._shape[1][0]:g},{self._shape[1][1]:g}")

    def getOutgoing(self):
        return {e: [] for e in self.outgoing}


def _corner(k: int) -> tuple[float, float]:
    a = 2 * math.pi * k / N
    return 500 * math.cos(a), 500 * math.sin(a)


EDGES = [FakeEdge(f"e{k}", _corner(k), _corner(k + 1)) for k in range(N)]
for _k, _e in enumerate(EDGES):
    _e.outgoing.append(EDGES[(_k + 1) % N])


class FakeBridge:
    """SUMO's router on the ring (the way round to the destination) and the lead's route in SUMO."""

    def __init__(self, accept: bool = True, routable: bool = True):
        self.accept, self.routable = accept, routable
        self.asked: list[tuple[str, str]] = []
        self.lead_routes: list[list[str]] = []

    def find_route(self, origin: str, destination: str) -> list[str]:
        self.asked.append((origin, destination))
        if not self.routable:
            return []
        i, j = int(origin[1:]), int(destination[1:])
        return [f"e{(i + n) % N}" for n in range((j - i) % N + 1)]

    def route_edge_left(self, vid: str) -> tuple[str, float]:
        return "e0", 0.0

    def queue_heads(self, edge: str, next_edge: str) -> list[tuple[int, float]]:
        return []  # the ring never jams

    def extend_route(self, vid: str, edges: list[str]) -> bool:
        assert vid == LEAD_ID
        if self.accept:
            self.lead_routes.append(list(edges))
        return self.accept


def _route(bridge, lead=True, world=None):
    events = []
    calls = []

    def drivable():
        calls.append(1)
        return EDGES

    r = EgoRoute(["e0", "e1"], rng=stream(1, "route"), drivable_edges=drivable, bridge=bridge,
                 world=world or World(capacity=4), emit=events.append, lead=lead)  # fmt: skip
    return r, events, calls


def test_a_leg_is_appended_only_when_the_road_ahead_runs_short_and_the_lead_gets_it():
    bridge = FakeBridge()
    w = World(capacity=4)
    w.add(LEAD_ID)
    r, events, calls = _route(bridge, world=w)
    assert not r.step(EXTEND_AHEAD_M + 1.0) and not calls  # the network is not even looked at
    assert r.update(100.0, 0, 10.0) == 2  # the ego's controller calls it by this name: the first new index
    assert len(calls) == 1 and r.extensions == 1 and len(r.edges) >= 4
    new = r.edges[2:]
    assert all(int(b[1:]) == (int(a[1:]) + 1) % N for a, b in zip(r.edges, r.edges[1:], strict=False))
    assert [e.kind for e in events] == ["route_extended"] and events[0].detail.endswith(new[-1])
    assert bridge.lead_routes == [new]
    r.step(100.0)
    assert len(calls) == 1  # the chainer is built once


def test_without_a_leg_it_waits_and_a_lead_not_yet_in_gets_the_edges_later():
    bridge = FakeBridge(routable=False)
    w = World(capacity=4)
    r, events, _ = _route(bridge, world=w)
    assert not r.step(100.0) and [e.kind for e in events] == ["route_not_extended"]
    w.t_s = RETRY_S - 0.1
    asked = len(bridge.asked)
    assert not r.step(100.0) and len(bridge.asked) == asked  # no new try before RETRY_S
    bridge.routable = True
    w.t_s = RETRY_S
    assert r.step(100.0)
    assert bridge.lead_routes == []  # the lead has not departed: its edges wait
    w.add(LEAD_ID)
    r.step(EXTEND_AHEAD_M + 1.0)
    assert bridge.lead_routes == [r.edges[2:]]
    r.close()


def test_without_a_lead_only_the_egos_route_grows():
    bridge = FakeBridge()
    r, _, _ = _route(bridge, lead=False)
    assert r.step(0.0) and bridge.lead_routes == []


# --- a way round a stalled queue -----------------------------------------------------------------------------
# e0 -> e1 -> e2 -> e3 -> e4 along the x axis; from the end of e1 a way round e2: x1 north, x2 east, x3 south
# back to the start of e3 (turns of 90 deg, never a hairpin).
def _grid():
    pts = {"e0": ((0, 0), (200, 0)), "e1": ((200, 0), (300, 0)), "e2": ((300, 0), (400, 0)),
           "e3": ((400, 0), (800, 0)), "e4": ((800, 0), (1200, 0)), "x1": ((300, 0), (300, 100)),
           "x2": ((300, 100), (400, 100)), "x3": ((400, 100), (400, 0))}  # fmt: skip
    edges = {k: FakeEdge(k, *v) for k, v in pts.items()}
    for a, b in [("e0", "e1"), ("e1", "e2"), ("e2", "e3"), ("e3", "e4"), ("e1", "x1"), ("x1", "x2"),
                 ("x2", "x3"), ("x3", "e3")]:  # fmt: skip
        edges[a].outgoing.append(edges[b])
    return list(edges.values())


ROUND = ["e1", "x1", "x2", "x3", "e3"]


class JamBridge:
    """SUMO as the replanning sees it: the lead's place, the queues, a router that goes round e2 once e2 is
    weighed, and the lead's route."""

    def __init__(self, lead_edge="e0", lead_left_m=50.0, queues=None, accept=True):
        self.lead_edge, self.lead_left_m = lead_edge, lead_left_m
        self.queues = queues if queues is not None else {"e2": [(5, 80.0)]}
        self.accept = accept
        self.weights: dict[str, float] = {}
        self.asked: list[tuple[str, str]] = []
        self.replaced: list[tuple[str, list[str]]] = []
        self.heads_asked = 0
        self.ahead: list[tuple[str, str | None]] = []  # the cars ahead of the lead in its lane, front first
        self.own_lane = (0, 0.0)  # halting in the lead's lane, its front car's wait [s]
        self.lane_ok = True  # the lead's lane leads onto the way round
        self.diverted: list[tuple[str, set[str], bool]] = []

    def route_edge_left(self, vid):
        assert vid == LEAD_ID
        return self.lead_edge, self.lead_left_m

    def queue_heads(self, edge, next_edge):
        self.heads_asked += 1
        return self.queues.get(edge, [(0, 0.0)])

    def weigh_edges(self, travel_time_s, hold_s):
        assert hold_s > 0
        self.weights.update(travel_time_s)

    def find_route(self, origin, destination):
        self.asked.append((origin, destination))
        straight = ["e0", "e1", "e2", "e3", "e4"]
        if "x2" in self.weights and (origin, destination) == ("e1", "e3"):  # a queue on the way round too
            return ["e1", "e2", "e3"]
        if "e2" in self.weights and destination == "e3":
            return straight[straight.index(origin) : 1] + ROUND if origin == "e0" else ROUND
        return straight[straight.index(origin) : straight.index(destination) + 1]

    def replace_route(self, vid, edges):
        self.replaced.append((vid, list(edges)))
        return self.accept

    def extend_route(self, vid, edges):
        return True

    def lane_queue(self, vid):
        return self.own_lane

    def queue_ahead(self, vid):
        return self.ahead

    def lane_leads_to(self, vid, edge):
        assert edge == "x1"  # the way round's first edge
        return self.lane_ok

    def divert(self, vid, keep_off, min_ahead_m, continue_m=300.0, from_its_lane=False):
        self.diverted.append((vid, set(keep_off), from_its_lane))
        return None if vid == "stuck" else "y1"


def _jam_route(bridge, lead=True, t_s=REPLAN_EVERY_S):
    w = World(capacity=4)
    w.t_s = t_s
    if lead:
        w.add(LEAD_ID)
    events = []
    r = EgoRoute(["e0", "e1", "e2", "e3", "e4"], rng=stream(1, "route"), drivable_edges=_grid, bridge=bridge,
                 world=w, emit=events.append, lead=lead)  # fmt: skip
    return r, events


def test_the_lead_takes_a_way_round_a_stalled_queue_and_gets_the_new_route_in_sumo():
    bridge = JamBridge()
    r, events = _jam_route(bridge)
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 10.0) == 2  # the first route index whose edge changed
    assert r.edges == ["e0", *ROUND, "e4"]
    assert bridge.asked == [("e1", "e3")]  # 50 m left on e0 (< COMMIT_M): the route is left at the end of e1
    assert bridge.weights == {"e2": pytest.approx(10.0 + 5 * STALL_HEADWAY_S)}  # the router sees the queue
    assert bridge.replaced == [(LEAD_ID, r.edges)]  # from the lead's own edge on
    (ev,) = events
    assert ev.kind == "route_replanned" and ev.vehicle == LEAD_ID and "e2" in ev.detail
    assert ev.value == pytest.approx((10 + 150 + 40) - (10 + 10 + 10 + 40))  # the time it saves [s]
    assert r.replans == 1


def test_with_room_to_turn_the_lead_leaves_the_route_at_the_end_of_its_own_edge():
    bridge = JamBridge(lead_left_m=COMMIT_M + 1.0)
    r, _ = _jam_route(bridge)
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 10.0) == 1
    assert bridge.asked == [("e0", "e3")] and r.edges == ["e0", *ROUND, "e4"]


@pytest.mark.parametrize(
    "queues",
    [
        {"e2": [(5, STALL_WAIT_S - 15.0)]},  # a queue at a red light: its front car waits less than a red
        {"e2": [(1, 90.0)]},  # one car waiting is no queue
        {"e2": [(5, 90.0), (0, 0.0)]},  # the other lane onward flows
        {},  # nothing stalled
    ],
)
def test_a_queue_that_moves_is_driven_through(queues):
    bridge = JamBridge(queues=queues)
    r, events = _jam_route(bridge)
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 10.0) is None
    assert r.edges == ["e0", "e1", "e2", "e3", "e4"] and not events and not bridge.replaced


def test_the_route_stays_when_sumo_refuses_the_lead_or_the_way_round_saves_too_little(monkeypatch):
    bridge = JamBridge(accept=False)
    r, events = _jam_route(bridge)
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 10.0) is None
    assert r.edges == ["e0", "e1", "e2", "e3", "e4"] and not events
    monkeypatch.setattr(route_phase, "REPLAN_GAIN_S", 200.0)  # the way round saves 130 s
    bridge = JamBridge()
    r, events = _jam_route(bridge)
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 10.0) is None and not bridge.replaced and not events


def test_it_looks_only_every_replan_interval_and_without_a_lead_the_ego_leads():
    bridge = JamBridge()
    r, _ = _jam_route(bridge, t_s=REPLAN_EVERY_S - 0.1)
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 10.0) is None and bridge.heads_asked == 0
    bridge = JamBridge()
    r, events = _jam_route(bridge, lead=False)
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 50.0) == 2  # the ego's own edge and metres left on it
    assert r.edges == ["e0", *ROUND, "e4"] and not bridge.replaced and events[0].vehicle == "ego"


def test_a_queue_gone_round_is_remembered_so_the_pair_does_not_turn_back_into_it():
    bridge = JamBridge()
    r, events = _jam_route(bridge)
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 10.0) == 2
    # 5 s on a shorter queue stalls on the way round; SUMO's router, still holding e2's cost, says back
    bridge.queues = {"x2": [(3, 80.0)]}
    r.world.t_s += REPLAN_EVERY_S
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 10.0) is None  # e2's 150 s against x2's 90 s: it stays
    assert r.edges == ["e0", *ROUND, "e4"] and len(events) == 1
    r.world.t_s += route_phase.JAM_HOLD_S  # e2 long forgotten: only x2's queue counts
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 10.0) == 2
    assert r.edges == ["e0", "e1", "e2", "e3", "e4"]


def test_no_way_round_that_loops_back_through_a_junction_it_passes():
    bridge = JamBridge()
    r, events = _jam_route(bridge)
    r.chainer.to_node["x2"] = r.chainer.to_node["e0"]  # as if x2 ended where e0 does, before the way round
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 10.0) is None
    assert r.edges == ["e0", "e1", "e2", "e3", "e4"] and not events and not bridge.replaced


def test_a_loop_the_route_already_makes_does_not_stop_a_way_round():
    bridge = JamBridge()
    r, events = _jam_route(bridge)
    r.chainer.to_node["e4"] = r.chainer.to_node["e1"]  # the route comes back to e1's end junction after e4
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 10.0) == 2
    assert r.edges == ["e0", *ROUND, "e4"] and events[0].kind == "route_replanned"


def test_standing_before_the_stalled_edge_the_pair_leaves_from_its_lane_and_the_cars_ahead_turn_off_first():
    bridge = JamBridge(lead_edge="e1", lead_left_m=10.0)  # e2 next: too near to change lanes for another turn
    bridge.ahead = [("scv1", "e2"), ("scv2", "e3"), ("stuck", "e2")]
    r, events = _jam_route(bridge)
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 60.0) == 2
    assert bridge.asked == [("e1", "e3")] and r.edges == ["e0", *ROUND, "e4"]
    assert bridge.replaced == [(LEAD_ID, r.edges[1:])]
    # those bound for the stalled edge turn off from the lane they stand in; scv2 goes elsewhere anyway
    assert bridge.diverted == [("scv1", {"e2"}, True), ("stuck", {"e2"}, True)]
    assert [(e.kind, e.vehicle) for e in events] == [("jam_diverted", "scv1"), ("route_replanned", LEAD_ID)]


def test_standing_before_the_stalled_edge_in_a_lane_that_does_not_lead_round_the_pair_stays():
    bridge = JamBridge(lead_edge="e1", lead_left_m=10.0)
    bridge.lane_ok = False
    bridge.ahead = [("scv1", "e2")]
    r, events = _jam_route(bridge)
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 60.0) is None
    assert r.edges == ["e0", "e1", "e2", "e3", "e4"] and not events and not bridge.diverted
    assert not bridge.replaced


def _look_until(r, bridge, t_s: float, creep_m: float = 0.0):
    """Let the route look every REPLAN_EVERY_S until ``t_s``, the lead ``creep_m`` nearer its edge's end
    each time; returns what the last look changed."""
    while r.world.t_s < t_s:
        changed = r.update(EXTEND_AHEAD_M + 1.0, 0, 60.0)
        if changed is not None:
            return changed
        r.world.t_s += REPLAN_EVERY_S
        bridge.lead_left_m = max(0.0, bridge.lead_left_m - creep_m)
    return r.update(EXTEND_AHEAD_M + 1.0, 0, 60.0)


def test_standing_in_a_stalled_queue_in_its_own_lane_the_pair_takes_another_turn():
    # the next road flows on another lane, but the lead's lane turns onto its stalled one: nothing on e2 is
    # stalled as a whole, the queue the lead stands in is
    bridge = JamBridge(lead_edge="e1", lead_left_m=10.0, queues={})
    bridge.own_lane = (4, STALL_WAIT_S + 5.0)
    bridge.ahead = [("scv1", "e2")]
    r, events = _jam_route(bridge)
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 60.0) is None  # the lead has stood there for no time yet
    r.world.t_s += REPLAN_EVERY_S
    assert _look_until(r, bridge, 2 * REPLAN_EVERY_S + STALL_WAIT_S) == 2  # ... and now for STALL_WAIT_S
    assert r.edges == ["e0", *ROUND, "e4"] and bridge.weights == {
        "e2": pytest.approx(10.0 + 4 * STALL_HEADWAY_S)
    }
    assert bridge.diverted == [("scv1", {"e2"}, True)]
    # a queue in its lane whose front car has waited less than a red lasts: it waits
    bridge = JamBridge(lead_edge="e1", lead_left_m=10.0, queues={})
    bridge.own_lane = (4, STALL_WAIT_S - 15.0)
    bridge.ahead = [("scv1", "e2")]
    r, events = _jam_route(bridge)
    assert r.update(EXTEND_AHEAD_M + 1.0, 0, 60.0) is None and not events


@pytest.mark.parametrize(
    "ahead", [[], [("scv1", "x1")]], ids=["the lead heads it", "the front car turns elsewhere"]
)
def test_a_long_wait_in_its_own_lane_is_no_stalled_turn_unless_a_car_bound_the_same_way_heads_it(ahead):
    bridge = JamBridge(lead_edge="e1", lead_left_m=10.0, queues={})
    bridge.own_lane = (4, STALL_WAIT_S + 5.0)  # the lead waiting for the ego or a gap, or behind another turn
    bridge.ahead = ahead
    r, events = _jam_route(bridge)
    assert _look_until(r, bridge, 3 * STALL_WAIT_S) is None and not events and not bridge.diverted


def test_a_queue_it_creeps_through_is_no_stalled_turn():
    # the front car has waited long in a queue that drains slowly at a line, the pair creeping on
    bridge = JamBridge(lead_edge="e1", lead_left_m=99.0, queues={})
    bridge.own_lane = (4, STALL_WAIT_S + 5.0)
    bridge.ahead = [("scv1", "e2")]
    r, events = _jam_route(bridge)
    creep = 1.5 * route_phase.STALL_PROGRESS_M * REPLAN_EVERY_S / STALL_WAIT_S  # 11 m a minute
    assert _look_until(r, bridge, 3 * STALL_WAIT_S, creep_m=creep) is None and not events

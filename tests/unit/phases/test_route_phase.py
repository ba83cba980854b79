"""The ego's route extension with fake ports: a ring road of fake edges, a fake router (no SUMO)."""

from __future__ import annotations

import math

from cosim.phases.route import EXTEND_AHEAD_M, RETRY_S, EgoRoute
from cosim.seeds import stream
from cosim.world import LEAD_ID, World

N = 8  # an octagon: every turn 45 deg, never a hairpin


class FakeEdge:
    def __init__(self, k: int):
        self.k = k
        a, b = 2 * math.pi * k / N, 2 * math.pi * (k + 1) / N
        self._shape = [(500 * math.cos(a), 500 * math.sin(a)), (500 * math.cos(b), 500 * math.sin(b))]
        self.next: FakeEdge | None = None

    def getID(self):
        return f"e{self.k}"

    def getLength(self):
        return math.dist(*self._shape)

    def getShape(self):
        return self._shape

    def getOutgoing(self):
        return {self.next: []}


EDGES = [FakeEdge(k) for k in range(N)]
for _k, _e in enumerate(EDGES):
    _e.next = EDGES[(_k + 1) % N]


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
    assert r.extend_if_short(100.0)  # the ego's controller calls it by this name
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

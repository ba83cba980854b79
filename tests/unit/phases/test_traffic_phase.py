"""The around-the-ego traffic generator with fake ports: a hand-made road, a fake bridge, a World filled by
the test (no SUMO, no MuJoCo)."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.phases.traffic import PENDING_TIMEOUT_S, REMOVE_MARGIN_M, START_CLEAR_M, TrafficAroundEgo
from cosim.scenario.demand import DemandParams
from cosim.seeds import stream
from cosim.world import EGO_ID, World


class FakeLane:
    def allows(self, vclass: str) -> bool:
        return vclass == "passenger"


class FakeEdge:
    """The getters the generator reads of a network edge (the read-only network view's)."""

    def __init__(self, eid: str, shape: list[tuple[float, float]], lanes: int = 2):
        self._id, self._shape, self._lanes = eid, shape, [FakeLane() for _ in range(lanes)]

    def getID(self):
        return self._id

    def getShape(self):
        return self._shape

    def getLanes(self):
        return self._lanes

    def getLength(self):
        return float(np.hypot(*np.diff(np.asarray(self._shape), axis=0).T).sum())

    def getType(self):
        return "highway.primary"


class FakeBridge:
    def __init__(self):
        self.added: list[tuple[str, str, float]] = []
        self.removed: list[str] = []

    def add_scv(self, vid: str, route_id: str, depart_pos_m: float) -> None:
        self.added.append((vid, route_id, float(depart_pos_m)))

    def remove_vehicle(self, vid: str) -> None:
        self.removed.append(vid)


EDGES = [FakeEdge("east", [(0.0, 0.0), (2000.0, 0.0)]), FakeEdge("west", [(2000.0, 10.0), (0.0, 10.0)])]


@pytest.fixture
def routes(tmp_path):
    f = tmp_path / "routes.rou.xml"
    f.write_text('<routes><route id="pool0" edges="east"/><route id="pool1" edges="west"/>'
                 '<route id="other" edges="east"/></routes>')  # fmt: skip
    return f


def _generator(routes, seed: int = 1):
    params = DemandParams(area="around_ego", vehicles_per_lane_km=20.0, radius_m=500.0, spawn_min_m=200.0)
    bridge = FakeBridge()
    gen = TrafficAroundEgo(params, EDGES, routes, start_xy=(100.0, 0.0), rng=stream(seed, "traffic"), step_s=0.1,
                           bridge=bridge)  # fmt: skip
    return gen, bridge


def _world_with_ego(x: float, speed: float) -> World:
    w = World(capacity=64)
    slot = w.add(EGO_ID, is_ego=True)
    w.x_m[slot], w.y_m[slot], w.heading_deg[slot], w.speed_mps[slot] = x, 0.0, 90.0, speed  # east
    return w


def test_the_first_fill_covers_the_disc_but_the_start_and_uses_only_pool_routes(routes):
    gen, bridge = _generator(routes)
    w = World(capacity=64)  # the ego has not departed yet: the disc is centred on its start
    w.step = 1
    gen.step(w)
    target = gen.target(100.0, 0.0)
    # every spot's surroundings at most at the target density: a little short of the target in all
    assert target > 10 and 0.8 * target <= len(bridge.added) == gen.generated <= target
    assert {r for _, r, _ in bridge.added} <= {"pool0", "pool1"}
    for _, route, pos in bridge.added:  # east runs along +x from 0 (y 0), west along -x from 2000 (y 10)
        x, y = (pos, 0.0) if route == "pool0" else (2000.0 - pos, 10.0)
        assert START_CLEAR_M < np.hypot(x - 100.0, y) <= 500.0
    assert len({(r, p) for _, r, p in bridge.added}) == len(bridge.added)  # one car per spot
    assert bridge.removed == []


def test_the_first_fill_keeps_the_streets_it_fills_at_the_target_density(tmp_path):
    """Cars start only on the pool's origin streets, while the target counts every lane-km of the disc:
    filling the target at once put 54 cars on the 70 spots of Krems' start (five times the target density
    on those streets) and every baseline began in a 300-m queue. Each spot is taken only while its
    surroundings hold less than the target density."""
    f = tmp_path / "routes.rou.xml"
    f.write_text('<routes><route id="pool0" edges="street"/></routes>')
    street = FakeEdge("street", [(0.0, 0.0), (400.0, 0.0)], lanes=1)  # the only origin
    others = [FakeEdge(f"road{i}", [(-500.0, 150.0 + 10 * i), (700.0, 150.0 + 10 * i)]) for i in range(4)]
    params = DemandParams(area="around_ego", vehicles_per_lane_km=7.5, radius_m=500.0, spawn_min_m=200.0)
    bridge = FakeBridge()
    gen = TrafficAroundEgo(params, [street, *others], f, start_xy=(200.0, -300.0), rng=stream(1, "traffic"),
                           step_s=0.1, bridge=bridge)  # fmt: skip
    w = World(capacity=64)
    w.step = 1
    gen.step(w)
    on_street = len(bridge.added)
    assert gen.target(200.0, -300.0) > 20  # enough to take all 20 spots of the street (as it did)
    # 7.5 per lane-km on its 0.4 lane-km, overshot by at most one car in a spot's surroundings
    assert 1 <= on_street <= 2 * 7.5 * 0.4


def test_far_vehicles_and_stale_insertions_are_removed_and_new_ones_start_ahead(routes):
    gen, bridge = _generator(routes)
    w = _world_with_ego(100.0, 10.0)
    w.step = 1
    gen.step(w)
    first = [vid for vid, _, _ in bridge.added]
    # one departed and drove far away; the others never departed
    far = w.add(first[0])
    w.x_m[far], w.y_m[far] = 100.0 + 500.0 + REMOVE_MARGIN_M + 1.0, 0.0
    w.step += round(PENDING_TIMEOUT_S / 0.1) + gen.every  # past the timeout, on an update step
    w.step -= w.step % gen.every
    bridge.added.clear()
    gen.step(w)
    assert set(bridge.removed) == set(first)  # the far one and every stale insertion
    assert gen.removed == len(first)
    # the shortfall comes back ahead of the moving ego (east), in the ring beyond spawn_min_m
    assert bridge.added and gen.generated == len(first) + len(bridge.added)
    for _, route, pos in bridge.added:
        x = pos if route == "pool0" else 2000.0 - pos
        assert 100.0 + 200.0 - 1.0 <= x <= 100.0 + 500.0 + 1.0


def test_between_updates_nothing_happens_and_the_stream_decides_the_spots(routes):
    a, bridge_a = _generator(routes, seed=3)
    b, bridge_b = _generator(routes, seed=3)
    for gen in (a, b):
        w = _world_with_ego(100.0, 10.0)
        w.step = 1
        gen.step(w)
        n = len((bridge_a if gen is a else bridge_b).added)
        w.step = 2  # not an update step (every 1 s)
        gen.step(w)
        assert len((bridge_a if gen is a else bridge_b).added) == n
    assert bridge_a.added == bridge_b.added
    c, bridge_c = _generator(routes, seed=4)
    w = _world_with_ego(100.0, 10.0)
    w.step = 1
    c.step(w)
    assert bridge_c.added != bridge_a.added
    c.close()


def test_a_scenario_without_a_pool_is_refused(tmp_path):
    f = tmp_path / "routes.rou.xml"
    f.write_text('<routes><route id="r" edges="east"/></routes>')
    with pytest.raises(ValueError, match="no route pool"):
        _generator(f)

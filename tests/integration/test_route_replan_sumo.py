"""What the lead's way round a stalled queue (cosim.phases.route) asks of SUMO, in SUMO: the queue read
from the lanes onward, the router's travel times for the queue and how long they hold.

A square of two ways from S to E: the short one through B (the road AB), the long one through N. A car
held standing at the end of AB builds a queue behind it."""

from __future__ import annotations

import pytest
from plain_net import plain_net

from cosim.sumo_bridge.bridge import SumoBridge

STEP_S = 0.1


@pytest.fixture(scope="module")
def square(tmp_path_factory):
    d = tmp_path_factory.mktemp("square")
    nodes = {"S": (-600, 0), "A": (-300, 0), "B": (0, 0), "N": (-300, 300), "M": (0, 300), "E": (300, 0)}
    edges = {"SA": ("S", "A", 3), "AB": ("A", "B", 3), "BE": ("B", "E", 3), "AN": ("A", "N", 2),
             "NM": ("N", "M", 2), "MB": ("M", "B", 2)}  # fmt: skip
    plain_net(d, nodes, edges, priority_nodes=["A", "B", "N", "M"])
    (d / "signs.add.xml").write_text("<additional/>")  # SumoBridge loads the scenario's signs file
    (d / "r.rou.xml").write_text(
        '<routes><route id="r" edges="SA AB BE"/>'
        '<flow id="f" route="r" begin="0" end="60" period="4" departSpeed="max"/></routes>'
    )
    (d / "s.sumocfg").write_text(
        '<configuration><input><net-file value="n.net.xml"/><route-files value="r.rou.xml"/></input>'
        '<processing><time-to-teleport value="-1"/></processing></configuration>'
    )
    return d


def test_a_stalled_queue_is_read_per_lane_onward_and_the_router_goes_round_it_while_its_cost_holds(square):
    bridge = SumoBridge(square / "s.sumocfg", seed=1, step_s=STEP_S)
    sumo = bridge._sumo
    try:
        assert bridge.find_route("SA", "BE") == ["SA", "AB", "BE"]  # the short way at free flow
        held = None
        for _ in range(int(120 / STEP_S)):
            bridge.advance()
            on_ab = sumo.lane.getLastStepVehicleIDs("AB_0")
            if held is None and on_ab and sumo.vehicle.getLanePosition(on_ab[-1]) > 250.0:
                held = on_ab[-1]
                sumo.vehicle.setSpeed(held, 0.0)  # the front car stops: the ones behind queue up
        assert held is not None
        (halting, wait_s), *more = bridge.queue_heads("AB", "BE")
        assert not more and halting >= 5 and wait_s > 60.0  # the front car's wait, in SUMO's memory
        assert bridge.queue_heads("AB", "AN") == []  # no lane of AB leads onto AN
        t0 = sumo.simulation.getTime()
        bridge.weigh_edges({"AB": 600.0}, hold_s=30.0)
        assert bridge.find_route("SA", "BE") == ["SA", "AN", "NM", "MB", "BE"]
        edge, left = bridge.route_edge_left(held)
        assert edge == "AB" and 0.0 < left < 50.0
        while sumo.simulation.getTime() < t0 + 31.0:
            bridge.advance()
        assert bridge.find_route("SA", "BE") == ["SA", "AB", "BE"]  # the queue's cost held 30 s
    finally:
        bridge.close()

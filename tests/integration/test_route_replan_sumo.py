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


def _fork(d, options=()):
    """W to E through A, with a road off to the right (AD) and one to the left (AN) at A; two lanes on WA,
    the right one for AD and E, the left one for N and E."""
    nodes = {"W": (-300, 0), "A": (0, 0), "E": (300, 0), "D": (0, -300), "N": (0, 300)}
    edges = {"WA": ("W", "A", 3, 2), "AE": ("A", "E", 3), "AD": ("A", "D", 2), "AN": ("A", "N", 2)}
    plain_net(d, nodes, edges, options=options)
    (d / "signs.add.xml").write_text("<additional/>")
    (d / "r.rou.xml").write_text(
        '<routes><route id="r" edges="WA AE"/>'
        '<flow id="f" route="r" begin="0" end="30" period="3" departLane="0" departSpeed="max"/></routes>'
    )
    (d / "s.sumocfg").write_text(
        '<configuration><input><net-file value="n.net.xml"/><route-files value="r.rou.xml"/></input>'
        '<processing><time-to-teleport value="-1"/></processing></configuration>'
    )
    return d


@pytest.fixture(scope="module")
def fork(tmp_path_factory):
    return _fork(tmp_path_factory.mktemp("fork"))


@pytest.fixture(scope="module")
def fork_with_light(tmp_path_factory):
    return _fork(tmp_path_factory.mktemp("fork_tls"), options=["--tls.set", "A"])


def _queue_at_a(bridge) -> str:
    """Run the flow with its first car held 75 m before A; returns the held car."""
    sumo, held = bridge._sumo, None
    for _ in range(int(60 / STEP_S)):
        bridge.advance()
        on_wa = sumo.lane.getLastStepVehicleIDs("WA_0")
        if held is None and on_wa and sumo.vehicle.getLanePosition(on_wa[-1]) > 200.0:
            held = on_wa[-1]
            sumo.vehicle.setSpeed(held, 0.0)  # the front car stops: a queue behind it
    return held


def test_a_queue_held_by_a_red_light_has_not_waited_for_a_way_round(fork_with_light):
    bridge = SumoBridge(fork_with_light / "s.sumocfg", seed=1, step_s=STEP_S)
    sumo = bridge._sumo
    try:
        held = _queue_at_a(bridge)
        last = sumo.lane.getLastStepVehicleIDs("WA_0")[0]
        n_links = len(sumo.trafficlight.getRedYellowGreenState("A"))
        sumo.trafficlight.setRedYellowGreenState("A", "r" * n_links)
        bridge.advance()
        assert bridge.lane_queue(last) == (sumo.lane.getLastStepHaltingNumber("WA_0"), 0.0)
        sumo.trafficlight.setRedYellowGreenState("A", "G" * n_links)
        bridge.advance()
        halting, wait_s = bridge.lane_queue(last)  # standing through a green: it waits for something else
        assert (
            halting >= 3
            and wait_s == pytest.approx(sumo.vehicle.getAccumulatedWaitingTime(held))
            and wait_s > 20
        )
    finally:
        bridge.close()


def test_the_cars_queued_ahead_are_read_front_first_and_one_turns_off_only_from_the_lane_it_stands_in(fork):
    bridge = SumoBridge(fork / "s.sumocfg", seed=1, step_s=STEP_S)
    sumo = bridge._sumo
    try:
        held = _queue_at_a(bridge)
        queue = sumo.lane.getLastStepVehicleIDs("WA_0")[::-1]  # front first
        assert held == queue[0] and len(queue) >= 4
        assert bridge.queue_ahead(queue[3]) == [(queue[0], "AE"), (queue[1], "AE"), (queue[2], "AE")]
        assert bridge.queue_ahead(held) == []
        halting, wait_s = bridge.lane_queue(queue[3])
        assert halting == sumo.lane.getLastStepHaltingNumber("WA_0") >= 3
        assert wait_s == pytest.approx(sumo.vehicle.getAccumulatedWaitingTime(held))
        assert wait_s > 20.0  # the front car's, held since it stopped
        assert bridge.lane_leads_to(held, "AD") and not bridge.lane_leads_to(held, "AN")  # AN: the left lane
        assert bridge.divert(held, {"AE"}, 0.0, from_its_lane=True) == "AD"  # right, from the lane it is in
        assert sumo.vehicle.getRoute(held) == ("WA", "AD")
        sumo.vehicle.add("left", "r", departLane="1", departPos="250", departSpeed="0")
        sumo.vehicle.setSpeed("left", 0.0)
        bridge.advance()
        assert sumo.vehicle.getLaneID("left") == "WA_1"
        # from the left lane: straight on is kept off, left is never taken, right is not from this lane
        assert bridge.divert("left", {"AE"}, 0.0, from_its_lane=True) is None
        assert bridge.divert("left", {"AE"}, 0.0) == "AD"  # from any lane of its edge
    finally:
        bridge.close()

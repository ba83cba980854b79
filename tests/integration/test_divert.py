"""SumoBridge.divert: a car is sent off a given way at the first junction far enough ahead, never back."""

from __future__ import annotations

import pytest
from plain_net import plain_net


@pytest.fixture
def crossroads(tmp_path):
    # W -> C -> E -> F is the lead's way; C and E each have a side road north and south
    nodes = {"W": (-300, 0), "C": (0, 0), "E": (300, 0), "F": (600, 0), "N": (0, 300), "S": (0, -300),
             "N2": (300, 300), "S2": (300, -300)}  # fmt: skip
    pairs = ["WC", "CE", "EF", "CN", "NC", "CS", "SC", "EN2", "N2E", "ES2", "S2E", "EC", "CW", "FE"]
    ends = [(p[0], p[1:]) if p[0] in "WCEF" and p[1:] in nodes else (p[:-1], p[-1]) for p in pairs]
    edges = {p: (a, b, 3 if set(p) <= set("WCEF") else 1) for p, (a, b) in zip(pairs, ends, strict=True)}
    return plain_net(tmp_path, nodes, edges)


@pytest.mark.own_process
def test_a_car_is_sent_off_the_way_and_never_back_onto_it(crossroads):
    import libsumo

    from cosim.sumo_bridge.bridge import SumoBridge

    libsumo.start(["sumo", "-n", str(crossroads), "--no-step-log", "true"])
    try:
        # the SUMO handle and the routes it gave: divert needs no more
        bridge = SumoBridge.__new__(SumoBridge)
        bridge._sumo, bridge._route_changes = libsumo, {}
        way = {"WC", "CE", "EF"}
        libsumo.route.add("r", ["WC", "CE", "EF"])
        libsumo.vehicle.add("x", "r", depart="now", departPos="280", departSpeed="0")
        libsumo.simulationStep()
        # the way ahead as far as the lead keeps cars off it: edges that begin within the distance
        assert bridge.route_ahead("x") == ["WC", "CE", "EF"]
        assert bridge.route_ahead("x", within_m=250.0) == ["WC"]  # CE begins ~300 m on from WC's start
        assert bridge.route_ahead("x", within_m=400.0) == ["WC", "CE"]
        # a vehicle gone since the snapshot (the ego's leader of the step) has no leader, rather than an error
        assert bridge.leader("gone") is None
        # 20 m before C: too close to turn there, so it turns off at E, 320 m ahead
        exit_edge = bridge.divert("x", way, min_ahead_m=40.0)
        assert exit_edge in ("EN2", "ES2")
        route = libsumo.vehicle.getRoute("x")
        assert route[:2] == ("WC", "CE") and route[2] == exit_edge
        assert not way & set(route[2:])
        seen = set()
        for _ in range(600):
            libsumo.simulationStep()
            if "x" not in libsumo.vehicle.getIDList():
                break
            seen.add(libsumo.vehicle.getRoadID("x"))
        assert exit_edge in seen and "EF" not in seen
        # never off by a left turn: it would wait in the junction for the oncoming traffic, in front of the
        # participant (at C and E the right-hand roads CS and ES2 count as the way here)
        libsumo.route.add("r3", ["WC", "CE", "EF"])
        libsumo.vehicle.add("z", "r3", depart="now", departPos="10", departSpeed="0")
        libsumo.simulationStep()
        assert bridge.divert("z", way | {"CS", "ES2"}, min_ahead_m=40.0) is None
        assert bridge.divert("z", way | {"CS"}, min_ahead_m=40.0) == "ES2"  # right at E, not left at C
        # a car whose own route leaves the way before any junction could divert it is left alone
        libsumo.route.add("r2", ["WC", "CN"])
        libsumo.vehicle.add("y", "r2", depart="now", departPos="10", departSpeed="0")
        libsumo.simulationStep()
        assert bridge.divert("y", way, min_ahead_m=40.0) is None
        assert libsumo.vehicle.getRoute("y") == ("WC", "CN")
    finally:
        libsumo.close()

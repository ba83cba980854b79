"""SumoBridge.divert: a car is sent off a given way at the first junction far enough ahead, never back."""

from __future__ import annotations

import pytest

from cosim.sumo_bridge.tools import run_tool


@pytest.fixture
def crossroads(tmp_path):
    # W -> C -> E -> F is the lead's way; C and E each have a side road north and south
    nodes = {"W": (-300, 0), "C": (0, 0), "E": (300, 0), "F": (600, 0), "N": (0, 300), "S": (0, -300),
             "N2": (300, 300), "S2": (300, -300)}  # fmt: skip
    (tmp_path / "n.nod.xml").write_text(
        "<nodes>" + "".join(f'<node id="{n}" x="{x}" y="{y}"/>' for n, (x, y) in nodes.items()) + "</nodes>"
    )
    pairs = ["WC", "CE", "EF", "CN", "NC", "CS", "SC", "EN2", "N2E", "ES2", "S2E", "EC", "CW", "FE"]
    edges = [(p, p[0], p[1:]) if p[0] in "WCEF" and p[1:] in nodes else (p, p[:-1], p[-1]) for p in pairs]
    (tmp_path / "n.edg.xml").write_text(
        "<edges>"
        + "".join(
            f'<edge id="{e}" from="{a}" to="{b}" numLanes="1" speed="13.89" priority="{3 if set(e) <= set("WCEF") else 1}"/>'
            for e, a, b in edges
        )
        + "</edges>"
    )
    run = run_tool("netconvert", ["-n", str(tmp_path / "n.nod.xml"), "-e", str(tmp_path / "n.edg.xml"),
                                  "-o", str(tmp_path / "n.net.xml")])  # fmt: skip
    assert run.returncode == 0, run.log
    return tmp_path / "n.net.xml"


@pytest.mark.own_process
def test_a_car_is_sent_off_the_way_and_never_back_onto_it(crossroads):
    import libsumo

    from cosim.sumo_bridge.bridge import SumoBridge

    libsumo.start(["sumo", "-n", str(crossroads), "--no-step-log", "true"])
    try:
        bridge = SumoBridge.__new__(SumoBridge)  # only the SUMO handle: divert needs nothing else
        bridge._sumo = libsumo
        way = {"WC", "CE", "EF"}
        libsumo.route.add("r", ["WC", "CE", "EF"])
        libsumo.vehicle.add("x", "r", depart="now", departPos="280", departSpeed="0")
        libsumo.simulationStep()
        # the way ahead as far as the lead keeps cars off it: edges that begin within the distance
        assert bridge.route_ahead("x") == ["WC", "CE", "EF"]
        assert bridge.route_ahead("x", within_m=250.0) == ["WC"]  # CE begins ~300 m on from WC's start
        assert bridge.route_ahead("x", within_m=400.0) == ["WC", "CE"]
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
        # a car whose own route leaves the way before any junction could divert it is left alone
        libsumo.route.add("r2", ["WC", "CN"])
        libsumo.vehicle.add("y", "r2", depart="now", departPos="10", departSpeed="0")
        libsumo.simulationStep()
        assert bridge.divert("y", way, min_ahead_m=40.0) is None
        assert libsumo.vehicle.getRoute("y") == ("WC", "CN")
    finally:
        libsumo.close()

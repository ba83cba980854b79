"""SumoBridge.yield_foes: the priority vehicles a car must yield to at its next junction, as far as 200 m
upstream (paper IV.B), not only those SUMO lists as approaching."""

from __future__ import annotations

import pytest
from plain_net import plain_net


@pytest.fixture
def t_junction(tmp_path):
    # W -> A -> C -> E is the priority road; S -> C -> N the minor road crossing it; at A a side road X
    # branches off the priority road upstream of C
    nodes = {"W": (-300, 0), "A": (-100, 0), "C": (0, 0), "E": (300, 0), "S": (0, -300), "N": (0, 300),
             "X": (-100, -300)}  # fmt: skip
    edges = {
        e: (e[0], e[1], p) for e, p in (("WA", 3), ("AC", 3), ("CE", 3), ("SC", 1), ("CN", 1), ("AX", 1))
    }
    return plain_net(tmp_path, nodes, edges, priority_nodes=["A", "C"])


@pytest.mark.own_process
def test_a_priority_car_one_road_upstream_is_a_foe_and_one_turning_off_before_is_not(t_junction):
    import libsumo

    from cosim.sumo_bridge.bridge import SumoBridge

    libsumo.start(["sumo", "-n", str(t_junction), "--no-step-log", "true"])
    try:
        bridge = SumoBridge.__new__(SumoBridge)  # only the SUMO handle: yield_foes needs nothing else
        bridge._sumo, bridge._incoming = libsumo, None
        for rid, edges in {"minor": ["SC", "CN"], "main": ["WA", "AC", "CE"], "off": ["WA", "AX"]}.items():
            libsumo.route.add(rid, edges)
        libsumo.vehicle.add("m", "minor", depart="now", departPos="280", departSpeed="0")
        # 150 m before C at 13.89 m/s: 11 s away, one road upstream of the lane into C
        libsumo.vehicle.add("fast", "main", depart="now", departPos="140", departSpeed="13.89")
        # and one that turns off at A before reaching the junction
        libsumo.vehicle.add("off", "off", depart="now", departPos="160", departSpeed="13.89")
        libsumo.simulationStep()
        # SUMO lists only foes that have announced their approach (within about their braking distance)
        assert "fast" not in [f[0] for f in libsumo.vehicle.getJunctionFoes("m", 50.0)]
        foes = {f[0]: f for f in bridge.yield_foes("m", 50.0)}
        assert set(foes) == {"fast"}
        _, ego_dist, foe_dist, standing_s, held_back = foes["fast"]
        assert ego_dist == pytest.approx(13.0, abs=3.0)  # m's front to its stop line (SC: ~293 m)
        assert foe_dist == pytest.approx(150.0, abs=15.0)  # to the junction, through A's internal lane
        assert standing_s == 0.0 and not held_back
        # farther than 200 m is not counted (paper IV.B)
        libsumo.vehicle.moveTo("fast", "WA_0", 0.0)
        libsumo.simulationStep()
        assert "fast" not in {f[0] for f in bridge.yield_foes("m", 50.0)}
        # the car with priority does not yield to the minor road
        assert bridge.yield_foes("fast", 300.0) == []
    finally:
        libsumo.close()


@pytest.mark.own_process
def test_junction_ahead_is_the_way_to_the_line_and_through_the_junction_and_none_inside_one(t_junction):
    """Where a priority car asked to let the participant in would stand (``CourtesyYield``): its line, not
    inside the junction."""
    import libsumo

    from cosim.sumo_bridge.bridge import SumoBridge

    libsumo.start(["sumo", "-n", str(t_junction), "--no-step-log", "true"])
    try:
        bridge = SumoBridge.__new__(SumoBridge)
        bridge._sumo, bridge._incoming = libsumo, None
        libsumo.route.add("main", ["AC", "CE"])
        libsumo.vehicle.add("car", "main", depart="now", departPos="40", departSpeed="0")
        libsumo.simulationStep()
        line_m, passage_m = bridge.junction_ahead("car")
        lane = libsumo.vehicle.getLaneID("car")
        assert line_m == pytest.approx(libsumo.lane.getLength(lane) - libsumo.vehicle.getLanePosition("car"))
        via = libsumo.vehicle.getNextLinks("car")[0][4]
        assert via.startswith(":C_") and passage_m >= libsumo.lane.getLength(via) > 0.0
        libsumo.vehicle.moveTo("car", via, 0.5)
        libsumo.simulationStep()
        assert libsumo.vehicle.getLaneID("car").startswith(":") and bridge.junction_ahead("car") is None
    finally:
        libsumo.close()

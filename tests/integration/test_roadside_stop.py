"""SumoBridge.pull_over / parked / rejoin in SUMO: the lead stands at the roadside, the car behind it drives
past, and it gets back onto its lane behind that car without a collision; the snapshot keeps its pose while
SUMO re-inserts it; near a lane's end it stops beyond the junction."""

from __future__ import annotations

import pytest
from plain_net import plain_net


@pytest.mark.own_process
def test_a_car_behind_drives_past_the_lead_at_the_roadside_and_the_lead_gets_back_in_behind_it(tmp_path):
    from cosim.sumo_bridge.bridge import SumoBridge
    from cosim.world import World

    net = plain_net(
        tmp_path,
        {"A": (0, 0), "B": (500, 0), "C": (1000, 0), "D": (1500, 0)},
        {"AB": ("A", "B", 1), "BC": ("B", "C", 1), "CD": ("C", "D", 1, 4)},
    )
    (tmp_path / "signs.add.xml").write_text("<additional/>")
    cfg = tmp_path / "s.sumocfg"
    cfg.write_text(f'<configuration><input><net-file value="{net}"/></input><processing>'
                   '<collision.action value="warn"/></processing></configuration>')  # fmt: skip
    bridge, w = SumoBridge(cfg, seed=1, step_s=0.1), World(capacity=8)
    sumo = bridge._sumo
    try:
        sumo.route.add("r", ["AB", "BC"])
        sumo.vehicle.add("lead", "r", depart="now", departPos="100", departSpeed="10")
        sumo.vehicle.add("car", "r", depart="now", departPos="70", departSpeed="10")
        bridge.step(w)
        assert bridge.pull_over("lead", ahead_m=30.0, clear_of_end_m=15.0) == "AB_0"
        while not bridge.parked("lead") and w.t_s < 30.0:
            bridge.step(w)
        stood_at = sumo.vehicle.getLanePosition("lead")
        assert bridge.parked("lead") and 125.0 < stood_at < 145.0  # where told, past its braking distance
        while sumo.vehicle.getLanePosition("car") < stood_at + 20.0 and w.t_s < 60.0:
            bridge.step(w)  # off the lane: the car behind drives past instead of stopping behind it
        assert sumo.vehicle.getLanePosition("car") > stood_at + 20.0 and bridge.parked("lead")
        assert bridge.route_edge_left("lead")[0] == "AB"  # at the roadside it has no lane; no error either
        lead = w.slot_of["lead"]
        # a second car close behind when the lead is told to rejoin: SUMO keeps the lead off the network,
        # waiting to re-insert it, until that car has passed; the snapshot keeps its pose meanwhile
        sumo.vehicle.add("close", "r", depart="now", departPos=f"{stood_at - 12.0:.1f}", departSpeed="8")
        bridge.step(w)
        bridge.rejoin("lead")
        off_network = 0
        for _ in range(100):
            bridge.step(w)
            off_network += sumo.vehicle.getPosition("lead")[0] < -1e6
            assert 100.0 < w.x_m[lead] < 500.0 and -20.0 < w.y_m[lead] < 0.0 and w.speed_mps[lead] >= 0.0
        assert off_network > 0
        assert not bridge.parked("lead") and sumo.vehicle.getLaneID("lead") in ("AB_0", "BC_0")
        assert sumo.vehicle.getSpeed("lead") > 3.0
        assert sumo.vehicle.getLeader("lead", 200.0)[0] == "close"  # back in, behind the cars it let past
        assert sumo.simulation.getCollidingVehiclesNumber() == 0
        # too near its lane's end (a junction's line): the roadside stop is early on the next edge instead
        sumo.vehicle.add("late", "r", depart="now", departPos="470", departSpeed="0")
        sumo.route.add("r_end", ["BC"])
        sumo.vehicle.add("last", "r_end", depart="now", departPos="470", departSpeed="0")
        bridge.step(w)
        assert bridge.pull_over("late", ahead_m=20.0, clear_of_end_m=15.0) == "BC_0"
        assert bridge.pull_over("last", ahead_m=20.0, clear_of_end_m=15.0) is None  # its route ends there
        sumo.route.add("r_wide", ["CD"])
        sumo.vehicle.add("wide", "r_wide", depart="now", departPos="100", departSpeed="0")
        bridge.step(w)  # on four lanes: no roadside stop where the cars behind would pass it far off
        assert bridge.pull_over("wide", ahead_m=20.0, clear_of_end_m=15.0, max_lanes=3) is None
        assert bridge.pull_over("wide", ahead_m=20.0, clear_of_end_m=15.0, max_lanes=4) == "CD_0"
        while not bridge.parked("late") and w.t_s < 120.0:
            bridge.step(w)
        assert bridge.parked("late") and sumo.vehicle.getRoadID("late") == "BC"
        assert sumo.vehicle.getLanePosition("late") == pytest.approx(10.0, abs=0.01)  # beyond the junction
    finally:
        bridge.close()

"""The MuJoCo ego with the scripted driver in the full loop (issue: ego car and drivers)."""

from __future__ import annotations

from pathlib import Path

import libsumo  # the runs' SUMO: libsumo runs in this process
import numpy as np
import pytest
from osm_factory import OsmSketch

from cosim.log import read
from cosim.runconfig import load_run_config
from cosim.scenario import build_scenario
from cosim.sim import Simulation

ROOT = Path(__file__).resolve().parents[2]


# libsumo runs one simulation per process: each test gets its own process (tests/conftest.py)
pytestmark = pytest.mark.own_process


# seed 5: its route passes Krems cluster_206089614_71582005 twice, where SUMO's free mapping once took the
# twin off the route (7935bc4); seed 9: its route changes lanes, which the pose check needs (seed 5's did too
# until its legs were held to destinations with a way on, 4eceb41; seed 8's until the one-way merge spread
# redrew the routes)
@pytest.mark.slow
@pytest.mark.parametrize("seed, changes_lanes", [(5, False), (9, True)])
def test_scripted_driver_300s_on_the_default_map(tmp_path, seed, changes_lanes):
    """No collision, never off the road, no red-light violation, lane keeping within 0.3 m on average; SUMO
    keeps the ego's planned route (its lights, right of way and foes depend on it)."""
    cfg = load_run_config(ROOT / "configs" / "default.yaml", **{"duration_s": 300, "seed": seed,
                                                                "scenario.demand.density": "low"})  # fmt: skip
    foreign_route_steps = []

    def check_route(sim) -> None:
        if "ego" in sim.world.slot_of:
            held, planned = list(libsumo.vehicle.getRoute("ego")), sim.ego_route
            if not any(
                planned[i : i + len(held)] == held for i in range(len(planned))
            ):  # not a stretch of it
                foreign_route_steps.append(sim.world.step)

    with Simulation(cfg, out_dir=tmp_path) as sim:
        sim.add_hook("log", check_route)
        stats = sim.run()
    assert not foreign_route_steps, f"{len(foreign_route_steps)} steps from step {foreign_route_steps[0]}"
    log = read(tmp_path / "run.mcap", topics=["/ego/state", "/events"])
    e = log["/ego/state"]
    ev = log.topics.get("/events", {"kind": np.array([]), "vehicle": np.array([])})
    ego_events = set(ev["kind"][ev["vehicle"] == "ego"])
    assert not ego_events & {"collision", "ego_off_road", "red_light_violation"}, ego_events
    assert stats["ego_off_road"] == 0
    offset = np.abs(e["path_offset_m"].astype(float))
    assert np.nanmean(offset) < 0.3
    # the logged pose is the car's, which moves continuously: no step longer than the speed allows. SUMO's
    # twin, logged before, was snapped onto the new lane as a change began: 2.5 m sideways in one step here
    x, y, v = (e[k].astype(float) for k in ("x_m", "y_m", "speed_mps"))
    if changes_lanes:
        assert (np.diff(e["lane_index"].astype(int)) != 0).any(), (
            "no lane change: the check below tests nothing"
        )
    excess = np.hypot(np.diff(x), np.diff(y)) - np.maximum(v[:-1], v[1:]) * cfg.timing.sumo_step_s
    assert excess.max() < 0.3, f"the ego's pose jumps {excess.max():.2f} m beyond its speed in one step"
    # it really drove: 969 m with one green per signalised approach (e753290), 1.0+ km before; the issue-15
    # target of 1 km in 300 s is measured on every map and seed by bench/bench_drive.py, not on one run here
    assert np.sum(e["speed_mps"]) * 0.1 > 800.0  # [m]


def signalised_street(tmp_path):
    s = OsmSketch()
    s.node("w", -400, 0)
    s.node("c", 0, 0, highway="traffic_signals")
    s.node("e", 400, 0)
    s.node("n", 0, 300)
    s.node("s", 0, -300)
    s.way(["w", "c", "e"], highway="secondary", maxspeed="50")
    s.way(["s", "c", "n"], highway="residential")
    return build_scenario(
        s.write(tmp_path / "m.osm"), tmp_path / "scn", density="low", seed=1, log=lambda *a: None
    )


def test_ego_stops_at_red_and_its_sumo_follower_stops_behind(tmp_path):
    scn = signalised_street(tmp_path)
    import sumolib

    net = sumolib.net.readNet(str(scn.net_file))
    west = [e for e in net.getEdges() if e.getFromNode().getCoord()[0] < e.getToNode().getCoord()[0] - 300]
    (approach,) = [e for e in west if e.getToNode().getType() == "traffic_light"]
    (exit_,) = [e for e in west if e.getFromNode().getType() == "traffic_light"]
    cfg = load_run_config(None, **{"scenario.map": str(tmp_path / "m.osm"), "scenario.demand.density": "low",
                                   "duration_s": 80, "ego.lead_vehicle": False,
                                   "ego.route": [approach.getID(), exit_.getID()], "ego.depart_s": 1.0,
                                   "ego.driver.profile": "daily_commuter", "vanet": None})  # fmt: skip
    with Simulation(cfg, out_dir=tmp_path / "run", scenario=scn, sumo_args=("--route-files", "")) as sim:
        tls = libsumo.trafficlight
        (tls_id,) = tls.getIDList()
        n = len(tls.getRedYellowGreenState(tls_id))
        sim.bridge.add_vehicle(
            "follower", [approach.getID(), exit_.getID()], depart=4.0, type_id="DEFAULT_VEHTYPE"
        )
        stopped_gap, follower_min_gap = None, np.inf
        for _ in range(800):
            t = sim.world.t_s
            tls.setRedYellowGreenState(tls_id, ("r" if t < 45.0 else "G") * n)
            sim.step()
            nxt = sim.bridge.next_tls("ego") if "ego" in sim.world.slot_of else None
            if nxt and sim.world.speed_mps[sim.world.slot_of["ego"]] < 0.05 and 30 < sim.world.t_s < 45:
                stopped_gap = nxt[2]
            if "follower" in sim.world.slot_of and "ego" in sim.world.slot_of:
                lead = sim.bridge.leader("follower", 100.0)
                if lead and lead[0] == "ego":
                    follower_min_gap = min(follower_min_gap, lead[1] + sim.bridge.min_gap("follower"))
        passed = (
            sim.world.slot_of.get("ego") is None
            or sim.world.edge_names[sim.world.edge_code[sim.world.slot_of["ego"]]] == exit_.getID()
        )
    assert stopped_gap is not None and 0.0 <= stopped_gap < 5.0, (
        stopped_gap
    )  # waits just before the stop line
    assert passed, "drives on at green"
    assert 0.5 < follower_min_gap < 6.0  # the SUMO follower braked behind the stopped ego, no collision
    ev = read(tmp_path / "run" / "run.mcap", topics=["/events"]).topics.get("/events", {"kind": np.array([])})
    assert "red_light_violation" not in set(ev["kind"]) and "collision" not in set(ev["kind"])

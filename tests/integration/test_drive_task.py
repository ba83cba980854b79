"""The driving task the results stand on: the ego and the lead from the first step, routes that never run
out, and the run's own health (issue: the drive holds on any real map)."""

from __future__ import annotations

import math
from pathlib import Path

import libsumo  # the runs' SUMO: libsumo runs in this process
import pytest
from osm_factory import OsmSketch, crossroads

from cosim.runconfig import load_run_config
from cosim.scenario import build_scenario
from cosim.sim import Simulation

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.own_process  # libsumo: one simulation per process


@pytest.mark.parametrize("map_name", ["krems", "munich"])
def test_ego_and_lead_are_on_the_road_from_the_first_step(map_name, tmp_path):
    """Placed, not queued: at t = 0.1 s both are in SUMO, the lead ~20 m ahead as the ego's leader."""
    cfg = load_run_config(ROOT / "configs" / "default.yaml", **{
        "duration_s": 10, "scenario.map": str(ROOT / "configs" / "maps" / f"{map_name}.osm.gz"),
        "scenario.demand.density": "high", "vanet": None})  # fmt: skip
    with Simulation(cfg) as sim:
        sim.step()
        assert {"ego", "lead"} <= set(sim.world.slot_of), "not placed at the first step"
        for _ in range(99):
            sim.step()
        p = sim.ego.percept
        assert p.leader_id == "lead" and 0.5 < p.leader_gap_m < 45.0, (p.leader_id, p.leader_gap_m)
        rep = sim.health.report()
    assert rep["ego_present_at_s"] == pytest.approx(0.1)
    assert rep["lead_leader_share"] > 0.95


def ring_town(tmp_path) -> Path:
    """A 400 m x 300 m block of two-way residential streets with a cross street: every edge has a way on."""
    s = OsmSketch()
    pts = {"a": (0, 0), "b": (200, 0), "c": (400, 0), "d": (400, 300), "e": (200, 300), "f": (0, 300)}
    for name, (x, y) in pts.items():
        s.node(name, x, y)
    s.way(["a", "b", "c", "d", "e", "f", "a"], highway="residential", maxspeed="50")
    s.way(["b", "e"], highway="residential", maxspeed="30")
    return s.write(tmp_path / "ring.osm")


@pytest.mark.slow
def test_the_route_is_extended_past_its_first_destination(tmp_path):
    """A two-edge route on a small map: after 200 s the ego has driven well past it (the route grew by A*
    legs), the lead's route in SUMO grew with it, and nobody stopped at the first destination."""
    osm = ring_town(tmp_path)
    scn = build_scenario(osm, tmp_path / "scn", density="low", seed=1, log=lambda *a: None)
    import sumolib

    net = sumolib.net.readNet(str(scn.net_file))
    first = sorted((e for e in net.getEdges() if e.getFunction() != "internal"), key=lambda e: e.getID())[0]
    nxt = sorted(first.getOutgoing(), key=lambda e: e.getID())[0]
    route = [first.getID(), nxt.getID()]
    planned_m = first.getLength() + nxt.getLength()
    cfg = load_run_config(None, **{"scenario.map": str(osm), "scenario.demand.density": "low",
                                   "ego.route": route, "vanet": None, "seed": 2, "duration_s": 200})  # fmt: skip
    with Simulation(cfg, out_dir=tmp_path / "run", scenario=scn) as sim:
        stats = sim.run()
        extended = len(sim.ego_route)
        lead_route = list(libsumo.vehicle.getRoute("lead")) if "lead" in sim.world.slot_of else []
    h = stats["health"]
    assert sim.route.extensions >= 1 and extended > 2
    assert h["ego_distance_m"] > planned_m + 300.0, (h["ego_distance_m"], planned_m)
    assert lead_route and lead_route[-1] == sim.ego_route[-1]  # the lead keeps to the same, extended route
    assert h["longest_standstill_s"] < 30.0 and h["stalls"] == 0
    assert h["lead_leader_share"] > 0.9, h


def test_a_map_without_a_loop_gets_turning_loops_and_the_ego_drives_on(tmp_path):
    """A T of two-way streets cut at the extract's edge has no loop: every route ran out at a cut end within
    a few hundred metres (graphhopper's bautzen.osm, a motorway junction with its feeder roads: 745 m, then
    196 s at the route's end). Each cut end gets a turning loop beyond it, driven like a cul-de-sac's: the
    ego drives on through the junction and the loops for the whole run, on the road, the lead ahead."""
    import sumolib

    from cosim.scenario.demand import RouteChainer, drivable_component
    from cosim.scenario.network import TURNING_LOOP_ID, is_turning_loop

    s = OsmSketch()
    for name, (x, y) in {"c": (0, 0), "w": (-250, 0), "e": (250, 0), "n": (0, 250)}.items():
        s.node(name, x, y)
    s.way(["w", "c", "e"], highway="secondary", maxspeed="50")
    s.way(["c", "n"], highway="residential", maxspeed="30")
    osm = s.write(tmp_path / "tee.osm")
    scn = build_scenario(osm, tmp_path / "scn", density="low", seed=1, log=lambda *a: None)
    assert scn.report["network"]["junction_fixes"]["turning_loops"] == 3
    net = sumolib.net.readNet(str(scn.net_file))
    comp = drivable_component(net)
    assert {e.getID() for e in comp} >= {e.getID() for e in net.getEdges() if is_turning_loop(e.getID())}
    assert RouteChainer(comp).endless  # legs may end somewhere with a way on
    for end in ("w", "e", "n"):  # the loops lie beyond the cut ends, where the roads would go on
        a = net.getNode(f"{s.ids[end]}{TURNING_LOOP_ID}a").getCoord()
        assert math.hypot(*a[:2]) > math.hypot(*net.getNode(s.ids[end]).getCoord()[:2]) + 5.0
    cfg = load_run_config(None, **{"scenario.map": str(osm), "scenario.demand.density": "low",
                                   "vanet": None, "seed": 1, "duration_s": 300})  # fmt: skip
    with Simulation(cfg, out_dir=tmp_path / "run", scenario=scn) as sim:
        h = sim.run()["health"]
    assert h["status"] == "ok", h["problems"]
    assert h["ego_distance_m"] > 1000.0 and h["longest_standstill_s"] < 30.0 and h["off_road_s"] == 0.0, h
    assert h["lead_leader_share"] > 0.9, h


def test_a_car_that_could_not_stop_behind_the_placed_ego_is_taken_out(tmp_path):
    """The ego appears standing at the start of its route; a car already coming up behind it at 90 km/h
    within its stopping distance (reaction + 4.5 m/s^2) is taken out at once, one farther back stays (Krems,
    seed 3: an initial car at 24 m/s ran into the ego placed on a 100-km/h road, 0.1 s after it appeared)."""
    sketch = crossroads("secondary", "residential", arm_m=400.0, major_tags={"maxspeed": "100"})
    osm = sketch.write(tmp_path / "cross.osm")
    scn = build_scenario(osm, tmp_path / "scn", density="low", seed=1, log=lambda *a: None)
    import sumolib

    net = sumolib.net.readNet(str(scn.net_file))
    west, centre, east = (sketch.ids[n] for n in ("w", "c", "e"))
    into_c = next(e for e in net.getNode(west).getOutgoing() if e.getToNode().getID() == centre)
    out_of_c = next(e for e in net.getNode(centre).getOutgoing() if e.getToNode().getID() == east)
    cfg = load_run_config(None, **{"scenario.map": str(osm), "scenario.demand.density": "low",
                                   "ego.route": [out_of_c.getID()], "vanet": None, "seed": 1,
                                   "duration_s": 10})  # fmt: skip
    with Simulation(cfg, out_dir=tmp_path / "run", scenario=scn) as sim:
        for vid, behind_m in (("near", 50.0), ("far", 250.0)):
            libsumo.route.add(f"r_{vid}", [into_c.getID(), out_of_c.getID()])
            libsumo.vehicle.add(vid, f"r_{vid}", depart="now", departSpeed="25",
                                departPos=f"{into_c.getLength() - behind_m:.1f}")  # fmt: skip
        sim.step()
        departed = set(libsumo.simulation.getDepartedIDList())
        running = set(libsumo.vehicle.getIDList())
        for _ in range(99):
            sim.step()
        rep = sim.health.report()
    assert {"ego", "near", "far"} <= departed  # all on the road at the first step ...
    assert "near" not in running and "far" in running, running  # ... and the near one taken out at once
    assert rep["collisions"] == 0, rep

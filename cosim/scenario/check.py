"""Run a built scenario in plain SUMO for a while and report how well its traffic flows.

Runs in a child process (libsumo allows one simulation per process) and returns teleports (SUMO removes
a vehicle stuck for ``time-to-teleport``), collisions (distinct collider/victim pairs; the first 50 with time,
lane and vehicles), vehicles and the teleport share, which
``build-scenario --check`` adds to report.json.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import time
from pathlib import Path


def _run(sumocfg: str, duration_s: float, queue) -> None:
    import libsumo

    from cosim.sumo_bridge.tools import binary

    cfg = Path(sumocfg)
    libsumo.start(
        [
            binary("sumo"),
            "-c",
            str(cfg),
            "--no-warnings",
            "true",
            "--additional-files",
            str(cfg.parent / "signs.add.xml"),
        ]
    )
    sim = libsumo.simulation
    out = {
        "duration_s": duration_s,
        "teleports": 0,
        "collisions": 0,
        "departed": 0,
        "arrived": 0,
        "max_vehicles": 0,
    }
    vehicles = []
    pairs: dict[tuple[str, str], dict] = {}  # a collision is one collider/victim pair, however long it lasts
    t0 = time.perf_counter()
    while sim.getTime() < duration_s:
        libsumo.simulationStep()
        out["teleports"] += sim.getStartingTeleportNumber()
        for c in sim.getCollisions():
            pairs.setdefault((c.collider, c.victim), {"time": round(sim.getTime(), 1), "type": c.type,
                                                      "lane": c.lane, "collider": c.collider,
                                                      "victim": c.victim})  # fmt: skip
        out["collisions"] = len(pairs)
        out["departed"] += sim.getDepartedNumber()
        out["arrived"] += sim.getArrivedNumber()
        n = libsumo.vehicle.getIDCount()
        vehicles.append(n)
        out["max_vehicles"] = max(out["max_vehicles"], n)
    libsumo.close()
    out["collision_list"] = list(pairs.values())[:50]
    out["mean_vehicles"] = round(sum(vehicles) / max(1, len(vehicles)), 1)
    out["teleport_share"] = round(out["teleports"] / max(1, out["departed"]), 4)
    out["wall_s"] = round(time.perf_counter() - t0, 1)
    queue.put(out)


def check_scenario(scenario_dir: str | Path, duration_s: float) -> dict:
    """Simulate ``duration_s`` of the scenario's own traffic; the numbers are also stored in report.json."""
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=_run, args=(str(Path(scenario_dir) / "scenario.sumocfg"), duration_s, q))
    p.start()
    while True:
        try:
            result = q.get(timeout=5)
            break
        except Exception:
            if not p.is_alive():
                raise RuntimeError(
                    f"the SUMO check of {scenario_dir} failed (exit code {p.exitcode})"
                ) from None
    p.join()
    report_file = Path(scenario_dir) / "report.json"
    report = json.loads(report_file.read_text())
    report["check"] = result
    report_file.write_text(json.dumps(report, indent=1))
    return result

"""A built scenario run in plain SUMO (libsumo, no cosim phases), for ``build-scenario --check``.

libsumo runs one simulation per process: ``run_plain`` is meant for a child process
(``cosim.scenario.check``).
"""

from __future__ import annotations

import time
from pathlib import Path

from cosim.sumo_bridge.tools import binary


def run_plain(sumocfg: str | Path, duration_s: float, seed: int | None = None) -> dict:
    """Simulate ``duration_s`` of the scenario's own traffic: teleports, collisions (distinct
    collider/victim pairs; the first 50 with time, lane and vehicles), vehicles and the teleport share.
    ``seed``: SUMO's random seed (its drivers' dawdling, departure speeds) instead of the scenario's."""
    import libsumo

    cfg = Path(sumocfg)
    seed_args = ["--seed", str(seed)] if seed is not None else []
    libsumo.start(
        [binary("sumo"), "-c", str(cfg), "--no-warnings", "true",
         "--additional-files", str(cfg.parent / "signs.add.xml"), *seed_args]
    )  # fmt: skip
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
    return out

"""Run a built scenario in plain SUMO for a while and report how well its traffic flows.

Runs in a child process (libsumo allows one simulation per process; the run itself is
``cosim.sumo_bridge.plain.run_plain``) and returns teleports (SUMO removes
a vehicle stuck for ``time-to-teleport``), collisions (distinct collider/victim pairs; the first 50 with time,
lane and vehicles), vehicles and the teleport share, which
``build-scenario --check`` adds to report.json.
"""

from __future__ import annotations

import json
import multiprocessing as mp
from pathlib import Path


def _run(sumocfg: str, duration_s: float, seed: int | None, queue) -> None:
    from cosim.sumo_bridge.plain import run_plain

    queue.put(run_plain(sumocfg, duration_s, seed))


def check_scenario(scenario_dir: str | Path, duration_s: float, *, seed: int | None = None,
                   record: bool = True) -> dict:  # fmt: skip
    """Simulate ``duration_s`` of the scenario's own traffic, with SUMO's random ``seed`` when given; with
    ``record`` the numbers are also stored in report.json."""
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=_run, args=(str(Path(scenario_dir) / "scenario.sumocfg"), duration_s, seed, q))
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
    if not record:
        return result
    report_file = Path(scenario_dir) / "report.json"
    report = json.loads(report_file.read_text())
    report["check"] = result
    report_file.write_text(json.dumps(report, indent=1))
    return result

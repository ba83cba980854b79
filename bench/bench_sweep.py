"""Sweep throughput: ``python -m bench.bench_sweep [--runs 8] [--duration 30] [--map munich]``.

One sweep (``--runs`` seeds on the shipped Munich map, low density, the ego as a SUMO car, the VANET layer
on with its defaults) executed from scratch on: the local process pool with 1 and 2 workers, and the Ray
backend (a local Ray instance) with 1 and 2 workers. Scenarios are built into the cache first, so the
numbers are the sweep itself: planning, spawning workers, the runs, reading every log for the metrics,
table and plot. Reported: wall time, runs per hour, and the Ray backend's overhead against the local pool
for the same sweep (total, and per run), with Ray's start-up time separately.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _sweep(folder: Path, map_path: Path, runs: int, duration_s: float):
    from cosim.sweep import load_sweep

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "base.yaml").write_text(f"name: base\nduration_s: {duration_s}\nscenario:\n  map: {map_path}\n"
                                      "  demand: {density: low}\nego: {physics: sumo}\n")  # fmt: skip
    seeds = ", ".join(str(s) for s in range(1, runs + 1))
    (folder / "sweep.yaml").write_text(f"name: bench\nbase: base.yaml\nseeds: [{seeds}]\n"
                                       "plots: [{metric: vehicles_mean, x: seed}]\n")  # fmt: skip
    return load_sweep(folder / "sweep.yaml")


def _time(sweep, backend, out: Path) -> dict:
    from cosim.sweep import run_sweep

    if out.exists():
        shutil.rmtree(out)
    t0 = time.perf_counter()
    res = run_sweep(sweep, backend=backend, out_dir=out, say=lambda *_: None)
    wall = time.perf_counter() - t0
    if res.failed:
        raise SystemExit(f"bench sweep failed: {res.failed[0]['error']}")
    per_run = [r["wall_s"] for r in res.results]
    return {"wall_s": round(wall, 2), "runs_per_hour": round(len(res.results) / wall * 3600, 1),
            "mean_run_wall_s": round(sum(per_run) / len(per_run), 2)}  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--duration", type=float, default=30.0, help="simulated seconds per run")
    ap.add_argument("--map", default="munich", help="a shipped map name (configs/maps/<name>.osm.gz)")
    ap.add_argument("--no-ray", action="store_true")
    args = ap.parse_args()

    from cosim.sweep import LocalBackend, plan
    from cosim.sweep.runner import ScenarioTask, prebuild_scenario

    map_path = ROOT / "configs" / "maps" / f"{args.map}.osm.gz"
    tmp = Path(tempfile.mkdtemp(prefix="bench-sweep-"))
    try:
        sweep = _sweep(tmp / "spec", map_path, args.runs, args.duration)
        t0 = time.perf_counter()
        for p in plan(sweep, tmp / "plan"):  # warm the scenario cache: the sweeps below measure runs only
            sc = p.task.config["scenario"]
            err = prebuild_scenario(ScenarioTask(sc["map"], sc, p.task.config["seed"], None))
            if err:
                raise SystemExit(err)
        print(
            f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores (other processes slow the runs)"
        )
        print(f"scenarios ready in {time.perf_counter() - t0:.1f} s ({args.runs} seeds of {map_path.name})")
        results: dict[str, dict] = {}
        for jobs in (1, 2):
            backend = LocalBackend(jobs)
            try:
                results[f"local_{jobs}"] = _time(sweep, backend, tmp / f"local{jobs}")
            finally:
                backend.close()
            print(f"local pool, {jobs} worker(s): {results[f'local_{jobs}']}")
        if not args.no_ray:
            try:
                import ray  # noqa: F401
            except ImportError:
                print("ray is not installed: pip install 'cosim[ray]' to measure the Ray backend")
            else:
                from cosim.sweep import RayBackend

                for jobs in (1, 2):
                    t0 = time.perf_counter()
                    backend = RayBackend(None, jobs)
                    init_s = time.perf_counter() - t0
                    try:
                        r = _time(sweep, backend, tmp / f"ray{jobs}")
                    finally:
                        t1 = time.perf_counter()
                        backend.close()
                        shutdown_s = time.perf_counter() - t1
                    local = results[f"local_{jobs}"]
                    r.update(ray_init_s=round(init_s, 2), ray_shutdown_s=round(shutdown_s, 2),
                             overhead_vs_local_s=round(r["wall_s"] - local["wall_s"], 2),
                             overhead_per_run_s=round((r["wall_s"] - local["wall_s"]) / args.runs, 3),
                             overhead_incl_init_s=round(r["wall_s"] + init_s - local["wall_s"], 2))  # fmt: skip
                    results[f"ray_{jobs}"] = r
                    print(f"Ray (local instance), {jobs} worker(s): {r}")
        load = [round(x, 2) for x in os.getloadavg()]
        print(json.dumps({"runs": args.runs, "duration_s": args.duration, "map": map_path.name, "cores": os.cpu_count(),
                          "loadavg_1_5_15min": load, **results}))  # fmt: skip
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()

"""The headline: ``cosim run`` against the ``sumo`` binary on the same scenario.

``python -m bench.bench_headline [--seconds 300] [--repeat 2] [--densities 5,10,20]``

What a traffic modeller compares: ``cosim run`` with the default config (everything on: MuJoCo ego with
its scripted driver, the lead car, every vehicle a VANET station, ADAS, the MCAP log) against
``sumo -c scenario.sumocfg`` on the very scenario cosim builds and runs (same network, same routes file,
same seed, step length and additional files, ``--end`` at the same simulated time). The map is the
Helsinki extract (../shared/data/osm/helsinki.osm.gz, the largest) with the default demand area
(``network``: a static routes file, so the binary gets exactly the same demand; cosim adds only the ego
and the lead and takes out the few vehicles in their way at the start). Densities in vehicles per lane-km
are chosen for about 250, 500 and 1000 running vehicles.

Both are timed as whole commands in subprocesses (start-up included: what a user waits for), A and B
interleaved per repeat; the ratio is taken per repeat (cosim / the sumo run right before it) and the
median of those is reported. Running vehicles are the mean over cosim's ``/traffic/vehicles`` messages.
The repeats start from the line-of-sight maps kept by the first run on the town (cosim/vanet/mapstore.py),
as a user's runs after their first do; that first run, with an empty store, is timed as a pair of its own.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HELSINKI = ROOT.parent / "shared" / "data" / "osm" / "helsinki.osm.gz"


def _config(tmp: Path, veh_per_lane_km: float, seconds: float) -> tuple[Path, object]:
    """A run config: configs/default.yaml on Helsinki at the given density; returns (path, RunConfig)."""
    import yaml

    from cosim.runconfig import load_run_config

    data = yaml.safe_load((ROOT / "configs" / "default.yaml").read_text())
    data["name"] = f"headline_{veh_per_lane_km:g}"
    data["duration_s"] = seconds
    data["scenario"]["map"] = str(HELSINKI)
    data["scenario"]["demand"]["vehicles_per_lane_km"] = veh_per_lane_km
    path = tmp / f"headline_{veh_per_lane_km:g}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path, load_run_config(path)


def _sumo_cmd(scn, cfg) -> list[str]:
    """The binary on cosim's scenario with the options cosim's bridge gives libsumo."""
    from cosim.sumo_bridge.tools import binary

    return [binary("sumo"), "-c", str(scn.sumocfg), "--seed", str(cfg.seed), "--step-length",
            f"{cfg.timing.sumo_step_s:g}", "--no-warnings", "true", "--no-step-log", "true",
            "--additional-files", str(scn.sumocfg.parent / "signs.add.xml"), "--end", f"{cfg.duration_s:g}"]  # fmt: skip


def _cpu_children() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _timed(cmd: list[str], env: dict | None = None) -> tuple[float, float, str]:
    """(wall, CPU, stdout) of a command; CPU counts the process and the children it waited for (cosim's
    log writer and radio)."""
    c0, t0 = _cpu_children(), time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env={**os.environ, **(env or {})})
    wall, cpu = time.perf_counter() - t0, _cpu_children() - c0
    if proc.returncode != 0:
        raise SystemExit(f"failed ({proc.returncode}): {' '.join(cmd)}\n{proc.stderr[-2000:]}")
    return wall, cpu, proc.stdout


def _running(mcap: Path) -> tuple[float, int]:
    """(mean, max) running vehicles over the log's /traffic/vehicles messages (+ the ego)."""
    import numpy as np

    from cosim.log import read

    t = read(mcap, topics=["/traffic/vehicles"])["/traffic/vehicles"]["t_s"]  # one row per vehicle
    counts = np.unique(t, return_counts=True)[1] + 1
    return float(counts.mean()), int(counts.max())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=300.0)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--densities", default="6,11.5,23", help="vehicles per lane-km, comma-separated")
    args = ap.parse_args()
    from cosim.scenario import build_scenario

    tmp = Path(tempfile.mkdtemp(prefix="cosim-headline-"))
    cosim_bin = str(Path(sys.executable).with_name("cosim"))
    rows = []
    for d in [float(v) for v in args.densities.split(",")]:
        path, cfg = _config(tmp, d, args.seconds)
        scn = build_scenario(cfg.scenario.map, config=cfg.scenario, seed=cfg.seed, log=lambda *a: None)
        out = tmp / f"run_{d:g}"
        sumo_cmd = _sumo_cmd(scn, cfg)
        cosim_cmd = [cosim_bin, "run", str(path), "--out", str(out), "--force", "--quiet"]
        # the first run on the town casts its line-of-sight maps and keeps them (cosim.vanet.mapstore); every
        # later run starts from them: the first is timed on its own, in a store of its own, then the others
        env = {"COSIM_MAP_STORE_DIR": str(tmp / f"visibility_{d:g}")}
        s, _s_cpu, _out = _timed(sumo_cmd)
        c, _c_cpu, _out = _timed(cosim_cmd, env)
        first = (c, c / s)
        sumo_s, cosim_s, loop_s, ratios, cpu_ratios = [], [], [], [], []
        for _ in range(args.repeat):
            s, s_cpu, _out = _timed(sumo_cmd)
            c, c_cpu, stdout = _timed(cosim_cmd, env)
            sumo_s.append(s)
            cosim_s.append(c)
            loop_s.append(json.loads(stdout.strip().splitlines()[-1])["wall_s"])
            ratios.append(c / s)
            cpu_ratios.append(c_cpu / s_cpu)
        mean_n, max_n = _running(out / "run.mcap")
        size_mb = (out / "run.mcap").stat().st_size / 1e6
        rows.append((d, mean_n, max_n, statistics.median(sumo_s), statistics.median(cosim_s),
                     statistics.median(loop_s), statistics.median(ratios), min(ratios), max(ratios),
                     statistics.median(cpu_ratios), size_mb * 60.0 / args.seconds, *first))  # fmt: skip
        print(f"# {d:g} veh/lane-km: sumo {sumo_s}, cosim {cosim_s}", file=sys.stderr, flush=True)
    print(f"Helsinki (helsinki.osm.gz), `configs/default.yaml` with `scenario.map` and "
          f"`scenario.demand.vehicles_per_lane_km` set, {args.seconds:g} simulated s, seed 1; "
          f"{args.repeat} interleaved repeat(s), medians.\n")  # fmt: skip
    print(
        "| veh/lane-km | running vehicles (mean / max) | `sumo -c` [s] | `cosim run` [s] (its loop) "
        "| cosim / sumo, wall (min-max) | cosim / sumo, CPU | first run on the town: cosim [s], / sumo "
        "| log [MB per sim min] |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for d, mean_n, max_n, s, c, loop, r, rmin, rmax, rcpu, mb, c_first, r_first in rows:
        print(
            f"| {d:g} | {mean_n:.0f} / {max_n} | {s:.1f} | {c:.1f} ({loop:.1f}) | **{r:.2f}** "
            f"({rmin:.2f}-{rmax:.2f}) | {rcpu:.2f} | {c_first:.1f}, {r_first:.2f} | {mb:.2f} |"
        )
    print(
        "\nsumo: `sumo -c <scenario>/scenario.sumocfg --seed 1 --step-length 0.1 --no-warnings true "
        "--no-step-log true --additional-files <scenario>/signs.add.xml --end <seconds>` on the scenario "
        "`cosim run` builds (same routes file: demand area `network`); cosim: `cosim run <config> --quiet`. "
        "Wall time of the whole command (start-up included); the ratio is per repeat (cosim / the sumo run "
        "just before it); CPU: user + system time of the command and the children it waited for (cosim's "
        "log writer and radio), less sensitive to the other jobs on the shared cores. The repeats start from the "
        "line-of-sight maps the first run on the town cast and kept (cosim/vanet/mapstore.py), as every run "
        "after a user's first does; the first run, with an empty store, is timed apart (one pair). "
        f"Load average after: {os.getloadavg()[0]:.1f}."
    )


if __name__ == "__main__":
    main()

"""Compiled kernels (issue 20 item 4): ``cosim run`` with the numba line-of-sight kernels and without.

``python -m bench.bench_kernels [--seconds 120] [--repeat 3] [--densities 11.5,23]``

The headline's scenario (configs/default.yaml on Helsinki at the given vehicles per lane-km, everything on)
run as whole commands, with numba (the default) and with ``COSIM_NO_NUMBA=1`` (numpy does the same
arithmetic: the logs are byte-identical, tests/integration/test_payload_identity.py and
tests/unit/vanet/test_shadowing_kernel.py), interleaved per repeat; the ratio is per repeat. The
per-topic payload digests of the two logs of the last repeat are compared as well. numba's compiled
kernels are cached on disk after the first run (a first compile costs ~0.7 s, a cached load ~0.15 s).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import statistics
import sys
import tempfile
from pathlib import Path

from bench.bench_headline import _config, _running, _timed


def _digest(mcap: Path) -> str:
    """One digest over every message's topic, log time and payload (metadata left out: it has wall times)."""
    from mcap.reader import make_reader

    h = hashlib.sha256()
    with open(mcap, "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages(log_time_order=True):
            h.update(channel.topic.encode())
            h.update(message.log_time.to_bytes(8, "little"))
            h.update(message.data)
    return h.hexdigest()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=120.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--densities", default="11.5,23", help="vehicles per lane-km, comma-separated")
    args = ap.parse_args()
    from cosim.scenario import build_scenario

    tmp = Path(tempfile.mkdtemp(prefix="cosim-kernels-"))
    cosim_bin = str(Path(sys.executable).with_name("cosim"))
    rows = []
    for d in [float(v) for v in args.densities.split(",")]:
        path, cfg = _config(tmp, d, args.seconds)
        build_scenario(cfg.scenario.map, config=cfg.scenario, seed=cfg.seed, log=lambda *a: None)
        outs = {k: tmp / f"run_{d:g}_{k}" for k in ("numba", "numpy")}
        cmd = {
            k: [cosim_bin, "run", str(path), "--out", str(o), "--force", "--quiet"] for k, o in outs.items()
        }
        _timed(cmd["numba"])  # numba compiles its kernels into the on-disk cache once (not timed)
        t = {k: [] for k in ("numba", "numpy", "numba_cpu", "numpy_cpu", "numba_loop", "numpy_loop")}
        ratios, cpu_ratios = [], []
        for _ in range(args.repeat):
            for k in ("numpy", "numba"):
                if k == "numpy":
                    os.environ["COSIM_NO_NUMBA"] = "1"
                try:
                    wall, cpu, stdout = _timed(cmd[k])
                finally:
                    os.environ.pop("COSIM_NO_NUMBA", None)
                t[k].append(wall)
                t[f"{k}_cpu"].append(cpu)
                t[f"{k}_loop"].append(json.loads(stdout.strip().splitlines()[-1])["wall_s"])
            ratios.append(t["numba"][-1] / t["numpy"][-1])
            cpu_ratios.append(t["numba_cpu"][-1] / t["numpy_cpu"][-1])
        same = _digest(outs["numba"] / "run.mcap") == _digest(outs["numpy"] / "run.mcap")
        mean_n, _ = _running(outs["numba"] / "run.mcap")
        med = {k: statistics.median(v) for k, v in t.items()}
        rows.append((d, mean_n, med, statistics.median(ratios), min(ratios), max(ratios),
                     statistics.median(cpu_ratios), min(cpu_ratios), max(cpu_ratios), same))  # fmt: skip
        print(f"# {d:g} veh/lane-km: {t}", file=sys.stderr, flush=True)
    print(f"Helsinki, `configs/default.yaml` (everything on) at the given density, {args.seconds:g} simulated s, "
          f"seed 1; {args.repeat} interleaved repeat(s), medians; numpy: `COSIM_NO_NUMBA=1`.\n")  # fmt: skip
    print("| veh/lane-km | running vehicles | numpy: wall [s] (loop) / CPU [s] | numba: wall [s] (loop) / CPU [s] "
          "| numba / numpy, wall (min-max) | numba / numpy, CPU (min-max) | logs identical |")  # fmt: skip
    print("|---:|---:|---:|---:|---:|---:|---|")
    for d, n, m, r, rmin, rmax, c, cmin, cmax, same in rows:
        print(f"| {d:g} | {n:.0f} | {m['numpy']:.1f} ({m['numpy_loop']:.1f}) / {m['numpy_cpu']:.1f} "
              f"| {m['numba']:.1f} ({m['numba_loop']:.1f}) / {m['numba_cpu']:.1f} | **{r:.2f}** ({rmin:.2f}-{rmax:.2f}) "
              f"| **{c:.2f}** ({cmin:.2f}-{cmax:.2f}) | {'yes' if same else 'NO'} |")  # fmt: skip
    print(f"\nLoad average after: {os.getloadavg()[0]:.1f}.")


if __name__ == "__main__":
    main()

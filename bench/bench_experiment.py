"""Wall time of the main job: ``python -m bench.bench_experiment [--phase-duration 300] [--repeat N]``.

Runs configs/experiment.yaml (4 participants x 3 phases, by default 5 min each = 60 simulated minutes)
with as many processes as cores, into a temporary directory, with the scenario already built. With
``--repeat`` the whole job runs N times in a row (this machine is shared: one run can be 15 % slower than
the next) and the median is reported beside every run.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--phase-duration", type=float, default=None)
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args()
    from cosim.experiment.protocol import load_experiment
    from cosim.experiment.runner import run_experiment

    exp, base = load_experiment(ROOT / "configs" / "experiment.yaml", phase_duration_s=args.phase_duration)
    print("| run | participants x phases | simulated [min] | wall [s] | faster than real time | processes "
          "| per participant [s] |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    walls = []
    for k in range(args.repeat):
        out = Path(tempfile.mkdtemp(prefix="cosim-bench-exp-"))
        t0 = time.perf_counter()
        summary = run_experiment(exp, base, out, jobs=os.cpu_count(), quiet=True)
        wall = time.perf_counter() - t0
        walls.append(wall)
        sim = summary["simulated_s"]
        each = ", ".join(f"{p['run']['wall_s']:.0f}" for p in summary["participants"])
        print(f"| {k + 1} | {len(exp.participants)} x {len(exp.phases)} | {sim / 60:.0f} | {wall:.0f} "
              f"| {sim / wall:.1f}x | {summary['jobs']} | {each} |", flush=True)  # fmt: skip
    if args.repeat > 1:
        print(f"\nMedian wall time of {args.repeat} runs: {statistics.median(walls):.0f} s "
              f"(fastest {min(walls):.0f} s, slowest {max(walls):.0f} s).")  # fmt: skip


if __name__ == "__main__":
    main()

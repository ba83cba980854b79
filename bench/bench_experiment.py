"""Wall time of the main job: ``python -m bench.bench_experiment [--phase-duration 300]``.

Runs configs/experiment.yaml (4 participants x 3 phases, by default 5 min each = 60 simulated minutes)
with as many processes as cores, into a temporary directory, with the scenario already built.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--phase-duration", type=float, default=None)
    args = ap.parse_args()
    from cosim.experiment.protocol import load_experiment
    from cosim.experiment.runner import run_experiment

    exp, base = load_experiment(ROOT / "configs" / "experiment.yaml", phase_duration_s=args.phase_duration)
    out = Path(tempfile.mkdtemp(prefix="cosim-bench-exp-"))
    t0 = time.perf_counter()
    summary = run_experiment(exp, base, out, jobs=os.cpu_count(), quiet=True)
    wall = time.perf_counter() - t0
    sim = summary["simulated_s"]
    print("| participants x phases | simulated [min] | wall [s] | faster than real time | processes |")
    print("|---|---|---|---|---|")
    print(
        f"| {len(exp.participants)} x {len(exp.phases)} | {sim / 60:.0f} | {wall:.0f} | {sim / wall:.1f}x | {summary['jobs']} |"
    )
    veh = [p["run"].get("steps", 0) for p in summary["participants"]]
    print(
        f"\n(per participant: {', '.join(str(p['run']['wall_s']) + ' s' for p in summary['participants'])}; steps {veh})"
    )


if __name__ == "__main__":
    main()

"""``cosim sweep SWEEP.yaml [--backend local|ray] [--address ADDR] [--jobs N]``: the lead wires
``add_sweep_parser(subparsers)`` into cosim/cli.py; ``main_sweep(args)`` returns the exit code."""

from __future__ import annotations

import argparse
import sys


def add_sweep_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "sweep", help="run a parameter sweep (seeds x densities x radio parameters ...) on a process pool or Ray",
        description="Run every run of a sweep file that is not done yet, then write results/<sweep>/table.csv "
                    "and the plots. Finished runs are skipped on a re-run; a failing run does not stop the "
                    "others. Exit code 0 when every run is ok, 1 when some failed, 2 for a bad sweep file.",
    )  # fmt: skip
    p.add_argument("sweep", metavar="SWEEP.yaml", help="sweep file (see configs/sweeps/example.yaml)")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local: a process pool on this machine (default); ray: one Ray task per run")  # fmt: skip
    p.add_argument("--address", help="Ray only: the cluster to join (e.g. auto, or ray://head:10001); "
                                     "default: start a local Ray instance")  # fmt: skip
    p.add_argument("--jobs", type=int, help="runs at a time (default: min(cores, runs to do))")
    p.add_argument("--out", help="results folder (default: results/<sweep name>)")
    p.add_argument(
        "--dry-run", action="store_true", help="list the runs and whether they are done; run nothing"
    )
    p.set_defaults(fn=main_sweep)
    return p


def main_sweep(args) -> int:
    from pathlib import Path

    from cosim.errors import CosimError
    from cosim.outdir import RunDir, check_dir
    from cosim.sweep.backends import make_backend
    from cosim.sweep.runner import plan, run_sweep
    from cosim.sweep.spec import load_sweep

    if args.address and args.backend != "ray":
        raise CosimError("--address joins a Ray cluster: use it with --backend ray")
    if args.jobs is not None and args.jobs < 1:
        raise CosimError(f"--jobs must be >= 1, got {args.jobs}")
    sweep = load_sweep(args.sweep)
    out = check_dir(args.out if args.out else Path("results") / sweep.spec.name)
    if args.dry_run:
        planned = plan(sweep, out)
        for p in planned:
            what = {
                "done": "done",
                "todo": "to run",
                "redo": "to redo (config changed)",
                "failed": "bad config",
            }[p.state]
            err = f": {p.result['error']}" if p.state == "failed" else ""
            print(f"{p.run.run_id}  {what:<24} {p.run.label()}{err}")
        print(f"{len(planned)} runs, {sum(p.state == 'done' for p in planned)} done -> {out}")
        return 0
    with RunDir(out, keep_existing=True):  # locked while written; a re-run resumes it: finished runs stay
        todo = sum(p.state in ("todo", "redo") for p in plan(sweep, out))
        backend = (
            make_backend(args.backend, jobs=args.jobs, n_runs=max(1, todo), address=args.address)
            if todo
            else None
        )

        def say(line: str) -> None:
            print(line, flush=True)

        try:
            result = run_sweep(sweep, backend=backend, out_dir=out, say=say)
        finally:
            if backend is not None:
                backend.close()
    for note in result.notes:
        print(f"note: {note}")
    print(f"{result.ok}/{len(result.results)} runs ok ({result.skipped} skipped as done), "
          f"{len(result.degraded)} degraded, {len(result.failed)} failed; table: {result.table}")  # fmt: skip
    if result.degraded:
        print(f"degraded runs (finished, but the drive did not happen as planned: see the error column): "
              f"{', '.join(r['run_id'] for r in result.degraded)}")  # fmt: skip
    for path in result.plots:
        print(f"plot: {path}")
    if result.failed:
        print(f"failed runs: {', '.join(r['run_id'] for r in result.failed)} (see <run-id>/result.json; "
              "re-run the sweep to retry them)", file=sys.stderr)  # fmt: skip
    return 1 if result.failed else 0

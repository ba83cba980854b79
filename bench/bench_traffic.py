"""Background traffic in plain SUMO over many random seeds: ``python -m bench.bench_traffic [--seconds 600]
[--seeds 10] [--maps krems,...] [--jobs 2]``.

For each real map (configs/maps/ and ../shared/data/osm/, as ``bench_drive``): the scenario is built once
(default density, demand seed 1) and its own traffic runs in plain SUMO (no ego, no cosim phases:
``cosim.scenario.check``) once per SUMO random seed, which changes only the drivers' dawdling and departure
speeds. A per-seed count swings by 0-4 collisions, so a scenario-pipeline change is judged here, on many
seeds of one demand, and by the junctions where the collisions happen (issue 15 item 5: no collision,
teleports <= 1 %).
"""

from __future__ import annotations

import argparse
import tempfile
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from functools import partial

from bench.bench_drive import maps


def junction(lane: str) -> str:
    """The junction of an internal lane (``:J_3_0`` -> J), else the lane's edge."""
    return lane[1:].rsplit("_", 2)[0] if lane.startswith(":") else lane.rsplit("_", 1)[0]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=600.0)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--maps", default="")
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    from cosim.scenario import build_scenario
    from cosim.scenario.check import check_scenario

    print(f"{args.seeds} SUMO seeds x {args.seconds:.0f} s per map; demand: density medium, seed 1; "
          "target (issue 15): no collision, teleports <= 1 %\n")  # fmt: skip
    print(
        "| map | vehicles per run | collisions (runs with any) | teleports (share) | where (junction: collisions) |"
    )
    print("|---|---|---|---|---|")
    for name, osm in maps([m for m in args.maps.split(",") if m]).items():
        scn = build_scenario(osm, tempfile.mkdtemp(prefix=f"cosim-bench-traffic-{name}-"), density="medium",
                             seed=1, log=lambda *a: None)  # fmt: skip
        with ThreadPoolExecutor(args.jobs) as pool:
            check = partial(check_scenario, scn.dir, args.seconds, record=False)
            runs = [f.result() for f in [pool.submit(check, seed=s) for s in range(1, args.seeds + 1)]]
        where = Counter(junction(c["lane"]) for r in runs for c in r["collision_list"])
        collisions = sum(r["collisions"] for r in runs)
        teleports, departed = sum(r["teleports"] for r in runs), sum(r["departed"] for r in runs)
        print(f"| {name} | {departed / len(runs):.0f} | {collisions} ({sum(r['collisions'] > 0 for r in runs)} of "
              f"{len(runs)}) | {teleports} ({teleports / max(1, departed):.1%}) | "
              f"{', '.join(f'{j}: {n}' for j, n in where.most_common(5)) or 'none'} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()

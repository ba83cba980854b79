"""Scenario build times: ``python -m bench.bench_scenario``.

For each real map: a cold build (empty cache: netconvert twice, polyconvert, A* routes for every trip), a
rebuild with another seed (network from the cache, routes partly from the route table) and the same build
again (scenario cache hit). Uses a temporary cache directory, so the user's cache is untouched.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "osm"
MAPS = Path(__file__).resolve().parents[1] / "configs" / "maps"


def main() -> None:
    os.environ["COSIM_CACHE_DIR"] = tempfile.mkdtemp(prefix="cosim-bench-cache-")
    from cosim.scenario import build_scenario

    print(
        "| map | cold build [s] | other seed: network cached + route table [s] (routes from table) | identical rebuild [s] |"
    )
    print("|---|---|---|---|")
    for name in ("munich", "krems", "helsinki"):
        osm = SHARED / f"{name}.osm.gz"
        osm = osm if osm.exists() else MAPS / f"{name}.osm.gz"
        if not osm.exists():
            continue
        quiet = {"log": lambda *a: None, "density": "medium"}
        t0 = time.perf_counter()
        build_scenario(osm, seed=1, **quiet)
        t1 = time.perf_counter()
        r2 = build_scenario(osm, seed=2, **quiet).report
        t2 = time.perf_counter()
        build_scenario(osm, seed=2, **quiet)
        t3 = time.perf_counter()
        d = r2["demand"]
        print(f"| {name} | {t1 - t0:.1f} | {t2 - t1:.1f} ({d['routes_from_table']} of "
              f"{d['routes_from_table'] + d['routes_computed']}) | {t3 - t2:.2f} |")  # fmt: skip


if __name__ == "__main__":
    main()

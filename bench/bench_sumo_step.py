"""Why SUMO's step costs more inside cosim than in the ``sumo`` binary: ``python -m bench.bench_sumo_step``.

The Helsinki scenario of the headline at ~500 running vehicles (11.5 veh/lane-km), two measurements:

1. Across processes, interleaved: the ``sumo`` binary (``--end`` 60 s minus ``--end`` 0: the stepping
   without the loading) against plain libsumo stepping the same scenario with the options cosim's bridge
   gives it (``SumoBridge``), each in its own process.
2. Inside one cosim run (default config on that scenario), SUMO's ``simulationStep`` timed per step, in
   alternating blocks of 10 steps: with only the SUMO phase (the bridge's snapshot read, no other phase),
   with the whole schedule, and with the whole schedule but the radio. Alternating blocks in one process
   cancel the load of the other jobs on the machine; the ratio says what running the other phases
   between two SUMO steps costs SUMO's own step (nothing of SUMO's work changes: the phases only read,
   and the ego's pose is written once per step).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

DENSITY = 11.5
SECONDS = 60.0


def _scenario():
    import bench.bench_headline as bh
    from cosim.scenario import build_scenario

    _, cfg = bh._config(Path(tempfile.mkdtemp()), DENSITY, SECONDS)
    return cfg, build_scenario(cfg.scenario.map, config=cfg.scenario, seed=cfg.seed, log=lambda *a: None)


def binary() -> float:
    import bench.bench_headline as bh

    cfg, scn = _scenario()
    cmd = bh._sumo_cmd(scn, cfg)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True)
    full = time.perf_counter() - t0
    t0 = time.perf_counter()
    subprocess.run([*cmd[:-1], "0"], check=True)  # --end 0: loading only
    return full - (time.perf_counter() - t0)


def libsumo_bare() -> float:
    import libsumo

    from cosim.sumo_bridge.bridge import SumoBridge

    cfg, scn = _scenario()
    bridge = SumoBridge(scn.sumocfg, seed=cfg.seed, step_s=cfg.timing.sumo_step_s)
    t0 = time.perf_counter()
    for _ in range(round(SECONDS / cfg.timing.sumo_step_s)):
        libsumo.simulationStep()
    wall = time.perf_counter() - t0
    bridge.close()
    return wall


def in_cosim(rounds: int = 20, block: int = 10) -> dict[str, float]:
    from cosim.sim import Simulation

    cfg, scn = _scenario()
    sim = Simulation(cfg, out_dir=tempfile.mkdtemp(), scenario=scn)
    sumo = sim.bridge._sumo  # the backend module: its simulationStep is timed in place
    real, spent = sumo.simulationStep, [0.0]

    def timed():
        s0 = time.perf_counter()
        real()
        spent[0] += time.perf_counter() - s0

    sumo.simulationStep = timed
    full = list(sim.schedule)
    modes = {"SUMO phase only": [], "whole schedule": full,
             "whole schedule but the radio": [(p, f) for p, f in full if p != "vanet"]}  # fmt: skip
    with sim:
        for _ in range(200):  # 20 s: the ego placed and moving, the radio warmed up
            sim.step()
        acc = {m: [] for m in modes}
        for _ in range(rounds):
            for m, schedule in modes.items():
                sim.schedule = list(schedule)
                spent[0] = 0.0
                for _ in range(block):
                    sim.step()
                acc[m].append(spent[0] / block * 1e3)
        sim.schedule = full
        sumo.simulationStep = real
        n = sim.world.n_valid
    return {"vehicles": n, **{m: statistics.median(v) for m, v in acc.items()}}


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--one":
        print(json.dumps({"binary": binary, "libsumo": libsumo_bare, "cosim": in_cosim}[sys.argv[2]]()))
        return

    def one(kind):
        out = subprocess.run([sys.executable, "-m", "bench.bench_sumo_step", "--one", kind], capture_output=True,
                             text=True, check=True, cwd=Path(__file__).resolve().parents[1])  # fmt: skip
        return json.loads(out.stdout.strip().splitlines()[-1])

    ratios, pairs = [], []
    for _ in range(3):
        b, lib = one("binary"), one("libsumo")
        pairs.append((b, lib))
        ratios.append(lib / b)
    c = one("cosim")
    base = c["SUMO phase only"]
    print(f"Helsinki at {DENSITY:g} veh/lane-km, {SECONDS:g} simulated s.\n")
    print("| SUMO stepping the same scenario | ms per step | / reference |")
    print("|---|---:|---:|")
    b_med = statistics.median(p[0] for p in pairs) / SECONDS * 100
    l_med = statistics.median(p[1] for p in pairs) / SECONDS * 100
    print(f"| `sumo` binary (stepping only) | {b_med:.2f} | 1 |")
    print(f"| libsumo, plain `simulationStep` loop | {l_med:.2f} | {statistics.median(ratios):.2f} "
          f"(per-pair {min(ratios):.2f}-{max(ratios):.2f}) |")  # fmt: skip
    print(f"| in cosim ({c['vehicles']} vehicles), SUMO phase only | {base:.2f} | 1 |")
    for m in ("whole schedule but the radio", "whole schedule"):
        print(f"| in cosim, {m} | {c[m]:.2f} | {c[m] / base:.2f} |")
    print(
        "\nFirst two rows: separate processes, 3 interleaved pairs, medians. Last three: one cosim run, "
        "alternating blocks of 10 steps, medians of 20 blocks; the ratio is the cost the other phases "
        f"put on SUMO's own step (its data evicted from the caches between two steps). Load average "
        f"after: {os.getloadavg()[0]:.1f}."
    )


if __name__ == "__main__":
    main()

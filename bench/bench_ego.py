"""CPU cost of the ego car per simulated second: ``python -m bench.bench_ego [--seconds 120] [--json]``.

Drives the default car the way the co-simulation loop does (one ``EgoCar.step`` per 0.1 s SUMO step, plus
``state()`` and the SUMO write-back conversion ``to_sumo()``) through a mixed cycle: launch, cornering,
hard braking, cruising. Reports process CPU time (not wall time: the machine may be shared), best of
``--repeats`` runs, split into MuJoCo stepping and the Python control layer.

Budget: the ego must add <= 10 % to a co-simulation step at 500 vehicles, i.e. roughly 1-2 ms of CPU per
0.1 s of simulated time (10-20 ms per simulated second).
"""

from __future__ import annotations

import argparse
import json
import math
import time

import mujoco

from cosim.ego_mujoco import CarParams, EgoCar

SUMO_STEP_S = 0.1


def drive_cycle(t_s: float) -> tuple[float, float, float]:
    """(throttle, brake, steer) of a repeating 40-s cycle."""
    phase = t_s % 40.0
    if phase < 10.0:
        return 1.0, 0.0, 0.0  # full-throttle launch
    if phase < 22.0:
        return 0.3, 0.0, 0.25 * math.sin(0.8 * phase)  # weaving
    if phase < 26.0:
        return 0.0, 1.0, 0.0  # emergency stop
    return 0.4, 0.0, 0.05  # gentle cruise


def measure(seconds: float) -> dict[str, float]:
    car = EgoCar(CarParams())
    car.reset(0.0, 0.0, 0.0, 0.0)
    n = round(seconds / SUMO_STEP_S)
    start = time.process_time()
    for i in range(n):
        state = car.step(*drive_cycle(i * SUMO_STEP_S), SUMO_STEP_S)
        state.to_sumo((0.0, 0.0))
    total = time.process_time() - start

    # Bare MuJoCo stepping of the same model (controls frozen at their last values).
    steps = round(seconds / car.timestep_s)
    start = time.process_time()
    mujoco.mj_step(car.model, car.data, steps)
    physics = time.process_time() - start
    return {
        "simulated_s": n * SUMO_STEP_S,
        "timestep_s": car.timestep_s,
        "cpu_ms_per_sim_s": 1e3 * total / (n * SUMO_STEP_S),
        "cpu_ms_per_sumo_step": 1e3 * total / n,
        "mujoco_ms_per_sim_s": 1e3 * physics / (steps * car.timestep_s),
        "python_ms_per_sim_s": 1e3
        * (total - physics * n * SUMO_STEP_S / (steps * car.timestep_s))
        / (n * SUMO_STEP_S),
        "mj_step_us": 1e6 * physics / steps,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=120.0, help="simulated seconds per run")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    args = parser.parse_args()
    runs = [measure(args.seconds) for _ in range(args.repeats)]
    best = min(runs, key=lambda r: r["cpu_ms_per_sim_s"])
    if args.json:
        print(json.dumps(best))
        return
    print(
        f"ego car, {best['simulated_s']:.0f} s simulated, timestep {best['timestep_s'] * 1e3:.1f} ms, "
        f"best of {args.repeats}"
    )
    print(
        f"  total CPU       {best['cpu_ms_per_sim_s']:7.2f} ms per simulated s  "
        f"({best['cpu_ms_per_sumo_step']:.2f} ms per 0.1 s step)"
    )
    print(
        f"  MuJoCo stepping {best['mujoco_ms_per_sim_s']:7.2f} ms per simulated s  "
        f"({best['mj_step_us']:.1f} us per mj_step)"
    )
    print(f"  Python control  {best['python_ms_per_sim_s']:7.2f} ms per simulated s")
    print("  budget          10-20 ms per simulated s (1-2 ms per 0.1 s step)")


if __name__ == "__main__":
    main()

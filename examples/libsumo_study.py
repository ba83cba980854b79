"""A small traffic / V2V study scripted through libsumo, with cosim as a library.

Question: what does holding the busiest traffic light of the map at red for a while do to the traffic
around it, to the network's mean speed, and to CAM delivery and channel load?

The script opens a scenario (``cosim.sim.Simulation``), steps it, reads the per-step ``World`` arrays (all
vehicles as numpy struct-of-arrays) and the VANET layer's per-step results, and changes SUMO's state
through libsumo itself (cosim runs SUMO in this process through libsumo: ``import libsumo`` reaches the same
simulation, ``trafficlight``, ``lane``, ``vehicle`` ...; cosim's own bridge keeps its handle private).
Three windows are compared: before, during and after the forced red phase.

    python examples/libsumo_study.py [--map configs/maps/munich.osm.gz] [--window 20] [--seed 1]

Runs in well under a minute on the shipped Munich map (the first call builds the scenario, ~5 s; later
calls use the cache).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import libsumo
import numpy as np

from cosim.runconfig import load_run_config
from cosim.sim import Simulation
from cosim.vanet import metrics

ROOT = Path(__file__).resolve().parents[1]


class Window:
    """What one time window saw: World samples every step, the VANET columns of every step."""

    def __init__(self, name: str):
        self.name = name
        self.speed_sum = 0.0  # sum over steps and vehicles [m/s]
        self.samples = 0  # vehicle-steps
        self.halted_at_light: list[int] = []  # vehicles halted on the light's approaches, per step
        self.vanet: dict[str, list[dict[str, np.ndarray]]] = {
            "/vanet/rx": [],
            "/vanet/load": [],
            "/vanet/tx": [],
        }

    def observe(self, sim: Simulation, approach_lanes: list[str]) -> None:
        w = sim.world
        speeds = w.speed_mps[w.valid]  # (n_valid,) float64 [m/s]
        self.speed_sum += float(speeds.sum())
        self.samples += int(speeds.size)
        lane = libsumo.lane
        self.halted_at_light.append(sum(lane.getLastStepHaltingNumber(ln) for ln in approach_lanes))
        res = sim.outputs.vanet  # the VANET phase's VanetStepResult of this step (radio on)
        if res is not None:
            for topic, cols in res.columns().items():
                if topic in self.vanet:
                    self.vanet[topic].append(cols)

    def columns(self) -> dict[str, dict[str, np.ndarray]]:
        out = {}
        for topic, parts in self.vanet.items():
            if parts:
                out[topic] = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
        return out

    def row(self) -> dict[str, object]:
        cols = self.columns()
        s = metrics.summarize(cols) if cols else None
        pdr = metrics.pdr_vs_distance(cols.get("/vanet/rx", {}), bin_m=100.0) if cols else None
        near = None
        if pdr is not None and pdr["n"].size and pdr["n"][0] > 0:
            near = float(pdr["pdr"][0])
        return {
            "window": self.name,
            "mean_speed_kmh": 3.6 * self.speed_sum / max(1, self.samples),
            "halted_at_light_max": max(self.halted_at_light, default=0),
            "pdr": None if s is None else s["pdr_overall"],
            "pdr_0_100m": near,
            "channel_busy": None if s is None else s["channel_load"]["busy_ratio"]["mean"],
            "receptions": None if s is None else sum(s["receptions"].values()),
        }


def busiest_light(sim: Simulation) -> tuple[str, list[str]]:
    """The traffic light with the most vehicles on its incoming lanes right now, and those lanes."""
    tls, lane = libsumo.trafficlight, libsumo.lane
    best, best_n, best_lanes = "", -1, []
    for tid in tls.getIDList():
        lanes = sorted(set(tls.getControlledLanes(tid)))
        n = sum(lane.getLastStepVehicleNumber(ln) for ln in lanes)
        if n > best_n:
            best, best_n, best_lanes = tid, n, lanes
    return best, best_lanes


def fmt(v) -> str:
    return "-" if v is None else (f"{v:.3f}" if isinstance(v, float) else str(v))


def main(argv: list[str] | None = None) -> list[dict[str, object]]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--map", default=str(ROOT / "configs" / "maps" / "munich.osm.gz"))
    ap.add_argument("--density", default="medium", choices=("low", "medium", "high"))
    ap.add_argument("--window", type=float, default=20.0, help="length of each window [s]")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)

    # A run config built in code: the ego is a plain SUMO car (no MuJoCo), every reception is kept in the
    # VANET results (rx_log: all) so that the PDR covers all vehicles, not only the ego.
    config = load_run_config(None, **{
        "scenario.map": args.map, "scenario.demand.density": args.density, "seed": args.seed,
        "duration_s": 4 * args.window, "ego.physics": "sumo", "vanet.rx_log": "all",
    })  # fmt: skip
    steps = round(args.window / config.timing.sumo_step_s)
    with Simulation(config, quiet=True) as sim:
        sumo = libsumo  # the simulation this process runs
        if sim.vanet is None:
            print("(the VANET layer is off in this config: no PDR / channel load)")
        for _ in range(steps):  # warm-up: let traffic enter the network
            sim.step()
        tls_id, approaches = busiest_light(sim)
        if not tls_id:
            raise SystemExit("this map has no traffic light to study")
        program = sumo.trafficlight.getProgram(tls_id)
        n_links = len(sumo.trafficlight.getRedYellowGreenState(tls_id))
        print(f"t = {sim.t_s:.0f} s: {sim.world.n_valid} vehicles; studying light {tls_id} "
              f"({len(approaches)} incoming lanes, program {program!r})")  # fmt: skip

        windows = [Window("before"), Window("forced red"), Window("after")]
        for k, win in enumerate(windows):
            if win.name == "forced red":
                sumo.trafficlight.setRedYellowGreenState(tls_id, "r" * n_links)  # hold every signal at red
            elif k and windows[k - 1].name == "forced red":
                sumo.trafficlight.setProgram(tls_id, program)  # back to its own program
            for _ in range(steps):
                sim.step()
                win.observe(sim, approaches)
        stats = {**sim.stats, "t_s": sim.t_s}

    rows = [w.row() for w in windows]
    keys = list(rows[0])
    print("  ".join(f"{k:>18}" for k in keys))
    for r in rows:
        print("  ".join(f"{fmt(r[k]):>18}" for k in keys))
    print(f"simulated {stats['t_s']:.0f} s; teleports {stats['teleports']}, collisions {stats['collisions']}")
    return rows


if __name__ == "__main__":
    main()

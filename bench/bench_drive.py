"""The driving task on every real map: ``python -m bench.bench_drive [--seconds 300] [--seeds 1,2,3]
[--maps krems,munich,...] [--experiment] [--jobs 2]``.

For each map in configs/maps/ and ../shared/data/osm/ (the shipped copy wins) and each seed, a default run
(configs/default.yaml, MuJoCo ego with its scripted driver, lead car, radio on) reports its drive health
(cosim.health): when the ego entered, how far it drove, its longest standstill, the lead as its direct
leader, cut-ins, collisions and teleports. With ``--experiment`` the paper's protocol (2 participants,
120-s phases) runs on each map too, one row per phase. Each run in its own process (libsumo).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGETS = "targets (issue 15): present at <= 1 s, >= 1 km in 300 s, standstill <= 120 s, no collision, teleports <= 1 %"


def maps(names: list[str] | None) -> dict[str, Path]:
    found: dict[str, Path] = {}
    for folder in (ROOT.parent / "shared" / "data" / "osm", ROOT / "configs" / "maps"):
        for p in sorted(folder.glob("*.osm.gz")) if folder.is_dir() else []:
            found[p.name.removesuffix(".osm.gz")] = p
    return {k: v for k, v in sorted(found.items()) if not names or k in names}


def one_run(map_path: Path, seed: int, seconds: float) -> dict:
    out = Path(tempfile.mkdtemp(prefix="cosim-bench-drive-"))
    cmd = [sys.executable, "-m", "cosim.cli", "run", str(ROOT / "configs" / "default.yaml"), "--map", str(map_path),
           "--seed", str(seed), "--duration", str(seconds), "--out", str(out / "run"), "--quiet"]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    if proc.returncode != 0 or not lines:
        return {"error": (proc.stderr.strip().splitlines() or ["?"])[-1]}
    return json.loads(lines[-1])


def one_experiment(map_path: Path) -> dict:
    out = Path(tempfile.mkdtemp(prefix="cosim-bench-drive-exp-"))
    cmd = [sys.executable, "-m", "cosim.cli", "experiment", str(ROOT / "configs" / "experiment.yaml"), "--map",
           str(map_path), "--participants", "2", "--phase-duration", "120", "--jobs", "1", "--out", str(out),
           "--quiet"]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    summary = out / "summary.json"
    if not summary.exists():
        return {"error": (proc.stderr.strip().splitlines() or ["?"])[-1]}
    return json.loads(summary.read_text())


def run_misses(h: dict, seconds: float) -> list[str]:
    """The issue-15 targets a default run misses (the health status flags only degenerate drives: its
    distance floor is a mean of 2 m/s, below the target's 1 km in 300 s)."""
    misses = []
    if h["ego_present_at_s"] is None or h["ego_present_at_s"] > 1.0:
        misses.append("present")
    if h["ego_distance_m"] < 1000.0 * seconds / 300.0:
        misses.append("1 km")
    if h["longest_standstill_s"] > 120.0:
        misses.append("standstill")
    if h["collisions"]:
        misses.append("collision")
    if h["teleport_share"] > 0.01:
        misses.append("teleports")
    return misses


def phase_misses(ph: dict) -> list[str]:
    """The issue-15 targets an experiment phase misses."""
    misses = []
    if ph.get("time_gap_mean_s") is None:
        misses.append("time gaps")
    if (ph.get("following_share") or 0.0) < 0.8:
        misses.append("following")
    if (ph.get("lead_leader_share") or 0.0) < 0.9:
        misses.append("lead")
    return misses


def _f(v, fmt="{:.2f}") -> str:
    return "–" if v is None else fmt.format(v)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=300.0)
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--maps", default="")
    ap.add_argument("--experiment", action="store_true")
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    chosen = maps([m for m in args.maps.split(",") if m] or None)
    seeds = [int(s) for s in args.seeds.split(",")]
    jobs = [(name, path, seed) for name, path in chosen.items() for seed in seeds]
    with ThreadPoolExecutor(args.jobs) as pool:
        results = list(pool.map(lambda j: one_run(j[1], j[2], args.seconds), jobs))
    print(f"Default runs, {args.seconds:.0f} s each; {TARGETS}.\n")
    print("| map | seed | ego at [s] | distance [m] | longest standstill [s] | stalls | lead is leader | cut-ins "
          "| collisions (ego) | teleports (share) | targets missed | status |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    met = 0
    for (name, _, seed), r in zip(jobs, results, strict=True):
        if "error" in r:
            print(f"| {name} | {seed} | FAILED: {r['error']} |||||||||")
            continue
        h = r["health"]
        misses = run_misses(h, args.seconds)
        met += not misses
        print(f"| {name} | {seed} | {_f(h['ego_present_at_s'], '{:.1f}')} | {h['ego_distance_m']:.0f} | "
              f"{h['longest_standstill_s']:.0f} | {h['stalls']} | {_f(h['lead_leader_share'])} | {h['cut_ins']} | "
              f"{h['collisions']} ({h['ego_collisions']}) | {h['teleports']} ({h['teleport_share']:.1%}) | "
              f"{', '.join(misses) or 'none'} | {h['status']}{': ' + '; '.join(h['problems']) if h['problems'] else ''} |")  # fmt: skip
    print(f"\nAll targets met in {met} of {len(jobs)} default runs.")
    if not args.experiment:
        return
    print(
        "\nExperiment (2 participants, 120-s phases) per map; targets: every phase with time-gap data, "
        "following >= 0.8, the lead the direct leader >= 0.9.\n"
    )
    print("| map | participant | phase | mean TG [s] | following | lead is leader | distance [m] | targets missed "
          "| status |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    met = total = 0
    with ThreadPoolExecutor(args.jobs) as pool:
        exps = list(pool.map(lambda kv: one_experiment(kv[1]), chosen.items()))
    for name, s in zip(chosen, exps, strict=True):
        if "error" in s:
            print(f"| {name} | FAILED: {s['error']} |||||||")
            continue
        for part in s["participants"]:
            for ph in part["phases"]:
                h = ph.get("health") or {}
                misses = phase_misses(ph)
                met, total = met + (not misses), total + 1
                print(f"| {name} | {part['participant']} | {ph['phase']} | {_f(ph.get('time_gap_mean_s'))} | "
                      f"{_f(ph.get('following_share'))} | {_f(ph.get('lead_leader_share'))} | "
                      f"{_f(h.get('ego_distance_m'), '{:.0f}')} | {', '.join(misses) or 'none'} | "
                      f"{h.get('status', 'no data')}"
                      f"{': ' + '; '.join(h['problems']) if h.get('problems') else ''} |")  # fmt: skip
    print(f"\nAll targets met in {met} of {total} experiment phases.")


if __name__ == "__main__":
    main()

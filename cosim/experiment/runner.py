"""Run every participant of an experiment (in parallel processes) and write results/<name>/."""

from __future__ import annotations

import json
import multiprocessing as mp
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from cosim.childproc import available_cores
from cosim.errors import CosimError
from cosim.experiment.analysis import (
    assumptions_markdown,
    mark_assumed,
    phase_summary,
    plot_timegap,
    response_assumptions,
    timegap_columns,
    write_timegap_csv,
)
from cosim.experiment.protocol import ExperimentConfig, participant_config, start_time_s

SUMMARY_TOPICS = ["/adas/state", "/ego/state", "/vanet/rx", "/events"]  # what timegap.csv and the summary use


class PhaseSchedule:
    """Sets the active assistance system from the protocol (hook in the 'sumo' phase, before vanet/adas)."""

    def __init__(self, sim, phases, start_s: float):
        self.sim = sim
        self.bounds = self.bounds_of(phases, start_s)
        sim.add_hook("sumo", self)

    @staticmethod
    def bounds_of(phases, start_s: float) -> list[tuple[float, float, object]]:
        """(start, end, phase) of each phase in simulated time."""
        bounds, t = [], start_s
        for p in phases:
            bounds.append((t, t + p.duration_s, p))
            t += p.duration_s
        return bounds

    def __call__(self, sim) -> None:
        adas = sim.adas
        if adas is None:
            return
        t = sim.world.t_s
        for t0, t1, p in self.bounds:
            if t0 <= t < t1 or (p is self.bounds[-1][2] and t0 <= t <= t1 + 1e-6):
                adas.active, adas.phase_name = p.system, p.name
                return
        adas.active, adas.phase_name = "none", "pre" if t < self.bounds[0][0] else "post"


def run_participant(exp: ExperimentConfig, index: int, base: Path, out_dir: Path, progress=None,
                    radio_process: bool | None = None) -> dict:  # fmt: skip
    """One participant's drive through the protocol, its time-gap table, plot and phase summary.
    ``radio_process``: see ``cosim.sim.Simulation``."""
    from cosim.log import Log
    from cosim.sim import Simulation

    part = exp.participants[index]
    cfg = participant_config(exp, index, base)
    pdir = out_dir / part.id
    pdir.mkdir(parents=True, exist_ok=True)
    start = start_time_s(exp, cfg.ego.depart_s)
    order = exp.order_of(index)
    t_wall = time.perf_counter()

    kept: dict[str, list] = {}  # the summary's topics: the log appends their messages during the run
    health = []  # the run's DriveHealth, judged per phase below

    def setup(sim) -> None:
        health.append(sim.health)
        PhaseSchedule(sim, order, start)
        kept.update(sim.mcap.keep(SUMMARY_TOPICS))
        sim.mcap.metadata("experiment", {"name": exp.name, "participant": part.id, "profile": part.profile,
                                         "start_s": start, "order": ",".join(p.name for p in order)})  # fmt: skip

    if cfg.ego.driver.kind in ("keyboard", "wheel"):  # a person at the wheel: the 3D view, in real time
        from cosim.world3d.drive import run_drive

        stats = run_drive(cfg, pdir, on_sim=setup)
    else:
        with Simulation(cfg, out_dir=pdir, quiet=True, radio_process=radio_process) as sim:
            setup(sim)
            steps = sim.steps_total
            for k in range(steps):
                sim.step()
                if progress is not None and k % 50 == 0:
                    progress[part.id] = k / steps
            stats = {**sim.stats, "simulated_s": round(sim.world.t_s, 1)}
    stats["wall_s"] = round(time.perf_counter() - t_wall, 1)
    stats["vanet_mac"] = cfg.vanet.mac if cfg.vanet is not None else None  # system B's radio access
    if progress is not None:
        progress[part.id] = 1.0
    log = Log.of_messages(pdir / "run.mcap", kept)
    cols = timegap_columns(log, start)
    write_timegap_csv(cols, pdir / "timegap.csv")
    title = f"{exp.name}: participant {part.id} ({part.profile}), order {' > '.join(p.name for p in order)}"
    plot_timegap(cols, pdir / "timegap.png", title)
    phases = phase_summary(log, cols, start)
    bounds = PhaseSchedule.bounds_of(order, start)
    for ph in phases:
        window = next(((a, b) for a, b, p in bounds if p.name == ph["phase"]), None)
        rep = health[0].report(*window) if window and health and health[0] is not None else None
        ph["health"] = rep
        if (
            rep is not None
        ):  # the following task as the drive health sees it (a queue behind the leader counts)
            ph["following_share"] = rep["following_share"]
            ph["lead_leader_share"] = rep["lead_leader_share"]
            ph["lead_paced_share"] = rep["lead_paced_share"]
    for p in order:  # a phase the protocol has but the log does not: no time-gap data at all
        if not any(ph["phase"] == p.name for ph in phases):
            phases.append({"phase": p.name, "system": p.system, "duration_s": 0.0, "health": None})
    return {"participant": part.id, "profile": part.profile, "order": [p.name for p in order],
            "phases": phases, "run": stats}  # fmt: skip


# What every participant's process needs, imported once in the fork server instead of once per process
# (~1.7 CPU s each: SUMO, MuJoCo, shapely, matplotlib's renderer; numba ~0.4 s, imported by the radio's
# line-of-sight kernels when it starts)
_PRELOAD = ["cosim.experiment.runner", "cosim.sim", "cosim.phases.ego", "cosim.phases.adas", "cosim.phases.vanet",
            "cosim.phases.traffic", "cosim.phases.lead", "cosim.log.recorder", "cosim.log.reader",
            "matplotlib.backends.backend_agg", "numba"]  # fmt: skip


def _participant_context():
    """Processes forked from a server that has imported the simulation's modules but never run one (libsumo
    runs one simulation per process, so each participant still gets a fresh process); spawn where there is
    no fork."""
    if "forkserver" not in mp.get_all_start_methods():
        return mp.get_context("spawn")
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(_PRELOAD)
    return ctx


def _worker(args):
    exp, index, base, out_dir, progress, radio_process = args
    return run_participant(exp, index, base, out_dir, progress, radio_process)


def render_clip(participant_dir: Path) -> None:
    """A short video of one participant's system-A and system-B phases (needs the `video` extra)."""
    try:
        from cosim.world3d.replay import RenderParams, render_phase_clip

        render_phase_clip(participant_dir / "run.mcap", participant_dir / "clip.mp4",
                          params=RenderParams(width=640, height=360))  # fmt: skip
        print(f"clip: {participant_dir / 'clip.mp4'}", flush=True)
    except CosimError as exc:  # no ffmpeg / no EGL: the experiment's results stand without the clip
        print(f"cosim: no clip: {exc}", file=sys.stderr, flush=True)


def run_experiment(
    exp: ExperimentConfig,
    base: Path,
    out_dir: Path,
    jobs: int | None = None,
    quiet: bool = False,
    clip: bool = False,
) -> dict:
    """``clip``: also render the first participant's clip (``render_clip``), in a process of its own that
    starts as soon as that participant is done, beside the others still running."""
    from cosim.scenario import build_scenario

    out_dir.mkdir(parents=True, exist_ok=True)
    first = participant_config(exp, 0, base)
    say = (lambda *a: None) if quiet else print
    build_scenario(
        first.scenario.map, config=first.scenario, seed=first.seed, log=say
    )  # once, before the workers
    n = len(exp.participants)
    jobs = max(1, min(jobs or os.cpu_count() or 1, n))
    t0 = time.perf_counter()
    first_dir = out_dir / exp.participants[0].id
    if first.ego.driver.kind in ("keyboard", "wheel"):  # people drive one after the other, in this process
        results = [run_participant(exp, i, base, out_dir) for i in range(n)]
        if clip:
            render_clip(first_dir)
        return _write_summary(exp, results, out_dir, t0, 1)
    ctx = _participant_context()
    clipper = None
    with ctx.Manager() as manager:
        progress = manager.dict({p.id: 0.0 for p in exp.participants})
        # a fresh process per participant: libsumo runs one simulation per process lifetime
        with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, max_tasks_per_child=1) as pool:
            spare = 2 * jobs <= available_cores()  # a core for each participant's radio process
            futures = [pool.submit(_worker, (exp, i, base, out_dir, progress, spare)) for i in range(n)]
            while not all(f.done() for f in futures):
                time.sleep(1.0)
                if clip and clipper is None and futures[0].done() and futures[0].exception() is None:
                    clipper = ctx.Process(target=render_clip, args=(first_dir,))
                    clipper.start()
                if not quiet:
                    line = "  ".join(f"{k} {100 * v:3.0f}%" for k, v in sorted(progress.items()))
                    sys.stderr.write(f"\r{line}  [{time.perf_counter() - t0:5.0f} s]")
                    sys.stderr.flush()
            results = [f.result() for f in futures]
    if not quiet:
        sys.stderr.write("\n")
    if clip and clipper is None:  # the first participant finished within the last poll
        render_clip(first_dir)
    elif clipper is not None:
        clipper.join()
    return _write_summary(exp, results, out_dir, t0, jobs)


def _write_summary(exp: ExperimentConfig, results: list[dict], out_dir: Path, t0: float, jobs: int) -> dict:
    wall = time.perf_counter() - t0
    simulated = sum(r["run"]["simulated_s"] if "simulated_s" in r["run"] else 0 for r in results)
    summary = {"experiment": exp.name, "participants": results, "across": across_participants(results),
               "wall_s": round(wall, 1), "jobs": jobs, "simulated_s": simulated}  # fmt: skip
    summary["vanet_mac"] = next((r["run"].get("vanet_mac") for r in results), None)  # issue 18
    summary["assumptions"] = response_assumptions(exp)  # which numbers rest on assumed responses to A and B
    mark_assumed(results, summary["across"], summary["assumptions"])
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=1))
    (out_dir / "summary.md").write_text(summary_markdown(summary))
    return summary


def phases_without_timegap(summary: dict) -> list[str]:
    """'P1 system_B' for every phase with no time-gap data (the ego never followed anyone there)."""
    return [f"{r['participant']} {ph['phase']}" for r in summary["participants"] for ph in r["phases"]
            if ph.get("time_gap_mean_s") is None]  # fmt: skip


def degraded_phases(summary: dict) -> list[str]:
    """'P1 system_B: reason; reason' for every phase whose drive health is not ok."""
    out = []
    for r in summary["participants"]:
        for ph in r["phases"]:
            h = ph.get("health")
            if h is None or h["status"] != "ok":
                out.append(f"{r['participant']} {ph['phase']}: {_problems(h)}")
    return out


def across_participants(results: list[dict]) -> list[dict]:
    """Per system: the mean over participants of each per-phase number."""
    by_system: dict[str, list[dict]] = {}
    for r in results:
        for ph in r["phases"]:
            by_system.setdefault(ph["system"], []).append(ph)
    rows = []
    for system, phs in by_system.items():
        row = {"system": system, "n": len(phs)}
        for key in ("time_gap_mean_s", "time_gap_mean_lead_free_s", "time_gap_sd_s", "share_below_2s",
                    "share_below_1s", "warnings", "hard_braking_events", "ego_collisions", "min_ttc_s",
                    "v2v_pdr_to_leader", "lead_paced_share"):  # fmt: skip
            vals = [p[key] for p in phs if p.get(key) is not None]
            row[key] = round(sum(vals) / len(vals), 3) if vals else None
        rows.append(row)
    return rows


_COLS = [("phase", "phase"), ("system", "system"), ("time_gap_mean_s", "mean TG [s]"),
         ("time_gap_mean_lead_free_s", "lead free [s]"), ("time_gap_sd_s", "SD [s]"),
         ("share_below_2s", "< 2 s"), ("share_below_1s", "< 1 s"), ("warnings", "warnings"),
         ("hard_braking_events", "hard brakes"), ("ego_collisions", "collisions"), ("min_ttc_s", "min TTC [s]"),
         ("v2v_pdr_to_leader", "PDR leader"),
         ("following_share", "following"), ("lead_leader_share", "lead is leader"),
         ("lead_paced_share", "lead paced")]  # fmt: skip


_HEALTH_COLS = ("distance [m]", "drive health")


def _health_cells(ph: dict) -> tuple[str, str]:
    """The phase's drive distance and health as the summary shows them: a degraded phase names why."""
    h = ph.get("health")
    if h is None:
        return "–", "no data"
    status = h["status"] if h["status"] == "ok" else f"{h['status']}: {_problems(h)}"
    return f"{h['ego_distance_m']:.0f}", status


def _problems(health: dict | None) -> str:
    """A phase health's problems as one line ("no data" without a health record)."""
    return "; ".join(health["problems"]) if health else "no data"


def _cell(v) -> str:
    return "–" if v is None else f"{v:g}" if isinstance(v, float) else str(v)


def summary_markdown(summary: dict) -> str:
    lines = [f"# {summary['experiment']}", "",
             f"{len(summary['participants'])} participants, {summary['simulated_s']:.0f} simulated s in "
             f"{summary['wall_s']:.0f} s wall ({summary['jobs']} processes). V2V radio access (system B): "
             f"{summary.get('vanet_mac') or 'none'}.", "",
             "Time gap (TG) = ground truth to the vehicle ahead while following (TG < 10 s); warnings = onsets of "
             "the red level (system B) or of the perceived 'keep distance' display (system A). The lead car "
             "waits for a participant who falls behind and is held back so that one keeps up "
             "(cosim/phases/lead.py): *lead paced* is the share of the phase in which it was, where the gap is "
             "partly the lead's doing; *lead free* is the mean TG without those samples (timegap.csv's "
             "`lead_paced` column marks them).", ""]  # fmt: skip
    if summary.get("assumptions", {}).get("values"):
        lines += ["The system A and B rows rest on assumed driver responses, not measured ones: see "
                  "*Assumptions* at the end.", ""]  # fmt: skip
    for r in summary["participants"]:
        lines += [f"## {r['participant']} ({r['profile']}), order: {' > '.join(r['order'])}", "",
                  "| " + " | ".join([*(h for _, h in _COLS), *_HEALTH_COLS]) + " |",
                  "|" + "---|" * (len(_COLS) + len(_HEALTH_COLS))]  # fmt: skip
        for ph in r["phases"]:
            lines.append(
                "| " + " | ".join([*(_cell(ph.get(k)) for k, _ in _COLS), *_health_cells(ph)]) + " |"
            )
        lines.append("")
    lines += ["## Across participants (mean per system)", "",
              "| system | n | mean TG [s] | lead free [s] | SD [s] | < 2 s | < 1 s | warnings | hard brakes | collisions | min TTC [s] | PDR leader | lead paced |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for row in summary["across"]:
        lines.append(f"| {row['system']} | {row['n']} | " + " | ".join(_cell(row.get(k)) for k in (
            "time_gap_mean_s", "time_gap_mean_lead_free_s", "time_gap_sd_s", "share_below_2s", "share_below_1s",
            "warnings", "hard_braking_events", "ego_collisions", "min_ttc_s", "v2v_pdr_to_leader",
            "lead_paced_share")) + " |")  # fmt: skip
    if summary.get("assumptions"):
        lines += ["", *assumptions_markdown(summary["assumptions"])]
    return "\n".join(lines) + "\n"

"""3D view cost: ``python -m bench.bench_render [--seconds 30] [--frames 120] [--json]``.

On the full default map (configs/default.yaml: Krems), with software OpenGL (Mesa llvmpipe through EGL):

1. scene: time to generate and compile the MuJoCo scene, its geoms, meshes and triangles;
2. fps: frames per second of the driver view at 1280x720 and 640x360 while the default run drives through
   town (scripted driver): each frame = pose the scene from the live state + render + HUD. The simulation
   steps between frames but is not timed here. Shadows off, no multisampling (the defaults);
3. drive: the real-time loop of ``cosim drive`` (headless: ``SDL_VIDEODRIVER=dummy``) for ``--seconds`` of
   wall time in medium-high traffic (the experiment's setting: 7.5 vehicles per lane-km within 250 m of
   the route; and the same density on the whole network), scripted driver in the seat: the simulation's
   real-time factor, late steps and time per step; the viewer process's frames per second, time per frame,
   stalled frames (the same picture again: a step came late) and input-to-display latency (median, p95)
   measured with a synthetic key toggled in the viewer every 0.37 s: from the viewer reading the key to the
   first frame that moves towards the step which read it ('first') and to the frame that shows that step
   whole ('full', one step later with interpolation). At 640x360 the loop before issue 20 (rendering in the
   simulation's process between steps) runs in turn with it, ``--repeat`` times each.

Each part runs in its own process (libsumo runs one simulation per process). The machine may be shared:
numbers are wall-clock.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import queue
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "configs" / "default.yaml"
SIZES = ((1280, 720), (640, 360))


def _config(**overrides):
    from cosim.runconfig import load_run_config

    return load_run_config(CONFIG, **overrides)


# each part puts its row(s) on the queue q


def scene_part(q) -> None:
    import cosim.world3d.render  # noqa: F401  (MUJOCO_GL before MuJoCo)
    from cosim.scenario import build_scenario
    from cosim.world3d.scene import build_scene

    cfg = _config()
    scn = build_scenario(cfg.scenario.map, config=cfg.scenario, seed=cfg.seed, log=lambda *a: None)
    best = None
    for _ in range(3):
        t0 = time.perf_counter()
        scene = build_scene(scn, car=cfg.ego.car)
        dt = time.perf_counter() - t0
        best = dt if best is None else min(best, dt)
    s = scene.stats
    q.put({"part": "scene", "build_s": round(best, 2), "ngeom": scene.model.ngeom, "nmesh": scene.model.nmesh,
           "triangles": sum(s.triangles.values()), **s.counts})  # fmt: skip


def fps_part(frames: int, q) -> None:
    import numpy as np

    import cosim.world3d.render as render
    from cosim.sim import Simulation
    from cosim.world3d.live import LiveSource
    from cosim.world3d.scene import build_scene

    cfg = _config(duration_s=3600.0)
    with Simulation(cfg) as sim:
        scene = build_scene(sim.scenario, car=cfg.ego.car, net=sim.net)
        src = LiveSource(sim)
        while sim.world.t_s < 60.0 or sim.world.ego_slot < 0:  # into town, traffic settled
            sim.step()
        rows = []
        for w, h in SIZES:
            view = render.View(scene, render.ViewParams(w, h, "driver"))
            view.render(src.frame())
            times = []
            for i in range(frames):
                if i % 3 == 0:  # about 30 frames per simulated second
                    sim.step()
                t0 = time.perf_counter()
                view.render(src.frame())
                times.append(time.perf_counter() - t0)
            view.close()
            t = np.array(times)
            rows.append({"part": "fps", "size": f"{w}x{h}", "fps": round(1.0 / t.mean(), 1),
                         "ms_mean": round(1e3 * t.mean(), 1), "ms_p95": round(1e3 * np.percentile(t, 95), 1),
                         "vehicles": sim.world.n_valid})  # fmt: skip
        q.put(rows)


def _drive_setup(overrides: dict):
    from cosim.sim import Simulation

    cfg = _config(duration_s=3600.0, **overrides)
    return Simulation(cfg)


def _settle(sim, viewer=None) -> None:
    from cosim.world3d.drive import wait_for_ego

    wait_for_ego(sim, viewer)  # at medium-high density on the whole map the ego departs after ~160 s
    t_ready = sim.world.t_s + 20.0
    while sim.world.t_s < t_ready:  # SUMO's initial insertions are slow: start in settled traffic
        sim.step()
        if viewer is not None and round(sim.world.t_s * 10) % 20 == 0:
            viewer.poll()  # take in the viewer's messages now and then


def drive_part(label: str, size: tuple[int, int], seconds: float, overrides: dict, fps: float, q) -> None:
    """``cosim drive``'s loop (DriveSession: the viewer in its own process), the scripted driver in the seat,
    the viewer toggling a synthetic key every 0.37 s for the input-to-display latency."""
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    from cosim.world3d.drive import DriveParams, DriveSession

    session = DriveSession(DriveParams(width=size[0], height=size[1], fps=fps), probe_every_s=0.37)
    try:
        with _drive_setup(overrides) as sim:
            session.scene_for(sim)
            _settle(sim, session.window)
            stats = session.run(sim, duration_s=seconds)
            stats["vehicles"] = sim.world.n_valid
    finally:
        session.close()
    keep = ("real_time_factor", "late_steps", "step_ms", "fps", "frame_ms", "stalled_frames", "latency_first_ms",
            "latency_first_p95_ms", "latency_full_ms", "latency_full_p95_ms", "input_events", "vehicles")  # fmt: skip
    q.put({"part": "drive", "loop": f"viewer process, --fps {fps:g}", "traffic": label,
           "size": f"{size[0]}x{size[1]}", **{k: stats.get(k) for k in keep}})  # fmt: skip


def inprocess_part(label: str, size: tuple[int, int], seconds: float, overrides: dict, q) -> None:
    """The loop ``cosim drive`` had before issue 20 (for the comparison in the same run): render in the
    simulation's process between steps, interpolated, at most 30 FPS, every step shown at least once."""
    import time as _t

    import cosim.world3d.render as render
    from cosim.world3d.live import LiveSource
    from cosim.world3d.scene import build_scene
    from cosim.world3d.state import Interpolator

    with _drive_setup(overrides) as sim:
        scene = build_scene(sim.scenario, car=sim.config.ego.car, net=sim.net)
        view = render.View(scene, render.ViewParams(size[0], size[1], "driver"))
        _settle(sim)
        src, dt, frame_dt, clock = LiveSource(sim), sim.step_s, 1.0 / 30.0, _t.perf_counter
        steps, k, frames, late, busy = round(seconds / dt), 0, 0, 0, 0.0
        prev = cur = interp = None
        t0 = clock()
        last_frame, need_frame = -1.0, False
        while k < steps:
            now = clock()
            due = t0 + k * dt
            if now >= due and not need_frame:
                late += now - due > dt
                t_step = clock()
                sim.step()
                k += 1
                prev, cur = cur, src.frame()
                interp = Interpolator(prev, cur) if prev is not None else None
                need_frame = True
                busy += clock() - t_step
                continue
            if cur is not None and (need_frame or now - last_frame >= frame_dt):
                alpha = (now - (t0 + (k - 1) * dt)) / dt
                view.render(interp.at(alpha) if interp is not None else cur)
                frames, last_frame, need_frame = frames + 1, now, False
                continue
            pause = min(t0 + k * dt, last_frame + frame_dt) - clock()
            if pause > 0.0005:
                _t.sleep(min(pause, 0.02))
        wall = clock() - t0
        view.close()
        q.put({"part": "drive", "loop": "in-process (before), 30 at most", "traffic": label, "size": f"{size[0]}x{size[1]}",
               "real_time_factor": round(seconds / wall, 3), "late_steps": late, "step_ms": round(1e3 * busy / k, 1),
               "fps": round(frames / wall, 1), "vehicles": sim.world.n_valid})  # fmt: skip


def _guarded(target, args, q) -> None:
    try:
        target(*args, q)
    except Exception as exc:  # noqa: BLE001 - report the failure as a row, keep the other parts
        q.put({"part": target.__name__, "error": f"{type(exc).__name__}: {exc}"})


def _run(target, *args):
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=_guarded, args=(target, args, q))
    p.start()
    while True:
        try:
            out = q.get(timeout=5.0)
            break
        except queue.Empty:
            if not p.is_alive():
                out = {"part": target.__name__, "error": f"process ended with code {p.exitcode}"}
                break
    p.join()
    rows = out if isinstance(out, list) else [out]
    for r in rows:
        print("  ".join(f"{k}={v}" for k, v in r.items()), file=sys.stderr, flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=30.0, help="wall seconds of each real-time drive")
    ap.add_argument("--frames", type=int, default=120, help="frames per size in the fps part")
    ap.add_argument("--repeat", type=int, default=3, help="drives of each loop at 640x360 (interleaved)")
    ap.add_argument("--skip-drive", action="store_true")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rows = _run(scene_part)
    rows += _run(fps_part, args.frames)
    if not args.skip_drive:
        experiment = {"scenario.demand.density": "medium_high", "scenario.demand.area": "ego_route",
                      "scenario.demand.corridor_m": 250}  # fmt: skip
        network = {"scenario.demand.density": "medium_high"}
        label = "medium_high, route corridor (experiment)"
        for _ in range(args.repeat):  # the new loop (30 FPS at most, the default; 60) and the old one in turn
            rows += _run(drive_part, label, (640, 360), args.seconds, experiment, 30.0)
            rows += _run(drive_part, label, (640, 360), args.seconds, experiment, 60.0)
            rows += _run(inprocess_part, label, (640, 360), args.seconds, experiment)
        rows += _run(drive_part, label, (1280, 720), args.seconds, experiment, 30.0)
        rows += _run(drive_part, "medium_high, whole map", (640, 360), args.seconds, network, 30.0)
    if args.json:
        print(json.dumps(rows))
    else:
        print(markdown(rows))


def markdown(rows: list[dict]) -> str:
    """One table per part (the format BENCHMARKS.md uses)."""
    out = []
    for part, title in (("scene", "Scene generation (default map)"), ("fps", "Driver view, render + HUD"),
                        ("drive", "cosim drive real-time loop (headless window, scripted driver)")):  # fmt: skip
        sel = [r for r in rows if r.get("part") == part or r.get("part", "").startswith(part)]
        if not sel:
            continue
        cols = [k for k in dict.fromkeys(k for r in sel for k in r) if k != "part"]
        out += [f"**{title}**", "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
        out += ["| " + " | ".join(str(r.get(c, "")) for c in cols) + " |" for r in sel]
        out.append("")
    out += summary(rows)
    return "\n".join(out)


def _range(rows: list[dict], key: str) -> str:
    import numpy as np

    v = [r[key] for r in rows if r.get(key) is not None]
    return f"{np.median(v):g} ({min(v):g}-{max(v):g})" if v else "-"


def summary(rows: list[dict]) -> list[str]:
    """The 640x360 route-corridor drives: medians (min-max) of each loop."""
    sel = [r for r in rows if r.get("part") == "drive" and r.get("size") == "640x360"
           and "corridor" in r.get("traffic", "") and "error" not in r]  # fmt: skip
    out = []
    for loop in dict.fromkeys(r["loop"] for r in sel):
        rs = [r for r in sel if r["loop"] == loop]
        line = (f"- {loop} ({len(rs)} drives): {_range(rs, 'fps')} FPS, real-time factor {_range(rs, 'real_time_factor')}, "
                f"{_range(rs, 'late_steps')} late steps")  # fmt: skip
        if any(r.get("latency_first_ms") is not None for r in rs):
            line += (f"; input-to-display latency {_range(rs, 'latency_first_ms')} ms to the first frame moving "
                     f"towards the step that read the input, {_range(rs, 'latency_full_ms')} ms to the frame "
                     f"showing that step whole (p95 {_range(rs, 'latency_full_p95_ms')} ms)")  # fmt: skip
        out.append(line + ".")
    if out:
        out.insert(
            0,
            "Summary, 640x360, experiment traffic, median (min-max):",
        )
        out.insert(1, "")
    threads = os.environ.get("LP_NUM_THREADS") or str(max(1, (os.cpu_count() or 2) - 1))
    out += [
        "",
        f"llvmpipe threads in the viewer: {threads} (LP_NUM_THREADS); load average after: {os.getloadavg()[0]:.1f}.",
    ]
    return out


if __name__ == "__main__":
    main()

"""3D view cost: ``python -m bench.bench_render [--seconds 30] [--frames 120] [--json]``.

On the full default map (configs/default.yaml: Krems), with software OpenGL (Mesa llvmpipe through EGL):

1. scene: time to generate and compile the MuJoCo scene, its geoms, meshes and triangles;
2. fps: frames per second of the driver view at 1280x720 and 640x360 while the default run drives through
   town (scripted driver): each frame = pose the scene from the live state + render + HUD. The simulation
   steps between frames but is not timed here. Shadows off, no multisampling (the defaults);
3. drive: the real-time loop of ``cosim drive`` (headless: ``SDL_VIDEODRIVER=dummy``) for ``--seconds`` of
   wall time in medium-high traffic (the experiment's setting: 7.5 vehicles per lane-km within 250 m of
   the route; and the same density on the whole network), scripted driver in the seat (input devices cost
   nothing measurable): real-time factor, frames per second, late steps, time per step and per frame.

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


def drive_part(label: str, size: tuple[int, int], seconds: float, overrides: dict, q) -> None:
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    from cosim.sim import Simulation
    from cosim.world3d.drive import DriveParams, DriveSession, wait_for_ego

    cfg = _config(duration_s=3600.0, **overrides)
    session = DriveSession(DriveParams(width=size[0], height=size[1], fps=30.0))
    try:
        with Simulation(cfg) as sim:
            session.scene_for(sim)
            wait_for_ego(sim)  # at medium-high density on the whole map the ego departs after ~160 s
            t_ready = sim.world.t_s + 20.0
            while sim.world.t_s < t_ready:  # SUMO's initial insertions are slow: start in settled traffic
                sim.step()
            stats = session.run(sim, duration_s=seconds)
            stats["vehicles"] = sim.world.n_valid
    finally:
        session.close()
    keep = ("real_time_factor", "fps", "late_steps", "lag_resets", "steps", "step_ms", "frame_ms", "vehicles")
    q.put({"part": "drive", "traffic": label, "size": f"{size[0]}x{size[1]}", **{k: stats[k] for k in keep}})


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
    ap.add_argument("--skip-drive", action="store_true")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rows = _run(scene_part)
    rows += _run(fps_part, args.frames)
    if not args.skip_drive:
        experiment = {"scenario.demand.density": "medium_high", "scenario.demand.area": "ego_route",
                      "scenario.demand.corridor_m": 250}  # fmt: skip
        network = {"scenario.demand.density": "medium_high"}
        for label, over in (
            ("medium_high, route corridor (experiment)", experiment),
            ("medium_high, whole map", network),
        ):
            for size in ((640, 360), (1280, 720)):
                rows += _run(drive_part, label, size, args.seconds, over)
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
    return "\n".join(out)


if __name__ == "__main__":
    main()

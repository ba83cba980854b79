"""The ``cosim drive`` and ``cosim render`` sub-commands: parsers and entry points for ``cosim/cli.py``.

Light on purpose: building the parser imports neither MuJoCo nor pygame; ``main_drive`` / ``main_render``
import the 3D modules (which select ``MUJOCO_GL=egl`` before MuJoCo loads) only when they run. Both return
an exit code and raise :class:`cosim.errors.CosimError` for user errors (the CLI prints one line, exit 2).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cosim.errors import CosimError, require_display
from cosim.outdir import RunDir, check_dir, check_file

CAMERAS = ("driver", "chase", "top")


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like 1280x720, got {text!r}") from None
    return w, h


def add_drive_parser(subparsers) -> argparse.ArgumentParser:
    """``cosim drive [CONFIG]``: a window with the driver's view, driven in real time, logged as any run."""
    from cosim.scenario.demand import DENSITY_NAMES

    d = subparsers.add_parser("drive", help="drive the ego yourself in a 3D window, in real time (logged)")
    d.add_argument("config", nargs="?", help="run config YAML (default: built-in defaults)")
    d.add_argument("--driver", choices=("keyboard", "wheel", "scripted"),
                   help="who drives (default: the config's ego.driver.kind; 'scripted' = watch the model)")  # fmt: skip
    d.add_argument("--map", help="OSM file to drive on instead of the config's map")
    d.add_argument("--density", choices=DENSITY_NAMES)
    d.add_argument("--duration", type=float, help="simulated (= wall-clock) seconds")
    d.add_argument("--seed", type=int)
    d.add_argument("--out", help="output directory (default results/<name>-drive)")
    d.add_argument(
        "--force", action="store_true", help="replace a run already in --out (its outputs are removed)"
    )
    d.add_argument("--camera", choices=CAMERAS, default="driver", help="first camera (C cycles)")
    d.add_argument("--size", type=_size, default=(1280, 720), help="window size WxH (default 1280x720)")
    d.add_argument("--fps", type=float, default=60.0, help="frames per second at most (default 60)")
    d.add_argument("--no-smooth", action="store_true", help="show each step as it is (no interpolation)")
    d.add_argument("--fullscreen", action="store_true")
    d.add_argument("--quiet", action="store_true", help="print the result as JSON only")
    d.set_defaults(fn=main_drive)
    return d


def main_drive(args) -> int:
    from cosim.runconfig import load_run_config
    from cosim.world3d.drive import DriveParams, run_drive

    overrides = {"scenario.map": args.map, "scenario.demand.density": args.density, "duration_s": args.duration,
                 "seed": args.seed, "ego.driver.kind": args.driver}  # fmt: skip
    config = load_run_config(args.config, **overrides)
    if not config.ego.enabled:
        raise CosimError("cosim drive needs an ego (ego.enabled: true in the config)")
    out = Path(args.out) if args.out else Path("results") / f"{config.name}-drive"
    try:
        params = DriveParams(width=args.size[0], height=args.size[1], camera=args.camera, fps=args.fps,
                             smooth=not args.no_smooth, fullscreen=args.fullscreen)  # fmt: skip
    except ValueError as exc:
        raise CosimError(str(exc)) from None
    if config.ego.driver.kind in ("keyboard", "wheel"):
        require_display(f"cosim drive --driver {config.ego.driver.kind}")
    with RunDir(out, force=args.force):
        if not args.quiet:
            print(f"cosim drive: {config.ego.driver.kind} driver, {config.duration_s:.0f} s, logging to "
                  f"{out / 'run.mcap'}; Esc ends, C changes the camera", file=sys.stderr)  # fmt: skip
        stats = run_drive(config, out, params, quiet=args.quiet,
                          ready=lambda: print("cosim drive: ready", file=sys.stderr, flush=True))  # fmt: skip
    print(json.dumps(stats) if args.quiet else "\n".join(f"{k}: {v}" for k, v in stats.items()))
    return 0


def add_render_parser(subparsers) -> argparse.ArgumentParser:
    """``cosim render RUN.mcap [--camera driver|chase|top] [--out video.mp4] [--fps 10] [--frames DIR]``."""
    r = subparsers.add_parser(
        "render", help="render a logged run to MP4 / PNG frames (driver, chase or top view)"
    )
    r.add_argument("log", help="the run's MCAP log (run.mcap)")
    r.add_argument("--camera", choices=CAMERAS, default="driver")
    r.add_argument("--out", help="MP4 file (default: <camera>.mp4 beside the log, unless --frames is given)")
    r.add_argument("--frames", help="write PNG stills into this directory (frame_00000.png ...)")
    r.add_argument("--fps", type=float, default=10.0, help="frames per simulated second (default 10)")
    r.add_argument("--start", type=float, help="first frame's simulated time [s]")
    r.add_argument("--end", type=float, help="last frame's simulated time [s]")
    r.add_argument("--size", type=_size, default=(1280, 720), help="frame size WxH, even (default 1280x720)")
    r.add_argument("--no-hud", action="store_true", help="leave the HUD out")
    r.add_argument("--scenario", help="scenario directory to use instead of the run's cached scenario")
    r.add_argument("--quiet", action="store_true", help="print the result as JSON only")
    r.set_defaults(fn=main_render)
    return r


def main_render(args) -> int:
    from cosim.world3d.replay import RenderParams, render_log

    try:
        params = RenderParams(camera=args.camera, width=args.size[0], height=args.size[1], fps=args.fps,
                              start_s=args.start, end_s=args.end, hud=not args.no_hud)  # fmt: skip
    except ValueError as exc:
        raise CosimError(str(exc)) from None
    out = args.out
    if out is None and args.frames is None:
        out = str(Path(args.log).with_name(f"{args.camera}.mp4"))
    if out is not None:
        check_file(out, "--out")
    if args.frames is not None:
        check_dir(args.frames, "--frames")
    summary = render_log(args.log, out, args.frames, params, scenario_dir=args.scenario, quiet=args.quiet)
    if args.quiet:
        print(json.dumps(summary))
    else:
        print("\n".join(f"{k}: {v}" for k, v in summary.items() if v is not None))
    return 0

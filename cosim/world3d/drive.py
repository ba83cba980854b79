"""``cosim drive CONFIG``: drive the ego yourself in a window, in real time, logged like any run.

The loop runs the same :class:`cosim.sim.Simulation` as ``cosim run``: each 0.1 s step starts when the wall
clock reaches it (a step that starts late is counted; a lag of more than ``max_lag_s`` is given up rather
than caught up, so the simulation never races to make up for a slow stretch). The window is a process of its
own (:mod:`cosim.world3d.viewer`): it draws ``fps`` frames per second, interpolated between the last two
steps (``smooth``: one step, 0.1 s, of display latency for fluid motion), independent of the simulation's
steps, and reads the keyboard or wheel there; each step's driver phase uses the newest input state the
viewer has sent (keyboard or wheel through :mod:`cosim.driver`, whichever the config's
``ego.driver.kind`` names). The stats report the frame rate and the input-to-display latency.

Keys besides the driving keys: Esc or closing the window ends the run (the log is complete), C cycles the
camera (driver / chase / top). Without a display, run it under Xvfb (``xvfb-run``) or with
``SDL_VIDEODRIVER=dummy``. :class:`DriveSession` is the reusable part: the experiment runner can drive
several phases in one window.
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from collections import deque
from collections.abc import Callable, Collection
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import cosim.world3d.render  # noqa: F401  first: sets MUJOCO_GL before MuJoCo is imported (also in the viewer)
from cosim.errors import CosimError, require_display
from cosim.world3d.live import LiveSource
from cosim.world3d.scene import SceneParams
from cosim.world3d.viewer import CAMERA_CYCLE, Viewer, ViewerParams, ViewerScene


@dataclass(frozen=True)
class DriveParams:
    width: int = 1280  # [px] window and render size
    height: int = 720  # [px]
    camera: str = "driver"  # first camera: 'driver' | 'chase' | 'top'
    # [1/s] frames drawn per wall-clock second at most, by the viewer process (on its own core: with a cap of
    # 30 the frame rate fell to 27-28 FPS when other jobs shared the 2 cores, with 60 it stayed at 40-56 FPS
    # and the simulation at real time; BENCHMARKS.md, section render)
    fps: float = 60.0
    smooth: bool = True  # interpolate between steps (one step of display latency); False: the newest step
    max_lag_s: float = 0.5  # [s] behind the wall clock by more than this: drop the backlog
    fullscreen: bool = False
    hud: bool = True

    def __post_init__(self) -> None:
        if self.camera not in CAMERA_CYCLE:
            raise ValueError(f"camera must be one of {CAMERA_CYCLE}, got {self.camera!r}")
        if not 1.0 <= self.fps <= 240.0:
            raise ValueError(f"fps must be in [1, 240], got {self.fps}")
        if self.width < 64 or self.height < 64:
            raise ValueError(f"window must be at least 64 x 64 px, got {self.width} x {self.height}")
        if not self.max_lag_s > 0:
            raise ValueError(f"max_lag_s must be > 0, got {self.max_lag_s}")


class DriveWindow:
    """The pygame window (in the viewer process): shows RGB frames and reports the quit / camera keys."""

    def __init__(self, width: int, height: int, title: str = "cosim drive", fullscreen: bool = False) -> None:
        os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
        from cosim.driver.keyboard import import_pygame

        os.environ.setdefault("SDL_AUDIODRIVER", "dummy")  # no sound: keep ALSA quiet
        # SDL would present the window through an OpenGL (GLX) context of its own, current on this thread,
        # and MuJoCo's EGL context then cannot be made current (EGL_BAD_ACCESS): use plain X11 blits
        os.environ.setdefault("SDL_FRAMEBUFFER_ACCELERATION", "0")
        self.pg = pg = import_pygame()
        pg.display.init()
        pg.joystick.init()
        try:
            flags = pg.FULLSCREEN if fullscreen else 0
            self.screen = pg.display.set_mode((width, height), flags)
        except pg.error as exc:
            raise CosimError(
                f"cannot open a window ({exc}); set DISPLAY, run under xvfb-run, or use SDL_VIDEODRIVER=dummy"
            ) from None
        pg.display.set_caption(title)
        self.size = (width, height)
        self.closed = False

    def show(self, img) -> None:
        h, w = img.shape[:2]
        surf = self.pg.image.frombuffer(np.ascontiguousarray(img), (w, h), "RGB")
        if (w, h) != self.size:
            surf = self.pg.transform.scale(surf, self.size)
        self.screen.blit(surf, (0, 0))
        self.pg.display.flip()

    def message(self, text: str) -> None:
        """A plain screen with one line (while the scenario and scene load)."""
        import numpy as np
        from PIL import Image, ImageDraw

        from cosim.world3d.textures import font

        img = Image.new("RGB", self.size, (30, 34, 40))
        ImageDraw.Draw(img).text((self.size[0] / 2, self.size[1] / 2), text, fill=(230, 230, 230),
                                 font=font(max(12, self.size[1] // 24)), anchor="mm")  # fmt: skip
        self.show(np.asarray(img))

    def poll(self) -> set[str]:
        """Pending window actions: 'quit' (Esc / window closed), 'camera' (C)."""
        pg = self.pg
        out: set[str] = set()
        for ev in pg.event.get():
            if ev.type == pg.QUIT or (ev.type == pg.KEYDOWN and ev.key == pg.K_ESCAPE):
                out.add("quit")
            elif ev.type == pg.KEYDOWN and ev.key == pg.K_c:
                out.add("camera")
        return out

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self.pg.display.quit()


class DriveSession:
    """Real-time driving of one or more simulations, shown by a viewer process (:mod:`cosim.world3d.viewer`).

    This process steps the simulation on the wall clock and sends each step's state to the viewer, which
    owns the window, reads the keyboard / wheel there, and draws interpolated frames at its own pace; see the
    module docstring. ``window`` is the viewer (it has ``message`` and ``poll`` like a window)."""

    def __init__(self, params: DriveParams | None = None, window: Viewer | None = None,
                 scene_params: SceneParams | None = None, probe_every_s: float | None = None) -> None:  # fmt: skip
        self.params = p = params or DriveParams()
        self.window = window or Viewer(ViewerParams(
            width=p.width, height=p.height, fullscreen=p.fullscreen, fps=p.fps, smooth=p.smooth, camera=p.camera,
            hud=p.hud, probe_every_s=probe_every_s))  # fmt: skip
        self.scene_params = scene_params or SceneParams(
            max_width=max(p.width, 1280), max_height=max(p.height, 720)
        )
        self._scene_key: str | None = None

    def scene_for(self, sim) -> None:
        """Have the viewer build (or reuse) the scene of ``sim``'s scenario; returns when it can draw."""
        key = str(Path(sim.scenario.dir).resolve())
        if key != self._scene_key:
            self.window.message("building the 3D scene ...")
            self.window.open_scene(ViewerScene(key, sim.step_s, self.scene_params, sim.config.ego.car,
                                               sim.config.ego.driver))  # fmt: skip
            self._scene_key = key

    def run(self, sim, duration_s: float | None = None, should_stop: Callable[[], bool] | None = None,
            on_step: Callable[[object], None] | None = None) -> dict:  # fmt: skip
        """Step ``sim`` in real time for ``duration_s`` (default: the config's) and show it; returns stats.

        Ends early on Esc / window close ('quit': True in the stats) or when ``should_stop()`` is true.
        Each step reads the newest input the viewer has sent (the driver phase) and its state goes to the
        viewer right after; this process never waits for a frame.
        """
        p = self.params
        viewer = self.window
        self.scene_for(sim)
        src = LiveSource(sim)
        dt = sim.step_s
        # the config's duration counts from t = 0 (steps already run, e.g. waiting for the ego, included)
        steps_total = (
            max(0, sim.steps_total - sim.stats["steps"]) if duration_s is None else round(duration_s / dt)
        )
        nearest = (
            2 * self.scene_params.vehicle_pool
        )  # the viewer's pool shows the nearest; a margin for motion
        reach = self.scene_params.vehicle_max_distance_m + 30.0
        clock = time.monotonic
        deadline = clock() + 2.0
        while viewer.input_seq == 0 and clock() < deadline and not viewer.poll(0.05):
            pass  # the devices' first state (a wheel's axes) before the first step reads it
        viewer.report()  # the viewer's frame and latency counters start with this run
        rtf_window: deque[tuple[float, float]] = deque(maxlen=40)  # (wall, sim time) of recent steps
        stats = {"steps": 0, "late_steps": 0, "lag_resets": 0, "quit": False}
        busy = {"step": 0.0, "send": 0.0}  # [s] wall time spent stepping and preparing / sending frames
        sim_t0 = sim.world.t_s
        t0 = clock()
        k = 0  # steps done; step k is due at t0 + k * dt
        viewer.send_frame(src.frame(nearest=nearest, max_distance_m=reach))
        try:
            while k < steps_total:
                if "quit" in viewer.poll() or (should_stop is not None and should_stop()):
                    stats["quit"] = viewer.quit
                    break
                now = clock()
                due = t0 + k * dt
                if now < due:
                    viewer.poll(min(due - now, 0.05))  # sleep, but take input in as it comes
                    continue
                if now - due > dt:
                    stats["late_steps"] += 1
                if now - due > p.max_lag_s:  # give the backlog up: re-anchor the pace here
                    t0 = now - k * dt
                    stats["lag_resets"] += 1
                tag = viewer.input_seq  # the input this step reads (the driver phase, inside sim.step)
                t_step = clock()
                sim.step()
                k += 1
                if on_step is not None:
                    on_step(sim)
                t_sent = clock()
                busy["step"] += t_sent - t_step
                rtf_window.append((t_sent, sim.world.t_s))
                rtf = None
                if len(rtf_window) > 5:
                    (w0, s0), (w1, s1) = rtf_window[0], rtf_window[-1]
                    rtf = (s1 - s0) / (w1 - w0) if w1 > w0 else None
                viewer.send_frame(src.frame(real_time_factor=rtf, nearest=nearest, max_distance_m=reach), tag)
                busy["send"] += clock() - t_sent
        except KeyboardInterrupt:
            stats["quit"] = True
        wall = clock() - t0
        sim_s = sim.world.t_s - sim_t0
        stats.update(steps=k, simulated_s=round(sim_s, 3), wall_s=round(wall, 2),
                     real_time_factor=round(sim_s / wall, 3) if wall > 0 else None,
                     step_ms=round(1e3 * busy["step"] / max(k, 1), 1),
                     send_ms=round(1e3 * busy["send"] / max(k, 1), 2))  # fmt: skip
        stats.update(viewer.report())  # frames, fps, frame time, input-to-display latency of this run
        return stats

    def close(self) -> dict:
        """Stop the viewer; returns its stats (frames, fps, frame time, input-to-display latency)."""
        return self.window.close()


def run_drive(config, out_dir: str | Path | None, params: DriveParams | None = None, *,
              key_source: Callable[[], Collection[str]] | None = None, quiet: bool = True,
              ready: Callable[[], None] | None = None, on_sim: Callable[[object], None] | None = None) -> dict:  # fmt: skip
    """Open the window, start the simulation of ``config`` (a RunConfig) logging to ``out_dir``, drive it.

    key_source: replaces the keyboard driver's key reader (a function returning the pressed key names);
    for scripted input in tests. ready: called once the first step is about to run. on_sim: called with
    the Simulation before the first step (e.g. the experiment's phase schedule).
    """
    from cosim.driver import KeyboardDriver, WheelDriver
    from cosim.sim import Simulation

    if config.ego.driver.kind in ("keyboard", "wheel") and key_source is None:
        # a person drives: without a display SDL falls back to an invisible window, and a run nobody drove
        # would be logged as if someone had
        require_display(f"cosim drive with the {config.ego.driver.kind} driver")
    session = DriveSession(params)
    # pygame's display is the viewer's: here (key names only, the driver's key reader is replaced below)
    # pygame would warn that it was not initialised
    warnings.filterwarnings("ignore", message=r"pygame\.init\(\) has not been called")
    try:
        drv = config.ego.driver
        if config.ego.physics == "mujoco" and key_source is None:  # check the device before a log is opened
            if drv.kind == "wheel":
                from cosim.driver.wheel import PygameJoystickSource

                PygameJoystickSource(drv.wheel, pump_events=False)
            elif drv.kind == "keyboard":
                from cosim.driver.keyboard import PygameKeySource

                PygameKeySource(drv.keyboard, pump_events=False)
        session.window.message("building the scenario ...")
        say = (lambda *a: None) if quiet else print
        with Simulation(config, out_dir=out_dir, quiet=quiet, log=say, radio_process=None) as sim:
            if drv.kind in ("keyboard", "wheel") or key_source is not None:
                if sim.ego is None:
                    raise CosimError("a person driving needs an ego driven by MuJoCo (ego.physics: mujoco)")
                # the devices are read in the viewer's window: the driver takes their state from it
                if key_source is not None or drv.kind == "keyboard":
                    sim.ego.driver = KeyboardDriver(
                        drv.keyboard, key_source=key_source or session.window.key_state
                    )
                else:
                    sim.ego.driver = WheelDriver(drv.wheel, source=session.window.wheel_state)
            if on_sim is not None:
                on_sim(sim)
            session.scene_for(sim)
            wait_for_ego(sim, session.window)
            if ready is not None:
                ready()
            stats = session.run(sim)
            stats.update({k: v for k, v in sim.stats.items() if k not in stats})
    finally:
        session.close()
    if out_dir is not None:
        stats["log"] = str(Path(out_dir) / "run.mcap")
    return stats


def wait_for_ego(sim, window: Viewer | DriveWindow | None = None, limit_s: float = 600.0) -> None:
    """Step (as fast as possible, logged as usual) until the ego is on the road, so the person does not
    wait in real time through SUMO's insertion of the initial traffic and the ego's departure delay."""
    steps = round(limit_s / sim.step_s)
    for i in range(steps):
        if sim.world.ego_slot >= 0 and (sim.ego is None or getattr(sim.ego, "started", True)):
            return
        if window is not None and i % 10 == 0:
            window.poll()
            window.message(f"waiting for the ego to depart ... t = {sim.world.t_s:.0f} s")
        sim.step()
    raise CosimError(f"the ego did not depart within {limit_s:.0f} s of simulated time; check ego.depart_s")


def main(argv: list[str] | None = None) -> int:
    """``python -m cosim.world3d.drive``: the same as ``cosim drive``."""
    from cosim.cli import main as cosim_main

    return cosim_main(["drive", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())

__all__ = ["DriveParams", "DriveSession", "DriveWindow", "run_drive", "wait_for_ego"]

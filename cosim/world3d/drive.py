"""``cosim drive CONFIG``: drive the ego yourself in a window, in real time, logged like any run.

The loop runs the same :class:`cosim.sim.Simulation` as ``cosim run``: each 0.1 s step starts when the wall
clock reaches it (a step that starts late is counted; a lag of more than ``max_lag_s`` is given up rather
than caught up, so the simulation never races to make up for a slow stretch). Between steps the window
shows frames interpolated between the last two steps (``smooth``), which adds one step (0.1 s) of display
latency but makes motion fluid at the display's frame rate; input is read once per step, by the driver
phase (keyboard or wheel through :mod:`cosim.driver`, whichever the config's ``ego.driver.kind`` names).

Keys besides the driving keys: Esc or closing the window ends the run (the log is complete), C cycles the
camera (driver / chase / top). Without a display, run it under Xvfb (``xvfb-run``) or with
``SDL_VIDEODRIVER=dummy``. :class:`DriveSession` is the reusable part: the experiment runner can drive
several phases in one window.
"""

from __future__ import annotations

import os
import sys
import time
from collections import deque
from collections.abc import Callable, Collection
from dataclasses import dataclass
from pathlib import Path

import cosim.world3d.render as render_mod  # first: sets MUJOCO_GL before MuJoCo is imported
from cosim.errors import CosimError, require_display
from cosim.world3d.live import LiveSource
from cosim.world3d.scene import Scene, SceneParams, build_scene
from cosim.world3d.state import Interpolator

CAMERA_CYCLE = ("driver", "chase", "top")


@dataclass(frozen=True)
class DriveParams:
    width: int = 1280  # [px] window and render size
    height: int = 720  # [px]
    camera: str = "driver"  # first camera: 'driver' | 'chase' | 'top'
    fps: float = 30.0  # [1/s] frames drawn per wall-clock second at most
    smooth: bool = True  # interpolate between steps (one step of display latency); False: show each step
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
    """The pygame window: shows RGB frames and reports the quit / camera keys."""

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
        surf = self.pg.image.frombuffer(img.tobytes(), (w, h), "RGB")
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
    """Real-time driving of one or more simulations in one window (scenes cached per scenario)."""

    def __init__(self, params: DriveParams | None = None, window: DriveWindow | None = None,
                 scene_params: SceneParams | None = None) -> None:  # fmt: skip
        self.params = p = params or DriveParams()
        self.window = window or DriveWindow(p.width, p.height, fullscreen=p.fullscreen)
        self.scene_params = scene_params or SceneParams(
            max_width=max(p.width, 1280), max_height=max(p.height, 720)
        )
        self._scenes: dict[str, Scene] = {}
        self._views: dict[int, render_mod.View] = {}  # one renderer per scene, all cameras
        self.camera = p.camera

    def scene_for(self, sim) -> Scene:
        key = str(Path(sim.scenario.dir).resolve())
        if key not in self._scenes:
            self.window.message("building the 3D scene ...")
            self._scenes[key] = build_scene(
                sim.scenario, self.scene_params, car=sim.config.ego.car, net=sim.net
            )
        return self._scenes[key]

    def view(self, scene: Scene) -> render_mod.View:
        if id(scene) not in self._views:
            p = self.params
            self._views[id(scene)] = render_mod.View(
                scene, render_mod.ViewParams(p.width, p.height, p.camera, p.hud)
            )
        return self._views[id(scene)]

    def run(self, sim, duration_s: float | None = None, should_stop: Callable[[], bool] | None = None,
            on_step: Callable[[object], None] | None = None) -> dict:  # fmt: skip
        """Step ``sim`` in real time for ``duration_s`` (default: the config's) and show it; returns stats.

        Ends early on Esc / window close ('quit': True in the stats) or when ``should_stop()`` is true.
        """
        p = self.params
        scene = self.scene_for(sim)
        src = LiveSource(sim)
        dt = sim.step_s
        # the config's duration counts from t = 0 (steps already run, e.g. waiting for the ego, included)
        steps_total = (
            max(0, sim.steps_total - sim.stats["steps"]) if duration_s is None else round(duration_s / dt)
        )
        frame_dt = 1.0 / p.fps
        clock = time.perf_counter
        rtf_window: deque[tuple[float, float]] = deque(maxlen=40)  # (wall, sim time) of recent steps
        stats = {"steps": 0, "frames": 0, "late_steps": 0, "lag_resets": 0, "quit": False}
        busy = {"step": 0.0, "draw": 0.0}  # [s] wall time spent stepping and drawing
        self.view(scene)  # open the renderer now: that takes a while
        prev = cur = None
        interp: Interpolator | None = None
        t0 = clock()
        k = 0  # steps done; step k is due at t0 + k * dt
        last_frame = -1.0
        need_frame = False
        sim_t0 = sim.world.t_s
        try:
            while k < steps_total:
                actions = self.window.poll()
                if "quit" in actions or (should_stop is not None and should_stop()):
                    stats["quit"] = "quit" in actions
                    break
                if "camera" in actions:
                    self.camera = CAMERA_CYCLE[(CAMERA_CYCLE.index(self.camera) + 1) % len(CAMERA_CYCLE)]
                now = clock()
                due = t0 + k * dt
                if now >= due and not need_frame:
                    if now - due > dt:
                        stats["late_steps"] += 1
                    if now - due > p.max_lag_s:  # give the backlog up: re-anchor the pace here
                        t0 = now - k * dt
                        stats["lag_resets"] += 1
                    t_step = clock()
                    sim.step()
                    k += 1
                    if on_step is not None:
                        on_step(sim)
                    rtf_window.append((clock(), sim.world.t_s))
                    rtf = None
                    if len(rtf_window) > 5:
                        (w0, s0), (w1, s1) = rtf_window[0], rtf_window[-1]
                        rtf = (s1 - s0) / (w1 - w0) if w1 > w0 else None
                    prev, cur = cur, src.frame(real_time_factor=rtf)
                    interp = Interpolator(prev, cur) if (p.smooth and prev is not None) else None
                    need_frame = True  # every step is shown at least once, even when running late
                    busy["step"] += clock() - t_step
                    continue
                if cur is not None and (need_frame or (p.smooth and now - last_frame >= frame_dt)):
                    alpha = (now - (t0 + (k - 1) * dt)) / dt  # how far into the current step
                    self._draw(scene, interp.at(alpha) if interp is not None else cur)
                    stats["frames"] += 1
                    busy["draw"] += clock() - now
                    last_frame = now
                    need_frame = False
                    continue
                wake = min(t0 + k * dt, last_frame + frame_dt) if p.smooth else t0 + k * dt
                pause = wake - clock()
                if pause > 0.0005:
                    time.sleep(min(pause, 0.02))
        except KeyboardInterrupt:
            stats["quit"] = True
        wall = clock() - t0
        sim_s = sim.world.t_s - sim_t0
        stats.update(steps=k, simulated_s=round(sim_s, 3), wall_s=round(wall, 2),
                     real_time_factor=round(sim_s / wall, 3) if wall > 0 else None,
                     fps=round(stats["frames"] / wall, 1) if wall > 0 else None,
                     step_ms=round(1e3 * busy["step"] / max(k, 1), 1),
                     frame_ms=round(1e3 * busy["draw"] / max(stats["frames"], 1), 1))  # fmt: skip
        return stats

    def _draw(self, scene: Scene, frame) -> None:
        self.window.show(self.view(scene).render(frame, camera=self.camera))

    def close(self) -> None:
        for v in self._views.values():
            v.close()
        self._views.clear()
        self.window.close()


def run_drive(config, out_dir: str | Path | None, params: DriveParams | None = None, *,
              key_source: Callable[[], Collection[str]] | None = None, quiet: bool = True,
              ready: Callable[[], None] | None = None, on_sim: Callable[[object], None] | None = None) -> dict:  # fmt: skip
    """Open the window, start the simulation of ``config`` (a RunConfig) logging to ``out_dir``, drive it.

    key_source: replaces the keyboard driver's key reader (a function returning the pressed key names);
    for scripted input in tests. ready: called once the first step is about to run. on_sim: called with
    the Simulation before the first step (e.g. the experiment's phase schedule).
    """
    from cosim.driver import KeyboardDriver
    from cosim.sim import Simulation

    if config.ego.driver.kind in ("keyboard", "wheel") and key_source is None:
        # a person drives: without a display SDL falls back to an invisible window, and a run nobody drove
        # would be logged as if someone had
        require_display(f"cosim drive with the {config.ego.driver.kind} driver")
    session = DriveSession(params)
    try:
        drv = config.ego.driver
        if config.ego.physics == "mujoco" and key_source is None:  # check the device before a log is opened
            if drv.kind == "wheel":
                from cosim.driver.wheel import PygameJoystickSource

                PygameJoystickSource(drv.wheel)
            elif drv.kind == "keyboard":
                from cosim.driver.keyboard import PygameKeySource

                PygameKeySource(drv.keyboard)
        session.window.message("building the scenario ...")
        say = (lambda *a: None) if quiet else print
        with Simulation(config, out_dir=out_dir, quiet=quiet, log=say) as sim:
            if key_source is not None:
                if sim.ego is None:
                    raise CosimError("key_source needs an ego driven by MuJoCo (ego.physics: mujoco)")
                sim.ego.driver = KeyboardDriver(config.ego.driver.keyboard, key_source=key_source)
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


def wait_for_ego(sim, window: DriveWindow | None = None, limit_s: float = 600.0) -> None:
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

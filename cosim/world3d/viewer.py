"""The drive view in a process of its own: window, input devices, MuJoCo rendering and the HUD.

``cosim drive`` steps the simulation in real time in its own process; libsumo and most of a step hold the
GIL, and a frame takes 15-40 ms of software rendering, so a view drawn in the same process (or a thread of
it) gets only the gaps between steps (16-18 FPS at 640x360). Here the simulation process sends each step's
:class:`FrameState` (the SCVs near the ego only) over a pipe, and this process draws frames at its own rate
(``fps``), each interpolated between the last two steps by the wall clock (:class:`state.Playback`), while
it reads the keyboard / wheel in its window and sends their state back; the simulation's driver phase uses
the newest state it has received when the step starts.

Protocol (tuples over a socket pair with ``multiprocessing.connection``; the viewer is its own interpreter):

- simulation -> viewer: ``("params", ViewerParams)`` first; ``("message", text)`` a status screen; ``("scene", ViewerScene)`` build the scene (cached
  per scenario directory) and open the renderer, answered by ``("ready", info)``; ``("frame", FrameState, tag)``
  a step (``tag``: the input event the step has read); ``("report",)`` answered by ``("stats", dict)`` (frames
  and latencies since the last report); ``("shown",)`` answered by ``("shown", FrameState)`` (the last frame's);
  ``("stop",)`` answered by ``("stats", dict)``, then the viewer exits;
- viewer -> simulation: ``("window",)`` or ``("error", text)`` once at the start; ``("input", seq, state)``
  when the devices' state changes (keyboard: the pressed bound key names; wheel: (axes, buttons));
  ``("quit",)`` (Esc or the window closed).

The viewer exits when the pipe closes or its parent process is gone, so it never outlives the simulation.
Latency: for each input event the viewer notes when it read it and when the first frame was flipped that
moves towards the step which read it (``latency_first_ms``) and that shows that step completely
(``latency_full_ms``, one step later with interpolation).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from collections import deque
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from typing import Any

from cosim.errors import CosimError

CAMERA_CYCLE = ("driver", "chase", "top")
PROBE_KEY = "__probe__"  # a synthetic key name no binding uses (benchmarks and tests measure latency with it)


@dataclass(frozen=True)
class ViewerParams:
    """The window and the frame pacing (sent to the viewer process at its start)."""

    width: int = 1280  # [px]
    height: int = 720  # [px]
    title: str = "cosim drive"
    fullscreen: bool = False
    fps: float = 60.0  # [1/s] frames drawn per wall-clock second at most
    smooth: bool = True  # interpolate between steps (adds one step of display latency)
    camera: str = "driver"
    hud: bool = True
    probe_every_s: float | None = None  # [s] toggle the synthetic PROBE_KEY this often (latency measurement)

    def __post_init__(self) -> None:
        if self.camera not in CAMERA_CYCLE:
            raise ValueError(f"camera must be one of {CAMERA_CYCLE}, got {self.camera!r}")
        if not 1.0 <= self.fps <= 240.0:
            raise ValueError(f"fps must be in [1, 240], got {self.fps}")
        if self.probe_every_s is not None and not self.probe_every_s > 0:
            raise ValueError(f"probe_every_s must be > 0, got {self.probe_every_s}")


@dataclass(frozen=True)
class ViewerScene:
    """What the viewer needs to build a scenario's scene and read the person's devices."""

    scenario_dir: str
    step_s: float  # [s] simulation step (the interpolation's pace)
    scene_params: Any = None  # scene.SceneParams
    car: Any = None  # ego_mujoco.CarParams of the ego
    driver: Any = None  # runconfig's ego.driver config: 'keyboard' / 'wheel' are read in the window


@dataclass
class _Latency:
    """Input events waiting for their frames, and the measured latencies [s]."""

    pending: deque = field(default_factory=deque)  # (seq, t_read, first flip or None)
    first: list[float] = field(default_factory=list)
    full: list[float] = field(default_factory=list)

    def flipped(self, t_flip: float, tag_next: int, tag_shown: int) -> None:
        for i, (seq, t_read, t_first) in enumerate(self.pending):
            if t_first is None and tag_next >= seq:
                self.pending[i] = (seq, t_read, t_flip)
                self.first.append(t_flip - t_read)
        while self.pending and self.pending[0][2] is not None and tag_shown >= self.pending[0][0]:
            seq, t_read, _ = self.pending.popleft()
            self.full.append(t_flip - t_read)


class _Counters:
    """A viewer's frame and latency statistics since the last report."""

    def __init__(self) -> None:
        self.lat = _Latency()
        self.frames = self.dropped = self.stalled = 0
        self.busy: list[float] = []  # [s] per frame: pose + render + HUD + show
        self.t_first: float | None = None
        self.t_last: float | None = None
        self._last_shown = None
        self._seq0: int | None = None

    def flipped(self, t_start: float, t_flip: float, tag_next: int, tag_shown: int, key) -> None:
        self.lat.flipped(t_flip, tag_next, tag_shown)
        if key == self._last_shown:
            self.stalled += 1  # the same picture again: the simulation's next step is late
        self._last_shown = key
        self.frames += 1
        self.busy.append(t_flip - t_start)
        self.t_first = t_start if self.t_first is None else self.t_first
        self.t_last = t_start

    def report(self) -> dict:
        import numpy as np

        out: dict[str, Any] = {
            "frames": self.frames,
            "dropped_frames": self.dropped,
            "stalled_frames": self.stalled,
        }
        if self.frames > 1 and self.t_last > self.t_first:
            out["fps"] = round((self.frames - 1) / (self.t_last - self.t_first), 1)
        if self.busy:
            b = 1e3 * np.asarray(self.busy)
            out["frame_ms"] = round(float(b.mean()), 1)
            out["frame_p95_ms"] = round(float(np.percentile(b, 95)), 1)
        out["input_events"] = len(self.lat.first)
        out.update(_summary(self.lat.first, "latency_first"))
        out.update(_summary(self.lat.full, "latency_full"))
        return out


def _summary(values: list[float], name: str) -> dict:
    import numpy as np

    if not values:
        return {}
    a = 1e3 * np.asarray(values)
    return {f"{name}_ms": round(float(np.median(a)), 1), f"{name}_p95_ms": round(float(np.percentile(a, 95)), 1),
            f"{name}_max_ms": round(float(a.max()), 1)}  # fmt: skip


class _Devices:
    """The person's input devices, read in the viewer's window (pygame state after the events are polled)."""

    def __init__(self, driver, probe_every_s: float | None) -> None:
        from cosim.driver.keyboard import PygameKeySource
        from cosim.driver.wheel import PygameJoystickSource

        kind = getattr(driver, "kind", None)
        self.keys = PygameKeySource(driver.keyboard, pump_events=False) if kind == "keyboard" else None
        self.wheel = PygameJoystickSource(driver.wheel, pump_events=False) if kind == "wheel" else None
        self.probe_every_s = probe_every_s
        self._probe_on = False
        self._next_probe: float | None = None

    def state(self, now: float):
        keys = set(self.keys()) if self.keys is not None else set()
        if self.probe_every_s is not None:
            if self._next_probe is None:
                self._next_probe = now + self.probe_every_s
            elif now >= self._next_probe:
                self._probe_on = not self._probe_on
                self._next_probe += self.probe_every_s
            if self._probe_on:
                keys.add(PROBE_KEY)
        if self.wheel is not None:
            axes, buttons = self.wheel()
            return (tuple(round(a, 4) for a in axes), tuple(buttons), frozenset(keys))
        return frozenset(keys)


def _child_main(fd: int) -> None:
    """The viewer process's entry (``python -c``): the connection on ``fd``, the params first."""
    conn = Connection(fd)
    parent = os.getppid()
    try:
        msg = conn.recv()
    except (EOFError, OSError):
        return
    viewer_main(conn, msg[1], parent)


def viewer_main(conn, params: ViewerParams, parent_pid: int) -> None:
    """The viewer: window, devices, frames, until ``stop``, the pipe's end or the parent's."""
    import cosim.world3d.render as render_mod  # first: MUJOCO_GL before MuJoCo loads
    from cosim.world3d.drive import DriveWindow
    from cosim.world3d.scene import build_scene
    from cosim.world3d.state import Playback

    try:
        window = DriveWindow(params.width, params.height, title=params.title, fullscreen=params.fullscreen)
    except CosimError as exc:
        conn.send(("error", str(exc)))
        return
    conn.send(("window",))
    clock = time.monotonic
    scenes: dict[str, tuple[Any, Any]] = {}  # scenario dir -> (Scene, View)
    view = playback = devices = last_frame = None
    camera = params.camera
    frame_dt = 1.0 / params.fps
    counters = _Counters()
    last_state = None
    seq = 0
    next_t = clock()

    def send(msg) -> bool:
        try:
            conn.send(msg)
            return True
        except (BrokenPipeError, ConnectionResetError, OSError):
            return False

    try:
        while True:
            if os.getppid() != parent_pid:  # the simulation is gone (even killed): never outlive it
                return
            # 1. what the simulation sent
            while conn.poll(0):
                msg = conn.recv()  # EOFError: the simulation closed the pipe
                kind = msg[0]
                if kind == "frame":
                    if playback is not None:
                        playback.push(msg[1], clock(), msg[2])
                elif kind == "message":
                    if playback is None or playback.empty:
                        window.message(msg[1])
                elif kind == "scene":
                    spec: ViewerScene = msg[1]
                    t0 = clock()
                    try:
                        if spec.scenario_dir not in scenes:
                            sc = build_scene(spec.scenario_dir, spec.scene_params, car=spec.car)
                            vp = render_mod.ViewParams(params.width, params.height, camera, params.hud)
                            scenes[spec.scenario_dir] = (sc, render_mod.View(sc, vp))
                        devices = _Devices(spec.driver, params.probe_every_s)
                    except Exception as exc:  # noqa: BLE001 - one line back to the simulation, which raises it
                        send(
                            ("error", f"the drive view could not open the scene: {type(exc).__name__}: {exc}")
                        )
                        return
                    view = scenes[spec.scenario_dir][1]
                    playback = Playback(spec.step_s, params.smooth)
                    last_state = None
                    send(("ready", {"scene_s": round(clock() - t0, 2)}))
                elif kind == "shown":  # what the last frame showed (tests)
                    send(("shown", last_frame))
                elif kind in ("report", "stop"):
                    send(("stats", counters.report()))
                    counters = _Counters()
                    if kind == "stop":
                        return
            # 2. the window and the devices
            actions = window.poll()
            if "quit" in actions:
                send(("quit",))
            if "camera" in actions:
                camera = CAMERA_CYCLE[(CAMERA_CYCLE.index(camera) + 1) % len(CAMERA_CYCLE)]
            now = clock()
            if devices is not None and playback is not None:
                state = devices.state(now)
                if state != last_state:
                    last_state = state
                    seq += 1
                    counters.lat.pending.append((seq, now, None))
                    send(("input", seq, state))
            # 3. a frame when one is due
            if playback is not None and not playback.empty and now >= next_t:
                shown = playback.at(now)
                frame, tag_next, tag_shown = shown
                img = view.render(frame, camera=camera)
                last_frame = frame
                window.show(img)
                t_flip = clock()
                counters.flipped(now, t_flip, tag_next, tag_shown, (frame.t_s, playback.received))
                next_t += frame_dt
                if (
                    t_flip - next_t > frame_dt
                ):  # behind the pace by more than a frame: re-anchor, no catching up
                    counters.dropped += int((t_flip - next_t) / frame_dt)
                    next_t = t_flip
                continue
            if playback is None or playback.empty:
                next_t = now
            # 4. sleep until the next frame, a message, or 10 ms (the devices are read at >= 100 Hz)
            conn.poll(max(0.0, min(next_t - clock(), 0.01)))
    except (EOFError, KeyboardInterrupt, BrokenPipeError, ConnectionResetError):
        return
    finally:
        for _, vw in scenes.values():
            vw.close()
        window.close()


class Viewer:
    """The simulation's handle on the viewer process: start, scene, frames, input, stop.

    The viewer is a fresh interpreter (``python -c``, not ``multiprocessing``: no re-import of the caller's
    ``__main__``), connected by a socket pair; ``MUJOCO_GL`` defaults to ``egl`` in its environment."""

    def __init__(self, params: ViewerParams | None = None, start_timeout_s: float = 60.0) -> None:
        self.params = params or ViewerParams()
        ours, theirs = socket.socketpair()
        env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL") or "egl"}
        # Mesa's software rasteriser (llvmpipe) draws with one thread per core by default; leave the
        # simulation a core of its own unless told otherwise
        env.setdefault("LP_NUM_THREADS", str(max(1, (os.cpu_count() or 2) - 1)))
        code = f"from cosim.world3d.viewer import _child_main; _child_main({theirs.fileno()})"
        try:
            self.proc = subprocess.Popen([sys.executable, "-c", code], pass_fds=(theirs.fileno(),), env=env)
        finally:
            theirs.close()
        self._conn = Connection(ours.detach())
        self.input_state: Any = None  # the newest device state received (None: none yet)
        self.input_seq = 0  # its event number (0: none yet)
        self.quit = False
        self.stats: dict = {}
        self._closed = False
        self._send(("params", self.params))
        try:
            msg = self._expect(("window", "error"), start_timeout_s, "open its window")
        except CosimError:
            self.close()
            raise
        if msg[0] == "error":
            self.close()
            raise CosimError(msg[1])

    @property
    def pid(self) -> int:
        return self.proc.pid

    @property
    def alive(self) -> bool:
        return not self._closed and self.proc.poll() is None

    def _send(self, msg) -> None:
        if self._closed:
            return
        try:
            self._conn.send(msg)
        except (BrokenPipeError, ConnectionResetError, OSError):
            self.quit = True  # the viewer is gone (window closed hard, crashed): the drive ends

    def _handle(self, msg) -> None:
        kind = msg[0]
        if kind == "input":
            self.input_seq, self.input_state = msg[1], msg[2]
        elif kind == "quit":
            self.quit = True
        elif kind == "stats":
            self.stats = msg[1]

    def _expect(self, kinds: tuple[str, ...], timeout_s: float, what: str):
        deadline = time.monotonic() + timeout_s
        while True:
            left = deadline - time.monotonic()
            try:
                ready = self._conn.poll(max(0.0, min(left, 0.5)))
            except (EOFError, OSError):
                ready = False
            if ready:
                try:
                    msg = self._conn.recv()
                except (EOFError, OSError):
                    raise CosimError(f"the drive view's process ended before it could {what}") from None
                if msg[0] in kinds:
                    return msg
                self._handle(msg)
                continue
            if self.proc.poll() is not None:
                raise CosimError(
                    f"the drive view's process ended (exit code {self.proc.returncode}) before it could {what}"
                )
            if left <= 0:
                raise CosimError(f"the drive view did not {what} within {timeout_s:.0f} s")

    def poll(self, timeout_s: float = 0.0) -> set[str]:
        """Take in what the viewer sent (input, quit), waiting up to ``timeout_s`` for the first message;
        returns {'quit'} once the person has quit or the viewer is gone."""
        if not self._closed:
            try:
                if self._conn.poll(timeout_s):
                    while True:
                        self._handle(self._conn.recv())
                        if not self._conn.poll(0):
                            break
            except (EOFError, OSError):
                self.quit = True
            if not self.quit and self.proc.poll() is not None:
                self.quit = True
        return {"quit"} if self.quit else set()

    def message(self, text: str) -> None:
        self._send(("message", text))

    def open_scene(self, scene: ViewerScene, timeout_s: float = 300.0) -> dict:
        """Build (or reuse) the scenario's scene in the viewer; returns once it can draw frames."""
        self._send(("scene", scene))
        msg = self._expect(("ready", "error"), timeout_s, "build the 3D scene")
        if msg[0] == "error":
            raise CosimError(msg[1])
        return msg[1]

    def send_frame(self, frame, tag: int | None = None) -> None:
        self._send(("frame", frame, self.input_seq if tag is None else tag))

    def shown(self, timeout_s: float = 10.0):
        """The FrameState the viewer's last frame showed (None before the first frame)."""
        self._send(("shown",))
        return self._expect(("shown",), timeout_s, "report its last frame")[1]

    def key_state(self) -> frozenset[str]:
        """The pressed key names (a KeyboardDriver's key_source)."""
        s = self.input_state
        if isinstance(s, tuple):
            return s[2]
        return s if s is not None else frozenset()

    def wheel_state(self) -> tuple[tuple[float, ...], tuple[bool, ...]]:
        """(axes, buttons) of the wheel (a WheelDriver's source); all centred before the first reading."""
        s = self.input_state
        if isinstance(s, tuple):
            return s[0], s[1]
        return (), ()

    def report(self, timeout_s: float = 10.0) -> dict:
        """The viewer's frame and latency statistics since its last report (or the scene's start)."""
        if not self.alive:
            return {}
        self._send(("report",))
        try:
            return self._expect(("stats",), timeout_s, "report")[1]
        except CosimError:
            return {}

    def close(self, timeout_s: float = 10.0) -> dict:
        """Stop the viewer (its stats come back) and wait for its process to end; idempotent."""
        if self._closed:
            return self.stats
        if self.proc.poll() is None:
            self._send(("stop",))
            try:
                self.stats = self._expect(("stats",), timeout_s, "stop")[1]
            except CosimError:
                pass
        self._closed = True
        self.quit = True
        for end in (None, self.proc.terminate, self.proc.kill):  # ask, then insist
            if end is not None:
                end()
            try:
                self.proc.wait(timeout_s if end is None else 5.0)
                break
            except subprocess.TimeoutExpired:
                continue
        self._conn.close()
        return self.stats


__all__ = ["PROBE_KEY", "Viewer", "ViewerParams", "ViewerScene", "viewer_main"]

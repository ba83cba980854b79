"""``cosim drive`` end to end: a real window on a virtual X server (Xvfb), real key events (XTEST)."""

from __future__ import annotations

import ctypes
import ctypes.util
import json
import os
import queue
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from cosim.log import read

pytest.importorskip("pygame", reason="cosim drive needs pygame (pip install 'cosim[input]')")


class XServer:
    """Xvfb on a free display number, stopped on exit."""

    def __init__(self, width: int = 640, height: int = 480) -> None:
        exe = shutil.which("Xvfb")
        if exe is None:
            pytest.skip("Xvfb is not installed (apt-get install xvfb)")
        for n in range(90, 140):
            if not Path(f"/tmp/.X11-unix/X{n}").exists() and not Path(f"/tmp/.X{n}-lock").exists():
                break
        self.display = f":{n}"
        self.proc = subprocess.Popen([exe, self.display, "-screen", "0", f"{width}x{height}x24", "-nolisten", "tcp"],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
        deadline = time.monotonic() + 10.0
        while not Path(f"/tmp/.X11-unix/X{n}").exists():
            if self.proc.poll() is not None or time.monotonic() > deadline:
                self.stop()
                pytest.skip(f"Xvfb did not start on {self.display}")
            time.sleep(0.05)

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()


class XKeys:
    """Key presses through the XTEST extension (as if typed), via libX11 / libXtst."""

    def __init__(self, display: str) -> None:
        x11 = ctypes.util.find_library("X11") or "libX11.so.6"
        xtst = ctypes.util.find_library("Xtst") or "libXtst.so.6"
        try:
            self.x, self.t = ctypes.CDLL(x11), ctypes.CDLL(xtst)
        except OSError as exc:
            pytest.skip(f"libX11 / libXtst not available for key injection: {exc}")
        self.x.XOpenDisplay.restype = ctypes.c_void_p
        self.x.XOpenDisplay.argtypes = [ctypes.c_char_p]
        self.x.XStringToKeysym.restype = ctypes.c_ulong
        self.x.XStringToKeysym.argtypes = [ctypes.c_char_p]
        self.x.XKeysymToKeycode.restype = ctypes.c_ubyte
        self.x.XKeysymToKeycode.argtypes = [ctypes.c_void_p, ctypes.c_ulong]
        self.x.XFlush.argtypes = [ctypes.c_void_p]
        self.x.XCloseDisplay.argtypes = [ctypes.c_void_p]
        self.t.XTestFakeKeyEvent.argtypes = [ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_ulong]
        self.t.XTestFakeMotionEvent.argtypes = [
            ctypes.c_void_p,
            ctypes.c_int,
            ctypes.c_int,
            ctypes.c_int,
            ctypes.c_ulong,
        ]
        self.d = self.x.XOpenDisplay(display.encode())
        if not self.d:
            pytest.skip(f"cannot open X display {display}")

    def pointer(self, x: int, y: int) -> None:
        """Without a window manager the keyboard focus follows the pointer: put it over the window."""
        self.t.XTestFakeMotionEvent(self.d, 0, x, y, 0)
        self.x.XFlush(self.d)

    def key(self, name: str, down: bool) -> None:
        code = self.x.XKeysymToKeycode(self.d, self.x.XStringToKeysym(name.encode()))
        self.t.XTestFakeKeyEvent(self.d, code, 1 if down else 0, 0)
        self.x.XFlush(self.d)

    def close(self) -> None:
        self.x.XCloseDisplay(self.d)


@pytest.mark.slow  # 10 s in real time
def test_drive_under_xvfb_with_key_presses_moves_and_turns_the_ego(gl, small_scenario, tmp_path):
    _, _, osm = small_scenario
    cfg = tmp_path / "drive.yaml"
    cfg.write_text(
        "name: drive-test\nseed: 1\nduration_s: 10\n"
        f"scenario: {{map: {osm}, demand: {{density: low}}}}\n"
        "ego: {depart_s: 0.0, lead_vehicle: false, driver: {kind: keyboard}}\n"
        "log: {scene_every_steps: 0}\n"
    )
    out = tmp_path / "run"
    xs = XServer()
    keys = None
    env = {**os.environ, "DISPLAY": xs.display, "SDL_VIDEODRIVER": "x11", "MUJOCO_GL": "egl",
           "SDL_VIDEO_WINDOW_POS": "0,0"}  # fmt: skip
    proc = subprocess.Popen([sys.executable, "-m", "cosim.world3d.drive", str(cfg), "--out", str(out),
                             "--size", "320x180", "--fps", "15", "--quiet"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    lines: queue.Queue[str] = queue.Queue()
    threading.Thread(target=lambda: [lines.put(ln) for ln in proc.stderr], daemon=True).start()
    try:
        deadline = time.monotonic() + 60.0
        while True:
            try:
                line = lines.get(timeout=0.5)
            except queue.Empty:
                line = ""
            if "ready" in line:
                break
            if proc.poll() is not None:
                pytest.fail(
                    f"cosim drive ended early ({proc.returncode}): {line}{''.join(list(lines.queue))}"
                )
            if time.monotonic() > deadline:
                pytest.fail("cosim drive did not get ready within 60 s")
        keys = XKeys(xs.display)
        keys.pointer(160, 90)
        keys.key("Up", True)  # throttle ...
        time.sleep(4.0)
        keys.key("Left", True)  # ... then steer left as well
        time.sleep(3.5)
        keys.key("Left", False)
        keys.key("Up", False)
        stdout, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        if keys is not None:
            keys.close()
        xs.stop()
    assert proc.returncode == 0, "".join(list(lines.queue))
    stats = json.loads(stdout.strip().splitlines()[-1])
    assert 0.5 < stats["real_time_factor"] < 1.5, stats  # paced to the wall clock
    assert stats["frames"] >= stats["steps"] - 1  # every step was shown (the last one ends the loop)
    ego = read(out / "run.mcap", topics=["/ego/state"]).topics["/ego/state"]
    assert np.nanmax(ego["throttle"]) > 0.8  # the Up key reached the car
    assert np.nanmax(ego["steer"]) > 0.3  # so did Left (steer > 0 = left)
    moved = float(np.hypot(ego["x_m"][-1] - ego["x_m"][0], ego["y_m"][-1] - ego["y_m"][0]))
    assert moved > 15.0, moved
    steering = np.flatnonzero(ego["steer"] > 0.1)
    heading = np.degrees(np.unwrap(np.radians(ego["heading_deg"])))
    turned = heading[steering[0]] - heading[-1]  # compass angles decrease in a left turn
    assert turned > 15.0, turned

"""A person as a participant: `cosim experiment --participant-driver keyboard` opens the driver view and
runs the protocol in real time (here under Xvfb, the throttle key pressed through XTEST)."""

from __future__ import annotations

import ctypes
import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest
from short_experiment import short_experiment_config
from test_world3d_drive import XKeys, XServer

from cosim.log import read


def _windows(keys: XKeys) -> int:
    """How many top-level windows the X server shows (no window manager: the root's children)."""
    x = keys.x
    x.XDefaultRootWindow.restype = ctypes.c_ulong
    x.XDefaultRootWindow.argtypes = [ctypes.c_void_p]
    x.XQueryTree.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.POINTER(ctypes.c_ulong),
                             ctypes.POINTER(ctypes.c_ulong), ctypes.POINTER(ctypes.POINTER(ctypes.c_ulong)),
                             ctypes.POINTER(ctypes.c_uint)]  # fmt: skip
    x.XFree.argtypes = [ctypes.c_void_p]
    root, parent, n = ctypes.c_ulong(), ctypes.c_ulong(), ctypes.c_uint()
    children = ctypes.POINTER(ctypes.c_ulong)()
    if not x.XQueryTree(keys.d, x.XDefaultRootWindow(keys.d), ctypes.byref(root), ctypes.byref(parent),
                        ctypes.byref(children), ctypes.byref(n)):  # fmt: skip
        return 0
    if children:
        x.XFree(children)
    return n.value


@pytest.mark.slow  # the protocol in real time
def test_experiment_with_a_person_at_the_keyboard(gl, small_scenario, tmp_path):
    _, _, osm = small_scenario
    cfg = tmp_path / "exp.yaml"
    short_experiment_config(cfg, "person", osm, 4, 1, log="scene_every_steps: 0")
    xs = XServer()
    keys = None
    try:
        env = {**os.environ, "DISPLAY": xs.display, "SDL_VIDEODRIVER": "x11", "MUJOCO_GL": "egl",
               "SDL_VIDEO_WINDOW_POS": "0,0"}  # fmt: skip
        proc = subprocess.Popen([sys.executable, "-m", "cosim.cli", "experiment", str(cfg), "--participant-driver",
                                 "keyboard", "--out", str(tmp_path / "out"), "--quiet"],
                                env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
        keys = XKeys(xs.display)
        deadline = time.monotonic() + 180.0
        while proc.poll() is None and time.monotonic() < deadline and not _windows(keys):
            time.sleep(0.1)
        # the window is up: the person drives off with the throttle held for 3 s, then keeps driving through the
        # whole protocol, pulsing it (0.6 s on, 0.6 s off), with the pointer over the window (focus follows it).
        # Holding it only for the first seconds left the car rolled out by system_B when the phases started late
        # on a loaded machine; pulsing from the start left the baseline without a time gap (still too slow).
        start = time.monotonic()
        pulse = (True, True, True, False, False, False)
        k = 0
        while proc.poll() is None and time.monotonic() < start + 120.0:
            keys.pointer(160, 90)
            keys.key("Up", time.monotonic() < start + 3.0 or pulse[k % len(pulse)])
            k += 1
            time.sleep(0.2)
        keys.key("Up", False)
        _, stderr = proc.communicate(timeout=180)
    finally:
        if keys is not None:
            keys.close()
        xs.stop()
    assert proc.returncode == 0, stderr[-3000:]
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    (part,) = summary["participants"]
    assert [p["phase"] for p in part["phases"]] == ["baseline", "system_A", "system_B"]
    assert part["run"]["wall_s"] >= 11.0  # paced to the wall clock: three 4-s phases take real time
    assert (tmp_path / "out" / "P1" / "timegap.csv").exists()
    ego = read(tmp_path / "out" / "P1" / "run.mcap", topics=["/ego/state"]).topics["/ego/state"]
    assert np.nanmax(ego["throttle"]) > 0.8  # the key reached the car ...
    moved = float(np.hypot(ego["x_m"][-1] - ego["x_m"][0], ego["y_m"][-1] - ego["y_m"][0]))
    assert moved > 20.0, moved  # ... and the car drove off with it

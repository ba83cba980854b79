"""The drive view's own process (cosim.world3d.viewer): starts, builds the scene, draws the frames it is sent
(interpolated between steps), sends input back, reports, stops cleanly and never outlives the simulation.

Headless: SDL's dummy video driver, MuJoCo through EGL. No assertion on how fast anything is.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cosim.errors import CosimError
from cosim.world3d.scene import SceneParams
from cosim.world3d.state import EgoPose, FrameState, VehicleFrame
from cosim.world3d.viewer import PROBE_KEY, Viewer, ViewerParams, ViewerScene

pytest.importorskip("pygame", reason="the drive view needs pygame (pip install 'cosim[input]')")


@pytest.fixture
def headless(monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")  # the viewer's environment is a copy of ours


def _frame(t: float, x: float) -> FrameState:
    """The ego at x (network coordinates) and a car 12 m ahead, both moving at 40 m/s."""
    return FrameState(t, EgoPose(x, 0.0, 0.0), VehicleFrame(("car",), [x + 12.0], [0.0], [0.0], [False]))


def _until(what, timeout_s: float = 30.0, every_s: float = 0.02):
    deadline = time.monotonic() + timeout_s
    while True:
        value = what()
        if value or time.monotonic() > deadline:
            return value
        time.sleep(every_s)


def _gone(pid: int) -> bool:
    """The process has exited (a zombie counts: nothing of it runs)."""
    stat = Path(f"/proc/{pid}/stat")
    try:
        return stat.read_text().rsplit(")", 1)[1].split()[0] in ("Z", "X")
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return True


def test_viewer_draws_the_interpolated_frames_sends_input_and_stops_cleanly(gl, small_scenario, headless):
    scn = small_scenario[0]
    v = Viewer(ViewerParams(width=160, height=96, fps=60.0, probe_every_s=0.05))
    try:
        assert v.alive
        info = v.open_scene(
            ViewerScene(str(scn.dir), 0.1, SceneParams(vehicle_pool=3, max_width=320, max_height=192))
        )
        assert info["scene_s"] >= 0.0
        # input: the synthetic probe key toggles in the viewer, which sends each new state
        assert _until(lambda: v.poll(0.05) == set() and v.input_seq >= 2), "no input from the viewer"
        assert PROBE_KEY in v.key_state() or v.input_seq % 2 == 1  # on every other event
        assert v.wheel_state() == ((), ())  # no wheel configured
        assert v.shown() is None  # no frame before the first step
        tag = v.input_seq
        v.send_frame(_frame(0.0, 0.0), tag)
        assert _until(lambda: v.shown() is not None)
        v.send_frame(_frame(0.1, 4.0), tag)
        seen = []

        def at_the_step() -> bool:
            f = v.shown()
            seen.append(f)
            return f.t_s == pytest.approx(0.1)

        assert _until(at_the_step, every_s=0.005)
        for f in seen:  # every frame between the two steps is on the straight line between them
            assert 0.0 <= f.ego.x_m <= 4.0
            assert f.ego.x_m == pytest.approx(40.0 * f.t_s)
            assert f.vehicles.x_m[0] == pytest.approx(f.ego.x_m + 12.0)
        time.sleep(0.3)  # no next step: the picture holds at the last one, it does not run ahead
        assert v.shown().ego.x_m == 4.0
        stats = v.report()
        assert stats["frames"] >= 2 and stats["stalled_frames"] >= 1
        assert stats["input_events"] >= 1 and stats["latency_first_ms"] > 0.0  # events up to `tag` got shown
        assert stats["latency_full_ms"] >= stats["latency_first_ms"]
        assert v.report()["frames"] < stats["frames"] + 60  # a report starts the counters again
    finally:
        stats = v.close()
    assert v.proc.returncode == 0  # stopped on request, not killed
    assert "frames" in stats and not v.alive
    assert v.poll() == {"quit"}  # a closed viewer reads as the person having quit
    v.send_frame(_frame(0.2, 8.0))  # harmless after close
    assert v.close() == stats


def test_viewer_reports_a_scene_it_cannot_build(gl, headless, tmp_path):
    v = Viewer(ViewerParams(width=64, height=64))
    try:
        with pytest.raises(CosimError, match="could not open the scene"):
            v.open_scene(ViewerScene(str(tmp_path / "no-such-scenario"), 0.1))
        assert _until(lambda: v.proc.poll() is not None), "the viewer kept running after its error"
    finally:
        v.close()


def test_viewer_never_outlives_a_killed_simulation(gl, headless):
    code = ("import os, signal\nfrom cosim.world3d.viewer import Viewer, ViewerParams\n"
            "v = Viewer(ViewerParams(width=64, height=64))\nprint(v.pid, flush=True)\n"
            "os.kill(os.getpid(), signal.SIGKILL)\n")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == -9, out.stderr
    pid = int(out.stdout.split()[0])
    assert _until(lambda: _gone(pid), timeout_s=30.0, every_s=0.1), f"viewer {pid} outlived its simulation"


def test_headless_drive_steps_in_real_time_and_the_viewer_shows_it(gl, small_scenario, headless):
    from cosim.runconfig import load_run_config
    from cosim.sim import Simulation
    from cosim.world3d.drive import DriveParams, DriveSession, wait_for_ego

    _, _, osm = small_scenario
    cfg = load_run_config(None, **{"scenario.map": str(osm), "scenario.demand.density": "low", "duration_s": 60.0,
                                   "ego.depart_s": 0.0, "ego.lead_vehicle": False})  # fmt: skip
    session = DriveSession(DriveParams(width=160, height=96, fps=20.0), probe_every_s=0.15)
    viewer = session.window
    try:
        with Simulation(cfg) as sim:
            wait_for_ego(sim, viewer)
            stats = session.run(sim, duration_s=2.0)
    finally:
        session.close()
    assert stats["steps"] == 20 and not stats["quit"]
    assert stats["frames"] >= 1 and stats["input_events"] >= 1
    assert np.isfinite(stats["latency_first_ms"]) and np.isfinite(stats["latency_full_ms"])
    assert viewer.proc.returncode == 0

"""A person as a participant: `cosim experiment --participant-driver keyboard` opens the driver view and
runs the protocol in real time (here under Xvfb, with nobody touching the keys)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from test_world3d_drive import XServer


def test_experiment_with_a_person_at_the_keyboard(gl, small_scenario, tmp_path):
    _, _, osm = small_scenario
    cfg = tmp_path / "exp.yaml"
    cfg.write_text(
        "name: person\nseed: 1\n"
        "phases: [{name: baseline, system: none, duration_s: 3}, {name: system_A, system: A, duration_s: 3},"
        " {name: system_B, system: B, duration_s: 3}]\n"
        "participants: [{id: P1, profile: daily_commuter}]\n"
        f"run: {{scenario: {{map: {osm}, demand: {{density: low}}}}, ego: {{depart_s: 0.0, lead_vehicle: false}},"
        " log: {scene_every_steps: 0}}\n"
    )
    xs = XServer()
    try:
        env = {**os.environ, "DISPLAY": xs.display, "SDL_VIDEODRIVER": "x11", "MUJOCO_GL": "egl"}
        proc = subprocess.run([sys.executable, "-m", "cosim.cli", "experiment", str(cfg), "--participant-driver",
                               "keyboard", "--out", str(tmp_path / "out"), "--quiet"],
                              env=env, capture_output=True, text=True, timeout=180)  # fmt: skip
    finally:
        xs.stop()
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    (part,) = summary["participants"]
    assert [p["phase"] for p in part["phases"]] == ["baseline", "system_A", "system_B"]
    assert part["run"]["wall_s"] >= 8.0  # paced to the wall clock: three 3-s phases take real time
    assert (tmp_path / "out" / "P1" / "timegap.csv").exists()

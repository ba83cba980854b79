"""`cosim experiment --clip`: the first participant's clip is rendered beside the participants still
running (its own process, started once that participant is done) and is there when the command ends."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from short_experiment import short_experiment_config

from cosim.log import read


@pytest.mark.slow  # two short participants and a clip
def test_the_first_participants_clip_is_whole_when_the_experiment_ends(gl, small_scenario, tmp_path):
    _, _, osm = small_scenario
    cfg = tmp_path / "exp.yaml"
    short_experiment_config(cfg, "clip", osm, 4, 3)
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "cosim.cli", "experiment", str(cfg), "--clip", "--jobs", "2",
                           "--out", str(out), "--quiet"],
                          capture_output=True, text=True, env={**os.environ, "MUJOCO_GL": "egl"}, timeout=600)  # fmt: skip
    assert proc.returncode in (0, 1), proc.stderr[-3000:]  # 1: a 4-s phase may have no time gap
    assert f"clip: {out / 'P1' / 'clip.mp4'}" in proc.stdout, proc.stdout + proc.stderr[-3000:]
    clip = out / "P1" / "clip.mp4"
    assert clip.stat().st_size > 10_000 and clip.read_bytes()[4:8] == b"ftyp"
    assert not list((out / "P1").glob(".clip-*"))  # moved into place whole
    umask = os.umask(0)
    os.umask(umask)
    assert clip.stat().st_mode & 0o777 == 0o666 & ~umask  # the mode of any new file (not mkstemp's 0600)
    assert all((out / p / "run.mcap").exists() for p in ("P1", "P2", "P3"))
    assert read(out / "P3" / "run.mcap").counts["/ego/state"] > 10  # the last participant ran to its end

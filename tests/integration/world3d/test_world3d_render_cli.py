"""``cosim render RUN.mcap``: a short logged run on the small map rendered to MP4 and to PNG stills."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from cosim.world3d import replay


@pytest.fixture(scope="module")
def run_log(gl, small_scenario, tmp_path_factory):
    """A 12-s run with system A in use, the scripted driver following the lead vehicle. It runs as
    ``cosim run`` in a child process: libsumo runs one simulation per process (tests/conftest.py)."""
    _, _, osm = small_scenario
    d = tmp_path_factory.mktemp("render-run")
    cfg = d / "run.yaml"
    cfg.write_text(
        f"name: render-test\nseed: 1\nduration_s: 12\nscenario: {{map: {osm}, demand: {{density: low}}}}\n"
        "ego: {depart_s: 0.0}\nadas: {system: A}\n"
    )
    proc = subprocess.run([sys.executable, "-m", "cosim.cli", "run", str(cfg), "--out", str(d / "run"), "--quiet"],
                          capture_output=True, text=True, env=os.environ.copy())  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    return d / "run" / "run.mcap"


def test_render_to_mp4_with_the_stated_frame_rate(run_log, tmp_path, capsys):
    ffmpeg = pytest.importorskip(
        "imageio_ffmpeg", reason="MP4 output needs the 'video' extra (imageio-ffmpeg)"
    )
    mp4 = tmp_path / "clip.mp4"
    rc = replay.main([str(run_log), "--out", str(mp4), "--camera", "chase", "--size", "320x180", "--fps", "5",
                      "--start", "6", "--end", "9", "--quiet"])  # fmt: skip
    assert rc == 0
    assert '"frames": 16' in capsys.readouterr().out  # 6.0 ... 9.0 s at 5 frames per simulated second
    reader = ffmpeg.read_frames(str(mp4))
    meta = reader.__next__()
    assert tuple(meta["size"]) == (320, 180) and meta["fps"] == pytest.approx(5.0)
    frames = [np.frombuffer(f, dtype=np.uint8).reshape(180, 320, 3) for f in reader]
    assert len(frames) == 16
    assert all(f.std() > 10 for f in frames)  # not blank
    assert np.abs(frames[0].astype(int) - frames[-1].astype(int)).mean() > 2  # the picture moves
    assert not list(tmp_path.glob(".clip-*"))  # no temporary file left behind


def test_render_png_stills_from_the_drivers_seat(run_log, tmp_path):
    rc = replay.main([str(run_log), "--frames", str(tmp_path / "png"), "--size", "320x180", "--fps", "2",
                      "--start", "8", "--end", "9", "--quiet"])  # fmt: skip
    assert rc == 0
    files = sorted((tmp_path / "png").glob("frame_*.png"))
    assert [f.name for f in files] == ["frame_00000.png", "frame_00001.png", "frame_00002.png"]
    img = np.asarray(Image.open(files[0]))
    assert img.shape == (180, 320, 3) and img.std() > 10
    sky = img[40:50, 140:180].reshape(-1, 3).astype(float).mean(axis=0)  # above the HUD, above the horizon
    assert sky[2] > sky[0] + 20
    speed_box = img[150:170, 10:30].reshape(-1, 3).astype(float).mean(axis=0)  # HUD: dark speed box
    assert speed_box.max() < 60


def test_render_rejects_a_file_that_is_not_a_log(tmp_path, capsys):
    bad = tmp_path / "run.mcap"
    bad.write_text("not an mcap")
    assert replay.main([str(bad), "--out", str(tmp_path / "x.mp4")]) == 2
    assert "is not an MCAP file" in capsys.readouterr().err
    assert not (tmp_path / "x.mp4").exists()
    assert replay.main([str(bad), "--size", "321x180"]) == 2  # H.264 needs even sizes: one clear line


def test_phase_clip_takes_the_middle_of_each_systems_phase(run_log, tmp_path):
    pytest.importorskip("imageio_ffmpeg", reason="MP4 output needs the 'video' extra (imageio-ffmpeg)")
    state = {
        "t_s": np.arange(0.0, 30.0, 0.1),
        "system": np.array(["none"] * 100 + ["A"] * 100 + ["B"] * 100, dtype=object),
    }
    spans = replay.phase_windows(state, ("B", "A"), seconds=4.0)
    assert [(s, round(a, 2), round(b, 2)) for s, a, b in spans] == [("B", 22.95, 26.95), ("A", 12.95, 16.95)]
    out = tmp_path / "clip.mp4"
    summary = replay.render_phase_clip(run_log, out, systems=("A", "B"), seconds=2.0,
                                       params=replay.RenderParams(width=320, height=180, fps=5.0))  # fmt: skip
    assert [w["system"] for w in summary["windows"]] == ["A"]  # this run used system A only
    assert summary["frames"] == 11 and out.stat().st_size > 1000

"""Bad input to the scenario builder: one clear line, exit code 2, nothing half-written left behind."""

from __future__ import annotations

import gzip
import os
import subprocess
import sys

import pytest
from osm_factory import OsmSketch
from testpaths import shared_map


def cosim(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "cosim.cli", *args], capture_output=True, text=True, cwd=cwd,
                          env=os.environ.copy())  # fmt: skip


def assert_clean_failure(proc, words: str, out_dir):
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert words in lines[0], lines[0]
    assert not out_dir.exists()
    cache = os.environ["COSIM_CACHE_DIR"]
    leftovers = (
        [p for p in os.listdir(cache) if p.startswith(("net-", "scn-"))] if os.path.isdir(cache) else []
    )
    assert not leftovers


def test_missing_file(tmp_path):
    assert_clean_failure(cosim("build-scenario", "--osm", str(tmp_path / "nope.osm"), "--out", str(tmp_path / "o")),
                         "does not exist", tmp_path / "o")  # fmt: skip


def test_truncated_gzip(tmp_path):
    data = shared_map("munich").read_bytes()
    bad = tmp_path / "cut.osm.gz"
    bad.write_bytes(data[: len(data) // 2])
    assert_clean_failure(
        cosim("build-scenario", "--osm", str(bad), "--out", str(tmp_path / "o")), "cut.osm.gz", tmp_path / "o"
    )


def test_xml_that_is_not_osm(tmp_path):
    bad = tmp_path / "x.osm"
    bad.write_text("<?xml version='1.0'?><html><body/></html>")
    assert_clean_failure(cosim("build-scenario", "--osm", str(bad), "--out", str(tmp_path / "o")),
                         "not an OpenStreetMap", tmp_path / "o")  # fmt: skip


def test_garbage_bytes(tmp_path):
    bad = tmp_path / "g.osm.gz"
    with gzip.open(bad, "wb") as fh:
        fh.write(b"\x00\x01 this is not xml")
    assert_clean_failure(
        cosim("build-scenario", "--osm", str(bad), "--out", str(tmp_path / "o")), "g.osm.gz", tmp_path / "o"
    )


def test_osm_without_drivable_roads(tmp_path):
    s = OsmSketch()
    s.node("a", 0, 0)
    s.node("b", 100, 0)
    s.way(["a", "b"], highway="footway")
    osm = s.write(tmp_path / "paths.osm")
    assert_clean_failure(
        cosim("build-scenario", "--osm", str(osm), "--out", str(tmp_path / "o")),
        "no drivable road",
        tmp_path / "o",
    )


def test_unknown_density(tmp_path):
    proc = cosim("build-scenario", "--osm", str(shared_map("munich")), "--density", "extreme")
    assert proc.returncode == 2 and "invalid choice" in proc.stderr


@pytest.mark.parametrize(
    ("yaml_text", "words"),
    [
        ("seed: 1\nfoo: 2\n", "config foo: unknown key"),
        ("ego:\n  depart_s: abc\n", "config ego.depart_s: expected a number"),
        (
            "timing:\n  physics_timestep_s: 0.003\n",
            "config timing: sumo_step_s (0.1) must be an integer multiple",
        ),
        ("timing:\n  cam_check_period_s: 0.15\n", "config timing: cam_check_period_s"),
        ("scenario:\n  demand:\n    density: extreme\n", "unknown density 'extreme'"),
        ("seed: [1\n", "is not valid YAML"),
    ],
)
def test_config_errors_name_the_key(tmp_path, yaml_text, words):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml_text)
    proc = cosim("run", str(cfg), "--out", str(tmp_path / "o"))
    assert proc.returncode == 2, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and words in proc.stderr, proc.stderr

"""What a run leaves behind: byte-identical files for the same seed, one run per --out at a time (locked),
an existing run replaced only with --force (and then without stale outputs), SIGTERM handled like Ctrl-C."""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import time

import pytest
from osm_factory import crossroads

from cosim.log import read


@pytest.fixture(scope="module")
def small_map(tmp_path_factory):
    return crossroads(major="primary", minor="residential").write(tmp_path_factory.mktemp("map") / "x.osm")


def cosim(*args, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cosim.cli", *map(str, args)], capture_output=True, text=True,
                          env=os.environ.copy(), timeout=300, **kw)  # fmt: skip


def sha256(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_same_config_and_seed_give_byte_identical_files(tmp_path, small_map):
    cfg = tmp_path / "c.yaml"
    # a chunk per 0.05 s: when that was wall-clock time (before issue 16) the runs (~0.3 s of wall time each)
    # flushed at different messages and the two files differed
    cfg.write_text(f"seed: 3\nduration_s: 12\nscenario: {{map: {small_map}, demand: {{density: low}}}}\n"
                   "log: {flush_every_s: 0.05, traffic_every_steps: 1}\n")  # fmt: skip
    for name in ("a", "b"):
        proc = cosim("run", cfg, "--out", tmp_path / name, "--quiet")
        assert proc.returncode == 0, proc.stderr[-3000:]
    a, b = tmp_path / "a" / "run.mcap", tmp_path / "b" / "run.mcap"
    assert read(a).counts["/traffic/vehicles"] == 120
    assert sha256(a) == sha256(b)
    from mcap.reader import make_reader

    with a.open("rb") as fh:
        chunks = make_reader(fh).get_summary().chunk_indexes
    assert len(chunks) >= 100  # one per step: a step's messages share their time
    assert all(c.message_end_time - c.message_start_time < 0.05e9 for c in chunks)


def _start(out, small_map, *extra) -> subprocess.Popen:
    proc = subprocess.Popen(
        [sys.executable, "-m", "cosim.cli", "run", "--map", str(small_map), "--density", "low", "--duration",
         "3000", "--out", str(out), "--quiet", *extra],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=os.environ.copy(),
    )  # fmt: skip
    mcap = out / "run.mcap"
    deadline = time.time() + 120
    while time.time() < deadline and (not mcap.exists() or mcap.stat().st_size < 20_000):
        if proc.poll() is not None:
            pytest.fail(f"the run ended early ({proc.returncode}): {proc.stderr.read()[-3000:]}")
        time.sleep(0.2)
    assert mcap.exists(), "no log appeared"
    return proc


def test_out_is_locked_and_an_existing_run_needs_force(tmp_path, small_map):
    out = tmp_path / "run"
    first = _start(out, small_map)
    try:
        second = cosim("run", "--map", small_map, "--density", "low", "--duration", "5", "--out", out, "--quiet",
                       "--force")  # fmt: skip
    finally:
        first.send_signal(signal.SIGTERM)  # ... ends it like Ctrl-C
        stdout, stderr = first.communicate(timeout=60)
    assert second.returncode == 2, second.stderr
    assert second.stderr.count("\n") == 1 and "being written by another cosim run" in second.stderr, (
        second.stderr
    )
    assert first.returncode == 128 + signal.SIGTERM, stderr[-3000:]
    stats = json.loads(stdout.strip().splitlines()[-1])  # the summary is printed
    assert stats["interrupted"] is True and stats["steps"] > 10
    log = read(out / "run.mcap")  # one run's complete log: the second one wrote nothing into it
    assert not log.truncated and log.counts["/traffic/vehicles"] > 2
    from mcap.reader import make_reader

    with (out / "run.mcap").open("rb") as fh:  # the standard reader accepts it (summary section written)
        assert make_reader(fh).get_summary().statistics.message_count == sum(log.counts.values())
    assert not (out / ".cosim.lock").exists()

    stale = out / "old_plot.png"
    stale.write_bytes(b"stale")
    (out / "vanet").mkdir()
    before = sha256(out / "run.mcap")
    again = cosim("run", "--map", small_map, "--density", "low", "--duration", "3", "--out", out, "--quiet")
    assert again.returncode == 2 and "already holds a run: add --force" in again.stderr, again.stderr
    assert again.stderr.count("\n") == 1
    assert sha256(out / "run.mcap") == before and stale.exists()

    forced = cosim("run", "--map", small_map, "--density", "low", "--duration", "3", "--out", out, "--quiet",
                   "--force")  # fmt: skip
    assert forced.returncode == 0, forced.stderr[-3000:]
    assert sorted(p.name for p in out.iterdir()) == ["run.mcap"]  # the old plots are gone
    assert read(out / "run.mcap").duration_s == pytest.approx(2.9, abs=0.11)

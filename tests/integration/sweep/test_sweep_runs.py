"""Sweeps that really run: a 4-run local sweep, the same on Ray, resume, a failing run, a killed worker.

All on the shipped Munich map, 20 simulated seconds per run, the ego as a plain SUMO car.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from testpaths import shared_map

from cosim.runconfig import load_run_config
from cosim.sweep import LocalBackend, load_sweep, plan, run_sweep

VOLATILE = {"real_time_factor", "sim_wall_s"}  # wall-clock based: differ between two executions


def write_sweep(folder: Path, body: str, duration_s: float = 20.0) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "base.yaml").write_text(
        f"name: base\nseed: 1\nduration_s: {duration_s}\n"
        f"scenario:\n  map: {shared_map('munich')}\n  demand: {{density: low}}\n"
        "ego: {physics: sumo}\n"
    )
    path = folder / "sweep.yaml"
    path.write_text(body)
    return path


FOUR = """name: four
base: base.yaml
overrides: {log.scene_every_steps: 0}
grid:
  scenario.demand.density: [low, medium]
seeds: [1, 2]
plots:
  - {metric: vehicles_mean, x: scenario.demand.density}
  - {metric: pdr_0_100m, x: seed, hue: scenario.demand.density}
"""


@pytest.fixture(scope="module")
def four(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sweep4")
    sweep = load_sweep(write_sweep(folder, FOUR))
    lines: list[str] = []
    backend = LocalBackend(2)
    try:
        result = run_sweep(sweep, backend=backend, out_dir=folder / "results", say=lines.append)
    finally:
        backend.close()
    return sweep, result, lines


def _table(path: Path) -> list[dict]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


@pytest.mark.slow
def test_local_sweep_of_four_runs(four):
    sweep, result, lines = four
    assert result.ok == 4 and not result.failed and result.skipped == 0, lines
    assert sum(line.startswith("[") and " ok " in line for line in lines) == 4  # one progress line per run
    rows = _table(result.table)
    assert [r["run_id"] for r in rows] == [r.run_id for r in sweep.runs()]
    assert {(r["scenario.demand.density"], r["seed"]) for r in rows} == {
        ("low", "1"), ("low", "2"), ("medium", "1"), ("medium", "2")}  # fmt: skip
    for r in rows:
        run_dir = result.out_dir / r["run_id"]
        assert (run_dir / "run.mcap").stat().st_size > 10_000
        cfg = load_run_config(run_dir / "config.yaml")  # the recorded config is a valid run config
        assert (cfg.seed, cfg.scenario.demand.density) == (int(r["seed"]), r["scenario.demand.density"])
        assert json.loads((run_dir / "result.json").read_text())["status"] == "ok"
        for col in ("pdr_overall", "pdr_0_100m", "channel_busy_mean", "vehicles_mean", "collisions", "teleports",
                    "real_time_factor", "wall_s", "timegap_mean_s"):  # fmt: skip
            assert r[col] != "", (col, r)
        assert 0.0 <= float(r["pdr_0_100m"]) <= 1.0
        assert cfg.log.scene_every_steps == 0  # the sweep's fixed override reached every run
    mean = {
        d: sum(float(r["vehicles_mean"]) for r in rows if r["scenario.demand.density"] == d)
        for d in ("low", "medium")
    }
    assert mean["medium"] > 1.5 * mean["low"]  # the swept parameter reached the runs
    assert [p.name for p in result.plots] == ["vehicles_mean_vs_scenario.demand.density.png",
                                              "pdr_0_100m_vs_seed_by_scenario.demand.density.png"]  # fmt: skip
    assert all(p.stat().st_size > 5000 for p in result.plots)


@pytest.mark.slow
def test_same_sweep_on_a_local_ray_instance(four, tmp_path):
    pytest.importorskip("ray", reason="Ray is not installed (pip install 'cosim[ray]')")
    from cosim.sweep import RayBackend

    sweep, local, _ = four
    lines: list[str] = []
    backend = RayBackend(address=None, jobs=2)  # starts a local Ray instance
    try:
        result = run_sweep(sweep, backend=backend, out_dir=tmp_path / "ray", say=lines.append)
    finally:
        backend.close()
    assert result.ok == 4 and not result.failed, lines
    assert any("Ray" in line for line in lines)
    assert {r["pid"] for r in result.results}.isdisjoint({os.getpid()})  # ran in Ray workers
    by_id = {r["run_id"]: r for r in local.results}
    for r in result.results:  # same runs, same seeds: the same metrics as on the local pool
        a = {k: v for k, v in by_id[r["run_id"]]["metrics"].items() if k not in VOLATILE}
        b = {k: v for k, v in r["metrics"].items() if k not in VOLATILE}
        assert a == b


@pytest.mark.slow
def test_resume_skips_finished_runs_and_redoes_partial_ones(four):
    sweep, first, _ = four
    out = first.out_dir
    ids = [r.run_id for r in sweep.runs()]
    partial = out / ids[1]
    (partial / "result.json").unlink()  # as if the worker was killed before it finished
    (partial / "leftover.tmp").write_text("half-written")
    stamps = {i: ((out / i / "result.json").stat().st_mtime_ns, (out / i / "run.mcap").stat().st_mtime_ns)
              for i in ids if i != ids[1]}  # fmt: skip
    lines: list[str] = []
    backend = LocalBackend(1)
    try:
        again = run_sweep(sweep, backend=backend, out_dir=out, say=lines.append)
    finally:
        backend.close()
    assert again.skipped == 3 and again.ok == 4, lines
    assert sum(line.startswith("[") for line in lines) == 1  # only the unfinished run ran
    for i, (t_res, t_log) in stamps.items():
        assert (out / i / "result.json").stat().st_mtime_ns == t_res
        assert (out / i / "run.mcap").stat().st_mtime_ns == t_log
    assert not (partial / "leftover.tmp").exists() and (partial / "result.json").exists()
    # the redone run reproduces its first result
    redone = json.loads((partial / "result.json").read_text())["metrics"]
    before = next(r for r in first.results if r["run_id"] == ids[1])["metrics"]
    assert {k: v for k, v in redone.items() if k not in VOLATILE} == {
        k: v for k, v in before.items() if k not in VOLATILE
    }
    # a changed base setting (here the duration) makes finished runs stale: they are redone, not skipped
    changed = load_sweep(write_sweep(out.parent / "changed", FOUR, duration_s=10.0))
    states = {p.run.run_id: p.state for p in plan(changed, out)}
    assert set(states) == set(ids) and set(states.values()) == {"redo"}


def test_a_bad_override_fails_alone_with_a_clear_message(tmp_path):
    body = """name: bad
base: base.yaml
runs:
  - {}
  - {scenario.demand.densty: low}
  - {scenario.demand.density: extreme}
  - {vanet.channel.shadowing: sometimes}
  - {ego.route: [no_such_edge]}
seeds: [1]
"""
    sweep = load_sweep(write_sweep(tmp_path, body, duration_s=5.0))  # only the good run simulates
    lines: list[str] = []
    backend = LocalBackend(1)
    try:
        result = run_sweep(sweep, backend=backend, out_dir=tmp_path / "results", say=lines.append)
    finally:
        backend.close()
    status = {r["label"]: r for r in result.results}
    assert status["seed=1"]["status"] == "ok"
    expected = {
        "scenario.demand.densty=low seed=1": "config scenario.demand.densty: unknown key (known keys here:",
        "scenario.demand.density=extreme seed=1": "config scenario.demand: unknown density 'extreme'",
        "vanet.channel.shadowing=sometimes seed=1": "config vanet.channel.shadowing: expected 'none' | 'los' | 'veins', got 'sometimes'",
        'ego.route=["no_such_edge"] seed=1': "no_such_edge",
    }  # fmt: skip
    for label, msg in expected.items():
        res = status[label]
        assert res["status"] == "failed" and msg in res["error"] and "\n" not in res["error"], res
        on_disk = json.loads((result.out_dir / res["run_id"] / "result.json").read_text())
        assert on_disk["status"] == "failed" and on_disk["error"] == res["error"]
        line = next(x for x in lines if res["run_id"] in x and x.startswith("["))
        assert "FAILED" in line and msg in line
    assert len(_table(result.table)) == 5


KILL_SCRIPT = """
import sys
from cosim.sweep import LocalBackend, load_sweep, run_sweep
if __name__ == "__main__":
    backend = LocalBackend(1)
    try:
        res = run_sweep(load_sweep(sys.argv[1]), backend=backend, out_dir=sys.argv[2], say=lambda s: print(s, flush=True))
    finally:
        backend.close()
    sys.exit(1 if res.failed else 0)
"""


def _descendants(pid: int) -> list[int]:
    out = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            kids = [int(k) for k in (task / "children").read_text().split()]
        except OSError:
            continue
        for k in kids:
            out += [k, *_descendants(k)]
    return out


def _worker_pids(pid: int) -> list[int]:
    pids = []
    for k in _descendants(pid):
        try:
            cmd = Path(f"/proc/{k}/cmdline").read_bytes().replace(b"\0", b" ")
        except OSError:
            continue
        if b"spawn_main" in cmd and b"resource_tracker" not in cmd:
            pids.append(k)
    return pids


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="needs /proc to find the worker process")
def test_a_killed_worker_is_survived(tmp_path):
    body = "name: kill\nbase: base.yaml\nseeds: [1, 2]\n"
    sweep_file = write_sweep(tmp_path, body, duration_s=60.0)
    out = tmp_path / "results"
    script = tmp_path / "run_sweep.py"
    script.write_text(KILL_SCRIPT)
    proc = subprocess.Popen([sys.executable, str(script), str(sweep_file), str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, env=os.environ.copy())  # fmt: skip
    killed = None
    deadline = time.time() + 90
    while time.time() < deadline and killed is None and proc.poll() is None:
        running = [
            d for d in out.glob("*/") if (d / "run.mcap").exists() and not (d / "result.json").exists()
        ]
        workers = _worker_pids(proc.pid)
        if running and len(workers) == 1 and (running[0] / "run.mcap").stat().st_size > 20_000:
            os.kill(workers[0], signal.SIGKILL)  # the worker dies in the middle of a run
            killed = running[0].name
        time.sleep(0.05)
    output, _ = proc.communicate(timeout=120)
    assert killed, output
    assert proc.returncode == 0, output
    assert f"worker died while running {killed}" in output
    results = [json.loads(p.read_text()) for p in out.glob("*/result.json")]
    assert len(results) == 2 and all(r["status"] == "ok" for r in results), output

"""`vanet.mac` in whole runs (issue 18): byte-identical logs per seed for 802.11p and C-V2X, a bad MAC name
refused with one line and exit 2, and the run summary and `vanet-report` naming the MAC."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys

import pytest
from osm_factory import crossroads

from cosim.log import read


@pytest.fixture(scope="module")
def small_map(tmp_path_factory):
    return crossroads(major="primary", minor="residential").write(tmp_path_factory.mktemp("map") / "x.osm")


def cosim(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cosim.cli", *map(str, args)], capture_output=True, text=True,
                          env=os.environ.copy(), timeout=300)  # fmt: skip


def sha256(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def config(tmp_path, small_map, mac, seed=3):
    cfg = tmp_path / f"{mac}_{seed}.yaml"
    cfg.write_text(f"seed: {seed}\nduration_s: 12\nscenario: {{map: {small_map}, demand: {{density: medium}}}}\n"
                   f"ego: {{physics: sumo}}\nvanet: {{mac: {mac}, rx_log: all}}\n")  # fmt: skip
    return cfg


@pytest.mark.parametrize("mac", ["80211p", "cv2x"])
def test_same_seed_gives_byte_identical_logs_per_mac(tmp_path, small_map, mac):
    logs = []
    for name, seed in (("a", 3), ("b", 3), ("c", 4)):
        proc = cosim("run", config(tmp_path, small_map, mac, seed), "--out", tmp_path / name, "--quiet")
        assert proc.returncode == 0, proc.stderr[-3000:]
        summary = json.loads(proc.stdout.strip().splitlines()[-1])
        assert summary["vanet_mac"] == mac
        logs.append(tmp_path / name / "run.mcap")
    assert sha256(logs[0]) == sha256(logs[1])
    assert sha256(logs[0]) != sha256(logs[2])
    log = read(logs[0], topics=["/vanet/tx", "/vanet/rx"])
    assert log.counts["/vanet/tx"] > 50 and log.counts["/vanet/rx"] > 50
    out = tmp_path / "vr"
    proc = cosim("vanet-report", logs[0], "--out", out)
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout[: proc.stdout.rindex("}") + 1])
    assert report["mac"] == mac and report["pdr_overall"] > 0.5


def test_unknown_mac_is_refused_with_one_line(tmp_path, small_map):
    cfg = config(tmp_path, small_map, "wifi")
    proc = cosim("run", cfg, "--out", tmp_path / "x", "--quiet")
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "vanet.mac" in proc.stderr, proc.stderr


def test_shipped_mac_sweep_resolves_to_one_run_config_per_mac_and_seed():
    from testpaths import ROOT

    from cosim.sweep.runner import _resolve_overrides, load_config
    from cosim.sweep.spec import load_sweep

    sweep = load_sweep(ROOT / "configs" / "sweeps" / "mac_comparison.yaml")
    runs = sweep.runs()
    assert len(runs) == 6 and len({r.run_id for r in runs}) == 6
    macs = []
    for run in runs:
        cfg = load_config(sweep.base_config, _resolve_overrides(sweep, run))
        assert cfg.adas.system == "B" and cfg.vanet.rx_log == "all"
        macs.append(cfg.vanet.mac)
    assert sorted(macs) == sorted(["sotdma", "80211p", "cv2x"] * 2)

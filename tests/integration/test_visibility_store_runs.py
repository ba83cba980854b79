"""Visibility maps kept between runs (cosim.vanet.mapstore) change nothing but the time: on the shipped
Krems map with ``configs/default.yaml``, a run without the store, the run that fills it and runs that start
from it (in the run's process and in the radio process) write the same bytes, and a run from the store
casts none of the maps it holds."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

import cosim.sim
from cosim.runconfig import load_run_config
from cosim.sim import Simulation

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.slow  # four 15-s runs on Krems


def _run(out: Path, store: Path | None, radio_process: bool, monkeypatch) -> tuple[str, dict]:
    monkeypatch.setattr(cosim.sim, "store_dir", lambda _cache: store)
    cfg = load_run_config(ROOT / "configs" / "default.yaml", duration_s=15.0, seed=3)
    with Simulation(cfg, out_dir=out, quiet=True, radio_process=radio_process) as sim:
        sim.run()
        pool = None if radio_process else sim.vanet.layer.aether.shadow
        counts = {} if pool is None else {"cast": pool.builds, "taken": pool.taken}
    return hashlib.sha256((out / "run.mcap").read_bytes()).hexdigest(), counts


def test_runs_from_the_store_write_the_same_bytes_and_cast_nothing_stored(tmp_path, monkeypatch):
    store = tmp_path / "visibility"
    plain, counts = _run(tmp_path / "no_store", None, False, monkeypatch)
    assert counts["cast"] > 100 and counts["taken"] == 0
    filled, counts = _run(tmp_path / "filling", store, False, monkeypatch)
    assert counts["taken"] == 0 and counts["cast"] > 100 and len(list(store.glob("*.vis"))) == 1
    warm, counts = _run(tmp_path / "warm", store, False, monkeypatch)
    assert counts["taken"] > 100 and counts["cast"] == 0  # the same run: every map from the store
    warm_child, _ = _run(tmp_path / "warm_radio_process", store, True, monkeypatch)
    assert plain == filled == warm == warm_child

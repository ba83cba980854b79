"""Sweep files, run ids and the metrics / table / plot code, without running a simulation."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from cosim.errors import ConfigError, CosimError
from cosim.sweep import SweepSpec, expand, load_sweep, metrics_from_topics, run_id
from cosim.sweep.aggregate import plot_metric, table_rows, write_table
from cosim.sweep.backends import LocalBackend, WorkerLost
from cosim.sweep.runner import load_config
from cosim.vanet.channel import OK


def write(tmp_path: Path, text: str, name: str = "sweep.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_grid_runs_and_seeds_are_crossed_and_ids_are_stable(tmp_path):
    spec = SweepSpec(name="s", grid={"scenario.demand.density": ("low", "high"), "timing.sumo_step_s": (0.1, 0.2)},
                     runs=({"vanet.channel.shadowing": "none"}, {"vanet.channel.shadowing": "los"}), seeds=(1, 2, 3))  # fmt: skip
    runs = expand(spec)
    assert len(runs) == 2 * 2 * 2 * 3
    assert len({r.run_id for r in runs}) == len(runs)
    first = runs[0]
    assert first.overrides == {"scenario.demand.density": "low", "timing.sumo_step_s": 0.1,
                               "vanet.channel.shadowing": "none"} and first.seed == 1  # fmt: skip
    # the id depends on the values only, not on the order of keys or of the lists
    assert run_id(dict(reversed(list(first.overrides.items()))), 1) == first.run_id
    spec2 = SweepSpec(name="s", grid={"timing.sumo_step_s": (0.2, 0.1), "scenario.demand.density": ("high", "low")},
                      runs=({"vanet.channel.shadowing": "los"}, {"vanet.channel.shadowing": "none"}), seeds=(3, 2, 1))  # fmt: skip
    assert {r.run_id for r in expand(spec2)} == {r.run_id for r in runs}
    assert run_id(first.overrides, 2) != first.run_id


def test_sweep_file_rejects_unknown_keys_and_impossible_values(tmp_path):
    base = write(tmp_path, "duration_s: 10\n", "base.yaml")
    ok = load_sweep(write(tmp_path, "name: a\nbase: base.yaml\ngrid: {seed_x: [1]}\n"))
    assert ok.base_config == base.resolve()
    with pytest.raises(ConfigError, match=r"config gird: unknown key"):
        load_sweep(write(tmp_path, "name: a\ngird: {scenario.demand.density: [low]}\n"))
    with pytest.raises(ConfigError, match=r"plots\[0\]\.metrc: unknown key"):
        load_sweep(write(tmp_path, "name: a\nplots: [{metrc: x, x: seed}]\n"))
    with pytest.raises(ConfigError, match="'seeds' for seeds"):
        load_sweep(write(tmp_path, "name: a\ngrid: {seed: [1, 2]}\n"))
    with pytest.raises(ConfigError, match="not swept"):
        load_sweep(
            write(
                tmp_path,
                "name: a\ngrid: {duration_s: [5]}\nplots: [{metric: pdr_overall, x: scenario.map}]\n",
            )
        )
    with pytest.raises(ConfigError, match="needs at least one value"):
        load_sweep(write(tmp_path, "name: a\ngrid: {duration_s: []}\n"))
    with pytest.raises(ConfigError, match="also a grid key"):
        load_sweep(write(tmp_path, "name: a\ngrid: {duration_s: [5]}\nruns: [{duration_s: 6}]\n"))
    with pytest.raises(ConfigError, match="plain folder name"):
        load_sweep(write(tmp_path, "name: ../up\n"))
    with pytest.raises(CosimError, match="same run"):
        load_sweep(write(tmp_path, "name: a\nruns: [{duration_s: 5}, {duration_s: 5}]\n"))
    with pytest.raises(CosimError, match="base config .* does not exist"):
        load_sweep(write(tmp_path, "name: a\nbase: nothere.yaml\n"))


def test_null_override_is_applied_and_unknown_null_key_rejected(tmp_path):
    cfg = load_config(None, {"vanet": None, "duration_s": 7.0})
    assert cfg.vanet is None and cfg.duration_s == 7.0
    with pytest.raises(ConfigError, match="vanet.chanel: unknown key"):
        load_config(None, {"vanet.chanel": None})
    with pytest.raises(ConfigError, match="nothing: unknown key"):
        load_config(None, {"nothing.at_all": None})


def _rx(distance_m, outcome):
    n = len(distance_m)
    return {"t_s": np.linspace(0.1, 1.0, n), "distance_m": np.asarray(distance_m, float),
            "outcome": np.asarray(outcome), "receiver_station_id": np.ones(n, int),
            "sender_station_id": np.arange(n) + 2, "gen_t_s": np.linspace(0.05, 0.95, n)}  # fmt: skip


def test_metrics_from_synthetic_columns():
    bad = OK + 1
    topics = {
        "/vanet/rx": _rx([50, 60, 150, 150, 250, 400, 700], [OK, bad, OK, OK, bad, OK, OK]),
        "/vanet/load": {
            "t_s": np.array([0.0, 1.0]),
            "busy_ratio": np.array([0.2, 0.4]),
            "airtime_ratio": np.array([0.1, 0.3]),
            "n_slots": np.array([100, 100]),
        },  # fmt: skip
        "/events": {"kind": np.array(["collision", "teleport", "teleport", "emergency_stop"], dtype=object)},
        "/traffic/vehicles": {"id": np.array(["a", "b", "c", "a", "b", "c", "d"], dtype=object)},
        "/adas/state": {
            "t_s": np.arange(8) * 0.1,
            "phase": np.array(["base"] * 4 + ["B"] * 4, dtype=object),
            "time_gap_true_s": np.array([3.0, 2.5, np.nan, 1.5, 1.0, 0.8, 1.9, 2.1]),
            "warning": np.array(
                ["none", "none", "none", "warning", "warning", "none", "warning", "none"], dtype=object
            ),
        },  # fmt: skip
    }
    counts = {"/vanet/rx": 7, "/traffic/vehicles": 2, "/events": 4, "/adas/state": 8}
    m = metrics_from_topics(topics, counts, pdr_bands_m=(0, 100, 300, 500))
    assert m["pdr_0_100m"] == pytest.approx(0.5)
    assert m["pdr_100_300m"] == pytest.approx(2 / 3)
    assert m["pdr_300_500m"] == pytest.approx(1.0)
    assert m["pdr_overall"] == pytest.approx(5 / 7) and m["rx_logged"] == 7
    assert m["channel_busy_mean"] == pytest.approx(0.3) and m["channel_airtime_mean"] == pytest.approx(0.2)
    assert m["slot_collision_fraction"] is None  # no /vanet/tx: empty, not zero
    assert (m["collisions"], m["teleports"], m["emergency_stops"], m["red_light_violations"]) == (1, 2, 1, 0)
    assert m["vehicles_mean"] == pytest.approx(3.5)
    assert m["ego_speed_mean_mps"] is None
    finite = np.array([3.0, 2.5, 1.5, 1.0, 0.8, 1.9, 2.1])
    assert m["timegap_mean_s"] == pytest.approx(finite.mean())
    assert m["timegap_share_below_2s"] == pytest.approx(4 / 7)
    assert m["warnings"] == 2  # two onsets of the warning level
    assert m["timegap_mean_s.base"] == pytest.approx(np.mean([3.0, 2.5, 1.5]))
    assert m["warnings.base"] == 1 and m["warnings.B"] == 2  # B starts in a warning: an onset
    assert m["timegap_min_s.B"] == pytest.approx(0.8)
    empty = metrics_from_topics({}, {})
    assert empty["pdr_0_100m"] is None and empty["collisions"] is None and empty["timegap_mean_s"] is None


def test_table_and_plot(tmp_path):
    results = []
    for dens, shadow, seed, pdr in [("low", "none", 1, 0.9), ("low", "none", 2, 0.8), ("high", "none", 1, 0.6),
                                    ("low", "los", 1, 0.5), ("high", "los", 1, 0.3)]:  # fmt: skip
        results.append({"run_id": f"{dens}{shadow}{seed}", "status": "ok", "seed": seed, "wall_s": 1.0,
                        "overrides": {"d": dens, "s": shadow}, "metrics": {"pdr_0_100m": pdr, "x.extra": 1}})  # fmt: skip
    results.append({"run_id": "bad", "status": "failed", "seed": 1, "error": "config d: nope",
                    "overrides": {"d": "weird", "s": "los"}, "metrics": {}})  # fmt: skip
    cols, rows = table_rows(results, ["d", "s"], (0, 100, 300))
    assert cols[:5] == ["run_id", "status", "d", "s", "seed"] and cols[-1] == "error" and "x.extra" in cols
    write_table(tmp_path / "t.csv", cols, rows)
    table = list(csv.DictReader((tmp_path / "t.csv").open()))
    assert len(table) == 6 and table[0]["pdr_0_100m"] == "0.9" and table[5]["pdr_0_100m"] == ""
    assert table[5]["error"] == "config d: nope" and table[5]["status"] == "failed"
    out = plot_metric(rows, "pdr_0_100m", "d", "s", tmp_path / "p.png")
    assert out is not None and out.stat().st_size > 5000
    assert plot_metric(rows, "pdr_100_300m", "d", None, tmp_path / "q.png") is None  # no values: no plot


def _die(x):
    import os

    if x == 1:
        os._exit(3)  # a worker that dies under a call
    return x * 10


def test_local_backend_reports_a_dead_worker_and_recovers():
    backend = LocalBackend(1)
    try:
        out = dict(backend.map_unordered(_die, [1]))
        assert isinstance(out[1], WorkerLost)
        assert dict(backend.map_unordered(_die, [2, 3])) == {2: 20, 3: 30}  # a fresh pool after the break
    finally:
        backend.close()

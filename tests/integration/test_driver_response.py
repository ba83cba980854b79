"""The assumed driver responses to systems A and B can be varied: the shipped sweep loads, expands and
resolves to run configs whose driver carries the swept values, and an override reaches the simulated driver."""

from __future__ import annotations

import numpy as np
import pytest
from testpaths import ROOT  # tests/ is on sys.path (conftest.py)

from cosim.driver import DriverConfig, make_driver
from cosim.errors import ConfigError
from cosim.experiment.analysis import RESPONSE_PARAMETERS
from cosim.runconfig import load_run_config
from cosim.sweep.runner import _resolve_overrides, load_config
from cosim.sweep.spec import load_sweep

SWEEP = ROOT / "configs" / "sweeps" / "driver_response.yaml"


def test_shipped_response_sweep_loads_expands_and_resolves():
    sweep = load_sweep(SWEEP)
    runs = sweep.runs()
    assert len(runs) == 27 and len({r.run_id for r in runs}) == 27
    systems = {r.overrides["adas.system"] for r in runs}
    assert systems == {"none", "A", "B"}
    swept = {
        k.rsplit(".", 1)[-1] for k in sweep.spec.swept_keys if k.startswith("ego.driver.profile_overrides.")
    }
    assert swept & set(RESPONSE_PARAMETERS["A"]) and swept & set(RESPONSE_PARAMETERS["B"])
    strengths = set()
    for run in runs:
        cfg = load_config(sweep.base_config, _resolve_overrides(sweep, run))
        prof = cfg.ego.driver.resolved_profile()
        assert cfg.adas.system == run.overrides["adas.system"]
        for key, value in run.overrides.items():
            if key.startswith("ego.driver.profile_overrides."):
                assert getattr(prof, key.rsplit(".", 1)[-1]) == pytest.approx(value)
        strengths.add((prof.a_brake_prob, prof.b_compliance))
    assert len(strengths) == 3


def test_override_reaches_the_driver_and_bad_ones_are_rejected():
    cfg = load_run_config(ROOT / "configs" / "default.yaml",
                          **{"ego.driver.profile_overrides.b_compliance": 0.35,
                             "ego.driver.profile_overrides.a_brake_prob": 0.1})  # fmt: skip
    driver = make_driver(cfg.ego.driver, np.random.default_rng(1), 0.6, 2.7)
    assert driver.profile.b_compliance == 0.35 and driver.profile.a_brake_prob == 0.1
    assert driver.profile.b_adapt_time_s == DriverConfig().resolved_profile().b_adapt_time_s  # the rest kept
    with pytest.raises(ConfigError, match="b_compliance"):
        load_run_config(
            ROOT / "configs" / "default.yaml", **{"ego.driver.profile_overrides.b_compliance": 1.5}
        )
    with pytest.raises(ConfigError, match="unknown parameter"):
        load_run_config(
            ROOT / "configs" / "default.yaml", **{"ego.driver.profile_overrides.b_complyance": 0.5}
        )


def test_override_reaches_the_driver_of_a_simulation(tmp_path):
    from cosim.sim import Simulation

    cfg = load_run_config(ROOT / "configs" / "default.yaml",
                          **{"duration_s": 1.0, "ego.driver.profile_overrides.b_compliance": 0.35})  # fmt: skip
    with Simulation(cfg, out_dir=tmp_path) as sim:
        assert sim.ego.driver.profile.b_compliance == 0.35


def test_experiment_summary_says_which_numbers_rest_on_the_assumed_responses():
    import dataclasses

    from cosim.experiment.analysis import assumptions_markdown, mark_assumed, response_assumptions
    from cosim.experiment.protocol import load_experiment
    from cosim.experiment.runner import summary_markdown

    exp, _ = load_experiment(ROOT / "configs" / "experiment.yaml", participants=2)
    run = {
        **exp.run,
        "ego": {**exp.run.get("ego", {}), "driver": {"profile_overrides": {"b_compliance": 0.5}}},
    }
    exp = dataclasses.replace(exp, run=run)
    a = response_assumptions(exp)
    assert a["scripted_participants"] == ["P1", "P2"] and a["sweep"] == "configs/sweeps/driver_response.yaml"
    assert a["values"]["P1"]["b_compliance"] == 0.5 and a["values"]["P1"]["a_brake_prob"] == 0.8
    assert "a_gap_increase_s" in a["parameters"]["A"] and "b_target_gap_s" in a["parameters"]["B"]
    phases = [{"phase": "baseline", "system": "none"}, {"phase": "system_A", "system": "A"},
              {"phase": "system_B", "system": "B"}]  # fmt: skip
    results = [{"participant": p, "profile": "daily_commuter", "order": [], "phases": [dict(x) for x in phases]}
               for p in ("P1", "P2")]  # fmt: skip
    across = [{"system": s, "n": 2} for s in ("none", "A", "B")]
    mark_assumed(results, across, a)
    marks = {ph["system"]: ph["rests_on_assumed_response"] for ph in results[0]["phases"]}
    assert marks["none"] == [] and "a_brake_prob" in marks["A"] and "b_compliance" in marks["B"]
    assert [bool(r["rests_on_assumed_response"]) for r in across] == [False, True, True]
    text = "\n".join(assumptions_markdown(a))
    assert "| B | `b_compliance` | 0.5 | 0.5 |" in text and "driver_response.yaml" in text
    summary = {"experiment": "x", "participants": [], "across": [], "wall_s": 1.0, "jobs": 1, "simulated_s": 1.0,
               "assumptions": a}  # fmt: skip
    md = summary_markdown(summary)
    assert "rest on assumed driver responses" in md and "## Assumptions" in md
    # a person at the wheel: nothing rests on the scripted assumptions
    person = dataclasses.replace(exp, run={**run, "ego": {"driver": {"kind": "keyboard"}}})
    assert response_assumptions(person)["values"] == {}

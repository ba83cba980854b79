"""The experiment protocol end to end, its golden time-gap trace, and system B against SUMO's own TGAP."""

from __future__ import annotations

import csv
import json
import os
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from cosim.experiment.analysis import phase_summary, timegap_columns, write_timegap_csv
from cosim.experiment.compare import compare_files
from cosim.experiment.protocol import load_experiment, participant_config, start_time_s
from cosim.experiment.runner import SUMMARY_TOPICS, run_experiment
from cosim.log import read
from cosim.runconfig import load_run_config
from cosim.sim import Simulation

ROOT = Path(__file__).resolve().parents[2]
# P2 (baseline > system_B > system_A) of the short protocol (``_short_protocol``)
GOLDEN = ROOT / "tests" / "golden" / "paper_P2_3x20s.csv"
# The shipped experiment's seed (7) starts its route in a 300-m queue at a merge (Krems 327615581 ->
# 448399300) since parking aisles are closed to cars: in 20-s phases system A never warns there. Seed 2
# starts on a free road and met every system's warnings until Krems' two lights at 83637441 became one
# junction (session 28); since then its system B phases never advise. Seed 4 meets them all again (seeds
# 2-5 tried: 2 and 3 miss B's advisory and warning, 4 and 5 show every level).
SHORT_SEED = 4


def _short_protocol():
    """configs/experiment.yaml with 20-s phases, two participants (both system orders) and SHORT_SEED."""
    import dataclasses

    exp, base = load_experiment(ROOT / "configs" / "experiment.yaml", participants=2, phase_duration_s=20)
    return dataclasses.replace(exp, seed=SHORT_SEED), base


pytestmark = pytest.mark.slow  # two participants x 60 s of the protocol on Krems; SUMO-only runs of 40-120 s


@pytest.fixture(scope="module")
def short_experiment(tmp_path_factory):
    """The short protocol (``_short_protocol``) run."""
    exp, base = _short_protocol()
    out = tmp_path_factory.mktemp("exp")
    summary = run_experiment(exp, base, out, jobs=2, quiet=True)
    return out, summary


def test_the_ego_collides_with_nothing_in_the_short_experiment(short_experiment):
    _, summary = short_experiment
    for part in summary["participants"]:
        assert [ph["health"]["ego_collisions"] for ph in part["phases"]] == [0, 0, 0], part["participant"]


def test_no_vehicle_collides_in_the_short_experiment(short_experiment):
    """Issue 15.5. Was an expected failure: cars collided in the parking lot of Krems 860978174, where a
    third of the trips looped to turn round; trips now run from street to street and none goes there."""
    _, summary = short_experiment
    assert [part["run"]["collisions"] for part in summary["participants"]] == [0, 0]


def test_summary_has_the_three_phases_per_participant(short_experiment):
    out, summary = short_experiment
    for part, order in zip(summary["participants"], (["baseline", "system_A", "system_B"],
                                                       ["baseline", "system_B", "system_A"]), strict=True):  # fmt: skip
        assert [p["phase"] for p in part["phases"]] == order
        assert [p["system"] for p in part["phases"]] == [
            {"baseline": "none", "system_A": "A", "system_B": "B"}[o] for o in order
        ]
        assert all(ph["health"]["ego_collisions"] == 0 for ph in part["phases"]), part["phases"]
    on_disk = json.loads((out / "summary.json").read_text())
    assert on_disk["participants"][0]["participant"] == "P1"
    for pid in ("P1", "P2"):
        assert (out / pid / "timegap.png").stat().st_size > 10_000
        header = (out / pid / "timegap.csv").read_text().splitlines()[0]
        assert header == "t_s,phase,system,time_gap_true_s,time_gap_displayed_s,warning,lead_paced"
    assert "Across participants" in (out / "summary.md").read_text()


def test_results_from_kept_messages_equal_results_from_the_file(short_experiment, tmp_path):
    """The runner summarises from messages kept in memory; the file read back must give the same."""
    out, summary = short_experiment
    exp, base = _short_protocol()
    for index, part in enumerate(summary["participants"]):
        start = start_time_s(exp, participant_config(exp, index, base).ego.depart_s)
        log = read(out / part["participant"] / "run.mcap", topics=SUMMARY_TOPICS)
        cols = timegap_columns(log, start)
        write_timegap_csv(cols, tmp_path / "timegap.csv")
        assert (tmp_path / "timegap.csv").read_bytes() == (
            out / part["participant"] / "timegap.csv"
        ).read_bytes()
        from_file = json.loads(json.dumps(phase_summary(log, cols, start)))
        # (the runner adds the drive health and the assumptions to each phase: not from the log)
        assert from_file == [{k: ph[k] for k in f} for ph, f in zip(part["phases"], from_file, strict=True)]


def test_time_gap_trace_matches_the_golden_one(short_experiment):
    """Fails when the simulation drifts: regenerate deliberately with COSIM_UPDATE_GOLDEN=1."""
    out, _ = short_experiment
    produced = out / "P2" / "timegap.csv"
    # a golden trace is worth keeping only while the run covers what it guards: every phase follows the lead
    # at some time gap, and between the two participants system B advises and warns and system A warns
    rows = {pid: list(csv.DictReader((out / pid / "timegap.csv").open())) for pid in ("P1", "P2")}
    for system, levels in (("none", set()), ("B", {"advisory", "warning"}), ("A", {"warning"})):
        shown = set()
        for pid, trace in rows.items():
            phase = [r for r in trace if r["system"] == system]
            assert any(float(r["time_gap_true_s"] or 10.0) < 10.0 for r in phase), (
                f"{pid}: no time gap in {system}"
            )
            shown |= {r["warning"] for r in phase}
        assert levels <= shown, f"{system}: {levels} not all shown"
    if os.environ.get("COSIM_UPDATE_GOLDEN") or not GOLDEN.exists():
        shutil.copy(produced, GOLDEN)
        pytest.skip(f"golden trace written to {GOLDEN}")
    result = compare_files(GOLDEN, produced)
    assert result.ok, result.table()
    # the MCAP of the same run gives the same trace as its CSV
    assert compare_files(produced, out / "P2" / "run.mcap").ok


def test_compare_detects_a_drifted_trace(short_experiment, tmp_path):
    out, _ = short_experiment
    lines = (out / "P1" / "timegap.csv").read_text().splitlines()
    drifted = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        if cells[3]:
            cells[3] = f"{float(cells[3]) * 1.2:.4f}"
        drifted.append(",".join(cells))
    bad = tmp_path / "drifted.csv"
    bad.write_text("\n".join(drifted) + "\n")
    assert not compare_files(out / "P1" / "timegap.csv", bad).ok


@pytest.mark.own_process
def test_system_b_agrees_with_sumo_ssm_time_gap_on_a_perfect_radio(tmp_path):
    """With no shadowing, the time gap system B shows from CAMs matches SUMO's SSM TGAP for the same pair:
    median error < 0.1 s, 90 % within 0.3 s (the rest: CAM age before a sudden speed change, the chord
    across a sharp bend). Compared where B warns at all (own speed >= its min_speed_mps): below, gap / speed
    is ill-conditioned (0.2 m of gap at 0.5 m/s is 0.4 s).

    Time stamps: SSM labels each value with the *start* of the SUMO step in which the vehicles moved (its
    timeSpan begins at 0.0, the log's first step at 0.1), the log with the step's end (``traci.getTime()``
    after ``simulationStep``): the SSM value of the state logged at t is at t - step. Without that shift the
    comparison was one step off, which alone cost ~0.2 s at the 90th percentile where the gap changes fast
    (measured: SUMO's own ground-truth time gap vs SSM, 90th percentile 0.21-0.29 s unshifted, 0.005 s
    shifted; B vs SSM 0.23-0.29 s -> 0.13-0.23 s)."""
    cfg = load_run_config(ROOT / "configs" / "default.yaml", **{
        "duration_s": 120, "scenario.demand.density": "low", "ego.physics": "sumo", "adas.system": "B",
        "vanet.channel.shadowing": "none"})  # fmt: skip
    ssm = tmp_path / "ssm.xml"
    args = ("--device.ssm.explicit", "ego", "--device.ssm.measures", "TGAP", "--device.ssm.file", str(ssm),
            "--device.ssm.trajectories", "true", "--device.ssm.range", "100")  # fmt: skip
    with Simulation(cfg, out_dir=tmp_path, sumo_args=args) as sim:
        sim.run()
    g = ET.parse(ssm).getroot().find("globalMeasures")
    ts = np.array(g.find("timeSpan").get("values").split(), float)
    tgap = np.array([np.nan if v == "NA" else float(v) for v in g.find("TGAPSpan").get("values").split()])
    log = read(tmp_path / "run.mcap", topics=["/adas/state", "/ego/state"])
    a, ego = log["/adas/state"], log["/ego/state"]
    shown = a["b_gap_s"].astype(float)
    sumo = np.interp(a["t_s"] - cfg.timing.sumo_step_s, ts, tgap, left=np.nan, right=np.nan)
    speed = np.interp(a["t_s"], ego["t_s"], ego["speed_mps"].astype(float))
    both = (
        (speed >= cfg.adas.v2v.min_speed_mps)
        & np.isfinite(shown)
        & np.isfinite(sumo)
        & (shown < 9.9)
        & (sumo < 9.9)
        & (a["b_leader_id"] == a["leader_id"])
    )
    assert both.sum() > 200
    err = np.abs(shown[both] - sumo[both])
    assert np.median(err) < 0.1 and np.percentile(err, 90) < 0.3, (np.median(err), np.percentile(err, 90))


@pytest.mark.own_process
def test_lost_cams_make_system_b_show_no_data(tmp_path):
    """The channel cut (10 nW: every link is below sensitivity beyond ~1 m): B never shows a gap, only "no data"."""
    cfg = load_run_config(ROOT / "configs" / "default.yaml", **{
        "duration_s": 40, "scenario.demand.density": "low", "ego.physics": "sumo", "adas.system": "B",
        "vanet.channel.tx_power_mw": 1e-5})  # fmt: skip
    with Simulation(cfg, out_dir=tmp_path) as sim:
        sim.run()
    a = read(tmp_path / "run.mcap", topics=["/adas/state"])["/adas/state"]
    assert np.isfinite(a["time_gap_true_s"].astype(float)).any()  # there was someone to follow
    assert not np.isfinite(a["b_gap_s"].astype(float)).any()
    assert set(a["b_status"]) <= {"no_cam", "stale"}

"""The radio in a second process (issue 20 item 3) logs exactly what the radio in the run's process does.

Runs on the shipped Krems map with ``configs/default.yaml`` (the ego, the lead, every vehicle a station,
system B reading the ego's OBU), once with ``radio_process=False`` and once with ``True``: the files must be
the same bytes, for SOTDMA and for an interface MAC (802.11p, whose OBU views are ready only after the MAC's
step), also when the run is cut short by Ctrl-C in the middle of a step. The golden payload digests
(test_payload_identity.py) are taken with the default, which is the radio process on a machine with two
cores.
"""

from __future__ import annotations

import dataclasses
import hashlib
from pathlib import Path

import numpy as np
import pytest

from cosim.runconfig import load_run_config
from cosim.seeds import stream
from cosim.sim import Simulation
from cosim.world import World

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.slow  # a few 15-s runs on Krems


def _run(
    out: Path, radio_process: bool, *, mac: str = "sotdma", interrupt_at_step: int | None = None
) -> dict:
    cfg = load_run_config(ROOT / "configs" / "default.yaml", duration_s=15.0, seed=2)
    cfg = dataclasses.replace(cfg, vanet=dataclasses.replace(cfg.vanet, mac=mac))
    with Simulation(cfg, out_dir=out, quiet=True, radio_process=radio_process) as sim:
        if interrupt_at_step is not None:

            def ctrl_c(sim) -> None:  # in the middle of a step: after the radio began, before the log
                if sim.world.step == interrupt_at_step:
                    raise KeyboardInterrupt

            sim.add_hook("driver", ctrl_c)
        stats = sim.run()
        assert (sim.vanet.__class__.__name__ == "VanetProcess") == radio_process
    return stats


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize("mac", ["sotdma", "80211p"])
def test_the_radio_process_gives_the_same_log_bytes(tmp_path, mac):
    a = _run(tmp_path / "in_process", False, mac=mac)
    b = _run(tmp_path / "radio_process", True, mac=mac)
    assert a["steps"] == b["steps"] == 150
    assert b["health"]["ego_present_at_s"] is not None  # the ego drove: system B had an OBU to read
    assert _sha(tmp_path / "in_process" / "run.mcap") == _sha(tmp_path / "radio_process" / "run.mcap")


def test_ctrl_c_in_the_middle_of_a_step_loses_nothing_the_run_in_one_process_keeps(tmp_path):
    a = _run(tmp_path / "in_process", False, interrupt_at_step=60)
    b = _run(tmp_path / "radio_process", True, interrupt_at_step=60)
    assert a["interrupted"] and b["interrupted"] and a["steps"] == b["steps"] == 59
    assert _sha(tmp_path / "in_process" / "run.mcap") == _sha(tmp_path / "radio_process" / "run.mcap")


def test_a_failing_radio_process_says_so(tmp_path):
    from cosim.phases.vanet_process import VanetProcess

    cfg = load_run_config(ROOT / "configs" / "default.yaml")
    proc = VanetProcess(cfg.vanet, tmp_path / "no_such_buildings.poly.xml", stream(1, "vanet"), log=False)
    try:
        with pytest.raises(RuntimeError, match="radio process failed.*no_such_buildings"):
            proc.begin(World(capacity=8), 0.1)
    finally:
        proc.close()


def test_the_ego_obu_view_from_the_radio_process_answers_as_the_layer_does():
    """``portable_view`` keeps only the CAMs a view can reach; every question system B asks gets the same
    answer from it as from the view over the whole record store."""
    from cosim.buildings import Buildings
    from cosim.phases.vanet import VanetPhase
    from cosim.phases.vanet_process import portable_view

    cfg = load_run_config(ROOT / "configs" / "default.yaml")
    phase = VanetPhase(cfg.vanet, Buildings(), np.random.default_rng(1), log=False)
    w = World(capacity=64)
    rng = np.random.default_rng(2)
    for i in range(40):
        s = w.add(f"v{i}", is_ego=i == 0)
        w.x_m[s], w.y_m[s] = (0.0 if i == 0 else rng.uniform(10, 300)), (0.0 if i % 2 == 0 else 3.5)
        w.heading_deg[s], w.speed_mps[s], w.length_m[s], w.width_m[s] = 90.0, 12.0, 4.5, 1.8
        w.lane_index[s] = 0
    for k in range(100):  # 10 s: older CAMs than the map's memory are held too
        w.step = k
        w.x_m[w.valid] += 1.2
        phase.step(w, 0.1)
    full = phase.layer.obu_view(w)
    small = portable_view(full)
    assert small.records.seqs.size < phase.layer.records.next_seq / 10
    a, b = full.neighbours(), small.neighbours()
    assert len(a) > 10 and np.array_equal(a.seq, b.seq) and np.array_equal(a.gap_m, b.gap_m)
    leader = full.find_leader(cfg.adas.leader_criteria)  # system B's criteria
    assert leader is not None and leader.seq == small.find_leader(cfg.adas.leader_criteria).seq
    for station in (2, 7, 39, 999):
        (ca, aa), (cb, ab) = (
            full.latest_from(station, max_age_s=np.inf),
            small.latest_from(station, max_age_s=np.inf),
        )
        assert ca == cb and aa == ab

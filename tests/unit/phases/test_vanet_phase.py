"""The VANET phase with fake ports: a World filled by the test, no buildings, its own random stream (no
SUMO, no MuJoCo)."""

from __future__ import annotations

import numpy as np

from cosim.adas.config import AdasConfig
from cosim.buildings import Buildings
from cosim.phases.vanet import VanetPhase, _logged_tx
from cosim.seeds import stream
from cosim.vanet import VanetParams
from cosim.world import EGO_ID, World


def _column_of_cars() -> World:
    """The ego and two cars ahead of it, 20 m apart, driving east at 10 m/s."""
    w = World(capacity=8)
    for k, vid in enumerate((EGO_ID, "car1", "car2")):
        s = w.add(vid, is_ego=vid == EGO_ID)
        w.x_m[s], w.y_m[s], w.heading_deg[s], w.speed_mps[s] = 20.0 * k, 0.0, 90.0, 10.0
        w.length_m[s], w.width_m[s], w.lane_index[s] = 4.5, 1.8, 0
    return w


def _run(phase: VanetPhase, w: World, steps: int):
    out = []
    for _ in range(steps):
        w.step += 1
        w.t_s = round(w.step * 0.1, 6)
        w.x_m[w.valid] += 1.0
        out.append(phase.step(w, 0.1))
    return out


def test_cams_reach_the_egos_obu_and_the_leader_is_named_by_its_station():
    w = _column_of_cars()
    phase = VanetPhase(VanetParams(), Buildings([]), stream(1, "vanet"), log=True)
    out = _run(phase, w, 30)
    assert all(res.step_index == k + 1 for k, (res, _) in enumerate(out))
    topics = {t for _, tp in out for t in tp}
    assert {"/vanet/rx", "/vanet/tx", "/vanet/load", "/vanet/step"} <= topics
    obu = phase.ego_obu(w)
    leader = obu.find_leader(AdasConfig().leader_criteria)  # system B's choice (criteria a-d, g)
    assert leader is not None
    assert phase.vehicle_of_station(w, leader.station_id) == "car1"  # the nearest car ahead
    assert phase.vehicle_of_station(w, None) == "" and phase.vehicle_of_station(w, 10**6) == ""
    phase.close()


def test_without_a_log_no_messages_and_the_same_radio():
    a, b = _column_of_cars(), _column_of_cars()
    logged = _run(VanetPhase(VanetParams(), Buildings([]), stream(1, "vanet"), log=True), a, 20)
    quiet = _run(VanetPhase(VanetParams(), Buildings([]), stream(1, "vanet"), log=False), b, 20)
    assert all(tp == {} for _, tp in quiet)
    for (ra, _), (rb, _) in zip(logged, quiet, strict=True):
        for topic, cols in ra.columns().items():
            for k, v in cols.items():
                np.testing.assert_array_equal(v, rb.columns()[topic][k])


def test_tx_rows_are_kept_only_when_a_reception_row_refers_to_them():
    tx = {"sender_slot": np.array([0, 1, 2]), "frame": np.array([5, 5, 5]), "slot": np.array([10, 11, 12]),
          "gen_t_s": np.array([0.1, 0.1, 0.2]), "size_bytes": np.array([200, 300, 400])}  # fmt: skip
    rx = {"sender_slot": np.array([1, 1]), "frame": np.array([5, 5]), "slot": np.array([11, 11]),
          "gen_t_s": np.array([0.1, 0.1])}  # fmt: skip
    kept = _logged_tx(tx, rx, "rx")
    assert kept["size_bytes"].tolist() == [300]
    assert len(_logged_tx(tx, rx, "none")["size_bytes"]) == 0
    assert len(_logged_tx(tx, {k: v[:0] for k, v in rx.items()}, "rx")["size_bytes"]) == 0

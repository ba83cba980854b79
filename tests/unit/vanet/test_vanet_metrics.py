"""Metrics from hand-made /vanet columns, and the report on a real layer run."""

import json

import numpy as np
import pytest
from vanet_testkit import advance, make_world

from cosim.vanet import VanetLayer, VanetParams
from cosim.vanet.channel import DAMAGED, OK, SHADOWED, ChannelParams
from cosim.vanet.metrics import (
    age_of_information,
    inter_packet_gap,
    outcome_counts,
    pdr_vs_distance,
    slot_collisions,
    summarize,
)
from cosim.vanet.report import vanet_report


def rx_cols(rows):
    """rows: (t_s, gen_t_s, sender_id, receiver_id, distance_m, outcome)."""
    a = np.array(rows, dtype=float)
    return {
        "t_s": a[:, 0],
        "gen_t_s": a[:, 1],
        "sender_station_id": a[:, 2].astype(np.uint32),
        "receiver_station_id": a[:, 3].astype(np.uint32),
        "distance_m": a[:, 4].astype(np.float32),
        "outcome": a[:, 5].astype(np.uint8),
    }


RX = rx_cols(
    [
        # pair (receiver 1, sender 2): decoded at 1.0, 2.0, 4.0 (the one at 3.0 was damaged)
        (1.0, 0.9, 2, 1, 5.0, OK),
        (2.0, 1.8, 2, 1, 7.0, OK),
        (3.0, 2.9, 2, 1, 12.0, DAMAGED),
        (4.0, 3.5, 2, 1, 15.0, OK),
        # pair (receiver 2, sender 1)
        (1.5, 1.4, 1, 2, 8.0, OK),
        (2.5, 2.4, 1, 2, 14.0, SHADOWED),
    ]
)


def test_pdr_vs_distance_in_10_m_bins():
    p = pdr_vs_distance(RX)
    assert p["bin_lo_m"].tolist() == [0.0, 10.0]
    assert p["n"].tolist() == [3, 3] and p["n_ok"].tolist() == [3, 1]
    assert p["pdr"] == pytest.approx([1.0, 1 / 3])
    assert outcome_counts(RX) == {"ok": 4, "below_sensitivity": 0, "shadowed": 1, "collided": 0, "damaged": 1}


def test_age_of_information_and_inter_packet_gap():
    aoi = age_of_information(RX)
    assert sorted(aoi["age_at_delivery_s"]) == pytest.approx(sorted([0.1, 0.2, 0.5, 0.1]))
    # peak AoI just before deliveries 2 and 3 of pair (1, 2): 2.0 - 0.9, 4.0 - 1.8
    assert sorted(aoi["peak_aoi_s"]) == pytest.approx([1.1, 2.2])
    # saw-tooth area: [1,2]: (1.1^2 - 0.1^2)/2 = 0.6; [2,4]: (2.2^2 - 0.2^2)/2 = 2.4 -> 3.0 / 3 s
    assert aoi["mean_aoi_s"] == pytest.approx([1.0]) and aoi["span_s"] == pytest.approx([3.0])
    assert sorted(inter_packet_gap(RX)) == pytest.approx([1.0, 2.0])


def test_slot_collisions():
    tx = {
        "frame": np.array([0, 0, 0, 1, 1]),
        "slot": np.array([5, 5, 9, 5, 6], dtype=np.int32),
        "t_s": np.zeros(5),
    }
    c = slot_collisions(tx)
    assert c == {
        "transmissions": 5,
        "slots_used": 4,
        "multi_tx_slots": 1,
        "tx_in_multi_slots": 2,
        "fraction": 0.4,
    }


def test_summary_handles_missing_topics():
    s = summarize({})
    assert s["transmissions"] == 0 and s["pdr_overall"] is None and s["aoi_s"]["time_average"] is None
    json.dumps(s)


def test_report_on_a_layer_run_writes_plots(tmp_path):
    w = make_world([[0, i * 60.0] for i in range(8)], heading_deg=0.0, speed_mps=8.0, ego=0)
    layer = VanetLayer(
        VanetParams(channel=ChannelParams(shadowing="none"), rx_log="all"), [], np.random.default_rng(0)
    )
    cols: dict[str, dict[str, list]] = {}
    for k in range(40):
        w.step = k
        for topic, c in layer.step(w, k, 0.1).columns().items():
            for name, arr in c.items():
                cols.setdefault(topic, {}).setdefault(name, []).append(arr)
        advance(w, 0.1)
    columns = {t: {n: np.concatenate(v) for n, v in c.items()} for t, c in cols.items()}
    summary = vanet_report(columns, tmp_path / "report")
    json.dumps(summary)
    assert summary["transmissions"] > 0 and summary["pdr_overall"] > 0.9
    assert summary["channel_load"]["frames"] == 4  # 40 steps of 0.1 s: frames 0..3 complete
    assert summary["aoi_s"]["peak"]["n"] > 0 and summary["inter_packet_gap_s"]["p50"] > 0
    for path in summary["plots"]:
        with open(path, "rb") as fh:
            assert fh.read(8) == b"\x89PNG\r\n\x1a\n"

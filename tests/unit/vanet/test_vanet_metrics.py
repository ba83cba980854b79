"""Metrics from hand-made /vanet columns, and the report on a real layer run."""

import json

import numpy as np
import pytest
from vanet_testkit import advance, make_world

from cosim.vanet import VanetLayer, VanetParams
from cosim.vanet.channel import DAMAGED, OK, SHADOWED, ChannelParams
from cosim.vanet.metrics import (
    age_of_information,
    app_metrics_from_log,
    inter_packet_gap,
    outcome_counts,
    pair_deliveries,
    pdr_vs_distance,
    slot_collisions,
    summarize,
)
from cosim.vanet.report import run_title, vanet_report


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


def test_pair_deliveries_streamed_equal_all_at_once():
    """cosim radio feeds deliveries window by window, vanet-report a whole log at once: same gaps and peaks."""
    rng = np.random.default_rng(3)
    key = rng.integers(0, 5, 200)
    t = np.sort(rng.uniform(0, 20, 200))
    gen = t - rng.uniform(0.0, 0.3, 200)
    once = pair_deliveries(key, t, gen, np.full(5, np.nan), np.full(5, np.nan))
    last_t, last_g = np.full(5, np.nan), np.full(5, np.nan)
    parts = [
        pair_deliveries(key[i : i + 17], t[i : i + 17], gen[i : i + 17], last_t, last_g)
        for i in range(0, 200, 17)
    ]
    gaps = np.concatenate([p[1] for p in parts])
    order = np.concatenate([p[0] + i for p, i in zip(parts, range(0, 200, 17), strict=True)])
    by_row = np.full(200, np.nan)
    by_row[order] = gaps
    ref = np.full(200, np.nan)
    ref[once[0]] = once[1]
    assert np.array_equal(np.isnan(by_row), np.isnan(ref)) and np.nansum(np.abs(by_row - ref)) < 1e-12
    assert np.isnan(ref).sum() == 5  # one first delivery per pair
    # peak AoI = gap + the previous CAM's age at its delivery
    prev_age = {}
    for i in np.lexsort((t, key)):
        if key[i] in prev_age:
            assert once[2][list(once[0]).index(i)] == pytest.approx(t[i] - prev_age[key[i]])
        prev_age[key[i]] = gen[i]


def test_application_pdr_counts_cams_never_sent():
    # sender 2 -> receiver 1 at 20 m: 3 CAMs sent, 2 decoded; a quarter of all generated CAMs never sent
    rx = rx_cols([(1.0, 0.9, 2, 1, 20.0, OK), (2.0, 1.9, 2, 1, 20.0, DAMAGED), (3.0, 2.9, 2, 1, 20.0, OK),
                  (3.0, 2.95, 3, 1, 70.0, OK)])  # fmt: skip
    step = {
        "cams_generated": np.array([4, 4], dtype=np.int32),
        "cams_dropped": np.array([1, 1], dtype=np.int32),
    }
    acc, q = app_metrics_from_log(rx, step)
    assert q == 0.25
    near, far = acc.band_table(q)
    assert near["pdr_link"] == pytest.approx(2 / 3) and near["pdr"] == pytest.approx(2 / 3 * 0.75)
    assert near["n_sent"] == 3 and far["from_m"] == 50.0 and far["pdr"] == pytest.approx(0.75)
    assert near["ipg_p50_s"] == pytest.approx(2.0) and near["age_p50_s"] == pytest.approx(0.1)
    assert far["ipg_p95_s"] is None  # one delivery: no gap
    s = summarize({"/vanet/rx": rx, "/vanet/step": step})
    assert s["never_sent_share"] == 0.25 and s["app_vs_distance"][0]["pdr"] == near["pdr"]


def test_report_titles_name_the_run_map_and_density(tmp_path, monkeypatch):
    import matplotlib.axes

    meta = {"cosim": {"config": json.dumps({"name": "dense-test", "seed": 4, "scenario": {
        "map": "/x/maps/munich.osm.gz", "demand": {"density": "high"}}}), "map": "munich.osm.gz", "seed": "4"}}  # fmt: skip
    title = run_title(meta)
    assert title == "run dense-test, munich.osm.gz, high traffic, seed 4"
    titles = []
    orig = matplotlib.axes.Axes.set_title
    monkeypatch.setattr(
        matplotlib.axes.Axes, "set_title", lambda ax, t, *a, **k: (titles.append(t), orig(ax, t, *a, **k))[1]
    )
    load = {"t_s": np.array([0.0, 1.0]), "n_slots": np.array([1953, 1953]), "busy_ratio": np.array([0.1, 0.2]), "airtime_ratio": np.array([0.05, 0.1]),
            "cbr_mean": np.array([0.1, 0.15]), "cbr_p95": np.array([0.2, 0.3]), "cbr_ego": np.array([np.nan, 0.1])}  # fmt: skip
    summary = vanet_report({"/vanet/rx": RX, "/vanet/load": load}, tmp_path, title=title)
    assert summary["run"] == title and len(summary["plots"]) == 4
    assert len(titles) == 5 and all(title in t for t in titles)
    assert summary["cbr"]["mean"]["max"] == pytest.approx(0.15) and summary["cbr"]["ego"]["n"] == 1

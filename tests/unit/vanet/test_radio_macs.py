"""`cosim radio --mac sotdma,80211p,cv2x` (issue 18): the MACs on one layout, seed, channel and receiver."""

import json

import numpy as np

from cosim.cli import main
from cosim.vanet.radio import RadioScenario, run_radio

ARGS = ["radio", "--layout", "highway", "--vehicles-per-km", "20", "--rate-hz", "10",
        "--size-bytes", "190", "--tx-dbm", "13", "--pathloss", "3gpp-highway", "--duration", "12"]  # fmt: skip


def test_several_macs_give_a_list_in_order_and_one_overlay_plot(tmp_path, capsys):
    out = tmp_path / "r"
    assert main([*ARGS, "--mac", "sotdma,80211p,cv2x", "--json", "--out", str(out)]) == 0
    res = json.loads(capsys.readouterr().out)
    assert [r["mac"] for r in res] == ["sotdma", "80211p", "cv2x"]
    keys = ["mac", "stations", "pdr", "cbr", "shared_slot_share", "never_sent_share", "ipg_p95_s"]
    assert all(list(r) == keys for r in res)
    assert len({r["stations"] for r in res}) == 1
    assert res[0]["shared_slot_share"] is not None and res[1]["shared_slot_share"] is None
    # the same layout: the denominators (receiver, generated CAM) per band are the MAC's own choices only
    # through never-sent CAMs, never through the positions
    assert [b["n"] for b in res[1]["pdr"]] == [b["n"] for b in res[2]["pdr"]]
    assert json.loads((out / "radio.json").read_text()) == res
    assert (out / "pdr_vs_distance.png").stat().st_size > 5000
    for r in res:  # every MAC delivers nearly everything at short range on this light highway
        assert r["pdr"][0]["pdr"] > 0.9, r["mac"]
    # the single-MAC form keeps its shape: one object
    assert main([*ARGS, "--mac", "cv2x", "--json"]) == 0
    one = json.loads(capsys.readouterr().out)
    assert isinstance(one, dict) and list(one) == keys and one == res[2]


def test_each_mac_is_deterministic_per_seed_and_seed_matters():
    for mac in ("80211p", "cv2x"):
        sc = RadioScenario(mac=mac, layout="highway", vehicles_per_km=20, rate_hz=10,
                           size_bytes=190, tx_dbm=13, pathloss="3gpp-highway", duration_s=12)  # fmt: skip
        a, b = run_radio(sc), run_radio(sc)
        assert a == b
        c = run_radio(RadioScenario(**{**sc.__dict__, "seed": 2}))
        assert c != a


def test_cv2x_cams_taken_over_count_with_their_generation():
    # C-V2X sends a CAM in its reserved subframe, often in the next 100-ms window: those CAMs must count
    # as delivered (with the generation they had), so the application PDR near the sender is ~ the link's
    sc = RadioScenario(mac="cv2x", layout="highway", vehicles_per_km=20, rate_hz=10,
                       size_bytes=190, tx_dbm=13, pathloss="3gpp-highway", duration_s=12)  # fmt: skip
    app, link = run_radio(sc, link_level=True)
    assert app["never_sent_share"] < 0.01
    assert app["pdr"][0]["pdr"] > 0.97 and abs(app["pdr"][0]["pdr"] - link[0]["pdr"]) < 0.02
    assert np.isfinite(app["ipg_p95_s"]) and app["ipg_p95_s"] <= 0.2


def test_80211p_pdr_vs_distance_agrees_with_the_ns3_reference():
    """ns-3 3.37 (validation/ns3/run.sh: 802.11p OCB 10 MHz 6 Mb/s, 3GPP TR 37.885 highway LOS, 3 dB
    shadowing, one sender, 40 runs); cosim's 802.11p MAC on the same link budget and shared receiver: 200
    standing stations on 10 km at 1 Hz (hardly any contention), seeds 1-6, link-level PDR (sent CAMs).
    Tolerance, as SOTDMA's: per 50-m band |dPDR| <= 0.10, mean over 0-1000 m <= 0.04 (measured 0.093 / 0.034:
    cosim is lower at 450-650 m, the receiver's 6-dB capture against ns-3's error-rate model)."""
    import csv
    from pathlib import Path

    ns3 = Path(__file__).resolve().parents[3] / "validation" / "ns3" / "ns3_highway_pdr.csv"
    ref = {float(r["from_m"]): float(r["pdr"]) for r in csv.DictReader(ns3.open())}
    num, den = {}, {}
    for seed in range(1, 7):
        sc = RadioScenario(mac="80211p", layout="highway", stations=200, area_m=10_000, lanes=1, rate_hz=1,
                           size_bytes=300, tx_dbm=13, pathloss="3gpp-highway", shadowing_db=3.0, duration_s=14,
                           warmup_s=10, seed=seed)  # fmt: skip
        for b in run_radio(sc, link_level=True)[1]:
            num[b["from_m"]] = num.get(b["from_m"], 0.0) + b["pdr"] * b["n"]
            den[b["from_m"]] = den.get(b["from_m"], 0) + b["n"]
    dev = [abs(num[f] / den[f] - p) for f, p in ref.items()]
    assert max(dev) <= 0.10, dev
    assert float(np.mean(dev)) <= 0.04, dev
    assert num[0.0] / den[0.0] > 0.99 and num[950.0] / den[950.0] < 0.1

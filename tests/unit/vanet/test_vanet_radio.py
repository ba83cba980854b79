"""`cosim radio`: the slot-order target, never-sent CAMs, the ns-3 reference, the command line."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from cosim.cli import main
from cosim.vanet.radio import RadioScenario, run_radio

NS3 = Path(__file__).resolve().parents[3] / "validation" / "ns3" / "ns3_highway_pdr.csv"


def test_slot_order_sotdma_shares_few_slots_with_all_stations_in_mutual_range():
    # issue 17 target: <= 1 % of the transmissions share a slot with 100 stations in mutual range (300 m
    # square), 10 Hz, for every seed (seconds 20-40: steady state). Measured: 24 % before slot-order decisions;
    # 0.17-1.73 % with them (seeds 1-3); 0.32-0.80 % once a move decided at a use without a CAM is announced by
    # the station's next transmission (seeds 1-8: 0.15-0.80 %)
    shares = []
    for seed in (1, 2, 3):
        sc = RadioScenario(layout="square", stations=100, area_m=300, rate_hz=10, size_bytes=243, tx_dbm=13,
                           duration_s=40, warmup_s=20, seed=seed)  # fmt: skip
        shares.append(run_radio(sc)["shared_slot_share"])
    assert max(shares) <= 0.01, shares


def test_never_sent_cams_count_as_lost():
    sc = RadioScenario(layout="square", stations=60, area_m=200, rate_hz=10, size_bytes=243, tx_dbm=13,
                       duration_s=16, warmup_s=6)  # fmt: skip
    app, link = run_radio(sc, link_level=True)
    assert app["never_sent_share"] > 0.01  # a newer CAM replaces one still waiting for its slot
    near_app, near_link = app["pdr"][0], link[0]
    # application PDR = P(sent) x P(decoded | sent): below the link-level one by the never-sent share
    assert near_app["pdr"] < near_link["pdr"]
    assert near_app["pdr"] == pytest.approx(near_link["pdr"] * (1 - app["never_sent_share"]), abs=0.01)
    assert near_app["n"] > near_link["n"]


def test_pdr_vs_distance_agrees_with_the_ns3_reference():
    """ns-3 3.37 (validation/ns3/run.sh): 802.11p, 3GPP TR 37.885 highway LOS, 3 dB shadowing, one sender.
    cosim: the same link budget and receiver, 200 standing stations on 10 km at 1 Hz, seeds 1-6, link-level
    PDR (sent CAMs). Tolerance: per 50-m band |dPDR| <= 0.10, mean over 0-1000 m <= 0.04; the residual is
    cosim's own SOTDMA interference (co-slot senders out of range), which the one-sender reference lacks."""
    ref = {float(r["from_m"]): float(r["pdr"]) for r in csv.DictReader(NS3.open())}
    num, den = {}, {}
    for seed in range(1, 7):
        sc = RadioScenario(layout="highway", stations=200, area_m=10_000, lanes=1, rate_hz=1, size_bytes=300,
                           tx_dbm=13, pathloss="3gpp-highway", shadowing_db=3.0, duration_s=14, warmup_s=10,
                           seed=seed)  # fmt: skip
        for b in run_radio(sc, link_level=True)[1]:
            num[b["from_m"]] = num.get(b["from_m"], 0.0) + b["pdr"] * b["n"]
            den[b["from_m"]] = den.get(b["from_m"], 0) + b["n"]
    dev = [abs(num[f] / den[f] - p) for f, p in ref.items()]
    assert max(dev) <= 0.10, dev
    assert float(np.mean(dev)) <= 0.04, dev
    # the curve itself: ~1 near, ~0.5 around the 513-m median range, ~0 at 1 km
    assert num[0.0] / den[0.0] > 0.99 and num[950.0] / den[950.0] < 0.1


def test_cli_json_shape_plot_and_bad_values(tmp_path, capsys):
    out = tmp_path / "radio"
    rc = main(["radio", "--layout", "square", "--stations", "30", "--rate-hz", "10", "--size-bytes", "200",
               "--tx-dbm", "13", "--pathloss", "winner-b1", "--duration", "12", "--json", "--out", str(out)])  # fmt: skip
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    assert list(res) == [
        "mac",
        "stations",
        "pdr",
        "cbr",
        "shared_slot_share",
        "never_sent_share",
        "ipg_p95_s",
    ]
    assert res["mac"] == "sotdma" and res["stations"] == 30
    assert all(
        list(b) == ["from_m", "to_m", "pdr", "n"] and b["to_m"] - b["from_m"] == 50 for b in res["pdr"]
    )
    assert res["pdr"][0]["from_m"] == 0.0
    assert (out / "pdr_vs_distance.png").stat().st_size > 1000
    for bad in (["--mac", "wifi"], ["--mac", "sotdma,sotdma"], ["--pathloss", "nope"], ["--lanes", "0"]):
        args = ["radio", "--layout", "highway", "--vehicles-per-km", "20", "--rate-hz", "10", "--size-bytes",
                "200", "--tx-dbm", "13", "--pathloss", "free-space", *bad]  # fmt: skip
        assert main(args) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "error" in err


def test_shared_slots_count_senders_that_can_hurt_each_other():
    """Same-slot senders count as sharing when a receiver that can decode one hears the other at or above the
    receiver's interference floor: radius = decoding range + interference range."""
    import dataclasses

    from cosim.vanet.channel import Aether
    from cosim.vanet.radio import hurt_radius_m, shared_slot_mask

    ch = RadioScenario(layout="square", stations=10, pathloss="free-space").channel()
    sinr, paper = Aether(ch, []), Aether(dataclasses.replace(ch, interference="paper"), [])
    assert paper.comm_range_m == pytest.approx(510.5, abs=1.0)
    assert hurt_radius_m(paper) == pytest.approx(
        2 * paper.comm_range_m
    )  # the paper: one receiver in both ranges
    # SINR rule: a receiver at the decoding edge of one sender gets the other exactly at the floor (-115 dBm)
    r = hurt_radius_m(sinr)
    p_other = ch.tx_power_dbm - float(sinr.path_loss.loss_db(r - sinr.comm_range_m))
    assert p_other == pytest.approx(sinr.rx.floor_dbm, abs=0.01) and sinr.rx.floor_dbm == pytest.approx(
        -115.0, abs=0.1
    )
    # slot 5: three senders, two 900 m apart, the third 20 km away; slot 6: one sender
    g = np.array([5, 6, 5, 5])
    xy = np.array([[0.0, 0.0], [10.0, 0.0], [900.0, 0.0], [20_000.0, 0.0]])
    assert shared_slot_mask(g, xy, hurt_radius_m(paper)).tolist() == [True, False, True, False]
    assert shared_slot_mask(g, xy, 800.0).tolist() == [False, False, False, False]
    assert shared_slot_mask(g, xy, r).tolist() == [True, False, True, False]

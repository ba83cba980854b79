"""cosim's C-V2X mode 4 MAC on the highway of Gonzalez-Martin et al. 2019, against their analytical model.

``scenario(beta, seed)`` configures ``cosim radio --mac cv2x`` (``RadioScenario``, Python API) as the paper:

==========================  ====================================================  ==============================
paper (gm2019.py)           cosim                                                 where
==========================  ====================================================  ==============================
beta 0.1 / 0.3 veh/m        ``vehicles_per_km`` 100 / 300 on a 5-km highway,       layout ``highway``
                            2 lanes per direction, wrap-around, receivers >= the
                            link range from both ends
lambda 10 Hz, 190 B         ``rate_hz`` 10, ``size_bytes`` 190, no header          ``overhead_bytes`` 0
Pt 20 dBm, 5.91 GHz         ``tx_dbm`` 20, ``frequency_hz`` 5.91e9
S = 4 subchannels,          ``n_subchannels`` 4 x ``subchannel_rbs`` 12 (2 SCI +   ``Cv2xParams``
190 B in 10 RBs (QPSK 0.7)  10 data), ``mcs`` 9 (I_TBS 9: 1544 bits in 10 RBs)
BLER(SINR), R1-160284       ``bler_curve`` = the same points                       ``Cv2xParams``
noise -95 dBm x 10/50 RBs   ``noise_dbm`` -95.79 (cosim scales the floor to the     ``ChannelParams``
                            frame's 12 RBs: -95.79 + 10 log10(12/50) = -101.99)
P_SEN -90.5 dBm             ``sensitivity_dbm`` -90.5; step-6 exclusion at the     ``ChannelParams``,
                            same power: PSSCH-RSRP -90.5 - 10 log10(144 RE)        ``rsrp_threshold_dbm``
WINNER+ B1, h 1.5 m, env.   ``winner_b1``, ``winner_height_offset_m`` 0,           ``ChannelParams``
height 0, >= free space,    ``winner_free_space_floor``, ``winner_min_m`` 3
3 dB log-normal             ``shadowing_db`` 3 (cosim: a spatial field, 10-m
                            decorrelation; the model: independent per link)
counter mean = lambda       ``prob_keep`` 0 (counter U{5..15}, mean 10 = tau)     ``Cv2xParams``
==========================  ====================================================  ==============================

Vehicles drive at 70 km/h (our choice: the model has no speed; cosim has no Doppler, speed only moves the
shadowing field past the links). ``python validation/cv2x/compare.py`` prints the comparison table.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from gm2019 import Gm2019  # noqa: E402

from cosim.vanet.radio import RadioScenario, run_radio  # noqa: E402

ROAD_M = 5000.0
SPEED_KMH = 70.0
BANDS_TO_M = 500.0  # the paper's curves end at 500 m
DECORRELATION_M = 1.0  # shadowing nearly independent per link and packet, as the model's (see the README)
SEEDS = {
    0.1: (1, 2),
    0.3: (1,),
}  # 500 / 1500 stations; ~1e5 / ~1e6 (receiver, packet) pairs per band and seed


def scenario(
    beta: float,
    seed: int,
    duration_s: float = 9.0,
    warmup_s: float = 4.0,
    decorrelation_m: float = DECORRELATION_M,
) -> RadioScenario:
    m = Gm2019(beta=beta)
    bler = tuple((float(s), float(m.bler(s))) for s in (0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 20 + 1e-6))
    sc_rbs = 12  # 2 (SCI) + 10 (data)
    frame_noise_dbm = m.noise_dbm  # -95 dBm in 50 RBs scaled to the 10 data RBs
    return RadioScenario(
        mac="cv2x",
        layout="highway",
        vehicles_per_km=beta * 1000.0,
        area_m=ROAD_M,
        lanes=2,
        speed_kmh=SPEED_KMH,
        rate_hz=m.lam_hz,
        size_bytes=190,
        tx_dbm=m.pt_dbm,
        pathloss="winner-b1",
        shadowing_db=m.sigma_db,
        noise_dbm=frame_noise_dbm - 10.0 * math.log10(sc_rbs / 50.0),
        duration_s=duration_s,
        warmup_s=warmup_s,
        seed=seed,
        channel_params={
            "frequency_hz": m.fc_hz,
            "antenna_height_m": m.h_m,
            "sensitivity_dbm": m.psen_dbm,
            "winner_height_offset_m": 0.0,
            "winner_min_m": 3.0,
            "winner_free_space_floor": True,
            "lognormal_decorrelation_m": decorrelation_m,
        },
        mac_params={
            "n_subchannels": m.subchannels,
            "subchannel_rbs": sc_rbs,
            "pscch_rbs": 2,
            "mcs": 9,
            "overhead_bytes": 0,
            "prob_keep": 0.0,
            "rsrp_threshold_dbm": m.psen_dbm - 10.0 * math.log10(12 * sc_rbs),
            "bler_curve": bler,
        },
    )


def cosim_bands(beta: float, seeds, **kw) -> list[dict]:
    """cosim's link-level PDR per 50-m band up to 500 m, pooled over seeds (sent CAMs: the model's PDR is
    per transmitted packet)."""
    num: dict[float, float] = {}
    den: dict[float, int] = {}
    for seed in seeds:
        for b in run_radio(scenario(beta, seed, **kw), link_level=True)[1]:
            if b["from_m"] >= BANDS_TO_M:
                continue
            num[b["from_m"]] = num.get(b["from_m"], 0.0) + b["pdr"] * b["n"]
            den[b["from_m"]] = den.get(b["from_m"], 0) + b["n"]
    return [{"from_m": f, "pdr": num[f] / den[f], "n": den[f]} for f in sorted(den)]


def reference_bands(beta: float) -> list[dict]:
    """The model's PDR per 50-m band as stored in gm2019_bands.csv (``python gm2019.py`` writes it)."""
    import csv

    path = Path(__file__).resolve().parent / "gm2019_bands.csv"
    rows = [r for r in csv.DictReader(path.open()) if float(r["beta_veh_per_m"]) == beta]
    return [{"from_m": float(r["from_m"]), "pdr": float(r["pdr"])} for r in rows]


def compare(beta: float, seeds=None, **kw) -> dict:
    ref = reference_bands(beta)
    seeds = SEEDS[beta] if seeds is None else seeds
    got = {b["from_m"]: b for b in cosim_bands(beta, seeds, **kw)}
    rows = [
        {
            "from_m": r["from_m"],
            "model": r["pdr"],
            "cosim": got[r["from_m"]]["pdr"],
            "n": got[r["from_m"]]["n"],
        }
        for r in ref
    ]
    dev = np.array([abs(r["cosim"] - r["model"]) for r in rows])
    return {"beta": beta, "rows": rows, "max_dev": float(dev.max()), "mean_dev": float(dev.mean())}


if __name__ == "__main__":
    for beta in (0.1, 0.3):
        res = compare(beta)
        print(f"beta {beta} veh/m: max |dPDR| {res['max_dev']:.3f}, mean {res['mean_dev']:.3f}")
        for r in res["rows"]:
            print(
                f"  {r['from_m']:5.0f}-{r['from_m'] + 50:3.0f} m  model {r['model']:.3f}  cosim {r['cosim']:.3f}"
                f"  ({r['n']} pairs)"
            )

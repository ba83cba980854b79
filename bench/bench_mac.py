"""Cost and PDR-vs-distance of the 802.11p and C-V2X MACs alone on a synthetic highway (issue 18).

python -m bench.bench_mac [--stations 100 500 1000] [--seconds 2] [--length-m 5000]

Highway: ``--length-m`` long, 3 lanes per direction 4 m apart, stations uniform along it, static; every
station has a 190-B CAM every 100 ms (10 Hz); free space, 13 dBm, sensitivity -89 dBm, noise -110 dBm.
PDR per 50-m band counts transmitters in the middle third only (no edge effects). The first second
(C-V2X sensing warm-up) is excluded from the PDR.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from cosim.vanet.mac import MacInput, distance_link_budget
from cosim.vanet.mac_80211p import Mac80211p, Mac80211pParams
from cosim.vanet.mac_cv2x import Cv2xParams, MacCv2x

LAMBDA_M = 299_792_458.0 / 5.89e9
LINK = distance_link_budget(lambda d: 13.0 - 20.0 * np.log10(4.0 * np.pi * d / LAMBDA_M), 510.5)


def highway(n, length_m, seed=0):
    r = np.random.default_rng(seed)
    return np.stack([r.uniform(0, length_m, n), r.integers(0, 6, n) * 4.0], axis=1)


def run(name, n, seconds, length_m, seed=1):
    xy = highway(n, length_m)
    mk = {
        "80211p": lambda: Mac80211p(Mac80211pParams(), n, np.random.default_rng(seed)),
        "cv2x": lambda: MacCv2x(Cv2xParams(), n, np.random.default_rng(seed)),
    }[name]
    mac = mk()
    st = np.arange(n)
    mac.start(st, 0, 100_000)
    steps = int(seconds * 10)
    d_all, ok_all, cbr, wall = [], [], [], 0.0
    mid = (xy[:, 0] > length_m / 3) & (xy[:, 0] < 2 * length_m / 3)
    for k in range(steps):
        inp = MacInput(
            k * 100_000, 100_000, st, xy, np.ones(n, bool), np.full(n, 190), np.full(n, k * 100_000), LINK
        )
        t = time.perf_counter()
        out = mac.step(inp)
        wall += time.perf_counter() - t
        if k >= 10:
            snd = out.tx_station[out.rx_tx]
            m = mid[snd]
            d_all.append(np.hypot(*(xy[snd[m]] - xy[out.rx_rx[m]]).T))
            ok_all.append(out.rx_outcome[m] == 0)
            cbr.append(out.busy_us.mean() / 1e5)
    d, ok = np.concatenate(d_all), np.concatenate(ok_all)
    bands = [(lo, float(ok[(d >= lo) & (d < lo + 50)].mean())) for lo in range(0, 500, 50)]
    return 1000 * wall / seconds, bands, float(np.mean(cbr))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--stations", type=int, nargs="+", default=[100, 500, 1000])
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--length-m", type=float, default=5000.0)
    a = ap.parse_args()
    for n in a.stations:
        for name in ("80211p", "cv2x"):
            ms, bands, cbr = run(name, n, a.seconds, a.length_m)
            pdr = " ".join(f"{p:.3f}" for _, p in bands)
            print(
                f"{name:7s} N={n:5d} ({n / a.length_m * 1000:.0f} veh/km) {ms:8.1f} ms/sim-s  CBR {cbr:.3f}  "
                f"PDR 0-500 m by 50 m: {pdr}",
                flush=True,
            )


if __name__ == "__main__":
    main()

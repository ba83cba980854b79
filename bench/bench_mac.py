"""Cost per simulated second of each MAC (SOTDMA, IEEE 802.11p, C-V2X mode 4) in ``cosim radio`` (issue 18).

python -m bench.bench_mac [--stations 100 500 1000] [--seconds 6]

The same scenario for every MAC (as ``bench_radio``): highway 5 km, 3 lanes per direction, 100 km/h,
10 Hz, 300-B CAMs, 13 dBm, 3GPP TR 37.885 highway path loss with its 3-dB log-normal shadowing, the shared
receiver; the whole run is timed (the warm-up steps cost the same), ``seconds`` simulated, the last 2 s
measured for the PDR. CPU time is the process's (what the MAC costs); wall time depends on the machine's
load. The issue's target: 802.11p within 2x of SOTDMA's cost per simulated second.
"""

from __future__ import annotations

import argparse
import time

from cosim.vanet.radio import RadioScenario, run_radio

MACS = ("sotdma", "80211p", "cv2x")


def measure(mac: str, n: int, seconds: float) -> tuple[float, float, dict]:
    sc = RadioScenario(mac=mac, layout="highway", stations=n, speed_kmh=100, rate_hz=10, size_bytes=300,
                       tx_dbm=13, pathloss="3gpp-highway", duration_s=seconds, warmup_s=seconds - 2)  # fmt: skip
    w0, c0 = time.perf_counter(), time.process_time()
    res = run_radio(sc)
    return (time.perf_counter() - w0) / seconds, (time.process_time() - c0) / seconds, res


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--stations", type=int, nargs="+", default=[100, 500, 1000])
    ap.add_argument("--seconds", type=float, default=6.0)
    a = ap.parse_args()
    print(
        "| stations | MAC | CPU per simulated s | x SOTDMA (CPU) | wall per simulated s | CBR | PDR 0-50 m | PDR 300-350 m |"
    )
    print("|---:|---|---:|---:|---:|---:|---:|---:|")
    for n in a.stations:
        ref = None
        for mac in MACS:
            wall, cpu, r = measure(mac, n, a.seconds)
            ref = cpu if mac == "sotdma" else ref
            pdr = {b["from_m"]: b["pdr"] for b in r["pdr"]}
            print(f"| {n} | {mac} | {cpu:.3f} s | {cpu / ref:.2f} | {wall:.3f} s | {r['cbr']:.3f} | "
                  f"{pdr.get(0.0, float('nan')):.3f} | {pdr.get(300.0, float('nan')):.3f} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()

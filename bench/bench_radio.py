"""``cosim radio`` cost per simulated second: ``python -m bench.bench_radio [--seconds S]``.

Highway layout (5 km, 3 lanes per direction, 100 km/h), 10 Hz, 300-B CAMs, 13 dBm, 3GPP highway path loss
with its 3 dB shadowing, SOTDMA; 100 / 500 / 1000 stations. Wall and CPU time per simulated second after
the 10-s warm-up window is included (the whole run is timed: warm-up steps cost the same).
"""

from __future__ import annotations

import argparse
import time

from cosim.vanet.radio import RadioScenario, run_radio


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=12.0)
    args = ap.parse_args()
    print(
        "| stations | simulated s | wall s | wall per simulated s | CPU per simulated s | shared slots | CBR |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for n in (100, 500, 1000):
        sc = RadioScenario(layout="highway", stations=n, speed_kmh=100, rate_hz=10, size_bytes=300, tx_dbm=13,
                           pathloss="3gpp-highway", duration_s=args.seconds, warmup_s=args.seconds - 2)  # fmt: skip
        w0, c0 = time.perf_counter(), time.process_time()
        r = run_radio(sc)
        w, c = time.perf_counter() - w0, time.process_time() - c0
        print(f"| {n} | {args.seconds:g} | {w:.1f} | {w / args.seconds:.3f} s | {c / args.seconds:.3f} s | "
              f"{r['shared_slot_share']:.3f} | {r['cbr']:.3f} |")  # fmt: skip


if __name__ == "__main__":
    main()

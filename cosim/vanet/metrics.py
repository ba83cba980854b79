"""VANET metrics computed from the logged columns of ``/vanet/tx``, ``/vanet/rx`` and ``/vanet/load``.

Definitions
-----------
* PDR vs distance: per ``bin_m`` (10 m) distance bin, decoded (outcome ok) / all logged receptions. The log
  holds every receiver within the communication range of the link budget, so the PDR falls to the share
  of links that survive shadowing and interference, not to zero at the range edge.
* Channel load: per frame, slots with at least one transmission / slots per frame (``busy_ratio``) and
  air time / frame length (``airtime_ratio``).
* Slot collisions: (frame, slot) pairs with two or more transmitters, and the transmissions in them.
* Age of information (per receiver-sender pair, decoded CAMs only, pairs identified by station ids):
  AoI(t) = t - generation time of the newest decoded CAM. Reported: the age at delivery, the peak AoI just
  before each delivery (t_k - gen_{k-1}), and the time-average AoI over each pair's observed span.
* Inter-packet gap: time between consecutive decoded CAMs of a pair.
"""

from __future__ import annotations

import numpy as np

from cosim.vanet.channel import OK, OUTCOME_NAMES


def _col(cols: dict[str, np.ndarray] | None, name: str, dtype=np.float64) -> np.ndarray:
    if not cols or name not in cols:
        return np.zeros(0, dtype=dtype)
    return np.asarray(cols[name])


def _stats(x: np.ndarray) -> dict[str, float | int | None]:
    x = np.asarray(x, dtype=np.float64)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {"n": 0, "mean": None, "p50": None, "p95": None, "max": None}
    return {
        "n": int(x.size),
        "mean": float(x.mean()),
        "p50": float(np.percentile(x, 50)),
        "p95": float(np.percentile(x, 95)),
        "max": float(x.max()),
    }


def outcome_counts(rx: dict[str, np.ndarray]) -> dict[str, int]:
    out = _col(rx, "outcome", np.uint8).astype(np.int64)
    counts = np.bincount(out, minlength=len(OUTCOME_NAMES)) if out.size else np.zeros(len(OUTCOME_NAMES), int)
    return {name: int(c) for name, c in zip(OUTCOME_NAMES, counts, strict=False)}


def pdr_vs_distance(rx: dict[str, np.ndarray], bin_m: float = 10.0) -> dict[str, np.ndarray]:
    """Arrays per bin: bin_lo_m, n (receptions logged), n_ok, pdr (NaN where n = 0)."""
    d = _col(rx, "distance_m")
    ok = _col(rx, "outcome", np.uint8) == OK
    if d.size == 0:
        e = np.zeros(0)
        return {"bin_lo_m": e, "n": e.astype(np.int64), "n_ok": e.astype(np.int64), "pdr": e}
    b = np.floor(d / bin_m).astype(np.int64)
    nb = int(b.max()) + 1
    n = np.bincount(b, minlength=nb)
    n_ok = np.bincount(b[ok], minlength=nb)
    with np.errstate(invalid="ignore", divide="ignore"):
        pdr = np.where(n > 0, n_ok / np.maximum(n, 1), np.nan)
    return {"bin_lo_m": np.arange(nb) * bin_m, "n": n, "n_ok": n_ok, "pdr": pdr}


def channel_load(load: dict[str, np.ndarray]) -> dict[str, object]:
    busy = _col(load, "busy_ratio")
    air = _col(load, "airtime_ratio")
    return {
        "frames": int(busy.size),
        "n_slots": int(_col(load, "n_slots", np.int32)[0]) if busy.size else None,
        "busy_ratio": _stats(busy),
        "airtime_ratio": _stats(air),
    }


def slot_collisions(tx: dict[str, np.ndarray]) -> dict[str, float | int]:
    frame = _col(tx, "frame", np.int64).astype(np.int64)
    slot = _col(tx, "slot", np.int32).astype(np.int64)
    if frame.size == 0:
        return {
            "transmissions": 0,
            "slots_used": 0,
            "multi_tx_slots": 0,
            "tx_in_multi_slots": 0,
            "fraction": 0.0,
        }
    key = frame * (int(slot.max()) + 1) + slot
    _, counts = np.unique(key, return_counts=True)
    multi = counts >= 2
    return {
        "transmissions": int(frame.size),
        "slots_used": int(counts.size),
        "multi_tx_slots": int(multi.sum()),
        "tx_in_multi_slots": int(counts[multi].sum()),
        "fraction": float(counts[multi].sum() / frame.size),
    }


def _pair_series(rx: dict[str, np.ndarray]):
    """Decoded receptions sorted by (pair, time): pair key, delivery time, generation time."""
    ok = _col(rx, "outcome", np.uint8) == OK
    if not ok.any():
        e = np.zeros(0)
        return e.astype(np.int64), e, e
    pair = (_col(rx, "receiver_station_id", np.uint32).astype(np.int64) << 32) | _col(
        rx, "sender_station_id", np.uint32
    ).astype(np.int64)
    pair, t, g = pair[ok], _col(rx, "t_s")[ok], _col(rx, "gen_t_s")[ok]
    order = np.lexsort((t, pair))
    return pair[order], t[order], g[order]


def age_of_information(rx: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Arrays: age_at_delivery_s (per decoded CAM), peak_aoi_s (per consecutive pair of deliveries),
    mean_aoi_s / span_s (per pair with >= 2 deliveries)."""
    pair, t, g = _pair_series(rx)
    age = t - g
    same = pair[1:] == pair[:-1] if pair.size else np.zeros(0, dtype=bool)
    peak = (t[1:] - g[:-1])[same]
    # area under the saw-tooth between consecutive deliveries of a pair
    area = 0.5 * ((t[1:] - g[:-1]) ** 2 - (t[:-1] - g[:-1]) ** 2)
    dur = t[1:] - t[:-1]
    if same.any():
        pid = np.cumsum(np.r_[0, ~same])  # pair index of each delivery
        pidx = pid[:-1][same]  # ... and of each interval between two deliveries of one pair
        n_pairs = int(pidx.max()) + 1 if pidx.size else 0
        a = np.bincount(pidx, weights=area[same], minlength=n_pairs)
        s = np.bincount(pidx, weights=dur[same], minlength=n_pairs)
        keep = s > 0
        mean_aoi, span = a[keep] / s[keep], s[keep]
    else:
        mean_aoi = span = np.zeros(0)
    return {"age_at_delivery_s": age, "peak_aoi_s": peak, "mean_aoi_s": mean_aoi, "span_s": span}


def inter_packet_gap(rx: dict[str, np.ndarray]) -> np.ndarray:
    """Time between consecutive decoded CAMs of the same (receiver, sender) pair [s]."""
    pair, t, _ = _pair_series(rx)
    if pair.size < 2:
        return np.zeros(0)
    same = pair[1:] == pair[:-1]
    return (t[1:] - t[:-1])[same]


def summarize(columns_by_topic: dict[str, dict[str, np.ndarray]], bin_m: float = 10.0) -> dict[str, object]:
    """All metrics as plain Python values (JSON-friendly)."""
    tx = columns_by_topic.get("/vanet/tx", {})
    rx = columns_by_topic.get("/vanet/rx", {})
    load = columns_by_topic.get("/vanet/load", {})
    counts = outcome_counts(rx)
    total = sum(counts.values())
    pdr = pdr_vs_distance(rx, bin_m)
    aoi = age_of_information(rx)
    span = aoi["span_s"]
    ipg = inter_packet_gap(rx)
    return {
        "transmissions": int(_col(tx, "t_s").size),
        "receptions": counts,
        "pdr_overall": (counts["ok"] / total) if total else None,
        "pdr_vs_distance": [
            {"bin_lo_m": float(lo), "n": int(n), "pdr": float(p)}
            for lo, n, p in zip(pdr["bin_lo_m"], pdr["n"], pdr["pdr"], strict=True)
            if n > 0
        ],
        "channel_load": channel_load(load),
        "slot_collisions": slot_collisions(tx),
        "aoi_s": {
            "age_at_delivery": _stats(aoi["age_at_delivery_s"]),
            "peak": _stats(aoi["peak_aoi_s"]),
            "time_average": float((aoi["mean_aoi_s"] * span).sum() / span.sum()) if span.size else None,
        },
        "inter_packet_gap_s": _stats(ipg),
    }

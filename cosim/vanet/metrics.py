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

Application level, per 50-m distance band (``AppMetrics``; ``cosim radio`` feeds it as it runs, ``cosim
vanet-report`` from a log's rows, so both compute every number with the same code):

* PDR = decoded (receiver, CAM) pairs / (receiver, generated CAM) pairs: a CAM that never went on the air (a
  newer one replaced it while it waited for its slot) counts as lost. ``cosim radio`` knows every generated
  CAM and its distance; a log has only the CAMs sent (``/vanet/rx``) and the network-wide count of those never
  sent (``/vanet/step``: cams_dropped / cams_generated = q), so there the generated pairs of a band are its
  sent pairs / (1 - q) (whether a CAM is sent depends on its sender's slots, not on the receiver's distance).
  The link-level PDR (sent CAMs only) is given beside it.
* Inter-packet gap (IPG) and age of information (age at delivery, t - generation; peak AoI, t_k - gen_{k-1})
  of consecutive decoded CAMs of a pair, in the band of the later delivery; kept as 1-ms histograms (the
  last bin: 10 s and longer), so percentiles are exact to 1 ms.
"""

from __future__ import annotations

import math

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


def slot_collisions(tx: dict[str, np.ndarray]) -> dict[str, float | int | None]:
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
    if (slot < 0).all():  # a MAC without slots (802.11p logs slot -1): no slot sharing to count
        return {
            "transmissions": int(frame.size),
            "slots_used": 0,
            "multi_tx_slots": 0,
            "tx_in_multi_slots": 0,
            "fraction": None,
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


def _deliveries(rx: dict[str, np.ndarray]):
    """Decoded receptions sorted by (pair, time): pair index, delivery time, generation time, and the
    inter-packet gap / peak AoI before each (``pair_deliveries``; NaN for a pair's first)."""
    ok = _col(rx, "outcome", np.uint8) == OK
    if not ok.any():
        e = np.zeros(0)
        return e.astype(np.int64), e, e, e, e
    pair = (_col(rx, "receiver_station_id", np.uint32).astype(np.int64) << 32) | _col(
        rx, "sender_station_id", np.uint32
    ).astype(np.int64)
    keys, key = np.unique(pair[ok], return_inverse=True)
    key = key.reshape(-1)
    t, g = _col(rx, "t_s")[ok], _col(rx, "gen_t_s")[ok]
    nan = np.full(keys.size, np.nan)
    order, gap, peak = pair_deliveries(key, t, g, nan, nan.copy())
    return key[order], t[order], g[order], gap, peak


def age_of_information(rx: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Arrays: age_at_delivery_s (per decoded CAM), peak_aoi_s (per consecutive pair of deliveries),
    mean_aoi_s / span_s (per pair with >= 2 deliveries)."""
    key, t, g, gap, peak = _deliveries(rx)
    same = np.isfinite(gap)
    # area under the saw-tooth between consecutive deliveries of a pair: from the previous delivery's age
    # (peak - gap) up to the peak
    area = 0.5 * (peak[same] ** 2 - (peak[same] - gap[same]) ** 2)
    if same.any():
        n_pairs = int(key.max()) + 1
        a = np.bincount(key[same], weights=area, minlength=n_pairs)
        s = np.bincount(key[same], weights=gap[same], minlength=n_pairs)
        keep = s > 0
        mean_aoi, span = a[keep] / s[keep], s[keep]
    else:
        mean_aoi = span = np.zeros(0)
    return {"age_at_delivery_s": t - g, "peak_aoi_s": peak[same], "mean_aoi_s": mean_aoi, "span_s": span}


def inter_packet_gap(rx: dict[str, np.ndarray]) -> np.ndarray:
    """Time between consecutive decoded CAMs of the same (receiver, sender) pair [s]."""
    gap = _deliveries(rx)[3]
    return gap[np.isfinite(gap)]


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
    app, q = app_metrics_from_log(rx, columns_by_topic.get("/vanet/step", {}))
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
        "never_sent_share": q,
        "app_vs_distance": app.band_table(q),
        "cbr": sensed_cbr(load),
    }


# ------------------------------------------------------------------------------------------------------------
# application level, per distance band (cosim radio and cosim vanet-report)
# ------------------------------------------------------------------------------------------------------------
BAND_M = 50.0  # distance bands from 0 m (issue 17: 50-m bands)
HIST_BIN_S = 1e-3  # time histograms: 1-ms bins ...
HIST_BINS = 10_001  # ... up to 10 s; the last bin holds everything longer


def band_index(distance_m: np.ndarray, n_bands: int, band_m: float = BAND_M) -> np.ndarray:
    """Band of each distance (0 = [0, band_m)); everything from n_bands bands on falls into band n_bands."""
    return np.minimum((np.asarray(distance_m) // band_m).astype(np.int64), n_bands)


def time_bins(x_s: np.ndarray) -> np.ndarray:
    """1-ms histogram bin of each time [s] (rounded to the nearest ms; >= 10 s: the last bin)."""
    return np.minimum((np.asarray(x_s) * 1000).round().astype(np.int64), HIST_BINS - 1)


def hist_percentile(hist: np.ndarray, q: float) -> float:
    """The q-th percentile [s] of a 1-ms histogram (NaN when empty): the first bin holding q % of the mass."""
    cum = np.cumsum(hist)
    if cum.size == 0 or cum[-1] <= 0:
        return float("nan")
    return float(np.searchsorted(cum, q / 100.0 * cum[-1]) / round(1.0 / HIST_BIN_S))


def pair_deliveries(key, t_s, gen_t_s, last_t: np.ndarray, last_gen: np.ndarray):
    """Consecutive decoded CAMs of the same (receiver, sender) pair.

    key (m,) int: the pair's index into the state arrays last_t / last_gen (time and generation time of the
    pair's previous delivery, NaN: none yet; updated in place); t_s, gen_t_s (m,) the deliveries, in any
    order (a pair may occur several times). Returns (order, gap, peak): the deliveries sorted by (pair, time)
    and, for each, the time since the pair's previous delivery (inter-packet gap) and the peak age of
    information just before it (t - that delivery's generation time), NaN for a pair's first delivery."""
    key = np.asarray(key, dtype=np.int64)
    t_s, gen_t_s = np.asarray(t_s, dtype=np.float64), np.asarray(gen_t_s, dtype=np.float64)
    order = np.lexsort((t_s, key))
    k, t, g = key[order], t_s[order], gen_t_s[order]
    first = np.ones(k.size, dtype=bool)
    first[1:] = k[1:] != k[:-1]
    prev_t = np.empty(k.size)
    prev_g = np.empty(k.size)
    prev_t[1:], prev_g[1:] = t[:-1], g[:-1]
    prev_t[first], prev_g[first] = last_t[k[first]], last_gen[k[first]]
    last = np.ones(k.size, dtype=bool)
    last[:-1] = k[1:] != k[:-1]
    last_t[k[last]], last_gen[k[last]] = t[last], g[last]
    return order, t - prev_t, t - prev_g


class AppMetrics:
    """Application-level metrics per distance band (see the module docstring), accumulated as CAMs are
    generated, sent and decoded. ``n_pairs``: the size of the pair index space of ``decoded``'s keys."""

    def __init__(self, n_bands: int, n_pairs: int, band_m: float = BAND_M):
        self.n_bands, self.band_m = int(n_bands), float(band_m)
        nb = self.n_bands + 1  # the last band: everything farther
        self.generated = np.zeros(nb)  # (receiver, generated CAM) pairs, by the distance at generation
        self.sent = np.zeros(nb)  # (receiver, sent CAM) pairs, by the distance at transmission
        self.decoded = np.zeros(nb)  # decoded (receiver, CAM) pairs, by the distance at transmission
        self.ipg = np.zeros((nb, HIST_BINS), dtype=np.int64)
        self.age = np.zeros((nb, HIST_BINS), dtype=np.int64)  # age at delivery
        self.peak = np.zeros((nb, HIST_BINS), dtype=np.int64)  # peak AoI before a delivery
        self._last_t = np.full(int(n_pairs), np.nan)
        self._last_gen = np.full(int(n_pairs), np.nan)

    def _band(self, distance_m) -> np.ndarray:
        return band_index(distance_m, self.n_bands, self.band_m)

    def add_generated(self, distance_m: np.ndarray) -> None:
        self.generated += np.bincount(self._band(distance_m), minlength=self.n_bands + 1)

    def add_sent(self, distance_m: np.ndarray) -> None:
        self.sent += np.bincount(self._band(distance_m), minlength=self.n_bands + 1)

    def add_decoded(self, distance_m, count=None) -> None:
        """Decoded (receiver, CAM) pairs for the PDR (``count``: a mask of the ones counted, default all)."""
        d = np.asarray(distance_m)
        self.decoded += np.bincount(self._band(d if count is None else d[count]), minlength=self.n_bands + 1)

    def add_deliveries(self, key, t_s, gen_t_s, distance_m) -> None:
        """Decoded CAMs for the gaps and ages: pair index ``key`` (< n_pairs), delivery and generation time."""
        order, gap, peak = pair_deliveries(key, t_s, gen_t_s, self._last_t, self._last_gen)
        band = self._band(np.asarray(distance_m)[order])
        t, g = np.asarray(t_s, dtype=np.float64)[order], np.asarray(gen_t_s, dtype=np.float64)[order]
        for hist, x in ((self.age, t - g), (self.ipg, gap), (self.peak, peak)):
            ok = np.isfinite(x)
            cell = band[ok] * HIST_BINS + time_bins(x[ok])
            hist.reshape(-1)[:] += np.bincount(cell, minlength=hist.size)

    @property
    def ipg_hist(self) -> np.ndarray:
        """Inter-packet gaps over all bands (1-ms histogram)."""
        return self.ipg.sum(axis=0)

    def pdr_bands(self, link_level: bool = False, never_sent_share: float | None = None) -> list[dict]:
        """[{from_m, to_m, pdr, n}, ...] for every band with a denominator (the last, open band left out).

        Application level: over the generated CAMs, or, without them (a log), the sent ones / (1 - q) with
        ``never_sent_share`` q; ``link_level``: over the sent CAMs."""
        if link_level:
            den = self.sent
        elif never_sent_share is not None:
            den = self.sent / (1.0 - never_sent_share) if never_sent_share < 1.0 else self.sent * np.inf
        else:
            den = self.generated
        return [
            {"from_m": float(i * self.band_m), "to_m": float((i + 1) * self.band_m),
             "pdr": float(self.decoded[i] / den[i]), "n": int(round(den[i]))}
            for i in range(self.n_bands)
            if den[i] > 0
        ]  # fmt: skip

    def band_table(self, never_sent_share: float | None = None) -> list[dict]:
        """Per band: application and link-level PDR, sent pairs, IPG p50 / p95, age at delivery p50 / p95
        and peak AoI p95 [s] (None without deliveries)."""
        app = {b["from_m"]: b for b in self.pdr_bands(never_sent_share=never_sent_share)}
        link = {b["from_m"]: b for b in self.pdr_bands(link_level=True)}
        rows = []

        def pct(hist, q):
            v = hist_percentile(hist, q)
            return None if math.isnan(v) else v

        for i in range(self.n_bands):
            lo = float(i * self.band_m)
            if lo not in link:
                continue
            rows.append({
                "from_m": lo, "to_m": lo + self.band_m,
                "pdr": app[lo]["pdr"] if lo in app else None, "pdr_link": link[lo]["pdr"], "n_sent": link[lo]["n"],
                "ipg_p50_s": pct(self.ipg[i], 50), "ipg_p95_s": pct(self.ipg[i], 95),
                "age_p50_s": pct(self.age[i], 50), "age_p95_s": pct(self.age[i], 95),
                "peak_aoi_p95_s": pct(self.peak[i], 95),
            })  # fmt: skip
        return rows


def never_sent_share(step: dict[str, np.ndarray]) -> float | None:
    """CAMs generated but never sent (replaced while waiting), from ``/vanet/step`` (None without CAMs)."""
    gen = int(_col(step, "cams_generated", np.int32).sum())
    return int(_col(step, "cams_dropped", np.int32).sum()) / gen if gen else None


def app_metrics_from_log(rx: dict[str, np.ndarray], step: dict[str, np.ndarray], band_m: float = BAND_M):
    """(AppMetrics over a log's logged receptions, never-sent share q) for ``band_table(q)``."""
    d = _col(rx, "distance_m").astype(np.float64)
    ok = _col(rx, "outcome", np.uint8) == OK
    n_bands = int(d.max() // band_m) + 1 if d.size else 0
    pair = (_col(rx, "receiver_station_id", np.uint32).astype(np.int64) << 32) | _col(
        rx, "sender_station_id", np.uint32
    ).astype(np.int64)
    keys, key = np.unique(pair[ok], return_inverse=True)
    acc = AppMetrics(n_bands, keys.size, band_m)
    acc.add_sent(d)
    acc.add_decoded(d[ok])
    acc.add_deliveries(key.reshape(-1), _col(rx, "t_s")[ok], _col(rx, "gen_t_s")[ok], d[ok])
    return acc, never_sent_share(step)


def sensed_cbr(load: dict[str, np.ndarray]) -> dict[str, object]:
    """The channel busy ratio the stations sense (``/vanet/load`` cbr_mean / cbr_p95 / cbr_ego, one value per
    completed frame), beside the map-wide slot use of ``channel_load``."""
    return {name: _stats(_col(load, f"cbr_{name}")) for name in ("mean", "p95", "ego")}

"""``cosim radio``: synthetic calibration scenarios for the radio layer, to hold against published curves.

Layouts
-------
* ``highway``: a straight road (default 5 km) with ``lanes`` lanes per direction (3.5 m wide), vehicles
  placed uniformly at random at ``vehicles_per_km`` (all lanes together) or ``stations`` in all, driving at
  ``speed_kmh`` (half each way); a vehicle leaving one end re-enters at the other (wrap-around keeps the
  density), and only receivers at least the link range away from both ends are counted, so every counted
  receiver has a full neighbourhood.
* ``square``: ``stations`` placed uniformly in an ``area_m`` x ``area_m`` square, standing; all counted.

Every station generates a CAM of ``size_bytes`` (facilities layer; the MAC adds its headers) every
1 / ``rate_hz`` s from a random phase and is switched on at a random time within the first second (a
station switched on listens for a frame first). A CAM still waiting when the next is generated is replaced:
it is never sent. Metrics count from ``warmup_s`` on (network entry is a transient):

* pdr per 50-m band (from 0 m): decoded (receiver, CAM) pairs / (receiver, generated CAM) pairs at that
  distance at generation: CAMs never sent count as lost (application level);
* cbr: the channel busy ratio each counted station senses (energy >= the CS threshold), averaged;
* shared_slot_share: transmissions whose slot also carries a transmission of a sender that can hurt it:
  closer than ``hurt_radius_m`` = the decoding range (``Aether.comm_range_m``: the sensitivity reached, with
  the shadowing tail) + the interference range (``Aether.link_range_m``: the other sender still at or above
  the receiver's interference floor, noise - 20 dB by default, or the sensitivity under the paper's rule),
  i.e. some receiver that can decode the one hears the other above the floor, so the receiver model
  counts it (13 dBm, free space: 0.5 + 10.2 km, WINNER+ B1: 0.3 + 1.3 km; paper rule, free space: 2 x
  0.5 km). Null for MACs without slots;
* never_sent_share: generated CAMs never sent; ipg_p95_s: 95th percentile of the time between consecutive
  decoded CAMs of a (receiver, sender) pair.

MACs are looked up in ``MACS`` (name -> class): ``sotdma``, ``80211p`` and ``cv2x`` (issue 18; the last two
through the common MAC interface, ``radio_macs.py``, on the same aether and receiver). A MAC class has
``__init__(scenario, n_stations, rng)``, ``start(stations, t_us)``, and ``window(t_lo_us, t_hi_us, pending,
evaluate)``, where ``evaluate(tx_station, tx_group) -> Links`` runs the aether (and the shared receiver) on
its transmissions; ``window`` returns (tx_station, tx_group, links, air time [us]) for the window. Optional:
``bind(aether, xy)`` (the scenario's aether and live positions, before any window) and ``tx_gen(gen_of,
tx_station)`` (the generation step of the CAM each transmission carries, when it is not the pending one).
``cosim radio --mac sotdma,80211p,cv2x`` runs each on the same layout and seed (``run_radios``) and overlays
their PDR and inter-packet-gap curves (``plot_many``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosim.vanet.channel import Aether, ChannelParams
from cosim.vanet.metrics import BAND_M, AppMetrics, hist_percentile
from cosim.vanet.report import save_png
from cosim.vanet.sotdma import SotdmaMac, SotdmaParams, report_rate

PATHLOSS_NAMES = {  # command-line spelling -> ChannelParams.path_loss
    "free-space": "free_space",
    "two-ray": "two_ray",
    "log-distance": "log_distance",
    "winner-b1": "winner_b1",
    "3gpp-highway": "3gpp_highway",
    "3gpp-urban": "3gpp_urban",
}
LANE_WIDTH_M = 3.5


@dataclass(frozen=True)
class RadioScenario:
    mac: str = "sotdma"
    layout: str = "highway"
    vehicles_per_km: float | None = None
    stations: int | None = None
    area_m: float | None = None  # square side / road length [m]; default 300 / 5000
    lanes: int = 3  # per direction (highway)
    speed_kmh: float = 0.0
    rate_hz: float = 10.0
    size_bytes: int = 300
    tx_dbm: float = 13.0
    pathloss: str = "free-space"
    shadowing_db: float | None = None  # None: the model's default
    noise_dbm: float | None = None  # None: thermal + noise figure
    cs_dbm: float = -85.0
    duration_s: float = 30.0
    warmup_s: float = 10.0
    seed: int = 1
    # further ChannelParams fields (e.g. the receiver's sensitivity, WINNER+ B1 options) and the MAC's own
    # parameters (Cv2xParams / Mac80211pParams fields), for calibrations against references (Python API only)
    channel_params: dict | None = None
    mac_params: dict | None = None

    def __post_init__(self) -> None:
        if self.mac not in MACS:
            raise ValueError(f"--mac {self.mac}: not available (MACs: {', '.join(MACS)})")
        if self.layout not in ("highway", "square"):
            raise ValueError(f"--layout must be highway or square, got {self.layout!r}")
        if (self.vehicles_per_km is None) == (self.stations is None):
            raise ValueError("give exactly one of --vehicles-per-km and --stations")
        if self.layout == "square" and self.stations is None:
            raise ValueError("--layout square needs --stations")
        if self.stations is not None and not 2 <= self.stations <= 20_000:
            raise ValueError(f"--stations must be in 2..20000, got {self.stations}")
        if self.vehicles_per_km is not None and not 0 < self.vehicles_per_km <= 1000:
            raise ValueError(f"--vehicles-per-km must be in (0, 1000], got {self.vehicles_per_km}")
        if self.area_m is not None and not 10 <= self.area_m <= 100_000:
            raise ValueError(f"--area-m must be in [10, 100000] m, got {self.area_m}")
        if not 1 <= self.lanes <= 8:
            raise ValueError(f"--lanes must be in 1..8, got {self.lanes}")
        if not 0 <= self.speed_kmh <= 300:
            raise ValueError(f"--speed-kmh must be in [0, 300], got {self.speed_kmh}")
        if not 0 < self.rate_hz <= 10 or abs(1000 / self.rate_hz - round(1000 / self.rate_hz)) > 1e-9:
            raise ValueError(f"--rate-hz must be in (0, 10] with a whole-ms period, got {self.rate_hz}")
        if not 20 <= self.size_bytes <= 1500:
            raise ValueError(f"--size-bytes must be in 20..1500, got {self.size_bytes}")
        if not -10 <= self.tx_dbm <= 33:
            raise ValueError(f"--tx-dbm must be in [-10, 33], got {self.tx_dbm}")
        if self.pathloss not in PATHLOSS_NAMES:
            raise ValueError(f"--pathloss must be one of {', '.join(PATHLOSS_NAMES)}, got {self.pathloss!r}")
        if self.shadowing_db is not None and not 0 <= self.shadowing_db <= 20:
            raise ValueError(f"--shadowing-db must be in [0, 20], got {self.shadowing_db}")
        if not self.duration_s > self.warmup_s + 1.0 or self.duration_s > 3600:
            raise ValueError(f"--duration must exceed the {self.warmup_s:g}-s warm-up by > 1 s (and <= 3600)")

    @property
    def side_m(self) -> float:
        return self.area_m if self.area_m is not None else (300.0 if self.layout == "square" else 5000.0)

    @property
    def n_stations(self) -> int:
        if self.stations is not None:
            return int(self.stations)
        return max(2, round(self.vehicles_per_km * self.side_m / 1000.0))

    def channel(self) -> ChannelParams:
        return ChannelParams(
            **{
                "tx_power_mw": 10.0 ** (self.tx_dbm / 10.0),
                "path_loss": PATHLOSS_NAMES[self.pathloss],
                "lognormal_sigma_db": self.shadowing_db,
                "shadowing": "none",
                "noise_dbm": self.noise_dbm,
                "cs_threshold_dbm": self.cs_dbm,
                **(self.channel_params or {}),
            }
        )


class SotdmaRadioMac:
    """SOTDMA (cosim.vanet.sotdma) behind the radio-scenario MAC interface."""

    has_slots = True

    def __init__(self, sc: RadioScenario, n: int, rng: np.random.Generator):
        self.p = SotdmaParams(**(sc.mac_params or {}))
        self.frame_us, self.slot_us, self.n_slots = self.p.frame_layout(sc.size_bytes)
        self.mac = SotdmaMac(self.p, self.n_slots, n, rng)
        self.air_us = float(self.p.air_times_us(np.array([sc.size_bytes]))[0])
        self.rate = int(report_rate(np.array([round(1000 / sc.rate_hz)]), self.frame_us // 1000, 10)[0])

    def _g(self, t_us: int) -> int:
        f, rem = divmod(int(t_us), self.frame_us)
        k = -(-rem // self.slot_us)
        return (f + 1) * self.n_slots if k >= self.n_slots else f * self.n_slots + k

    def start(self, stations: np.ndarray, t_us: int) -> None:
        self.mac.start(stations, self._g(t_us))
        self.mac.set_rates(stations, np.full(stations.size, self.rate), self._g(t_us))

    def window(self, t_lo_us: int, t_hi_us: int, pending: np.ndarray, evaluate):
        g_lo, g_hi = self._g(t_lo_us), self._g(t_hi_us)
        self.mac.enter(g_lo)
        tx = self.mac.transmissions(g_lo, g_hi, pending)
        links = evaluate(tx.station, tx.g)

        def decoded_by(stations):
            t_i, r_i, d_m = links.decoded_at(stations)
            return r_i, t_i, d_m

        self.mac.resolve(tx, decoded_by)
        lt, lr, dist = links.decoded()
        self.mac.hear(lr, lt, tx.g, tx.timeout, tx.offset, dist)
        return tx.station, tx.g, links, np.full(tx.g.size, self.air_us)


def _interface_macs() -> dict:
    from cosim.vanet.radio_macs import Cv2xRadioMac, Ieee80211pRadioMac

    return {"80211p": Ieee80211pRadioMac, "cv2x": Cv2xRadioMac}


MACS = {"sotdma": SotdmaRadioMac, **_interface_macs()}


def _positions(sc: RadioScenario, rng: np.random.Generator):
    """(xy (n, 2) [m], velocity along x (n,) [m/s])."""
    n = sc.n_stations
    if sc.layout == "square":
        return rng.uniform(0.0, sc.side_m, (n, 2)), np.zeros(n)
    lane = rng.integers(0, 2 * sc.lanes, n)
    x = rng.uniform(0.0, sc.side_m, n)
    y = (lane + 0.5) * LANE_WIDTH_M
    v = np.where(lane < sc.lanes, 1.0, -1.0) * sc.speed_kmh / 3.6
    return np.stack([x, y], axis=1), v


def hurt_radius_m(aether: Aether) -> float:
    """Two same-slot senders closer than this can hurt each other: a receiver within the decoding range of
    one (``comm_range_m``) can be within the interference range of the other (``link_range_m``: at or above
    the receiver's interference floor; both include the aether's shadowing tail)."""
    return float(aether.comm_range_m + aether.link_range_m)


def shared_slot_mask(tx_g: np.ndarray, tx_xy: np.ndarray, radius_m: float) -> np.ndarray:
    """(T,) bool: transmissions whose slot (``tx_g``) carries another one from a sender within radius_m."""
    shared = np.zeros(tx_g.size, dtype=bool)
    order = np.argsort(tx_g, kind="stable")
    g_sorted = tx_g[order]
    starts = np.flatnonzero(np.r_[True, g_sorted[1:] != g_sorted[:-1]])
    ends = np.r_[starts[1:], g_sorted.size]
    for a, z in zip(starts[ends - starts > 1].tolist(), ends[ends - starts > 1].tolist(), strict=True):
        idx = order[a:z]  # a few per window
        p = tx_xy[idx]
        d = np.hypot(p[:, None, 0] - p[None, :, 0], p[:, None, 1] - p[None, :, 1])
        np.fill_diagonal(d, np.inf)
        shared[idx] = (d <= radius_m).any(axis=1)
    return shared


def run_radio(sc: RadioScenario, link_level: bool = False, details: dict | None = None):
    """Run the scenario: the ``cosim radio --json`` object; with ``link_level`` also the link-level PDR
    bands (sent CAMs only: what a PHY reference such as ns-3 with one sender measures) as a second value.
    ``details`` (a dict) receives ``ipg_hist``: counts of inter-packet gaps in 1-ms bins (last: >= 10 s)."""
    rng = np.random.default_rng(sc.seed)
    place_rng, mac_rng, phase_rng, field_rng = rng.spawn(4)
    n = sc.n_stations
    xy, vel = _positions(sc, place_rng)
    aether = Aether(sc.channel(), [], rng=field_rng)
    mac = MACS[sc.mac](sc, n, mac_rng)
    if hasattr(mac, "bind"):
        mac.bind(aether, xy)
    stations = np.arange(n)
    period_ms = round(1000 / sc.rate_hz)
    step_ms = math.gcd(100, period_ms)
    dt = step_ms / 1000.0
    n_steps = round(sc.duration_s * 1000 / step_ms)
    warm_step = round(sc.warmup_s * 1000 / step_ms)
    stop_gen_step = n_steps - round(1000 / step_ms)  # CAMs from the last second may still be waiting
    on_step = phase_rng.integers(0, round(1000 / step_ms), n)  # switched on within the first second
    gen_phase = phase_rng.integers(0, period_ms // step_ms, n)
    pending = np.zeros(n, dtype=bool)
    pending_gen = np.full(n, -1, dtype=np.int64)  # step at which the pending CAM was generated
    started = np.zeros(n, dtype=bool)
    margin = aether.comm_range_m  # no link beyond it is ever decoded
    hurt_m = hurt_radius_m(aether)
    n_bands = int(math.ceil(aether.comm_range_m / BAND_M))
    app = AppMetrics(n_bands, n * n)  # PDR, IPG, AoI per band (metrics.py); pair: receiver * n + sender
    generated = dropped = 0
    tx_total = tx_shared = 0
    busy_us = np.zeros(n)
    for k in range(n_steps):
        t_us = k * step_ms * 1000
        counted = (
            np.ones(n, dtype=bool)
            if sc.layout == "square"
            else (xy[:, 0] >= margin) & (xy[:, 0] <= sc.side_m - margin)
        )
        new = (~started & (on_step <= k)).nonzero()[0]
        if new.size:
            mac.start(new, t_us)
            started[new] = True
        gen = started & ((k - gen_phase) % (period_ms // step_ms) == 0)
        measure = warm_step <= k < stop_gen_step
        g_idx = gen.nonzero()[0]
        if measure and g_idx.size:
            generated += g_idx.size
            dropped += int(np.count_nonzero(pending[g_idx] & (pending_gen[g_idx] >= warm_step)))
            d = np.hypot(xy[g_idx, None, 0] - xy[None, :, 0], xy[g_idx, None, 1] - xy[None, :, 1])
            ok = counted[None, :] & (d > 0)
            app.add_generated(d[ok])
        pending[g_idx] = True
        pending_gen[g_idx] = k
        gen_of = pending_gen.copy()

        def evaluate(tx_station, tx_group):
            return aether.links(xy[tx_station], tx_station, tx_group, xy, stations)

        tx_st, tx_g, links, air = mac.window(t_us, t_us + step_ms * 1000, pending, evaluate)
        cam_gen = mac.tx_gen(gen_of, tx_st) if hasattr(mac, "tx_gen") else gen_of[tx_st]
        if k < warm_step:
            continue
        lt, lr, dist = links.decoded()
        sent_meas = ((cam_gen >= warm_step) & (cam_gen < stop_gen_step)).nonzero()[0]
        if sent_meas.size:
            s_st = tx_st[sent_meas]
            d = np.hypot(xy[s_st, None, 0] - xy[None, :, 0], xy[s_st, None, 1] - xy[None, :, 1])
            ok = counted[None, :] & (d > 0)
            app.add_sent(d[ok])
        keep = counted[lr] & (cam_gen[lt] >= warm_step) & (cam_gen[lt] < stop_gen_step)
        app.add_decoded(dist, keep)
        # inter-packet gaps and ages of (receiver, sender) pairs, timed at the window start
        gen_s = cam_gen[lt] * step_ms / 1000.0
        app.add_deliveries(lr * n + tx_st[lt], np.full(lt.size, t_us / 1e6), gen_s, dist)
        busy_us += links.sensed_busy_us(air)
        if k < stop_gen_step and tx_g.size:
            tx_total += tx_g.size
            if getattr(mac, "has_slots", False):
                tx_shared += int(shared_slot_mask(tx_g, xy[tx_st], hurt_m).sum())
        # move (wrap-around on the highway)
        if sc.layout == "highway" and sc.speed_kmh > 0:
            xy[:, 0] = (xy[:, 0] + vel * dt) % sc.side_m
    measured_s = (n_steps - warm_step) * dt
    counted_final = (
        np.ones(n, dtype=bool)
        if sc.layout == "square"
        else (xy[:, 0] >= margin) & (xy[:, 0] <= sc.side_m - margin)
    )
    cbr = float(np.mean(busy_us[counted_final]) / (measured_s * 1e6)) if counted_final.any() else 0.0
    if details is not None:
        details["ipg_hist"] = app.ipg_hist
    ipg_p95 = hist_percentile(app.ipg_hist, 95)
    bands = app.pdr_bands()
    result = {
        "mac": sc.mac,
        "stations": int(n),
        "pdr": bands,
        "cbr": cbr,
        "shared_slot_share": (tx_shared / tx_total if tx_total else 0.0)
        if getattr(mac, "has_slots", False)
        else None,
        "never_sent_share": dropped / generated if generated else 0.0,
        "ipg_p95_s": ipg_p95,
    }
    if not link_level:
        return result
    return result, app.pdr_bands(link_level=True)


def title(sc: RadioScenario) -> str:
    density = (
        f"{sc.vehicles_per_km:g} veh/km" if sc.vehicles_per_km is not None else f"{sc.n_stations} stations"
    )
    return (
        f"cosim radio: {sc.mac}, {sc.layout} {sc.side_m:g} m, {density}, {sc.rate_hz:g} Hz, {sc.size_bytes} B, "
        f"{sc.tx_dbm:g} dBm, {sc.pathloss}, seed {sc.seed}"
    )


def plot(result: dict, sc: RadioScenario, out_dir: str | Path) -> Path:
    """PDR vs distance (50-m bands) into out_dir/pdr_vs_distance.png."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(8, 4.5))
    c = [0.5 * (b["from_m"] + b["to_m"]) for b in result["pdr"]]
    ax.plot(
        c, [b["pdr"] for b in result["pdr"]], marker="o", lw=1.2, label="PDR (never-sent CAMs count as lost)"
    )
    ax.set_xlabel("distance [m] (50-m bands)")
    ax.set_ylabel("packet delivery ratio")
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left")
    ax.set_title(title(sc), fontsize=8)
    path = out / "pdr_vs_distance.png"
    save_png(fig, path)
    return path


def run_radios(scenarios: list[RadioScenario]) -> tuple[list[dict], list[np.ndarray]]:
    """Run the same scenario with each MAC (same layout, seed, channel, receiver): (results, IPG histograms)."""
    results, hists = [], []
    for sc in scenarios:
        d: dict = {}
        results.append(run_radio(sc, details=d))
        hists.append(d["ipg_hist"])
    return results, hists


def plot_many(results: list[dict], scenarios: list[RadioScenario], ipg_hists, out_dir: str | Path) -> Path:
    """The MACs side by side: PDR vs distance and the inter-packet-gap CCDF, one line per MAC, into
    out_dir/pdr_vs_distance.png."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.5), gridspec_kw={"width_ratios": [3, 2]})
    for res, hist in zip(results, ipg_hists, strict=True):
        c = [0.5 * (b["from_m"] + b["to_m"]) for b in res["pdr"]]
        ax.plot(
            c,
            [b["pdr"] for b in res["pdr"]],
            marker="o",
            ms=3,
            lw=1.2,
            label=MAC_LABELS.get(res["mac"], res["mac"]),
        )
        h = np.asarray(hist, dtype=np.float64)
        if h.sum() > 0:
            ccdf = 1.0 - np.cumsum(h) / h.sum()
            t = np.arange(h.size) / 1000.0
            keep = ccdf > 0
            bx.step(t[keep], ccdf[keep], where="post", lw=1.2, label=MAC_LABELS.get(res["mac"], res["mac"]))
    ax.set_xlabel("distance [m] (50-m bands)")
    ax.set_ylabel("packet delivery ratio (never-sent CAMs lost)")
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left")
    bx.set_xlabel("inter-packet gap of a (receiver, sender) pair [s]")
    bx.set_ylabel("P(gap > x)")
    bx.set_yscale("log")
    bx.set_xlim(0, 1.0)
    bx.grid(alpha=0.3, which="both")
    bx.legend(loc="upper right")
    sc = scenarios[0]
    macs = ", ".join(s.mac for s in scenarios)
    fig.suptitle(title(sc).replace(f": {sc.mac},", f": {macs},"), fontsize=8)
    path = out / "pdr_vs_distance.png"
    save_png(fig, path)
    return path


MAC_LABELS = {"sotdma": "SOTDMA", "80211p": "IEEE 802.11p (EDCA AC_BE)", "cv2x": "C-V2X mode 4 (SB-SPS)"}

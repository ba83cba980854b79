"""``vanet_report``: the VANET metrics of one run, plus PNG plots (matplotlib, Agg backend).

Input is what the log reader returns: ``{topic: {column: ndarray}}`` with the topics written by
``VanetLayer`` (``/vanet/tx``, ``/vanet/rx``, ``/vanet/load``); missing topics give empty metrics.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cosim.vanet import metrics


def _figure():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _cdf(ax, x: np.ndarray, label: str) -> None:
    x = np.sort(np.asarray(x, dtype=np.float64))
    x = x[np.isfinite(x)]
    if x.size:
        ax.step(x, np.arange(1, x.size + 1) / x.size, where="post", label=f"{label} (n={x.size})")


def vanet_report(columns_by_topic: dict[str, dict[str, np.ndarray]], out_dir: str | Path) -> dict:
    """Compute the metrics, write ``pdr_vs_distance.png``, ``aoi.png`` and ``channel_load.png`` into
    ``out_dir`` (created if needed) and return the summary (plain Python values) with ``plots``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    summary = metrics.summarize(columns_by_topic)
    rx = columns_by_topic.get("/vanet/rx", {})
    load = columns_by_topic.get("/vanet/load", {})
    plt = _figure()
    plots = []

    pdr = metrics.pdr_vs_distance(rx)
    fig, ax = plt.subplots(figsize=(7, 4))
    has = pdr["n"] > 0
    if has.any():
        centres = pdr["bin_lo_m"][has] + 5.0
        ax.plot(centres, pdr["pdr"][has], marker=".", lw=1)
        ax2 = ax.twinx()
        ax2.bar(centres, pdr["n"][has], width=8.0, alpha=0.15, color="gray")
        ax2.set_ylabel("receptions logged per 10 m bin")
    ax.set_xlabel("distance [m]")
    ax.set_ylabel("packet delivery ratio")
    ax.set_ylim(0, 1.02)
    ax.set_title("PDR vs distance (10 m bins)")
    ax.grid(alpha=0.3)
    path = out / "pdr_vs_distance.png"
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    plots.append(str(path))

    aoi = metrics.age_of_information(rx)
    fig, ax = plt.subplots(figsize=(7, 4))
    _cdf(ax, aoi["age_at_delivery_s"], "age at delivery")
    _cdf(ax, aoi["peak_aoi_s"], "peak AoI")
    _cdf(ax, metrics.inter_packet_gap(rx), "inter-packet gap")
    ax.set_xscale("symlog", linthresh=0.1)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("CDF")
    ax.set_title("Age of information and inter-packet gap (decoded CAMs, per pair)")
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="lower right")
    path = out / "aoi.png"
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    plots.append(str(path))

    fig, ax = plt.subplots(figsize=(7, 3))
    if len(load.get("t_s", [])):
        ax.plot(load["t_s"], load["busy_ratio"], label="busy slots / slots")
        ax.plot(load["t_s"], load["airtime_ratio"], label="air time / frame")
        ax.legend(loc="upper right")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("channel load per frame")
    ax.grid(alpha=0.3)
    path = out / "channel_load.png"
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    plots.append(str(path))

    summary["plots"] = plots
    return summary

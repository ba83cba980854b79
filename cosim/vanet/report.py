"""``vanet_report``: the VANET metrics of one run, plus PNG plots (matplotlib, Agg backend).

Input is what the log reader returns: ``{topic: {column: ndarray}}`` with the topics written by
``VanetLayer`` (``/vanet/tx``, ``/vanet/rx``, ``/vanet/load``, ``/vanet/step``); missing topics give empty
metrics. Link level (10-m bins: PDR of the logged receptions, AoI / IPG CDFs) beside the application level of
``cosim radio`` (50-m bands, ``metrics.AppMetrics``: PDR counting CAMs never sent, IPG and age of information
per band), and the channel busy ratio the stations sense beside the map-wide slot use. Every plot title names
the run, its map and its traffic density (``run_title``, from the log's metadata).
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


def run_title(metadata: dict[str, dict[str, str]] | None) -> str:
    """The title "run <name>, <map>, <density> traffic, seed <k>" from a log's metadata (its ``cosim``
    record: the config); what is missing is shown as "?" or left out."""
    import json

    meta = (metadata or {}).get("cosim", {})
    try:
        cfg = json.loads(meta.get("config", "{}")) or {}
    except ValueError:
        cfg = {}
    scenario = cfg.get("scenario") or {}
    demand = scenario.get("demand") or {}
    parts = [f"run {cfg['name']}" if cfg.get("name") else "run ?"]
    map_name = meta.get("map") or (Path(scenario["map"]).name if scenario.get("map") else "")
    parts.append(map_name or "map ?")
    parts.append(f"{demand['density']} traffic" if demand.get("density") else "density ?")
    if meta.get("seed") is not None or cfg.get("seed") is not None:
        parts.append(f"seed {meta.get('seed', cfg.get('seed'))}")
    return ", ".join(parts)


def save_png(fig, path: Path) -> str:
    """Lay out, write and close a figure (every vanet plot the same way); returns the path."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return str(path)


def _title(ax, what: str, run: str) -> None:
    ax.set_title(f"{what}\n{run}", fontsize=9)


def vanet_report(
    columns_by_topic: dict[str, dict[str, np.ndarray]], out_dir: str | Path, title: str | None = None
) -> dict:
    """Compute the metrics, write ``pdr_vs_distance.png``, ``app_vs_distance.png``, ``aoi.png`` and
    ``channel_load.png`` into ``out_dir`` (created if needed) and return the summary (plain Python values)
    with ``run`` (``title``: the run, map and density, see ``run_title``) and ``plots``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    run = title or "run ?, map ?, density ?"
    summary = {"run": run, **metrics.summarize(columns_by_topic)}
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
    _title(ax, "Link-level PDR vs distance (10-m bins, CAMs sent)", run)
    ax.grid(alpha=0.3)
    path = out / "pdr_vs_distance.png"
    plots.append(save_png(fig, path))

    aoi = metrics.age_of_information(rx)
    fig, ax = plt.subplots(figsize=(7, 4))
    _cdf(ax, aoi["age_at_delivery_s"], "age at delivery")
    _cdf(ax, aoi["peak_aoi_s"], "peak AoI")
    _cdf(ax, metrics.inter_packet_gap(rx), "inter-packet gap")
    ax.set_xscale("symlog", linthresh=0.1)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("CDF")
    _title(ax, "Age of information and inter-packet gap (decoded CAMs, per pair)", run)
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="lower right")
    path = out / "aoi.png"
    plots.append(save_png(fig, path))

    # application level per 50-m band: PDR counting never-sent CAMs, IPG and age of information
    bands = summary["app_vs_distance"]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.2))
    if bands:
        c = [0.5 * (b["from_m"] + b["to_m"]) for b in bands]
        q = summary["never_sent_share"]
        ax.plot(
            c,
            [b["pdr"] for b in bands],
            marker="o",
            lw=1.2,
            label=f"application (never-sent CAMs lost: {q:.1%})" if q is not None else "application",
        )
        ax.plot(c, [b["pdr_link"] for b in bands], marker=".", lw=1, ls="--", label="link level (CAMs sent)")
        ax.legend(loc="lower left")
        for key, label in (
            ("ipg_p95_s", "inter-packet gap p95"),
            ("ipg_p50_s", "inter-packet gap p50"),
            ("peak_aoi_p95_s", "peak age of information p95"),
            ("age_p50_s", "age at delivery p50"),
        ):
            y = [np.nan if b[key] is None else b[key] for b in bands]
            bx.plot(c, y, marker=".", lw=1, label=label)
        bx.legend(loc="upper left")
    ax.set_xlabel("distance at transmission [m] (50-m bands)")
    ax.set_ylabel("packet delivery ratio")
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    _title(ax, "Application-level PDR vs distance", run)
    bx.set_xlabel("distance at transmission [m] (50-m bands)")
    bx.set_ylabel("time [s]")
    bx.set_yscale("log")
    bx.grid(alpha=0.3, which="both")
    _title(bx, "Inter-packet gap and age of information per band", run)
    path = out / "app_vs_distance.png"
    plots.append(save_png(fig, path))

    fig, ax = plt.subplots(figsize=(8, 3.6))
    if len(load.get("t_s", [])):
        ax.plot(load["t_s"], load["busy_ratio"], label="map-wide: busy slots / slots")
        ax.plot(load["t_s"], load["airtime_ratio"], label="map-wide: air time / frame")
        for col, label, style in (
            ("cbr_mean", "sensed CBR, mean over stations", "-"),
            ("cbr_p95", "sensed CBR, 95th percentile", "--"),
            ("cbr_ego", "sensed CBR at the ego", ":"),
        ):
            if col in load:
                v = np.asarray(load[col], dtype=np.float64)
                ok = np.isfinite(v)
                if ok.any():
                    ax.plot(np.asarray(load["t_s"])[ok], v[ok], ls=style, label=label)
        ax.legend(loc="upper right", fontsize=7)
    ax.set_xlabel("time [s] (frame start)")
    ax.set_ylabel("channel load per frame")
    ax.grid(alpha=0.3)
    _title(ax, "Channel busy ratio sensed (energy >= CS threshold) beside map-wide slot use", run)
    path = out / "channel_load.png"
    plots.append(save_png(fig, path))

    summary["plots"] = plots
    return summary

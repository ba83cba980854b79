"""Headline metrics of one run (from its MCAP log) and the sweep's table.csv and plots.

Per run (``run_metrics``), every metric computed from the log where its topic exists, else None (an empty
cell in table.csv):

* VANET (``/vanet/rx``, ``/vanet/tx``, ``/vanet/load``, via ``cosim.vanet.metrics``): ``pdr_overall``;
  ``pdr_<lo>_<hi>m`` = decoded / logged receptions with the sender-receiver distance in [lo, hi) per band
  of the sweep's ``pdr_bands_m``; ``rx_logged``; ``channel_busy_mean`` / ``channel_airtime_mean`` (mean
  per frame of busy slots / slots and air time / frame); ``slot_collision_fraction`` (transmissions that
  share their slot); ``aoi_mean_s`` (time-average age of information); ``ipg_p95_s``.
* Traffic: ``vehicles_mean`` (SCVs per ``/traffic/vehicles`` sample); ``collisions``, ``teleports``,
  ``emergency_stops``, ``red_light_violations``, ``ego_off_road`` counted from ``/events`` (the recorder
  writes every event, so a log without ``/events`` had none); ``ego_speed_mean_mps``.
* Time gap (the experiment's ``timegap.csv`` in the run folder, else a log topic with a
  ``time_gap_true_s`` column, e.g. an ``/adas/*`` topic): ``timegap_mean_s``, ``timegap_sd_s``,
  ``timegap_min_s``, ``timegap_share_below_2s``, ``timegap_share_below_1s`` over samples with a leader,
  and ``warnings`` (onsets of the 'warning' level); the same per phase as ``<metric>.<phase>`` when the
  trace has phases.
* From the simulation's own stats: ``simulated_s``, ``real_time_factor``, ``sim_wall_s`` (stepping only);
  the run's total wall time (set-up, stepping, metrics) is ``wall_s`` in result.json and the table.
"""

from __future__ import annotations

import csv
import json
import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cosim.errors import CosimError

EVENT_KINDS = {"collision": "collisions", "teleport": "teleports", "emergency_stop": "emergency_stops",
               "red_light_violation": "red_light_violations", "ego_off_road": "ego_off_road"}  # fmt: skip
TIMEGAP_STATS = ("timegap_mean_s", "timegap_sd_s", "timegap_min_s", "timegap_share_below_2s",
                 "timegap_share_below_1s", "warnings")  # fmt: skip
_PREFIXES = ("/vanet/", "/adas/", "/experiment/")
_FIXED_TOPICS = ("/vanet/rx", "/vanet/tx", "/vanet/load", "/events", "/traffic/vehicles", "/ego/state")


def band_names(edges_m: Sequence[float]) -> list[str]:
    return [f"pdr_{lo:g}_{hi:g}m" for lo, hi in zip(edges_m, edges_m[1:], strict=False)]


def metric_columns(edges_m: Sequence[float]) -> list[str]:
    """The fixed metric columns of table.csv, in order (per-phase time-gap columns follow)."""
    return ["pdr_overall", *band_names(edges_m), "rx_logged", "channel_busy_mean", "channel_airtime_mean",
            "slot_collision_fraction", "aoi_mean_s", "ipg_p95_s", "vehicles_mean", *EVENT_KINDS.values(),
            "ego_speed_mean_mps", *TIMEGAP_STATS, "simulated_s", "real_time_factor", "sim_wall_s"]  # fmt: skip


class _Topics:
    """A ``topics`` filter for cosim.log.read: the fixed topics and every /vanet/, /adas/, /experiment/ one."""

    def __contains__(self, topic: str) -> bool:
        return topic in _FIXED_TOPICS or topic.startswith(_PREFIXES)


def _f(x) -> float | None:
    return None if x is None or not math.isfinite(float(x)) else float(x)


def vanet_metrics(topics: dict[str, dict[str, np.ndarray]], edges_m: Sequence[float]) -> dict[str, Any]:
    from cosim.vanet import metrics
    from cosim.vanet.channel import OK

    out: dict[str, Any] = dict.fromkeys(["pdr_overall", *band_names(edges_m), "rx_logged", "channel_busy_mean",
                                         "channel_airtime_mean", "slot_collision_fraction", "aoi_mean_s",
                                         "ipg_p95_s"])  # fmt: skip
    if not any(t in topics for t in ("/vanet/rx", "/vanet/tx", "/vanet/load")):
        return out
    s = metrics.summarize(topics)
    if "/vanet/rx" in topics:
        rx = topics["/vanet/rx"]
        d = np.asarray(rx.get("distance_m", np.zeros(0)), dtype=np.float64)
        ok = np.asarray(rx.get("outcome", np.zeros(0)), dtype=np.float64) == OK
        out["rx_logged"] = int(d.size)
        out["pdr_overall"] = _f(s["pdr_overall"])
        for name, lo, hi in zip(band_names(edges_m), edges_m, edges_m[1:], strict=False):
            inside = (d >= lo) & (d < hi)
            n = int(inside.sum())
            out[name] = float(ok[inside].sum() / n) if n else None
        out["aoi_mean_s"] = _f(s["aoi_s"]["time_average"])
        out["ipg_p95_s"] = _f(s["inter_packet_gap_s"]["p95"])
    if "/vanet/load" in topics:
        out["channel_busy_mean"] = _f(s["channel_load"]["busy_ratio"]["mean"])
        out["channel_airtime_mean"] = _f(s["channel_load"]["airtime_ratio"]["mean"])
    if "/vanet/tx" in topics:
        out["slot_collision_fraction"] = _f(s["slot_collisions"]["fraction"])
    return out


def _timegap_trace(topics: dict[str, dict[str, np.ndarray]], run_dir: Path | None):
    """The run's time-gap trace: timegap.csv in the run folder, else a logged topic with time_gap_true_s."""
    from cosim.experiment.compare import TimeGapTrace, load_trace_csv

    if run_dir is not None and (run_dir / "timegap.csv").is_file():
        return load_trace_csv(run_dir / "timegap.csv")
    names = sorted((t for t, c in topics.items() if "time_gap_true_s" in c and "t_s" in c),
                   key=lambda t: ("timegap" not in t.replace("_", ""), t))  # fmt: skip
    for name in names:
        c = topics[name]
        n = len(c["t_s"])
        if n == 0:
            continue
        cols = {"t_s": c["t_s"], "time_gap_true_s": np.asarray(c["time_gap_true_s"], dtype=np.float64),
                "phase": c.get("phase", np.full(n, "run", dtype=object)),
                "system": c.get("system", np.full(n, "", dtype=object)),
                "time_gap_displayed_s": c.get("time_gap_displayed_s", np.full(n, np.nan)),
                "warning": c.get("warning", c.get("level", np.full(n, "none", dtype=object)))}  # fmt: skip
        try:
            return TimeGapTrace.from_columns(cols, source=name)
        except CosimError:  # not one row per time (e.g. per-vehicle rows): not a trace
            continue
    return None


def _gap_stats(tg: np.ndarray, warning: np.ndarray) -> dict[str, Any]:
    fin = tg[np.isfinite(tg)]
    is_warn = warning == "warning"
    onsets = int(np.count_nonzero(is_warn[1:] & ~is_warn[:-1]) + (1 if is_warn.size and is_warn[0] else 0))
    if fin.size == 0:
        return {**dict.fromkeys(TIMEGAP_STATS[:-1]), "warnings": onsets}
    return {"timegap_mean_s": float(fin.mean()), "timegap_sd_s": float(fin.std(ddof=1)) if fin.size > 1 else 0.0,
            "timegap_min_s": float(fin.min()), "timegap_share_below_2s": float(np.mean(fin < 2.0)),
            "timegap_share_below_1s": float(np.mean(fin < 1.0)), "warnings": onsets}  # fmt: skip


def timegap_metrics(trace) -> dict[str, Any]:
    if trace is None:
        return dict.fromkeys(TIMEGAP_STATS)
    out = _gap_stats(trace.time_gap_true_s, trace.warning)
    phase = np.asarray([p or "run" for p in trace.phase], dtype=object)  # no protocol: one phase, "run"
    phases = list(dict.fromkeys(phase))
    if phases != ["run"]:
        for ph in phases:
            sel = phase == ph
            for k, v in _gap_stats(trace.time_gap_true_s[sel], trace.warning[sel]).items():
                out[f"{k}.{ph}"] = v
    return out


def metrics_from_topics(topics: dict[str, dict[str, np.ndarray]], counts: dict[str, int],
                        pdr_bands_m: Sequence[float] = (0.0, 100.0, 300.0, 500.0),
                        run_dir: Path | None = None) -> dict[str, Any]:  # fmt: skip
    """Headline metrics from decoded log columns ``{topic: {column: array}}`` and per-topic message counts."""
    out = vanet_metrics(topics, pdr_bands_m)
    tv = topics.get("/traffic/vehicles")
    n_msgs = counts.get("/traffic/vehicles", 0)
    out["vehicles_mean"] = float(len(tv["id"]) / n_msgs) if tv is not None and "id" in tv and n_msgs else None
    has_log = bool(counts)
    kinds = topics.get("/events", {}).get("kind", np.zeros(0, dtype=object))
    for kind, col in EVENT_KINDS.items():
        out[col] = int(np.count_nonzero(kinds == kind)) if has_log else None
    ego = topics.get("/ego/state")
    out["ego_speed_mean_mps"] = (
        _f(np.nanmean(ego["speed_mps"])) if ego and len(ego.get("speed_mps", ())) else None
    )
    out.update(timegap_metrics(_timegap_trace(topics, run_dir)))
    return out


def run_metrics(mcap: str | Path, *, stats: dict | None = None, pdr_bands_m: Sequence[float] = (0.0, 100.0, 300.0, 500.0),
                run_dir: str | Path | None = None) -> dict[str, Any]:  # fmt: skip
    """All headline metrics of one run from its log (and its simulation stats when given)."""
    from cosim.log import read

    log = read(mcap, topics=_Topics())  # type: ignore[arg-type] - any container with __contains__
    out = metrics_from_topics(log.topics, log.counts, pdr_bands_m, Path(run_dir) if run_dir else None)
    stats = stats or {}
    out["simulated_s"] = stats.get("simulated_s", round(log.duration_s, 3) if log.counts else None)
    out["real_time_factor"] = stats.get("real_time_factor")
    out["sim_wall_s"] = stats.get("wall_s")
    out["log_truncated"] = bool(log.truncated)
    return out


# -- the sweep's table -------------------------------------------------------------------------------------------
def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "" if not math.isfinite(value) else f"{value:.6g}"
    if isinstance(value, (int, str)):
        return str(value)
    return json.dumps(value, sort_keys=True)


def table_columns(results: list[dict], swept: Sequence[str], pdr_bands_m: Sequence[float]) -> list[str]:
    fixed = metric_columns(pdr_bands_m)
    extra = sorted(
        {k for r in results for k in r.get("metrics", {}) if k not in fixed and k != "log_truncated"}
    )
    return ["run_id", "status", *swept, "seed", *fixed, *extra, "wall_s", "error"]


def table_rows(
    results: list[dict], swept: Sequence[str], pdr_bands_m: Sequence[float]
) -> tuple[list[str], list[dict]]:
    """Columns and one row per run (values as Python objects; missing = None)."""
    cols = table_columns(results, swept, pdr_bands_m)
    rows = []
    for r in results:
        row: dict[str, Any] = {"run_id": r["run_id"], "status": r["status"], "seed": r.get("seed"),
                               "wall_s": r.get("wall_s"), "error": r.get("error")}  # fmt: skip
        ov = r.get("overrides", {})
        for k in swept:
            row[k] = ov.get(k)
        row.update({k: v for k, v in r.get("metrics", {}).items() if k in cols})
        rows.append(row)
    return cols, rows


def write_table(path: Path, cols: list[str], rows: list[dict]) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    with tmp.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for row in rows:
            w.writerow([_cell(row.get(c)) for c in cols])
    tmp.replace(path)


# -- plots -----------------------------------------------------------------------------------------------------------
def _numeric(values: list) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def _order(values: list) -> list:
    """Distinct values in order: numbers sorted, anything else in order of first appearance (the grid's)."""
    keys = list(dict.fromkeys(_cell(v) for v in values))
    by_key = {_cell(v): v for v in values}
    uniq = [by_key[k] for k in keys]
    return sorted(uniq) if _numeric(uniq) else uniq


def _safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text)


def plot_metric(rows: list[dict], metric: str, x: str, hue: str | None, out: Path, title: str = "",
                logy: bool = False) -> Path | None:  # fmt: skip
    """``metric`` against parameter ``x`` (mean and SD over the runs at each point: seeds and any other swept
    parameter), one line per value of ``hue``. None when no run has a value of the metric."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    pts = [r for r in rows if r["status"] == "ok" and isinstance(r.get(metric), (int, float))
           and not isinstance(r.get(metric), bool) and math.isfinite(r[metric])]  # fmt: skip
    if not pts:
        return None
    xs = _order([r.get(x) for r in rows])
    hues = _order([r.get(hue) for r in rows]) if hue else [None]
    numeric_x = _numeric(xs)
    pos = {_cell(v): (float(v) if numeric_x else i) for i, v in enumerate(xs)}
    fig = Figure(figsize=(7, 4.2))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    per_point = []
    for k, hv in enumerate(hues):
        sel = [r for r in pts if hue is None or _cell(r.get(hue)) == _cell(hv)]
        px, py, pe = [], [], []
        for v in xs:
            ys = np.array([r[metric] for r in sel if _cell(r.get(x)) == _cell(v)], dtype=np.float64)
            if ys.size:
                px.append(pos[_cell(v)] + (0.0 if numeric_x else (k - (len(hues) - 1) / 2) * 0.04))
                py.append(ys.mean())
                pe.append(ys.std(ddof=1) if ys.size > 1 else 0.0)
                per_point.append(ys.size)
        if px:
            label = f"{hue} = {_cell(hv)}" if hue else None
            ax.errorbar(px, py, yerr=pe, marker="o", capsize=3, lw=1.2, label=label)
    if not numeric_x:
        ax.set_xticks(range(len(xs)), [_cell(v) for v in xs])
    ax.set_xlabel(x)
    ax.set_ylabel(metric)
    if logy:
        ax.set_yscale("log")
    n_lo, n_hi = min(per_point), max(per_point)
    n_txt = f"{n_lo}" if n_lo == n_hi else f"{n_lo}-{n_hi}"
    ax.set_title(title or f"{metric} vs {x} (mean ± SD over {n_txt} run(s) per point)", fontsize=10)
    ax.grid(alpha=0.3)
    if hue:
        ax.legend(fontsize=8)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    return out


def aggregate(sweep, results: list[dict], out_dir: Path) -> tuple[Path, list[Path], list[str]]:
    """Write ``table.csv`` and the sweep's plots into ``out_dir``; returns (table, plots, notes)."""
    spec = sweep.spec
    swept = spec.swept_keys
    cols, rows = table_rows(results, swept, spec.pdr_bands_m)
    table = out_dir / "table.csv"
    write_table(table, cols, rows)
    plots: list[Path] = []
    notes: list[str] = []
    for p in spec.plots:
        name = _safe(f"{p.metric}_vs_{p.x}" + (f"_by_{p.hue}" if p.hue else "")) + ".png"
        if p.metric not in cols:
            known = [c for c in cols if c not in ("run_id", "status", "seed", "error", *swept)]
            notes.append(f"plot {name}: no column {p.metric!r} in table.csv (metrics: {', '.join(known)})")
            continue
        path = plot_metric(rows, p.metric, p.x, p.hue, out_dir / "plots" / name, logy=p.logy)
        if path is None:
            notes.append(f"plot {name}: no run has a value of {p.metric} (topic missing from the logs?)")
        else:
            plots.append(path)
    return table, plots, notes

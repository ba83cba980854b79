"""Regression of time-gap traces: how far apart are two runs' time-gap traces, per phase, within tolerances?

Input: two traces with the columns of ``timegap.csv`` (t_s, phase, system, time_gap_true_s,
time_gap_displayed_s, warning), from CSV or from already-loaded columns. Per phase (matched by name) both
traces are interpolated onto one common grid (the overlapping time span, at the finer of the two sample
steps) and compared:

- RMSE and maximum deviation of the true time gap and of the displayed time gap (samples where both are
  finite), plus the share of time one shows "no data" (NaN) and the other a value;
- share of time in each time-gap band (>= 3 s, 2-3 s, 1-2 s, < 1 s, n/a) of the true gap, both traces and
  the difference; share of time with an advisory and with a warning shown;
- phase duration and the active system.

Tolerances follow SUMO's fpdiff (tools/sumolib/fpdiff.py): a number passes when its deviation is within
the ABSOLUTE tolerance OR within the RELATIVE tolerance times the reference value, where the reference is
trace A (the golden / expected one). Shares are fractions in [0, 1] and use absolute tolerances only.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cosim.errors import CosimError

COLUMNS = ("t_s", "phase", "system", "time_gap_true_s", "time_gap_displayed_s", "warning")
LEVELS = ("none", "advisory", "warning")
BANDS = (">=3s", "2-3s", "1-2s", "<1s", "n/a")  # of the true time gap; n/a = not finite (no leader)
_EPS = 1e-9
_NO_VALUE = {"", "nan", "none", "null", "na", "n/a"}
_TRUE = {"1", "true", "yes", "on"}
_FALSE = {"0", "false", "no", "off", ""}


@dataclass(frozen=True, eq=False)
class TimeGapTrace:
    """One run's time-gap trace. Every array has shape (N,); N >= 1; ``t_s`` strictly increasing."""

    t_s: np.ndarray  # (N,) float64, simulated time [s]
    phase: np.ndarray  # (N,) object (str), protocol phase name
    system: np.ndarray  # (N,) object (str), assistance system active ('none', 'A', 'B', ...)
    time_gap_true_s: np.ndarray  # (N,) float64, ground-truth time gap [s]; NaN = no leader
    time_gap_displayed_s: np.ndarray  # (N,) float64, displayed time gap [s]; NaN = nothing / "no data"
    warning: np.ndarray  # (N,) object (str), one of LEVELS
    source: str = ""  # where it came from, for messages

    def __post_init__(self) -> None:
        n = len(self.t_s)
        where = f"{self.source}: " if self.source else ""
        if n == 0:
            raise CosimError(f"{where}time-gap trace has no rows")
        set_ = object.__setattr__
        set_(self, "t_s", np.asarray(self.t_s, dtype=np.float64))
        for name in ("time_gap_true_s", "time_gap_displayed_s"):
            set_(self, name, np.asarray(getattr(self, name), dtype=np.float64))
        for name in ("phase", "system"):
            set_(self, name, np.asarray([str(v) for v in getattr(self, name)], dtype=object))
        set_(self, "warning", np.asarray([_level(v, where) for v in self.warning], dtype=object))
        for name in COLUMNS:
            if getattr(self, name).shape != (n,):
                raise CosimError(f"{where}column {name} has {len(getattr(self, name))} rows, t_s has {n}")
        if not np.all(np.isfinite(self.t_s)):
            raise CosimError(f"{where}t_s contains a non-finite time")
        if n > 1 and not np.all(np.diff(self.t_s) > 0.0):
            k = int(np.flatnonzero(np.diff(self.t_s) <= 0.0)[0])
            raise CosimError(f"{where}t_s is not strictly increasing at row {k + 1} ({self.t_s[k + 1]} s)")

    @classmethod
    def from_columns(cls, columns: Mapping[str, Sequence | np.ndarray], source: str = "") -> TimeGapTrace:
        """Build from a mapping column name -> values (extra columns are ignored)."""
        missing = [c for c in COLUMNS if c not in columns]
        if missing:
            where = f"{source}: " if source else ""
            raise CosimError(f"{where}missing column(s) {', '.join(missing)} (expected {', '.join(COLUMNS)})")
        return cls(**{c: columns[c] for c in COLUMNS}, source=source)

    def step_s(self) -> float:
        """Median sample step [s] (0 for a single row)."""
        return float(np.median(np.diff(self.t_s))) if len(self.t_s) > 1 else 0.0


def _level(value: object, where: str) -> str:
    """Normalise a warning cell: level names as they are, booleans / 0 / 1 as 'warning' / 'none'."""
    if isinstance(value, (bool, np.bool_)):
        return "warning" if value else "none"
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        if value != value:  # NaN: nothing shown
            return "none"
        return "warning" if value else "none"
    text = str(value).strip().lower()
    if text in LEVELS:
        return text
    if text in _TRUE:
        return "warning"
    if text in _FALSE or text in _NO_VALUE:
        return "none"
    raise CosimError(f"{where}warning value {value!r} is not one of {', '.join(LEVELS)} or a boolean")


def _number(text: str, path: Path, line: int, column: str) -> float:
    text = text.strip()
    if text.lower() in _NO_VALUE:
        return math.nan
    try:
        return float(text)
    except ValueError:
        raise CosimError(f"{path}:{line}: column {column}: {text!r} is not a number") from None


def load_trace_csv(path: str | Path) -> TimeGapTrace:
    """Read a ``timegap.csv``; a missing file, column or bad number is a CosimError naming file and line."""
    path = Path(path)
    if not path.is_file():
        raise CosimError(f"time-gap trace {path} does not exist")
    with path.open(newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh, skipinitialspace=True)
        header = [h.strip() for h in (reader.fieldnames or [])]
        reader.fieldnames = header
        missing = [c for c in COLUMNS if c not in header]
        if missing:
            raise CosimError(
                f"{path}: missing column(s) {', '.join(missing)} (expected {', '.join(COLUMNS)})"
            )
        cols: dict[str, list] = {c: [] for c in COLUMNS}
        for line, row in enumerate(reader, start=2):
            for c in ("t_s", "time_gap_true_s", "time_gap_displayed_s"):
                cols[c].append(_number(row[c] or "", path, line, c))
            for c in ("phase", "system", "warning"):
                cols[c].append((row[c] or "").strip())
    return TimeGapTrace.from_columns(cols, source=str(path))


def load_trace(path: str | Path) -> TimeGapTrace:
    """Load a trace by file type. CSV here; MCAP runs are converted by the caller (cosim.log reader)."""
    path = Path(path)
    if path.suffix.lower() == ".csv":
        return load_trace_csv(path)
    if path.suffix.lower() == ".mcap":
        from cosim.experiment.analysis import timegap_columns
        from cosim.log import read

        log = read(path, topics=["/adas/state"])
        if "/adas/state" not in log.topics:
            raise CosimError(f"{path} has no /adas/state topic: not a run with an ego and assistance systems")
        start = float(log.metadata.get("experiment", {}).get("start_s", 0.0))
        return TimeGapTrace.from_columns(timegap_columns(log, start), source=str(path))
    raise CosimError(f"cannot read a time-gap trace from {path}: expected timegap.csv or run.mcap")


@dataclass(frozen=True)
class CompareTolerances:
    """How close two traces must be. fpdiff-style: pass if within the absolute OR the relative tolerance."""

    rmse_abs_s: float = 0.02  # RMSE of a time gap [s]
    rmse_rel: float = 0.0  # ... or this fraction of the reference's RMS time gap [-]
    sample_abs_s: float = 0.1  # every aligned sample: |a - b| within this [s] ...
    sample_rel: float = 0.02  # ... or this fraction of |a| [-]
    band_share_abs: float = 0.01  # share of time in each time-gap band [-]
    warning_share_abs: float = 0.01  # share of time with an advisory / a warning shown [-]
    nodata_share_abs: float = 0.01  # share of time one trace displays a value and the other not [-]
    duration_abs_s: float = 0.2  # phase duration [s]

    def __post_init__(self) -> None:
        for name in (
            "rmse_abs_s",
            "rmse_rel",
            "sample_abs_s",
            "sample_rel",
            "band_share_abs",
            "warning_share_abs",
            "nodata_share_abs",
            "duration_abs_s",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value}")


@dataclass(frozen=True)
class Check:
    """One compared quantity: the values in A and B, the deviation and the tolerance it was held to."""

    metric: str
    a: str  # value in trace A, formatted ('' when the metric is a pairwise one)
    b: str  # value in trace B, formatted
    deviation: float  # NaN when there was nothing to compare
    tolerance: str  # formatted tolerance
    ok: bool


@dataclass(frozen=True)
class PhaseComparison:
    """The comparison of one phase."""

    phase: str
    system_a: str
    system_b: str
    n_grid: int  # samples on the common grid
    duration_a_s: float
    duration_b_s: float
    rmse_true_s: float  # NaN when nothing to compare
    max_dev_true_s: float
    rmse_displayed_s: float
    max_dev_displayed_s: float
    nodata_mismatch_share: float
    band_share_a: tuple[float, ...]  # per BANDS
    band_share_b: tuple[float, ...]
    warning_share_a: tuple[float, ...]  # per LEVELS
    warning_share_b: tuple[float, ...]
    checks: tuple[Check, ...]

    @property
    def ok(self) -> bool:
        return all(c.ok for c in self.checks)


@dataclass(frozen=True)
class CompareResult:
    """All phases; ``ok`` only when every check of every phase passed and no phase is missing."""

    phases: tuple[PhaseComparison, ...]
    missing_in_a: tuple[str, ...]
    missing_in_b: tuple[str, ...]
    tolerances: CompareTolerances
    source_a: str = "A"
    source_b: str = "B"

    @property
    def ok(self) -> bool:
        return not self.missing_in_a and not self.missing_in_b and all(p.ok for p in self.phases)

    def failures(self) -> list[str]:
        out = [f"phase {p!r} missing in {self.source_a}" for p in self.missing_in_a]
        out += [f"phase {p!r} missing in {self.source_b}" for p in self.missing_in_b]
        for ph in self.phases:
            for c in ph.checks:
                if not c.ok and c.deviation != c.deviation:
                    out.append(
                        f"{ph.phase}: {c.metric}: {c.a or '-'} vs {c.b or '-'} (expected {c.tolerance})"
                    )
                elif not c.ok:
                    out.append(f"{ph.phase}: {c.metric}: deviation {_fmt(c.deviation)} outside {c.tolerance}")
        return out

    def table(self) -> str:
        """A fixed-width text table of every check, then a verdict line."""
        head = ("phase", "metric", "A", "B", "deviation", "tolerance", "")
        rows = [head]
        for ph in self.phases:
            for c in ph.checks:
                rows.append(
                    (ph.phase, c.metric, c.a, c.b, _fmt(c.deviation), c.tolerance, "ok" if c.ok else "FAIL")
                )
        for p in self.missing_in_a:
            rows.append((p, "phase present", "no", "yes", "", "", "FAIL"))
        for p in self.missing_in_b:
            rows.append((p, "phase present", "yes", "no", "", "", "FAIL"))
        widths = [max(len(r[i]) for r in rows) for i in range(len(head))]
        lines = [f"A = {self.source_a}", f"B = {self.source_b}"]
        for k, r in enumerate(rows):
            lines.append("  ".join(cell.ljust(w) for cell, w in zip(r, widths, strict=True)).rstrip())
            if k == 0:
                lines.append("  ".join("-" * w for w in widths))
        n_fail = len(self.failures())
        lines.append(
            "OK: traces agree within tolerances" if self.ok else f"FAIL: {n_fail} check(s) outside tolerances"
        )
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()


def _fmt(x: float) -> str:
    return "-" if x != x else f"{x:.4g}"


def _interp(t: np.ndarray, v: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Linear interpolation that keeps NaN gaps: a grid point is NaN if a bracketing sample it uses is NaN."""
    if len(t) == 1:
        return np.full(len(grid), v[0], dtype=np.float64)
    i = np.clip(np.searchsorted(t, grid, side="right") - 1, 0, len(t) - 2)
    w = np.clip((grid - t[i]) / (t[i + 1] - t[i]), 0.0, 1.0)
    with np.errstate(invalid="ignore"):
        lin = v[i] + (v[i + 1] - v[i]) * w
    return np.where(w < _EPS, v[i], np.where(w > 1.0 - _EPS, v[i + 1], lin))


def _hold(t: np.ndarray, v: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Zero-order hold (the last sample at or before each grid point) for categorical columns."""
    if len(t) == 1:
        return np.full(len(grid), v[0], dtype=v.dtype)
    i = np.clip(
        np.searchsorted(t, grid + _EPS * max(1.0, abs(float(t[-1]))), side="right") - 1, 0, len(t) - 1
    )
    return v[i]


def _bands(tg: np.ndarray) -> tuple[float, ...]:
    n = len(tg)
    fin = np.isfinite(tg)
    safe = np.where(fin, tg, 0.0)
    counts = (
        np.count_nonzero(fin & (safe >= 3.0)),
        np.count_nonzero(fin & (safe >= 2.0) & (safe < 3.0)),
        np.count_nonzero(fin & (safe >= 1.0) & (safe < 2.0)),
        np.count_nonzero(fin & (safe < 1.0)),
        np.count_nonzero(~fin),
    )
    return tuple(c / n for c in counts)


def _deviation(
    a: np.ndarray, b: np.ndarray, tol: CompareTolerances
) -> tuple[float, float, int, float, float]:
    """(rmse, max |a-b|, samples outside the per-sample tolerance, RMS of a, RMS of b), finite in both."""
    both = np.isfinite(a) & np.isfinite(b)
    if not both.any():
        return math.nan, math.nan, 0, math.nan, math.nan
    d = np.abs(a[both] - b[both])
    outside = (d > tol.sample_abs_s + _EPS) & (d > tol.sample_rel * np.abs(a[both]) + _EPS)
    rmse = float(np.sqrt(np.mean(d * d)))
    rms_a, rms_b = (float(np.sqrt(np.mean(v[both] ** 2))) for v in (a, b))
    return rmse, float(d.max()), int(np.count_nonzero(outside)), rms_a, rms_b


def _compare_phase(
    name: str, a: TimeGapTrace, ia: np.ndarray, b: TimeGapTrace, ib: np.ndarray, tol: CompareTolerances
) -> PhaseComparison:
    ta, tb = a.t_s[ia], b.t_s[ib]
    step_a = float(np.median(np.diff(ta))) if len(ta) > 1 else a.step_s()
    step_b = float(np.median(np.diff(tb))) if len(tb) > 1 else b.step_s()
    dur_a, dur_b = float(ta[-1] - ta[0]) + step_a, float(tb[-1] - tb[0]) + step_b
    sys_a = "/".join(dict.fromkeys(a.system[ia]))
    sys_b = "/".join(dict.fromkeys(b.system[ib]))
    checks = [
        Check("system", sys_a, sys_b, math.nan, "equal", sys_a == sys_b),
        Check(
            "duration [s]",
            f"{dur_a:.4g}",
            f"{dur_b:.4g}",
            abs(dur_a - dur_b),
            f"abs {tol.duration_abs_s:g}",
            abs(dur_a - dur_b) <= tol.duration_abs_s + _EPS,
        ),
    ]
    start, end = max(ta[0], tb[0]), min(ta[-1], tb[-1])
    steps = [s for s in (step_a, step_b) if s > 0.0]
    dt = min(steps) if steps else 0.0
    if end < start - _EPS:
        checks.append(Check("common time span", "", "", math.nan, "overlap", False))
        grid = np.empty(0)
    elif dt == 0.0 or end - start < _EPS:
        grid = np.array([start])
    else:
        grid = start + dt * np.arange(int(math.floor((end - start) / dt + 1e-6)) + 1)
    nan = math.nan
    rmse_t = max_t = rmse_d = max_d = nan
    nodata = nan
    bands_a = bands_b = (nan,) * len(BANDS)
    warn_a = warn_b = (nan,) * len(LEVELS)
    if grid.size:
        true_a = _interp(ta, a.time_gap_true_s[ia], grid)
        true_b = _interp(tb, b.time_gap_true_s[ib], grid)
        disp_a = _interp(ta, a.time_gap_displayed_s[ia], grid)
        disp_b = _interp(tb, b.time_gap_displayed_s[ib], grid)
        lev_a = _hold(ta, a.warning[ia], grid)
        lev_b = _hold(tb, b.warning[ib], grid)
        for label, va, vb in (("true", true_a, true_b), ("displayed", disp_a, disp_b)):
            rmse, dmax, n_out, rms_ref, rms_b = _deviation(va, vb, tol)
            rmse_ok = rmse != rmse or rmse <= tol.rmse_abs_s + _EPS or rmse <= tol.rmse_rel * rms_ref
            checks.append(
                Check(
                    f"{label} gap RMSE [s]",
                    "" if rms_ref != rms_ref else f"RMS {_fmt(rms_ref)}",
                    "" if rms_b != rms_b else f"RMS {_fmt(rms_b)}",
                    rmse,
                    f"abs {tol.rmse_abs_s:g} | rel {tol.rmse_rel:g}",
                    rmse_ok,
                )
            )
            checks.append(
                Check(
                    f"{label} gap max dev [s]",
                    "",
                    f"{n_out} outside",
                    dmax,
                    f"abs {tol.sample_abs_s:g} | rel {tol.sample_rel:g}",
                    n_out == 0,
                )
            )
            if label == "true":
                rmse_t, max_t = rmse, dmax
            else:
                rmse_d, max_d = rmse, dmax
        nodata = float(np.mean(np.isfinite(disp_a) != np.isfinite(disp_b)))
        checks.append(
            Check(
                "no-data mismatch share",
                "",
                "",
                nodata,
                f"abs {tol.nodata_share_abs:g}",
                nodata <= tol.nodata_share_abs + _EPS,
            )
        )
        bands_a, bands_b = _bands(true_a), _bands(true_b)
        for band, sa, sb in zip(BANDS, bands_a, bands_b, strict=True):
            dev = abs(sa - sb)
            checks.append(
                Check(
                    f"share true gap {band}",
                    f"{sa:.4f}",
                    f"{sb:.4f}",
                    dev,
                    f"abs {tol.band_share_abs:g}",
                    dev <= tol.band_share_abs + _EPS,
                )
            )
        warn_a = tuple(float(np.mean(lev_a == lv)) for lv in LEVELS)
        warn_b = tuple(float(np.mean(lev_b == lv)) for lv in LEVELS)
        for k, lv in enumerate(LEVELS[1:], start=1):
            dev = abs(warn_a[k] - warn_b[k])
            checks.append(
                Check(
                    f"share {lv} shown",
                    f"{warn_a[k]:.4f}",
                    f"{warn_b[k]:.4f}",
                    dev,
                    f"abs {tol.warning_share_abs:g}",
                    dev <= tol.warning_share_abs + _EPS,
                )
            )
    return PhaseComparison(
        phase=name,
        system_a=sys_a,
        system_b=sys_b,
        n_grid=int(grid.size),
        duration_a_s=dur_a,
        duration_b_s=dur_b,
        rmse_true_s=rmse_t,
        max_dev_true_s=max_t,
        rmse_displayed_s=rmse_d,
        max_dev_displayed_s=max_d,
        nodata_mismatch_share=nodata,
        band_share_a=bands_a,
        band_share_b=bands_b,
        warning_share_a=warn_a,
        warning_share_b=warn_b,
        checks=tuple(checks),
    )


def _phase_rows(trace: TimeGapTrace) -> dict[str, np.ndarray]:
    """Phase name -> its row indices, in order of first appearance."""
    names = list(dict.fromkeys(trace.phase))
    return {n: np.flatnonzero(trace.phase == n) for n in names}


def compare_traces(
    a: TimeGapTrace, b: TimeGapTrace, tolerances: CompareTolerances | None = None
) -> CompareResult:
    """Compare trace B against the reference trace A, phase by phase."""
    tol = tolerances if tolerances is not None else CompareTolerances()
    rows_a, rows_b = _phase_rows(a), _phase_rows(b)
    phases = tuple(_compare_phase(n, a, rows_a[n], b, rows_b[n], tol) for n in rows_a if n in rows_b)
    return CompareResult(
        phases=phases,
        missing_in_a=tuple(n for n in rows_b if n not in rows_a),
        missing_in_b=tuple(n for n in rows_a if n not in rows_b),
        tolerances=tol,
        source_a=a.source or "trace A",
        source_b=b.source or "trace B",
    )


def compare_files(
    path_a: str | Path, path_b: str | Path, tolerances: CompareTolerances | None = None
) -> CompareResult:
    """Load two traces (see ``load_trace``) and compare them; A is the reference."""
    return compare_traces(load_trace(path_a), load_trace(path_b), tolerances)

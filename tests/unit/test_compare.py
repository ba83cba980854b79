"""Time-gap trace regression: alignment, per-phase RMSE / max deviation / band shares, tolerances, CSV."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from cosim.errors import CosimError
from cosim.experiment.compare import (
    BANDS,
    CompareTolerances,
    TimeGapTrace,
    compare_files,
    compare_traces,
    load_trace,
    load_trace_csv,
)

PHASES = (("baseline", "none"), ("rear", "A"), ("v2v", "B"))


def make_trace(fn=None, dt=0.1, phase_s=10.0, offset=0.0, shift_s=0.0, displayed=True, warning=None):
    """Three phases of ``phase_s`` seconds; true gap = fn(t - shift_s) + offset."""
    fn = fn or (lambda t: 2.5 + 1.5 * np.sin(0.3 * t))
    n = round(phase_s / dt)
    t = np.arange(3 * n) * dt
    phase = np.repeat([p for p, _ in PHASES], n)
    system = np.repeat([s for _, s in PHASES], n)
    true = fn(t - shift_s) + offset
    disp = np.where(system == "B", true, np.nan) if displayed else np.full(t.size, np.nan)
    if warning is None:
        warning = np.where(
            system == "B", np.where(true < 2.0, "warning", np.where(true < 3.0, "advisory", "none")), "none"
        )
    cols = dict(
        t_s=t, phase=phase, system=system, time_gap_true_s=true, time_gap_displayed_s=disp, warning=warning
    )
    return TimeGapTrace.from_columns(cols)


def phase(result, name):
    return next(p for p in result.phases if p.phase == name)


def test_identical_traces_are_ok():
    a = make_trace()
    res = compare_traces(a, make_trace())
    assert res.ok and not res.failures()
    assert [p.phase for p in res.phases] == ["baseline", "rear", "v2v"]
    for p in res.phases:
        assert p.rmse_true_s == 0.0 and p.max_dev_true_s == 0.0 and p.n_grid == 100
        assert p.band_share_a == p.band_share_b and sum(p.band_share_a) == pytest.approx(1.0)
    assert phase(res, "v2v").rmse_displayed_s == 0.0
    assert math.isnan(phase(res, "baseline").rmse_displayed_s)  # nothing displayed in either
    table = res.table()
    assert "OK: traces agree" in table and "FAIL" not in table
    assert "share true gap 2-3s" in table


def test_value_offset_fails_with_the_offset_as_rmse():
    res = compare_traces(make_trace(), make_trace(offset=0.3))
    assert not res.ok
    for p in res.phases:
        assert p.rmse_true_s == pytest.approx(0.3) and p.max_dev_true_s == pytest.approx(0.3)
    assert phase(res, "v2v").rmse_displayed_s == pytest.approx(0.3)
    assert any("true gap RMSE" in f for f in res.failures())
    assert "FAIL" in res.table()


def test_time_shift_of_a_ramp_gives_slope_times_shift():
    ramp = lambda t: 1.0 + 0.1 * t  # noqa: E731
    res = compare_traces(make_trace(ramp, displayed=False), make_trace(ramp, shift_s=0.5, displayed=False))
    for p in res.phases:
        assert p.rmse_true_s == pytest.approx(0.05) and p.max_dev_true_s == pytest.approx(0.05)
    # 0.05 s is inside the default per-sample tolerance (0.1 s) but outside the RMSE tolerance (0.02 s)
    assert not res.ok
    assert all(("RMSE" in f) or ("share" in f) for f in res.failures())
    loose = CompareTolerances(rmse_abs_s=0.05, band_share_abs=0.1, warning_share_abs=0.1)
    assert compare_traces(make_trace(ramp), make_trace(ramp, shift_s=0.5), loose).ok


def test_tolerance_edges():
    a, b = make_trace(displayed=False), make_trace(offset=0.25, displayed=False)
    at_edge = CompareTolerances(
        rmse_abs_s=0.25, sample_abs_s=0.25, sample_rel=0.0, band_share_abs=1.0, warning_share_abs=1.0
    )
    assert compare_traces(a, b, at_edge).ok
    above = CompareTolerances(
        rmse_abs_s=0.2499, sample_abs_s=0.25, sample_rel=0.0, band_share_abs=1.0, warning_share_abs=1.0
    )
    assert not compare_traces(a, b, above).ok
    samples_only = CompareTolerances(
        rmse_abs_s=0.25, sample_abs_s=0.2499, sample_rel=0.0, band_share_abs=1.0, warning_share_abs=1.0
    )
    res = compare_traces(a, b, samples_only)
    assert not res.ok and all("max dev" in f for f in res.failures())


def test_relative_tolerance_is_fpdiff_style_or():
    const = lambda v: lambda t: np.full_like(t, v)  # noqa: E731
    a, b = make_trace(const(8.0), displayed=False), make_trace(const(8.12), displayed=False)
    # 0.12 s deviation: outside abs 0.1 but within 2 % of 8 s (0.16 s); RMSE 0.12 within 2 % of RMS 8
    tol = CompareTolerances(rmse_abs_s=0.0, rmse_rel=0.02, sample_abs_s=0.1, sample_rel=0.02)
    assert compare_traces(a, b, tol).ok
    assert not compare_traces(a, b, CompareTolerances(rmse_abs_s=0.0, rmse_rel=0.01, sample_rel=0.01)).ok
    # relative to the reference (A): with small values the relative part does not help
    a2, b2 = make_trace(const(1.0), displayed=False), make_trace(const(1.12), displayed=False)
    assert not compare_traces(a2, b2, tol).ok


def test_interpolation_onto_a_common_grid():
    ramp = lambda t: 1.0 + 0.1 * t  # noqa: E731
    fine, coarse = make_trace(ramp, dt=0.1), make_trace(ramp, dt=0.2)
    res = compare_traces(fine, coarse)
    assert res.ok
    for p in res.phases:
        assert p.rmse_true_s == pytest.approx(0.0, abs=1e-12)
        assert p.n_grid == 99  # 0.1-s grid over the overlap (the coarse trace ends 0.1 s earlier)


def test_band_shares_and_their_difference():
    steady = lambda t: np.full_like(t, 2.5)  # noqa: E731
    half = lambda t: np.where((t % 10.0) < 5.0, 2.5, 0.5)  # noqa: E731
    res = compare_traces(make_trace(steady, displayed=False), make_trace(half, displayed=False))
    p = phase(res, "baseline")
    assert dict(zip(BANDS, p.band_share_a, strict=True)) == {
        ">=3s": 0,
        "2-3s": 1,
        "1-2s": 0,
        "<1s": 0,
        "n/a": 0,
    }
    b = dict(zip(BANDS, p.band_share_b, strict=True))
    assert b["2-3s"] == pytest.approx(0.5) and b["<1s"] == pytest.approx(0.5)
    assert not res.ok
    assert any("share true gap <1s" in f for f in res.failures())
    # exact band edges: 3.0 is in >=3s, 2.0 in 2-3s, 1.0 in 1-2s; NaN counts as n/a
    edges = lambda t: np.select([t < 7.5, t < 15, t < 22.5], [3.0, 2.0, 1.0], np.nan)  # noqa: E731
    r = compare_traces(
        make_trace(edges, phase_s=30.0, displayed=False), make_trace(edges, phase_s=30.0, displayed=False)
    )
    shares = dict(zip(BANDS, r.phases[0].band_share_a, strict=True))
    assert shares == {">=3s": 0.25, "2-3s": 0.25, "1-2s": 0.25, "<1s": 0.0, "n/a": 0.25}


def test_warning_shares():
    a = make_trace()
    warn = np.where(np.arange(300) % 4 == 0, "warning", "none")
    res = compare_traces(a, make_trace(warning=warn))
    assert not res.ok
    assert phase(res, "baseline").warning_share_b[2] == pytest.approx(0.25)
    assert any("share warning shown" in f for f in res.failures())


def test_no_data_mismatch():
    a = make_trace()
    b_cols = {
        k: getattr(make_trace(), k).copy() for k in ("t_s", "phase", "system", "time_gap_true_s", "warning")
    }
    disp = make_trace().time_gap_displayed_s.copy()
    disp[200:210] = np.nan  # B shows "no data" for 1 s of its 10-s v2v phase
    b = TimeGapTrace.from_columns({**b_cols, "time_gap_displayed_s": disp})
    res = compare_traces(a, b)
    assert phase(res, "v2v").nodata_mismatch_share == pytest.approx(0.1)
    assert phase(res, "v2v").rmse_displayed_s == pytest.approx(0.0)
    assert not res.ok and res.failures() == [f for f in res.failures() if "v2v" in f]
    assert compare_traces(a, b, CompareTolerances(nodata_share_abs=0.1)).ok


def test_missing_phase_system_and_duration_mismatch():
    a = make_trace()
    cut = {
        k: getattr(a, k)[:250]
        for k in ("t_s", "phase", "system", "time_gap_true_s", "time_gap_displayed_s", "warning")
    }
    res = compare_traces(a, TimeGapTrace.from_columns(cut))
    assert not res.ok
    assert any("duration" in f and "v2v" in f for f in res.failures())
    only_two = {k: v[:200] for k, v in cut.items()}
    res = compare_traces(a, TimeGapTrace.from_columns(only_two))
    assert res.missing_in_b == ("v2v",) and not res.ok
    swapped = {k: getattr(a, k) for k in cut}
    swapped["system"] = np.where(a.system == "A", "B", np.where(a.system == "B", "A", a.system))
    res = compare_traces(a, TimeGapTrace.from_columns(swapped))
    assert {f.split(":")[0] for f in res.failures()} >= {"rear", "v2v"}


def _write_csv(path, trace, warning_as_bool=False):
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t_s", "phase", "system", "time_gap_true_s", "time_gap_displayed_s", "warning", "extra"])
        for i in range(len(trace.t_s)):
            disp = trace.time_gap_displayed_s[i]
            warn = int(trace.warning[i] == "warning") if warning_as_bool else trace.warning[i]
            w.writerow(
                [
                    f"{trace.t_s[i]:.3f}",
                    trace.phase[i],
                    trace.system[i],
                    f"{trace.time_gap_true_s[i]:.6f}",
                    "" if np.isnan(disp) else f"{disp:.6f}",
                    warn,
                    "x",
                ]
            )


def test_csv_round_trip_and_compare_files(tmp_path):
    a = make_trace()
    pa, pb = tmp_path / "a.csv", tmp_path / "b.csv"
    _write_csv(pa, a)
    _write_csv(pb, make_trace(offset=0.5))
    loaded = load_trace(pa)
    assert loaded.source == str(pa)
    np.testing.assert_allclose(loaded.time_gap_true_s, a.time_gap_true_s, atol=1e-6)
    assert np.array_equal(np.isnan(loaded.time_gap_displayed_s), np.isnan(a.time_gap_displayed_s))
    assert list(loaded.warning) == list(a.warning)
    assert compare_files(pa, pa).ok
    res = compare_files(pa, pb)
    assert not res.ok and str(pa) in res.table() and str(pb) in res.table()
    assert phase(res, "rear").rmse_true_s == pytest.approx(0.5, abs=1e-6)
    pc = tmp_path / "c.csv"
    _write_csv(
        pc, make_trace(warning=np.where(np.arange(300) % 3 == 0, "warning", "none")), warning_as_bool=True
    )
    assert set(load_trace_csv(pc).warning) == {"none", "warning"}


def test_csv_errors(tmp_path):
    with pytest.raises(CosimError, match="does not exist"):
        load_trace_csv(tmp_path / "nope.csv")
    with pytest.raises(CosimError, match="expected timegap.csv or run.mcap"):
        load_trace(tmp_path / "run.json")
    p = tmp_path / "bad.csv"
    p.write_text("t_s,phase,system,time_gap_true_s,warning\n0,b,none,1.0,none\n")
    with pytest.raises(CosimError, match="missing column.*time_gap_displayed_s"):
        load_trace_csv(p)
    p.write_text("t_s,phase,system,time_gap_true_s,time_gap_displayed_s,warning\n0,b,none,fast,,none\n")
    with pytest.raises(CosimError, match=r"bad.csv:2: column time_gap_true_s"):
        load_trace_csv(p)
    p.write_text(
        "t_s,phase,system,time_gap_true_s,time_gap_displayed_s,warning\n0,b,none,1,,none\n0,b,none,1,,none\n"
    )
    with pytest.raises(CosimError, match="not strictly increasing"):
        load_trace_csv(p)
    p.write_text("t_s,phase,system,time_gap_true_s,time_gap_displayed_s,warning\n0,b,none,1,,loud\n")
    with pytest.raises(CosimError, match="warning value"):
        load_trace_csv(p)
    p.write_text("t_s,phase,system,time_gap_true_s,time_gap_displayed_s,warning\n")
    with pytest.raises(CosimError, match="no rows"):
        load_trace_csv(p)


def test_tolerance_validation():
    with pytest.raises(ValueError, match="rmse_abs_s"):
        CompareTolerances(rmse_abs_s=-1.0)
    with pytest.raises(ValueError, match="sample_rel"):
        CompareTolerances(sample_rel=float("nan"))


def test_deterministic_output():
    a, b = make_trace(), make_trace(offset=0.1, shift_s=0.3)
    assert compare_traces(a, b).table() == compare_traces(a, b).table()

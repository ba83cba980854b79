"""The libsumo-scripted study in examples/ runs as a script and prints its three windows."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from testpaths import shared_map

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "libsumo_study.py"


@pytest.mark.slow
def test_libsumo_study_runs_and_reports_each_window():
    proc = subprocess.run([sys.executable, str(EXAMPLE), "--map", str(shared_map("munich")), "--window", "10"],
                          capture_output=True, text=True, timeout=120, env=os.environ.copy())  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout.splitlines()
    assert out[0].startswith("t = 10 s:") and "studying light" in out[0]
    header = out[1].split()
    assert header == ["window", "mean_speed_kmh", "halted_at_light_max", "pdr", "pdr_0_100m", "channel_busy",
                      "receptions"]  # fmt: skip
    rows = {}
    for line in out[2:]:
        if line.startswith("simulated"):
            break
        cells = line.rsplit(None, 6)
        rows[cells[0].strip()] = dict(zip(header[1:], cells[1:], strict=True))
    assert list(rows) == ["before", "forced red", "after"]
    for r in rows.values():
        assert 0.0 < float(r["mean_speed_kmh"]) < 120.0
        assert 0.0 < float(r["pdr"]) <= 1.0 and 0.0 < float(r["channel_busy"]) < 1.0  # the radio is on
    assert int(rows["forced red"]["halted_at_light_max"]) > 0  # the red light holds traffic
    assert out[-1].startswith("simulated 40 s")
    # (its speed is a benchmark's business, not a test's: under a loaded machine it took 55 s)

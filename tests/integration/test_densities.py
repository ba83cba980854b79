"""600 s of each shipped density on the default map: the traffic flows, teleports stay a small share."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cosim.scenario import build_scenario
from cosim.scenario.check import check_scenario
from cosim.scenario.demand import DENSITY_NAMES

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("density", DENSITY_NAMES)
def test_600s_of_each_density_on_the_default_map(tmp_path, density):
    scn = build_scenario(ROOT / "configs" / "maps" / "krems.osm.gz", tmp_path / density, density=density, seed=1,
                         log=lambda *a: None)  # fmt: skip
    result = check_scenario(scn.dir, 600.0)
    assert (
        json.loads((scn.dir / "report.json").read_text())["check"] == result
    )  # the report shows the numbers
    assert result["departed"] > 100
    assert result["teleport_share"] < 0.05, result
    assert result["arrived"] > 0.1 * result["departed"]

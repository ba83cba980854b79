"""Where the background traffic is placed: the whole network of a town, the ego's route through a city
(``DemandParams.area`` "auto", ``LARGE_NETWORK_LANE_KM``)."""

from __future__ import annotations

import pytest
from osm_factory import crossroads

from cosim.scenario import build_scenario
from cosim.scenario import demand as demand_module
from cosim.scenario.build import ScenarioConfig
from cosim.scenario.demand import DemandParams

# a seed each: the scenario cache's key does not hold the threshold (a constant)
CASES = [
    ("auto", 400.0, "network", 1),  # a town: filled whole
    ("auto", 0.5, "ego_route", 2),  # a "city" (the threshold below this map's 3.5 lane-km): along the route
    ("network", 0.5, "network", 3),  # asked for: filled whole all the same
]


@pytest.mark.parametrize("area, large_lane_km, placed, seed", CASES)
def test_auto_fills_a_town_and_keeps_a_citys_traffic_along_the_egos_route(
    tmp_path, monkeypatch, area, large_lane_km, placed, seed
):
    monkeypatch.setattr(demand_module, "LARGE_NETWORK_LANE_KM", large_lane_km)
    osm = crossroads(arm_m=300.0).write(tmp_path / "x.osm")
    lines: list[str] = []
    config = ScenarioConfig(map=str(osm), demand=DemandParams(area=area))
    scn = build_scenario(osm, tmp_path / "scn", seed=seed, config=config, log=lines.append)
    d = scn.report["demand"]
    assert d["area"] == placed
    assert ("along the ego's route" in "\n".join(lines)) == (placed == "ego_route")

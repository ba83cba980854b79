"""Full builds of the real OSM extracts in ../shared/data/osm with plausible counts."""

from __future__ import annotations

import pytest
from testpaths import shared_map

from cosim.scenario import build_scenario


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    out = {}
    for name in ("munich", "krems", "helsinki"):
        scn = build_scenario(
            shared_map(name), tmp_path_factory.mktemp(name), density="low", seed=1, log=lambda *a: None
        )
        out[name] = scn.report
    return out


def test_krems_has_stop_junctions_and_city_limits(reports):
    r = reports["krems"]
    assert r["network"]["stop_junctions"] >= 10  # 17 stop nodes in OSM, some at signalised junctions
    assert r["signs"]["stop"] >= 10
    assert r["signs"]["city_limit"] >= 10
    assert r["network"]["traffic_lights"] >= 8
    assert r["buildings"]["count"] > 1000


def test_munich_has_turn_lanes_and_traffic_lights(reports):
    r = reports["munich"]
    assert r["network"]["turn_lane_connections"] >= 50
    assert r["network"]["traffic_lights"] >= 4
    assert r["signs"]["traffic_light"] >= 10
    assert r["buildings"]["height_from"]["levels"] > 100  # building:levels x 3 m


def test_helsinki_has_yield_junctions_and_signals(reports):
    r = reports["helsinki"]
    assert r["network"]["yield_junctions"] >= 10
    assert r["network"]["traffic_lights"] >= 30
    assert r["network"]["turn_lane_connections"] > 50


@pytest.mark.parametrize("name", ["munich", "krems", "helsinki"])
def test_every_map_has_traffic_and_signs(reports, name):
    r = reports[name]
    assert r["demand"]["initial_vehicles"] > 20
    assert r["demand"]["vehicles"] > r["demand"]["initial_vehicles"]
    assert r["signs"]["speed_limit"] > 0 and r["signs"]["one_way"] > 0
    assert r["network"]["junctions"] > 100


def test_second_build_reuses_network_and_route_table(tmp_path):
    osm = shared_map("munich")
    first = build_scenario(osm, tmp_path / "a", density="low", seed=11, log=lambda *a: None).report
    again = build_scenario(osm, tmp_path / "b", density="low", seed=11, log=lambda *a: None).report
    assert again["scenario_cache"] == "hit"
    other = build_scenario(osm, tmp_path / "c", density="medium", seed=11, log=lambda *a: None).report
    assert other["cache"]["network"] == "hit"  # netconvert not run again
    assert other["demand"]["routes_from_table"] > 0
    assert first["cache"]["network_key"] == other["cache"]["network_key"]

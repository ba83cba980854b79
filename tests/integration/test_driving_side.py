"""Left-hand traffic where the extract lies in a left-hand-traffic country (cosim.scenario.driving_side)."""

from __future__ import annotations

import dataclasses
import math
import re
import xml.etree.ElementTree as ET

import pytest
import sumolib
from fake_net import Conn, Edge
from osm_factory import OsmSketch, crossroads
from testpaths import ROOT

from cosim.scenario import build_scenario
from cosim.scenario.build import ScenarioConfig
from cosim.scenario.driving_side import resolve
from cosim.scenario.network import turn_lane_deletions
from cosim.sumo_bridge.network import read_network

CAMBRIDGE_UK = (52.2053, 0.1218)


@pytest.mark.parametrize(
    ("centre", "left", "country"),
    [
        ((57.15, -2.10), True, "GB"),  # Aberdeen
        ((49.20, -2.10), True, "JE"),  # Jersey ...
        ((49.64, -1.62), False, "FR"),  # ... and Cherbourg, 50 km away
        ((36.14, -5.35), False, "GI"),  # Gibraltar drives on the right
        ((22.30, 114.17), True, "HK"),  # Hong Kong ...
        ((22.55, 114.05), False, "CN"),  # ... and Shenzhen across the border
        ((35.68, 139.70), True, "JP"),
        ((13.75, 100.50), True, "TH"),  # Bangkok ...
        ((11.55, 104.90), False, "KH"),  # ... and Phnom Penh
        ((-26.20, 28.00), True, "ZA"),
        ((6.80, -58.16), True, "GY"),  # Georgetown, Guyana, in right-hand South America
        ((48.41, 15.60), False, "AT"),  # Krems
    ],
)
def test_auto_finds_the_side_from_the_country(centre, left, country):
    is_left, how = resolve("auto", centre)
    assert is_left is left and country in how, how


def test_no_country_and_explicit_settings():
    left, how = resolve("auto", (45.0, -30.0))  # mid-Atlantic
    assert left is False and "set scenario.driving_side" in how
    assert resolve("left", (48.4, 15.6))[0] is True
    assert resolve("right", (57.15, -2.10))[0] is False
    with pytest.raises(ValueError, match="driving_side"):
        resolve("middle", (0.0, 0.0))


def _build(sketch: OsmSketch, tmp_path, name: str, **config):
    osm = sketch.write(tmp_path / f"{name}.osm")
    cfg = dataclasses.replace(ScenarioConfig(map=str(osm)), **config)
    return build_scenario(osm, tmp_path / f"{name}-scn", config=cfg, seed=1, log=lambda *a: None)


def _eastbound_lane_y(scn, sketch: OsmSketch) -> float:
    """How far the lanes of the major road's eastbound edge into the junction lie left of the road's axis
    (from node w to node c) [m]; the network's projection turns the axis a few degrees off its x."""
    net = sumolib.net.readNet(str(scn.net_file))
    w, c = sketch.ids["w"], sketch.ids["c"]
    edge = next(e for e in net.getEdges() if e.getFromNode().getID() == w and e.getToNode().getID() == c)
    (x0, y0), (x1, y1) = net.getNode(w).getCoord()[:2], net.getNode(c).getCoord()[:2]
    ux, uy = (x1 - x0) / math.hypot(x1 - x0, y1 - y0), (y1 - y0) / math.hypot(x1 - x0, y1 - y0)
    offs = [ux * (p[1] - y0) - uy * (p[0] - x0) for lane in edge.getLanes() for p in lane.getShape()]
    return sum(offs) / len(offs)


def test_a_town_in_the_uk_keeps_left_and_one_in_germany_right(tmp_path):
    uk_map, de_map = crossroads(origin=CAMBRIDGE_UK), crossroads()
    uk, de = _build(uk_map, tmp_path, "uk"), _build(de_map, tmp_path, "de")
    assert uk.report["network"]["driving_side"].startswith("left (GB"), uk.report["network"]["driving_side"]
    assert de.report["network"]["driving_side"].startswith("right (DE"), de.report["network"]["driving_side"]
    assert ET.parse(uk.net_file).getroot().get("lefthand") == "true"
    assert ET.parse(de.net_file).getroot().get("lefthand") is None
    assert read_network(uk.net_file).lefthand and not read_network(de.net_file).lefthand
    # the eastbound lanes lie left of the road's axis in the UK, right of it in Germany
    assert _eastbound_lane_y(uk, uk_map) > 0.5 and _eastbound_lane_y(de, de_map) < -0.5
    # the setting overrides where the extract lies
    forced = _build(de_map, tmp_path, "de-left", driving_side="left")
    assert forced.report["network"]["driving_side"] == "left (scenario.driving_side)"
    assert _eastbound_lane_y(forced, de_map) > 0.5


def test_turn_lane_arrows_are_read_from_the_kerb_side():
    """OSM lists lanes left to right; SUMO counts them from the kerb: lane 0 is the right lane in right-hand
    traffic, the left one in left-hand traffic. "left|through" lets the left turn go from OSM's first lane."""
    approach, left_road, ahead = (
        Edge.straight(eid, 0.0, 100.0, n) for eid, n in (("in", 2), ("left", 1), ("ahead", 2))
    )
    approach.params["turn:lanes"] = "left|through"
    approach.out = {
        left_road: [Conn(approach.lanes[i], left_road.lanes[0], direction="l") for i in (0, 1)],
        ahead: [Conn(approach.lanes[i], ahead.lanes[i], direction="s") for i in (0, 1)],
    }

    def deleted(lefthand):
        lines = turn_lane_deletions(approach, lefthand)
        return sorted(
            (re.search(r'to="([^"]+)"', x)[1], int(re.search(r'fromLane="(\d+)"', x)[1])) for x in lines
        )

    # right-hand traffic: OSM's left lane is SUMO's lane 1, so lane 1 turns left and lane 0 goes straight
    assert deleted(False) == [("ahead", 1), ("left", 0)]
    # left-hand traffic: OSM's left lane is SUMO's lane 0
    assert deleted(True) == [("ahead", 0), ("left", 1)]


def test_the_shipped_uk_map_is_built_for_left_hand_traffic():
    scn = build_scenario(ROOT / "configs" / "maps" / "aberdeen.osm.gz", seed=1, log=lambda *a: None)
    assert scn.report["network"]["driving_side"].startswith("left (GB"), scn.report["network"]["driving_side"]
    assert ET.parse(scn.net_file).getroot().get("lefthand") == "true"


def test_the_turn_across_the_oncoming_lanes_yields_on_either_side():
    """Where two paths come too close, the lower-ranked movement yields (cosim.scenario.conflicts): the turn
    across the oncoming lanes ranks below the kerb-side turn: left in right-hand traffic, right in
    left-hand traffic."""
    from cosim.scenario.conflicts import _Conn, _rank

    def rank(direction, lefthand):
        return _rank(_Conn("a", "a_0", "b", "b_0", direction, "m", [], lefthand))

    assert rank("r", False) < rank("l", False)
    assert rank("l", True) < rank("r", True)
    assert rank("s", True) < rank("l", True) and rank("r", True) < rank("t", True)


def test_the_3d_view_seats_the_driver_on_the_right_where_traffic_keeps_left(tmp_path):
    import mujoco

    from cosim.world3d.scene import build_scene

    uk = _build(crossroads(origin=CAMBRIDGE_UK), tmp_path, "uk")
    de = _build(crossroads(), tmp_path, "de")

    def eye_y(scn):
        m = build_scene(scn).model
        return float(m.cam_pos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, "driver")][1])

    assert eye_y(uk) < 0 < eye_y(de)  # y: to the car's left


def test_an_extract_across_the_antimeridian_is_placed_by_its_own_middle(tmp_path):
    """Taveuni (Fiji) straddles 180 degrees: its nodes' longitudes run 179.8..180 and -180..-179.9; the
    middle of -180..180 would be 0 (the Gulf of Guinea), Fiji keeps left."""
    from cosim.scenario.osm import read_osm

    osm = tmp_path / "taveuni.osm"
    nodes = [(-16.80, 179.85), (-16.85, 179.99), (-16.90, -179.95), (-16.95, -179.92)]
    body = "".join(f'<node id="{i + 1}" lat="{lat}" lon="{lon}"/>' for i, (lat, lon) in enumerate(nodes))
    refs = "".join(f'<nd ref="{i + 1}"/>' for i in range(len(nodes)))
    osm.write_text(f'<osm version="0.6">{body}<way id="9">{refs}<tag k="highway" v="primary"/></way></osm>')
    lat, lon = read_osm(osm).centre
    assert lat == pytest.approx(-16.875) and (lon > 179.9 or lon < -179.9), lon
    left, how = resolve("auto", (lat, lon))
    assert left and "FJ" in how, how

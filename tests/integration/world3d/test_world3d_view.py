"""The generated scene rendered offscreen (EGL): what appears where, lamps, the vehicle pool, the big map."""

from __future__ import annotations

import math
import os
import time
from pathlib import Path

import mujoco
import numpy as np
import pytest
import sumolib
from conftest import BUILDING_HEIGHT_M
from PIL import Image
from testpaths import shared_map

from cosim.scenario.buildings import load_buildings
from cosim.world3d.render import View, ViewParams
from cosim.world3d.scene import HIDDEN_GROUP, SceneParams, build_scene
from cosim.world3d.state import EgoPose, FrameState, VehicleFrame

W, H = 480, 480  # top views
TOP_M = 120.0  # [m] the top view shows 120 m x 120 m: 0.25 m per pixel
OUT = Path(os.environ["COSIM_TEST_IMAGES"]) if os.environ.get("COSIM_TEST_IMAGES") else None  # keep pictures


@pytest.fixture(scope="module")
def world(gl, small_scenario):
    scn, _, _ = small_scenario
    scene = build_scene(scn, SceneParams(vehicle_pool=3, max_width=640, max_height=480))
    net = sumolib.net.readNet(str(scn.net_file))
    polys, heights = load_buildings(scn.buildings_file)
    return scene, net, polys[0], heights[0]


def junction(net) -> np.ndarray:
    return np.array(next(n for n in net.getNodes() if n.getType() == "traffic_light").getCoord()[:2])


def west_lane_point(net, back_m: float) -> tuple[float, float, float]:
    """A point ``back_m`` before the junction on the rightmost lane coming from the west, and its yaw."""
    jx = junction(net)[0]
    edge = next(
        e
        for e in net.getEdges()
        if e.getToNode().getType() == "traffic_light" and e.getFromNode().getCoord()[0] < jx - 100
    )
    shape = np.array([p[:2] for p in edge.getLane(0).getShape()])
    seg = np.hypot(*np.diff(shape, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    at = s[-1] - back_m
    x, y = np.interp(at, s, shape[:, 0]), np.interp(at, s, shape[:, 1])
    d = shape[-1] - shape[-2]
    return float(x), float(y), math.atan2(d[1], d[0])


def pixel(centre: np.ndarray, xy) -> tuple[int, int]:
    """Row, column of a network point in a north-up top view centred on ``centre``."""
    m_per_px = TOP_M / H
    return int(round(H / 2 - (xy[1] - centre[1]) / m_per_px)), int(
        round(W / 2 + (xy[0] - centre[0]) / m_per_px)
    )


def patch(img: np.ndarray, rc: tuple[int, int], r: int = 3) -> np.ndarray:
    return img[rc[0] - r : rc[0] + r + 1, rc[1] - r : rc[1] + r + 1].reshape(
        -1, img.shape[-1] if img.ndim == 3 else 1
    )


def geom_name(scene, gid: int) -> str:
    return "sky" if gid < 0 else mujoco.mj_id2name(scene.model, mujoco.mjtObj.mjOBJ_GEOM, gid)


def test_top_view_has_road_building_and_grass_where_the_map_has_them(world):
    scene, net, building, _ = world
    c = junction(net)
    frame = FrameState(
        0.0, EgoPose(c[0] - 200.0, c[1], 0.0)
    )  # ego out of the picture: centre on the junction
    view = View(scene, ViewParams(W, H, "top", hud=False, top_view_m=TOP_M))
    view.camera("top")
    scene.apply(frame)
    # the top camera follows the ego; move it to the junction for this picture
    scene.data.mocap_pos[scene.model.body("ego").mocapid[0]][:2] = c - scene.origin_xy
    img = view.render()
    seg = view.segmentation()
    Image.fromarray(img).save(OUT / "top_view.png") if OUT else None
    assert img.std() > 15  # not blank
    b = np.array(building.centroid.coords[0])
    road = np.array(west_lane_point(net, 35.0)[:2])
    grass = c + (-40.0, 40.0)  # north-west quadrant: away from both roads and the building
    rgb = {
        k: patch(img, pixel(c, p)).astype(float).mean(axis=0)
        for k, p in (("roof", b), ("road", road), ("grass", grass))
    }
    r, g, bl = rgb["roof"]
    assert r > g + 25 and r > bl + 25, rgb  # red-brown roof
    assert np.ptp(rgb["road"]) < 20 and 40 < rgb["road"].mean() < 140, rgb  # grey asphalt
    r, g, bl = rgb["grass"]
    assert g > r + 10 and g > bl + 20, rgb  # green
    names = {k: {geom_name(scene, i) for i in patch(seg, pixel(c, p)).ravel()} for k, p in
             (("roof", b), ("road", road), ("grass", grass))}  # fmt: skip
    assert names == {"roof": {"roofs"}, "road": {"roads"}, "grass": {"ground"}}
    view.close()


def test_driver_view_sees_the_road_ahead_and_the_building_ahead_left(world):
    scene, net, building, height = world
    x, y, yaw = west_lane_point(net, 60.0)
    view = View(scene, ViewParams(480, 270, "driver", hud=False))
    img = view.render(FrameState(0.0, EgoPose(x, y, yaw)))
    seg = view.segmentation()
    names = np.vectorize(lambda i: geom_name(scene, int(i)))(seg)
    walls = np.char.startswith(names.astype(str), "walls")
    left, right = walls[:, :240].sum(), walls[:, 240:].sum()
    assert left > 500 and right < left / 5, (left, right)  # the building is ahead on the left
    rows = np.flatnonzero(walls.any(axis=1))
    horizon = 135 - 0.03 / math.tan(math.radians(25.0)) * 135  # the camera looks 0.03 rad down (fovy 50 deg)
    assert rows.min() < horizon - 25 and rows.max() > horizon  # 15 m tall, 80-100 m away: its base below
    Image.fromarray(img).save(OUT / "driver_view.png") if OUT else None
    # the road ahead: the lower-middle band (above the dashboard) is asphalt
    band = names[150:170, 200:280]
    assert (band == "roads").mean() > 0.8, np.unique(band, return_counts=True)
    sky = img[5:15, 200:280].reshape(-1, 3).astype(float).mean(axis=0)
    assert sky[2] > sky[0] + 20 and (names[0:10] == "sky").all()  # blue sky at the top
    assert (names[260:270, 200:280] == "ego_dark").all()  # the dashboard at the bottom
    assert height == BUILDING_HEIGHT_M
    view.close()


def test_lamps_follow_the_traffic_light_state(world):
    scene, net, _, _ = world
    tls = net.getTrafficLights()[0]
    n_links = 1 + max(c[2] for c in tls.getConnections())
    assert len(scene.approaches) == 4  # one lamp per signalised approach (4 arms)
    lamps = [mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_GEOM, f"lamp{i}") for i in range(4)]
    z = {}
    for state, colour in (("G", "g"), ("y", "y"), ("r", "r")):
        scene.apply(FrameState(0.0, None, lights={tls.getID(): state * n_links}))
        assert scene.lamp_states() == [colour] * 4
        rgba = scene.model.geom_rgba[lamps]
        assert np.all(rgba[:, {"g": 1, "y": 0, "r": 0}[colour]] >= 0.99)
        assert np.all(scene.model.geom_group[lamps] == 0)
        z[colour] = scene.data.geom_xpos[lamps, 2].copy()
    assert np.all(z["r"] > z["y"]) and np.all(z["y"] > z["g"])  # red on top, green at the bottom
    mixed = "".join("G" if i % 2 else "r" for i in range(n_links))
    scene.apply(FrameState(0.0, None, lights={tls.getID(): mixed}))
    assert [
        s == ("g" if mixed[a.link_index] == "G" else "r")
        for s, a in zip(scene.lamp_states(), scene.approaches, strict=True)
    ] == [True] * 4
    scene.apply(FrameState(0.0, None, lights={tls.getID(): "O" * n_links}))
    assert scene.lamp_states() == [None] * 4 and np.all(scene.model.geom_group[lamps] == HIDDEN_GROUP)


def test_vehicle_pool_shows_the_nearest_cars_and_the_leaders_display(world):
    scene, net, _, _ = world
    x, y, yaw = west_lane_point(net, 80.0)
    ux, uy = math.cos(yaw), math.sin(yaw)
    ahead = [10.0, 60.0, 25.0, 40.0]  # pool of 3: the car 60 m ahead is not shown
    ids = ("lead", "far", "b", "c")
    veh = VehicleFrame(
        ids, [x + d * ux for d in ahead], [y + d * uy for d in ahead], [yaw] * 4, [True, False, False, False]
    )
    body = [mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_GEOM, f"car{i}_body") for i in range(3)]
    display = mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_GEOM, "rear_display")
    scene.apply(FrameState(0.0, EgoPose(x, y, yaw), veh, leader_id="lead", rear_display_lit=True))
    shown = sorted(
        round(
            float(np.hypot(*(scene.data.xpos[scene.model.geom_bodyid[g], :2] + scene.origin_xy - (x, y)))), 1
        )
        for g in body
    )
    assert shown == [10.0, 25.0, 40.0]
    assert np.all(scene.model.geom_group[body] == 0)
    assert scene.model.geom_group[display] == 0
    assert scene.model.geom_matid[display] == scene.model.material("display_on").id
    lead_body = scene.model.geom_bodyid[body[scene.pool.slot_of["lead"]]]
    assert np.allclose(scene.data.xpos[scene.model.geom_bodyid[display]], scene.data.xpos[lead_body])
    view = View(scene, ViewParams(480, 270, "driver", hud=False))
    seg = view.segmentation()
    assert (seg == display).sum() > 20  # the lit panel is visible from the driver's seat
    view.close()
    scene.apply(FrameState(0.0, EgoPose(x, y, yaw), veh, leader_id="lead", rear_display_lit=False))
    assert scene.model.geom_matid[display] == scene.model.material("display_off").id
    scene.apply(FrameState(0.0, EgoPose(x, y, yaw), VehicleFrame.empty()))
    assert (
        np.all(scene.model.geom_group[body] == HIDDEN_GROUP)
        and scene.model.geom_group[display] == HIDDEN_GROUP
    )


def test_default_map_scene_builds_fast_with_few_geoms(gl):
    from cosim.runconfig import load_run_config
    from cosim.scenario import build_scenario

    cfg = load_run_config(None, **{"scenario.map": str(shared_map("krems"))})
    scn = build_scenario(cfg.scenario.map, config=cfg.scenario, seed=cfg.seed, log=lambda *a: None)
    t0 = time.perf_counter()
    scene = build_scene(scn)
    build_s = time.perf_counter() - t0
    s = scene.stats
    assert s.counts["buildings"] > 1000 and s.counts["lanes"] > 1000 and s.counts["signs"] > 100
    assert build_s < 10.0, build_s  # ~1.5 s on the 2-core reference machine
    assert scene.model.ngeom < 300, scene.model.ngeom  # thousands of lanes and buildings: a few meshes
    assert sum(s.triangles.values()) < 200_000
    view = View(scene, ViewParams(320, 180, "top", hud=False, top_view_m=2000.0))
    img = view.render(FrameState(0.0, None))
    assert img.std() > 10
    view.close()

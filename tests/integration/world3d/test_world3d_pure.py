"""The pure parts of the 3D view: mesh geometry, the vehicle pool, interpolation, the HUD, log replay."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import shapely

from cosim.world3d import geometry as geo
from cosim.world3d.hud import LEVEL_COLOURS, HudState, draw_hud
from cosim.world3d.replay import LogReplay
from cosim.world3d.state import EgoPose, FrameState, Interpolator, Playback, VehicleFrame, VehiclePool


def face_normals(mesh: geo.MeshData) -> np.ndarray:
    v = mesh.vertices[mesh.faces]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def area(mesh: geo.MeshData) -> float:
    v = mesh.vertices[mesh.faces]
    return float(0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1).sum())


def test_lane_strip_covers_length_times_width_and_faces_up():
    xy = np.array([[0.0, 0.0], [50.0, 0.0], [100.0, 0.0], [100.0, 0.0005]])  # a duplicate point is dropped
    m = geo.strip(xy, 3.2, 0.02)
    assert area(m) == pytest.approx(100.0 * 3.2, rel=1e-9)
    assert np.all(face_normals(m)[:, 2] > 0.999)
    assert np.allclose(m.vertices[:, 2], 0.02)
    bent = geo.strip(np.array([[0.0, 0.0], [50.0, 0.0], [50.0, 50.0]]), 3.0, 0.0)
    assert np.all(face_normals(bent)[:, 2] > 0.999)  # the mitred corner does not fold over


def test_dashes_are_evenly_spaced_and_offset():
    m = geo.dashes(np.array([[0.0, 0.0], [100.0, 0.0]]), 0.12, 0.05, 3.0, 6.0, offset_m=1.6)
    assert m.n_faces == 2 * 11  # 11 dashes of 3 m every 9 m fit into 100 m
    assert np.allclose(m.vertices[:, 1].mean(), 1.6)
    assert area(m) == pytest.approx(11 * 3.0 * 0.12)
    assert geo.dashes(np.array([[0.0, 0.0], [2.0, 0.0]]), 0.12, 0.05, 3.0, 6.0).empty


def test_extruded_walls_face_outwards_with_whole_window_bays():
    square = shapely.Polygon([(0, 0), (0, 10), (10, 10), (10, 0)])  # clockwise on purpose
    holed = shapely.Polygon([(20, 0), (40, 0), (40, 20), (20, 20)], [[(25, 5), (35, 5), (35, 15), (25, 15)]])
    m = geo.extrude_walls([square, holed], np.array([12.0, 6.0]), bay_m=3.5, storey_m=3.0)
    assert m.n_faces == 2 * (4 + 8)  # one quad per outline segment, holes included
    v = m.vertices[m.faces]
    centre = v.mean(axis=1)
    n = face_normals(m)
    inner = (centre[:, 0] > 24) & (centre[:, 0] < 36) & (centre[:, 1] > 4) & (centre[:, 1] < 16)
    for mid, poly_centre in ((centre[:, 0] < 15, (5.0, 5.0)), (~inner & (centre[:, 0] > 15), (30.0, 10.0))):
        out = centre[mid, :2] - poly_centre
        assert np.all(np.einsum("ij,ij->i", out, n[mid, :2]) > 0)  # outer walls face away from the middle
    hole_out = (30.0, 10.0) - centre[inner, :2]
    assert np.all(
        np.einsum("ij,ij->i", hole_out, n[inner, :2]) > 0
    )  # courtyard walls face into the courtyard
    assert abs(n[:, 2]).max() < 1e-9
    assert m.texcoords[:, 0].max() == pytest.approx(round(20 / 3.5))  # 20 m wall: 6 bays
    assert set(np.round(m.texcoords[:, 1], 6)) == {0.0, 4.0, 2.0}  # 12 m: 4 storeys, 6 m: 2


def test_flat_polygons_triangulate_exactly_with_holes():
    holed = shapely.Polygon([(0, 0), (40, 0), (40, 20), (0, 20)], [[(5, 5), (15, 5), (15, 15), (5, 15)]])
    l_shape = shapely.Polygon([(50, 0), (70, 0), (70, 5), (55, 5), (55, 20), (50, 20)])
    m = geo.flat_polygons(np.array([holed, l_shape], dtype=object), np.array([7.0, 3.0]))
    assert area(m) == pytest.approx(holed.area + l_shape.area)
    assert np.all(face_normals(m)[:, 2] > 0.999)
    assert set(np.round(m.vertices[:, 2], 6)) == {7.0, 3.0}


def test_car_meshes_are_closed_enough_and_dashboard_only_on_request():
    body, dark, lamps = geo.car_meshes(geo.CarShape())
    _, dark_ego, _ = geo.car_meshes(geo.CarShape(), dashboard=True)
    assert dark_ego.n_faces > dark.n_faces
    lo, hi = body.vertices.min(axis=0), body.vertices.max(axis=0)
    assert hi[0] - lo[0] == pytest.approx(4.5) and hi[1] - lo[1] == pytest.approx(1.8)
    assert hi[2] == pytest.approx(1.45)
    assert lamps.vertices[:, 0].max() < -2.2  # the lamps are at the rear
    with pytest.raises(ValueError):
        geo.CarShape(beltline_m=2.0)


def test_pool_takes_the_nearest_and_keeps_their_bodies():
    pool = VehiclePool(2)
    ids = ("a", "b", "c", "d")
    slots = pool.assign(ids, np.array([10.0, 50.0, 20.0, 300.0]))
    assert slots.tolist() == [0, -1, 1, -1]
    slots = pool.assign(("c", "a", "b"), np.array([5.0, 30.0, 40.0]))  # 'a' and 'c' stay on their bodies
    assert slots.tolist() == [1, 0, -1]
    slots = pool.assign(("b", "c"), np.array([1.0, 900.0]), max_dist_m=500.0)  # 'a' left, 'c' too far
    assert slots.tolist() == [0, -1]
    assert pool.assign(("x", "y", "z"), np.array([3.0, 3.0, 3.0])).tolist() == [0, 1, -1]  # ties: by id
    with pytest.raises(ValueError):
        pool.assign(("a",), np.array([1.0, 2.0]))


def test_interpolation_blends_poses_the_short_way_round():
    a = FrameState(
        0.0,
        EgoPose(0.0, 0.0, math.radians(179.0)),
        VehicleFrame(("p", "gone"), [0.0, 5.0], [0.0, 5.0], [math.radians(-170.0), 0.0], [False, False]),
    )
    b = FrameState(
        0.5,
        EgoPose(10.0, 2.0, math.radians(-179.0), braking=True),
        VehicleFrame(("new", "p"), [7.0, 10.0], [7.0, 0.0], [1.0, math.radians(170.0)], [True, True]),
    )
    f = Interpolator(a, b).at(0.5)
    assert f.t_s == pytest.approx(0.25)
    assert (f.ego.x_m, f.ego.y_m) == (pytest.approx(5.0), pytest.approx(1.0))
    assert abs(math.cos(f.ego.yaw_rad) + 1.0) < 1e-9  # through 180 deg, not through 0
    assert f.vehicles.ids == ("new", "p")
    assert f.vehicles.x_m.tolist() == [7.0, 5.0]
    assert abs(math.cos(f.vehicles.yaw_rad[1]) + 1.0) < 1e-9
    assert Interpolator(a, b).at(7.0).ego.x_m == pytest.approx(10.0)  # clamped


def test_hud_shows_warning_colours_and_no_in_car_system_a_warning():
    frame = np.full((360, 640, 3), 128, dtype=np.uint8)
    base = HudState(t_s=1.0, speed_mps=13.9, speed_limit_mps=13.89)
    plain = draw_hud(frame, base)
    assert plain.shape == frame.shape and not np.array_equal(plain, frame)
    assert np.array_equal(plain[20:50, 280:360], frame[20:50, 280:360])  # system B off: nothing at the top
    for level in ("none", "advisory", "warning"):
        img = draw_hud(
            frame, HudState(t_s=1.0, speed_mps=10.0, sys_b_active=True, sys_b_gap_s=1.2, sys_b_level=level)
        )
        bg = np.array(LEVEL_COLOURS[level][0], dtype=float)
        patch = img[9:12, 266:380].reshape(-1, 3).astype(float)  # inside the box, above the text
        assert np.abs(patch.mean(axis=0) - (0.9 * bg + 0.1 * 128)).max() < 12
    # system A is the leader's rear display only: the driver's HUD is the same whether it is perceived or not
    seen = HudState(t_s=1.0, speed_mps=10.0, sys_a_perceived=True)
    assert np.array_equal(draw_hud(frame, seen), draw_hud(frame, HudState(t_s=1.0, speed_mps=10.0)))
    for b_on in (False, True):
        with_b = HudState(t_s=1.0, speed_mps=10.0, sys_b_active=b_on, sys_b_gap_s=2.5, sys_a_perceived=True)
        assert np.array_equal(
            draw_hud(frame, with_b), draw_hud(frame, dataclasses.replace(with_b, sys_a_perceived=False))
        )
    # an observer may ask for a note of it (off by default), never the old amber in-car banner
    obs = draw_hud(frame, dataclasses.replace(seen, observer_overlay=True))
    assert not np.array_equal(obs, draw_hud(frame, seen))
    assert np.array_equal(obs[:120], draw_hud(frame, seen)[:120])  # nothing at the top (where the banner was)
    amber = np.all(np.abs(obs.astype(int) - (255, 150, 0)) < 30, axis=2)
    assert not amber.any()
    with pytest.raises(ValueError):
        HudState(t_s=0.0, speed_mps=1.0, sys_b_level="red")


def test_live_view_never_shows_system_a_in_the_car():
    """`cosim drive` (and a participant at the wheel) build LiveSource without the observer overlay."""
    import inspect

    from cosim.world3d import drive
    from cosim.world3d.live import LiveSource

    assert inspect.signature(LiveSource).parameters["observer_overlay"].default is False
    from cosim.world3d import viewer

    assert "observer_overlay" not in inspect.getsource(drive)
    assert "observer_overlay" not in inspect.getsource(viewer)  # the view draws the HudState it is sent
    assert HudState(t_s=0.0, speed_mps=0.0).observer_overlay is False


def _ego_topic(ts, xs, heading=90.0):
    n = len(ts)
    return {"t_s": np.asarray(ts, float), "x_m": np.asarray(xs, float), "y_m": np.zeros(n), "heading_deg": np.full(n, heading),
            "speed_mps": np.full(n, 10.0), "edge": np.array(["e1"] * n, dtype=object), "lane_index": np.zeros(n),
            "leader_id": np.array(["lead"] * n, dtype=object)}  # fmt: skip


def test_log_replay_interpolates_traffic_and_applies_displays_in_time():
    topics = {
        "/ego/state": _ego_topic([0.0, 0.1, 0.2, 0.3, 0.4, 0.5], [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]),
        "/traffic/vehicles": {"t_s": np.array([0.0, 0.0, 0.5]), "id": np.array(["lead", "x", "lead"], dtype=object),
                              "x_m": np.array([20.0, 50.0, 30.0]), "y_m": np.zeros(3),
                              "heading_deg": np.array([90.0, 90.0, 90.0]), "signals": np.array([0, 8, 8])},
        "/traffic/lights": {"t_s": np.array([0.0, 0.3]), "id": np.array(["J1", "J1"], dtype=object),
                            "state": np.array(["rr", "GG"], dtype=object)},
        "/adas/timegap": {"t_s": np.array([0.2]), "time_gap_s": np.array([1.5]), "level": np.array(["warning"], dtype=object)},
        "/adas/rear": {"t_s": np.array([0.4]), "display_lit": np.array([True]), "perceived": np.array([True])},
    }  # fmt: skip
    rp = LogReplay(
        topics, ego_length_m=4.0, scv_length_m=5.0, lane_speed=lambda e, i: 13.89 if e == "e1" else None
    )
    f = rp.frame_at(0.25)
    assert f.ego.x_m == pytest.approx(2.5 - 2.0)  # front bumper 2.5 m -> centre 2 m behind it
    assert f.ego.yaw_rad == pytest.approx(0.0)
    assert f.vehicles.ids == ("lead",)  # 'x' is not in the next sample: gone
    assert f.vehicles.x_m[0] == pytest.approx(25.0 - 2.5)
    assert f.lights == {"J1": "rr"} and rp.frame_at(0.3).lights == {"J1": "GG"}
    assert f.hud.sys_b_active and f.hud.sys_b_gap_s == 1.5 and f.hud.sys_b_level == "warning"
    assert f.hud.speed_limit_mps == pytest.approx(13.89)
    assert f.rear_display_lit is None and not f.hud.sys_a_perceived  # system A's first record is at 0.4 s
    g = rp.frame_at(0.45)
    assert g.rear_display_lit is True and g.hud.sys_a_perceived and g.leader_id == "lead"
    assert not rp.frame_at(0.1).hud.sys_b_active


def test_log_replay_reads_the_adas_phase_records():
    """/adas/state as cosim.phases.adas writes it: system in use, shown gap, colours, display, phase."""
    t = np.array([0.0, 0.1, 0.2, 0.3])
    topics = {
        "/ego/state": _ego_topic(t, [0.0, 1.0, 2.0, 3.0]),
        "/adas/state": {"t_s": t, "phase": np.array(["baseline", "sysA", "sysB", "sysB"], dtype=object),
                        "system": np.array(["none", "A", "B", "B"], dtype=object),
                        "time_gap_displayed_s": np.array([np.nan, np.nan, 2.5, np.nan]),
                        "b_level": np.array(["none", "none", "advisory", "none"], dtype=object),
                        "a_lit": np.array([True, True, False, False]), "a_perceived": np.array([True, False, False, False])},
    }  # fmt: skip
    rp = LogReplay(topics, ego_length_m=4.0)
    f0, f1, f2, f3 = (rp.frame_at(x) for x in t)
    assert (f0.hud.phase, f0.rear_display_lit, f0.hud.sys_a_perceived, f0.hud.sys_b_active) == (
        "baseline",
        None,
        False,
        False,
    )
    assert (f1.rear_display_lit, f1.hud.sys_a_perceived, f1.hud.sys_b_active) == (True, False, False)
    assert (f2.hud.sys_b_active, f2.hud.sys_b_gap_s, f2.hud.sys_b_level, f2.rear_display_lit) == (
        True,
        2.5,
        "advisory",
        None,
    )
    assert f3.hud.sys_b_active and f3.hud.sys_b_gap_s is None  # "no data"


def test_log_replay_keeps_the_last_speed_limit_across_a_junction():
    topics = {"/ego/state": _ego_topic([0.0, 0.1, 0.2], [0.0, 1.0, 2.0])}
    topics["/ego/state"]["edge"] = np.array(["e1", ":J1_0", "e2"], dtype=object)
    rp = LogReplay(topics, ego_length_m=4.0, lane_speed=lambda e, i: {"e1": 13.89, "e2": 8.33}[e])
    assert [rp.frame_at(t).hud.speed_limit_mps for t in (0.0, 0.1, 0.2)] == [13.89, 13.89, 8.33]


def _pose_frame(t: float, x: float) -> FrameState:
    return FrameState(t, EgoPose(x, 0.0, 0.0), VehicleFrame(("v",), [x + 10.0], [0.0], [0.0], [False]))


def test_playback_interpolates_by_the_wall_clock_and_reports_the_input_tags():
    pb = Playback(step_s=0.1)
    assert pb.empty and pb.at(5.0) is None
    pb.push(_pose_frame(1.0, 0.0), arrival_s=10.0, tag=0)
    frame, tag_next, tag_shown = pb.at(10.05)  # one step only: shown as it is
    assert frame.ego.x_m == 0.0 and (tag_next, tag_shown) == (0, 0)
    pb.push(_pose_frame(1.1, 2.0), arrival_s=10.1, tag=3)  # this step read input event 3
    frame, tag_next, tag_shown = pb.at(10.1)  # just arrived: still the previous step's picture
    assert frame.ego.x_m == pytest.approx(0.0) and frame.t_s == pytest.approx(1.0)
    assert (tag_next, tag_shown) == (3, 0)
    frame, tag_next, tag_shown = pb.at(10.125)  # a quarter of a step later: a quarter of the way
    assert frame.ego.x_m == pytest.approx(0.5) and frame.vehicles.x_m[0] == pytest.approx(10.5)
    assert frame.t_s == pytest.approx(1.025) and (tag_next, tag_shown) == (3, 0)
    frame, tag_next, tag_shown = pb.at(10.9)  # the next step is late: the picture holds, no extrapolation
    assert frame.ego.x_m == 2.0 and (tag_next, tag_shown) == (3, 3)
    assert pb.alpha(9.0) == 0.0 and pb.alpha(11.0) == 1.0
    sharp = Playback(step_s=0.1, smooth=False)  # without smoothing: the newest step at once
    sharp.push(_pose_frame(1.0, 0.0), 10.0, 0)
    sharp.push(_pose_frame(1.1, 2.0), 10.1, 1)
    assert sharp.at(10.1)[0].ego.x_m == 2.0 and sharp.at(10.1)[1:] == (1, 1)
    with pytest.raises(ValueError):
        Playback(step_s=0.0)


def test_live_source_sends_only_the_nearest_vehicles_to_the_viewer():
    from types import SimpleNamespace

    from cosim.world3d.live import LiveSource

    n = 6
    world = SimpleNamespace(valid=np.ones(n, bool), is_ego=np.zeros(n, bool), x_m=np.arange(n) * 100.0,
                            y_m=np.zeros(n), heading_deg=np.full(n, 90.0), length_m=np.zeros(n),
                            ids=[f"v{i}" for i in range(n)], signals=np.zeros(n, np.int64))  # fmt: skip
    src = LiveSource(SimpleNamespace(world=world))
    assert src.vehicles().ids == tuple(world.ids)
    # heading 90 (east) and length 0: the centre is the front bumper, at x = 100 i
    assert src.vehicles((240.0, 0.0), nearest=3).ids == ("v1", "v2", "v3")
    assert src.vehicles((240.0, 0.0), nearest=3, max_distance_m=100.0).ids == ("v2", "v3")

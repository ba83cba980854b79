"""System A: camera geometry, stereo error model, warning rule with hysteresis, perception by the follower."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from cosim.adas import RearStereoWarning, RearWarningParams, StereoCameraParams, VehicleState
from cosim.adas.rear_stereo import camera_frame, eye_xy, stereo_depth
from cosim.config import from_dict
from cosim.errors import ConfigError

LEADER_LEN = 4.5
EXACT_CAM = StereoCameraParams(disparity_noise_px=0.0, disparity_step_px=0.0)


def leader(speed=10.0, heading=0.0):
    # front bumper at the origin; heading north -> rear bumper at (0, -4.5)
    return VehicleState(0.0, 0.0, heading, speed, LEADER_LEN)


def follower(depth, lateral=0.0, speed=10.0):
    """Follower heading north, front bumper ``depth`` m behind the leader's rear, ``lateral`` m to the east."""
    return VehicleState(lateral, -LEADER_LEN - depth, 0.0, speed, 4.5)


def system(rng_seed=0, buildings=(), **kw):
    params = RearWarningParams(**{"camera": EXACT_CAM, "min_on_s": 0.0, **kw})
    return RearStereoWarning(params, buildings, rng=np.random.default_rng(rng_seed))


# -- geometry ----------------------------------------------------------------------------------------------
def test_camera_frame_depth_and_lateral():
    depth, lateral = camera_frame(leader(), follower(20.0, lateral=3.0))
    assert depth == pytest.approx(20.0)
    assert abs(lateral) == pytest.approx(3.0)
    # same relative geometry rotated to heading east: leader front at (0,0), rear at (-4.5, 0)
    lead_e = VehicleState(0.0, 0.0, 90.0, 10.0, LEADER_LEN)
    foll_e = VehicleState(-24.5, -3.0, 90.0, 10.0, 4.5)
    depth_e, lateral_e = camera_frame(lead_e, foll_e)
    assert depth_e == pytest.approx(20.0) and abs(lateral_e) == pytest.approx(3.0)


@pytest.mark.parametrize(
    ("depth", "lateral", "status"),
    [
        (20.0, 0.0, "ok"),
        (10.0, 3.5, "ok"),  # atan(3.5/10) = 19.3 deg < 22 deg half-FOV
        (10.0, 4.5, "outside_fov"),  # 24.2 deg > 22 deg
        (59.0, 0.0, "ok"),
        (61.0, 0.0, "out_of_range"),
        (0.3, 0.0, "too_close"),
        (-8.0, 0.0, "behind_camera"),  # "follower" is actually ahead of the leader's rear
    ],
)
def test_fov_and_range(depth, lateral, status):
    out = system().update(0.0, leader(), follower(depth, lateral))
    assert out.measurement == status
    assert (out.measured_distance_m is not None) == (status == "ok")
    if status == "ok":  # exact camera: the measurement is the true depth
        assert out.measured_distance_m == pytest.approx(depth)
        assert out.true_distance_m == pytest.approx(depth)


def test_fov_parameter_widens_the_cone():
    params = RearWarningParams(camera=StereoCameraParams(hfov_deg=60.0))
    sys_ = RearStereoWarning(params, rng=np.random.default_rng(0))
    assert sys_.update(0.0, leader(), follower(10.0, 4.5)).measurement == "ok"  # 24.2 deg < 30 deg


# -- error model -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("depth", [10.0, 20.0, 40.0, 60.0])
def test_depth_error_std_grows_with_z_squared(depth):
    cam = StereoCameraParams(disparity_step_px=0.0)
    rng = np.random.default_rng(1234)
    z = np.array([stereo_depth(depth, cam, rng) for _ in range(4000)])
    expected = depth**2 * cam.disparity_noise_px / (cam.focal_px * cam.baseline_m)
    assert cam.depth_sigma_m(depth) == pytest.approx(expected)
    assert np.std(z) == pytest.approx(expected, rel=0.10)
    # Z = fB/d is convex in d: second-order bias Z * (sigma_d / d)^2
    bias = depth * (cam.disparity_noise_px * depth / (cam.focal_px * cam.baseline_m)) ** 2
    assert np.mean(z) == pytest.approx(depth + bias, abs=4 * expected / np.sqrt(len(z)))


def test_depth_error_ratio_is_quadratic_and_quantisation_adds_q2_over_12():
    cam = StereoCameraParams(disparity_noise_px=0.2, disparity_step_px=0.25)
    rng = np.random.default_rng(7)
    std = {}
    for depth in (15.0, 30.0, 45.0):
        z = np.array([stereo_depth(depth, cam, rng) for _ in range(4000)])
        std[depth] = float(np.std(z))
        assert std[depth] == pytest.approx(cam.depth_sigma_m(depth), rel=0.10)
    assert std[30.0] / std[15.0] == pytest.approx(4.0, rel=0.10)
    assert std[45.0] / std[15.0] == pytest.approx(9.0, rel=0.10)


def test_quantised_measurements_lie_on_the_disparity_grid():
    cam = StereoCameraParams(disparity_noise_px=0.3, disparity_step_px=0.5)
    rng = np.random.default_rng(3)
    fb = cam.focal_px * cam.baseline_m
    for _ in range(200):
        z = stereo_depth(25.0, cam, rng)
        d = fb / z
        assert d / 0.5 == pytest.approx(round(d / 0.5), abs=1e-9)


def test_no_positive_disparity_gives_no_measurement():
    # 2 px of noise on a 0.8 px disparity: many draws are <= 0
    cam = StereoCameraParams(baseline_m=0.1, disparity_noise_px=2.0, max_range_m=200.0)
    sys_ = RearStereoWarning(RearWarningParams(camera=cam), rng=np.random.default_rng(5))
    statuses = {sys_.update(0.1 * k, leader(), follower(100.0)).measurement for k in range(200)}
    assert statuses == {"ok", "no_disparity"}


def test_system_noise_through_update_matches_model():
    sys_ = RearStereoWarning(RearWarningParams(), rng=np.random.default_rng(11))
    z = [sys_.update(0.1 * k, leader(speed=30.0), follower(40.0)).measured_distance_m for k in range(3000)]
    assert np.std(z) == pytest.approx(sys_.params.camera.depth_sigma_m(40.0), rel=0.10)


# -- warning rule ------------------------------------------------------------------------------------------
def test_threshold_and_hysteresis_sequence():
    sys_ = system()  # v = 10 m/s -> required 20 m, released at >= 23 m
    seq = [
        (25.0, False),
        (19.0, True),
        (21.0, True),
        (22.9, True),
        (23.1, False),
        (21.0, False),
        (19.9, True),
    ]
    for k, (depth, lit) in enumerate(seq):
        out = sys_.update(0.1 * k, leader(10.0), follower(depth))
        assert out.required_distance_m == pytest.approx(20.0)
        assert out.display_lit is lit, (k, depth)
    shown = [(e.t_s, e.new) for e in sys_.events if e.kind == "display"]
    assert shown == [(pytest.approx(0.1), "on"), (pytest.approx(0.4), "off"), (pytest.approx(0.6), "on")]


def test_minimum_on_time_holds_the_display():
    sys_ = system(min_on_s=2.0)
    assert sys_.update(0.0, leader(), follower(15.0)).display_lit
    assert sys_.update(0.5, leader(), follower(40.0)).display_lit  # far again, but only lit 0.5 s
    assert sys_.update(1.9, leader(), follower(40.0)).display_lit
    assert not sys_.update(2.0, leader(), follower(40.0)).display_lit
    # losing the follower from view also releases it only after the minimum on-time
    assert sys_.update(3.0, leader(), follower(15.0)).display_lit
    assert sys_.update(3.1, leader(), follower(15.0, lateral=20.0)).measurement == "outside_fov"
    assert sys_.update(3.2, leader(), follower(15.0, lateral=20.0)).display_lit
    assert not sys_.update(5.0, leader(), follower(15.0, lateral=20.0)).display_lit


def test_low_speed_rules():
    sys_ = system()
    # standing / creeping leader: never lit, even very close
    assert not sys_.update(0.0, leader(speed=1.0), follower(2.0)).display_lit
    # slow leader: the minimum distance (5 m) rules, not 2 s * 2 m/s = 4 m
    out = sys_.update(0.1, leader(speed=2.0), follower(4.5))
    assert out.required_distance_m == pytest.approx(5.0) and out.display_lit


def test_time_gap_parameter():
    sys_ = system(time_gap_s=3.0)
    out = sys_.update(0.0, leader(10.0), follower(25.0))
    assert out.required_distance_m == pytest.approx(30.0) and out.display_lit


# -- perception --------------------------------------------------------------------------------------------
def test_driver_eye_position():
    f = VehicleState(10.0, 0.0, 0.0, 0.0, 4.5)  # heading north: left is -x
    assert eye_xy(f, 1.8, 0.35) == pytest.approx((9.65, -1.8))
    f = VehicleState(0.0, 0.0, 90.0, 0.0, 4.5)  # heading east: left is +y
    assert eye_xy(f, 1.8, 0.35) == pytest.approx((-1.8, 0.35))


def test_perceived_when_lit_in_sight_and_legible():
    out = system().update(0.0, leader(), follower(15.0))
    assert out.display_lit and out.perceived and out.reason == "ok/perceived"


def test_not_perceived_when_display_off():
    out = system().update(0.0, leader(), follower(30.0))
    assert not out.display_lit and not out.perceived and out.perception == "display_off"


def test_line_of_sight_blocked_by_building():
    # a building footprint crossing the segment eye -> display (e.g. the road bends around a corner block)
    block = shapely.box(-2.0, -15.0, 2.0, -12.0)
    beside = shapely.box(3.0, -30.0, 10.0, -5.0)  # next to the road, not on the segment
    assert system(buildings=[beside]).update(0.0, leader(), follower(15.0)).perceived
    out = system(buildings=[beside, block]).update(0.0, leader(), follower(15.0))
    assert out.display_lit and not out.perceived and out.perception == "occluded"


def test_legibility_distance():
    fast = leader(speed=30.0)  # required 60 m, so the display is lit at 55 m
    out = system().update(0.0, fast, follower(55.0))
    assert out.display_lit and out.perception == "too_far"  # eye 56.8 m away > 50 m
    assert system().update(0.0, fast, follower(45.0)).perceived
    assert system(legible_distance_m=60.0).update(0.0, fast, follower(55.0)).perceived


def test_display_readable_only_from_behind():
    sys_ = system(min_on_s=2.0)
    assert sys_.update(0.0, leader(), follower(10.0)).perceived
    # follower pulls out beside the leader's rear within the minimum on-time: display still lit
    out = sys_.update(0.5, leader(), follower(1.0, lateral=8.0))
    assert out.display_lit and out.perception == "outside_view_angle"
    kinds = [(e.kind, e.new) for e in sys_.events]
    assert kinds == [("display", "on"), ("perceived", "on"), ("perceived", "off")]


def test_pop_events_drains_once():
    sys_ = system()
    sys_.update(0.0, leader(), follower(15.0))
    first = sys_.pop_events()
    assert [(e.system, e.kind, e.old, e.new) for e in first] == [
        ("A", "display", "off", "on"),
        ("A", "perceived", "off", "on"),
    ]
    assert first[0].value == pytest.approx(15.0)
    assert sys_.pop_events() == []
    sys_.update(0.1, leader(), follower(30.0))
    assert [(e.kind, e.new) for e in sys_.pop_events()] == [("display", "off"), ("perceived", "off")]
    assert len(sys_.events) == 4


# -- determinism and parameters ----------------------------------------------------------------------------
def _run(seed):
    sys_ = RearStereoWarning(
        RearWarningParams(), [shapely.box(3, -40, 9, -10)], rng=np.random.default_rng(seed)
    )
    outs = []
    for k in range(300):
        depth = 30.0 + 15.0 * np.sin(0.05 * k)
        outs.append(sys_.update(0.1 * k, leader(12.0), follower(depth, lateral=0.5)))
    return outs, sys_.events


def test_deterministic_with_seed():
    a, ev_a = _run(42)
    b, ev_b = _run(42)
    c, _ = _run(43)
    assert a == b and ev_a == ev_b
    assert [o.measured_distance_m for o in a] != [o.measured_distance_m for o in c]
    assert any(o.display_lit for o in a) and not all(o.display_lit for o in a)


def test_params_validation_and_config_loading():
    with pytest.raises(ValueError, match="baseline_m"):
        StereoCameraParams(baseline_m=0.0)
    with pytest.raises(ValueError, match="min_range_m"):
        StereoCameraParams(min_range_m=70.0)
    with pytest.raises(ValueError, match="release_ratio"):
        RearWarningParams(release_ratio=0.9)
    p = from_dict(RearWarningParams, {"time_gap_s": 1.5, "camera": {"baseline_m": 0.3}})
    assert p.time_gap_s == 1.5 and p.camera.baseline_m == 0.3 and p.camera.focal_px == 800.0
    with pytest.raises(ConfigError, match="camera.focal"):
        from_dict(RearWarningParams, {"camera": {"focal": 700}})
    with pytest.raises(ConfigError, match="hfov_deg"):
        from_dict(RearWarningParams, {"camera": {"hfov_deg": 200}})

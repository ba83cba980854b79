"""CAM generation rules (EN 302 637-2 §6.1.3), content units and UPER size."""

import numpy as np
import pytest

from cosim.vanet.cam import (
    ACC_BRAKE_PEDAL,
    ACC_EMERGENCY_BRAKE,
    LIGHT_LEFT_TURN,
    TRIGGER_DYNAMICS,
    TRIGGER_FIRST,
    TRIGGER_TIMER,
    CamGenerator,
    CamParams,
    cam_size_bytes,
    decode_cam,
)


def run(gen: CamGenerator, times_ms, x=None, y=None, h=None, v=None):
    """Feed one station through checks at times_ms; returns the times (ms) and triggers of CAMs."""
    out = []
    act = np.array([True])
    for i, t in enumerate(times_ms):
        xi = np.array([0.0 if x is None else x[i]])
        yi = np.array([0.0 if y is None else y[i]])
        hi = np.array([0.0 if h is None else h[i]])
        vi = np.array([0.0 if v is None else v[i]])
        gen.observe(t, act, xi, yi, hi)
        d = gen.check(t, act, xi, yi, hi, vi)
        if d.generate[0]:
            out.append((t, int(d.trigger[0]), bool(d.lf[0])))
    return out


T = list(range(0, 3001, 100))


def test_first_check_generates_then_every_t_gen_cam_max_when_nothing_changes():
    cams = run(CamGenerator(CamParams(), 1), T)
    assert [c[0] for c in cams] == [0, 1000, 2000, 3000]
    assert cams[0][1] == TRIGGER_FIRST
    assert all(c[1] == TRIGGER_TIMER for c in cams[1:])


@pytest.mark.parametrize(
    "field,change,expect",
    [
        ("h", 4.1, True),
        ("h", 3.9, False),  # heading > 4 deg
        ("x", 4.1, True),
        ("x", 3.9, False),  # position > 4 m
        ("v", 0.51, True),
        ("v", 0.49, False),  # speed > 0.5 m/s
    ],
)
def test_dynamics_thresholds(field, change, expect):
    n = len(T)
    series = {k: np.zeros(n) for k in "xhv"}
    series[field][3:] = change  # changes at t = 300 ms and stays
    cams = run(CamGenerator(CamParams(), 1), T, x=series["x"], h=series["h"], v=series["v"])
    got = [c for c in cams if c[0] == 300]
    assert bool(got) == expect
    if expect:
        assert got[0][1] == TRIGGER_DYNAMICS


def test_heading_change_wraps_around_north():
    h = np.full(len(T), 358.0)
    h[2:] = 2.5  # 4.5 deg clockwise across north
    cams = run(CamGenerator(CamParams(), 1), T, h=h)
    assert any(t == 200 and trig == TRIGGER_DYNAMICS for t, trig, _ in cams)


def test_t_gen_cam_min_and_dcc_respected_with_faster_checks():
    p = CamParams(check_period_s=0.05, t_gen_cam_min_s=0.1, t_gen_cam_dcc_s=0.1)
    times = list(range(0, 1001, 50))
    h = np.arange(len(times)) * 10.0  # heading changes by 10 deg every 50 ms
    cams = run(CamGenerator(p, 1), times, h=h)
    gaps = np.diff([c[0] for c in cams])
    assert gaps.min() == 100 and np.all(gaps == 100)


def test_n_gen_cam_keeps_short_interval_for_three_cams_then_t_gen_cam_max():
    # moves 5 m at t = 300 ms (condition 1 after 300 ms), then stands still
    x = np.where(np.array(T) >= 300, 5.0, 0.0)
    cams = run(CamGenerator(CamParams(), 1), list(range(0, 6001, 100)), x=np.r_[x, np.full(30, 5.0)])
    times = [c[0] for c in cams]
    assert times[:6] == [0, 300, 600, 900, 1200, 2200]


def test_low_frequency_container_first_then_every_500_ms():
    h = np.arange(len(T)) * 5.0  # a CAM every 100 ms
    cams = run(CamGenerator(CamParams(), 1), T, h=h)
    lf_times = [t for t, _, lf in cams if lf]
    assert lf_times[:4] == [0, 500, 1000, 1500]
    assert len(cams) == len(T)


def test_vectorised_over_stations_and_reset():
    gen = CamGenerator(CamParams(), 4)
    act = np.array([True, True, False, True])
    z = np.zeros(4)
    d = gen.check(0, act, z, z, z, z)
    assert d.generate.tolist() == [True, True, False, True]
    x = np.array([0.0, 5.0, 0.0, 0.0])
    d = gen.check(100, act, x, z, z, z)
    assert d.generate.tolist() == [False, True, False, False]
    gen.reset(np.array([0]))  # a new vehicle in slot 0: its first check generates at once
    d = gen.check(200, act, x, z, z, z)
    # slot 1: T_GenCam was shortened to 100 ms by its condition-1 CAM, so a timer CAM follows
    assert d.generate.tolist() == [True, True, False, False]
    assert d.trigger.tolist() == [TRIGGER_FIRST, TRIGGER_TIMER, 0, 0]


def test_cam_size_matches_uper_bit_count():
    sizes = cam_size_bytes(np.array([False, True, True, True, True]), np.array([0, 0, 1, 23, 40]))
    assert sizes[0] == 42  # 333 bit, no LF container
    assert sizes[1] == 44  # + 19 bit LF container with an empty path history
    assert 40 <= sizes[0] <= 60 and 40 <= sizes[1] <= 60
    # each path point adds 69 bit
    assert sizes.tolist() == [42, 44, (352 + 69 + 7) // 8, (352 + 69 * 23 + 7) // 8, (352 + 69 * 40 + 7) // 8]
    assert CamParams().max_size_bytes == sizes[3]


def test_build_fields_in_etsi_units_and_decode_roundtrip():
    p = CamParams(path_point_spacing_m=10.0)
    gen = CamGenerator(p, 2)
    act = np.array([True, True])
    xs = [np.array([0.0, 100.0]), np.array([12.0, 100.0]), np.array([25.0, 100.0])]
    h = np.array([90.0, 359.96])
    for k, x in enumerate(xs):
        gen.observe(k * 100, act, x, np.zeros(2), h)
    assert gen.path_count.tolist() == [2, 0]
    d = gen.check(200, act, xs[-1], np.zeros(2), h, np.array([13.337, 0.0]))
    f = gen.build(
        np.array([0, 1]),
        200,
        np.array([7, 8], dtype=np.uint32),
        d.lf,
        d.trigger,
        xs[-1],
        np.zeros(2),
        h,
        np.array([13.337, -1.0]),
        np.array([-5.0, 0.3]),
        np.array([4.5, 12.0]),
        np.array([1.8, 2.5]),
        np.array([0, 2], dtype=np.int16),
        np.array([(1 << 3) | (1 << 1), 0]),
    )
    assert f["heading_01deg"].tolist() == [900, 0]
    assert f["speed_001mps"].tolist() == [1334, 100]
    assert f["drive_direction"].tolist() == [0, 1]
    assert f["long_accel_01mps2"].tolist() == [-50, 3]
    assert f["length_01m"].tolist() == [45, 120]
    assert f["lane_position"].tolist() == [1, 3]
    assert f["accel_control"][0] & ACC_BRAKE_PEDAL and f["accel_control"][0] & ACC_EMERGENCY_BRAKE
    assert not f["accel_control"][1] & ACC_EMERGENCY_BRAKE
    assert f["has_lf"].tolist() == [True, True] and f["exterior_lights"][0] & LIGHT_LEFT_TURN
    assert f["n_path_points"].tolist() == [2, 0]
    assert f["size_bytes"].tolist() == cam_size_bytes(np.array([True, True]), np.array([2, 0])).tolist()
    phys = decode_cam(f)
    assert phys["x_m"][0] == pytest.approx(25.0) and phys["speed_mps"][1] == pytest.approx(-1.0)


def test_yaw_rate_sign_and_curvature():
    gen = CamGenerator(CamParams(), 1)
    act = np.array([True])
    gen.observe(0, act, np.zeros(1), np.zeros(1), np.array([10.0]))
    gen.observe(100, act, np.zeros(1), np.zeros(1), np.array([9.0]))  # compass decreases: a left turn
    assert gen.yaw_rate_dps[0] == pytest.approx(10.0)
    d = gen.check(100, act, np.zeros(1), np.zeros(1), np.array([9.0]), np.array([10.0]))
    f = gen.build(
        np.array([0]),
        100,
        np.array([1], dtype=np.uint32),
        d.lf,
        d.trigger,
        np.zeros(1),
        np.zeros(1),
        np.array([9.0]),
        np.array([10.0]),
        np.zeros(1),
        np.ones(1),
        np.ones(1),
        np.zeros(1, np.int16),
        np.zeros(1, int),
    )
    assert f["yaw_rate_001degps"][0] == 1000
    assert f["curvature"][0] == round(np.radians(10.0) / 10.0 * 10000)


@pytest.mark.parametrize(
    "kw",
    [
        {"check_period_s": 0.2},  # > T_GenCamMin
        {"t_gen_cam_dcc_s": 2.0},
        {"n_gen_cam": 0},
        {"path_history_max_points": 41},
        {"heading_threshold_deg": 0.0},
        {"t_gen_cam_min_s": 0.0005},
    ],
)
def test_impossible_params_rejected(kw):
    with pytest.raises(ValueError):
        CamParams(**kw)

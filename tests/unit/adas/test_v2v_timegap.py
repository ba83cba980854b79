"""System B: gap from CAM data, extrapolation by age, thresholds and hysteresis, stale data, ground truth."""

from __future__ import annotations

import math

import pytest

from cosim.adas import CamData, TimeGapParams, V2VTimeGapWarning, VehicleState, ground_truth_time_gap
from cosim.adas.common import time_gap_s
from cosim.adas.v2v_timegap import cam_gap_m, extrapolate_cam, ground_truth_gap_m
from cosim.config import from_dict
from cosim.errors import ConfigError

LEAD_LEN = 5.0


def ego(speed=10.0, y=0.0, x=0.0, heading=0.0):
    return VehicleState(x, y, heading, speed, 4.5)


def cam_at_gap(gap_m, t_gen, speed=10.0, accel=0.0, ego_y=0.0):
    """A CAM whose leader rear is ``gap_m`` ahead (north) of an ego front bumper at (0, ego_y)."""
    return CamData(t_gen, 0.0, ego_y + gap_m + LEAD_LEN, 0.0, speed, LEAD_LEN, accel)


def test_fresh_cam_gives_the_true_gap():
    e = ego(speed=10.0)
    out = V2VTimeGapWarning().update(0.0, e, cam_at_gap(20.0, 0.0))
    assert out.gap_m == pytest.approx(20.0)
    assert out.time_gap_s == pytest.approx(2.0)
    assert out.data_age_s == 0.0 and out.status == "ok"
    truth = VehicleState(0.0, 25.0, 0.0, 10.0, LEAD_LEN)
    assert ground_truth_gap_m(e, truth) == pytest.approx(20.0)
    assert ground_truth_time_gap(e, truth) == pytest.approx(out.time_gap_s)


def test_gap_is_the_straight_distance_to_the_leaders_rear():
    # ego heading east, leader 30 m east (rear at 25 m) and 3 m to the side: the chord from bumper to rear
    e = VehicleState(0.0, 0.0, 90.0, 12.5, 4.5)
    cam = CamData(0.0, 30.0, 3.0, 90.0, 12.5, LEAD_LEN)
    out = V2VTimeGapWarning().update(0.0, e, cam)
    assert out.gap_m == pytest.approx(math.hypot(25.0, 3.0)) and out.time_gap_s == pytest.approx(
        out.gap_m / 12.5
    )


def test_gap_stays_positive_around_a_bend():
    # after a 90-degree left bend the leader drives north 20 m left of the ego's line: a projection on the
    # ego's heading would give ~0 m, the chord gives the distance a V2V system measures
    e = VehicleState(0.0, 0.0, 90.0, 10.0, 4.5)
    cam = CamData(0.0, 15.0, 20.0 + LEAD_LEN, 0.0, 10.0, LEAD_LEN)
    out = V2VTimeGapWarning().update(0.0, e, cam)
    assert out.gap_m == pytest.approx(25.0) and out.time_gap_s == pytest.approx(2.5)


def test_extrapolation_by_age():
    cam = cam_at_gap(20.0, 0.0, speed=10.0)
    e = ego(speed=10.0)
    assert cam_gap_m(e, cam, 0.5, "constant_speed") == pytest.approx(25.0)
    assert cam_gap_m(e, cam, 0.5, "none") == pytest.approx(20.0)
    out = V2VTimeGapWarning(TimeGapParams(extrapolation="constant_speed")).update(0.5, e, cam)
    assert out.data_age_s == pytest.approx(0.5) and out.gap_m == pytest.approx(25.0)
    # constant acceleration, and a braking leader stops instead of reversing
    acc = cam_at_gap(20.0, 0.0, speed=10.0, accel=2.0)
    assert cam_gap_m(e, acc, 1.0, "constant_accel") == pytest.approx(31.0)
    brake = cam_at_gap(20.0, 0.0, speed=10.0, accel=-5.0)
    assert cam_gap_m(e, brake, 1.0, "constant_accel") == pytest.approx(27.5)
    assert cam_gap_m(e, brake, 2.9, "constant_accel") == pytest.approx(30.0)  # stopped after 2 s, 10 m
    # heading east: the extrapolation follows the CAM heading
    east = CamData(0.0, 10.0, 0.0, 90.0, 8.0, LEAD_LEN)
    assert extrapolate_cam(east, 0.5, "constant_speed") == pytest.approx((14.0, 0.0))


@pytest.mark.parametrize(
    ("mode", "tolerance_s"), [("constant_accel", 1e-9), ("constant_speed", 0.5 * 1.0 * 0.1**2 / 14.0)]
)
def test_agreement_with_truth_when_fresh_over_a_drive(mode, tolerance_s):
    """Leader brakes, then accelerates; a CAM every 0.1 s, delivered 0.05 s after generation.

    The leader's acceleration is piecewise constant and each CAM carries the one it is applying, so
    constant-acceleration extrapolation is exact; constant speed errs by at most a * age^2 / 2 / v_ego.
    """
    params = TimeGapParams(extrapolation=mode)
    sys_ = V2VTimeGapWarning(params)
    dt = 0.05
    lead_y, lead_v, ego_y, ego_v = 60.0, 14.0, 0.0, 14.0
    cam = pending = None
    worst = 0.0
    for k in range(600):
        t = k * dt
        lead_a = -1.0 if 5.0 <= t < 10.0 else (1.0 if 10.0 <= t < 15.0 else 0.0)
        if k % 2 == 1:  # the CAM generated one step ago arrives now
            cam = pending
        else:
            pending = CamData(t, 0.0, lead_y, 0.0, lead_v, LEAD_LEN, lead_a)
        e = VehicleState(0.0, ego_y, 0.0, ego_v, 4.5)
        truth = ground_truth_time_gap(e, VehicleState(0.0, lead_y, 0.0, lead_v, LEAD_LEN, lead_a), params)
        out = sys_.update(t, e, cam)
        if cam is not None:
            assert out.data_age_s <= 0.1 + 1e-9
            worst = max(worst, abs(out.time_gap_s - truth))
        lead_y += lead_v * dt + 0.5 * lead_a * dt * dt  # exact for piecewise-constant acceleration
        lead_v += lead_a * dt
        ego_y += ego_v * dt
    assert worst <= tolerance_s + 1e-12
    assert truth == pytest.approx(30.0 / 14.0)  # gap 55 m -> 30 m: the drive really changed it


def test_threshold_and_hysteresis_sequence():
    sys_ = V2VTimeGapWarning(TimeGapParams(min_on_s=0.0))  # advisory < 3, warning < 2, hysteresis 0.2
    seq = [
        (3.5, "none"),
        (2.9, "advisory"),
        (3.1, "advisory"),  # inside 3.0 .. 3.2
        (3.25, "none"),
        (1.9, "warning"),
        (2.1, "warning"),  # inside 2.0 .. 2.2: the warning persists until the gap is restored
        (2.25, "advisory"),
        (1.99, "warning"),
        (3.1, "advisory"),  # leaving warning passes through advisory while below 3.2
        (3.3, "none"),
    ]
    for k, (tg, level) in enumerate(seq):
        t = 0.1 * k
        out = sys_.update(t, ego(10.0), cam_at_gap(10.0 * tg, t))
        assert out.time_gap_s == pytest.approx(tg)
        assert out.level == level, (k, tg)
    changes = [(round(e.t_s, 3), e.old, e.new) for e in sys_.events if e.kind == "level"]
    assert changes == [
        (0.1, "none", "advisory"),
        (0.3, "advisory", "none"),
        (0.4, "none", "warning"),
        (0.6, "warning", "advisory"),
        (0.7, "advisory", "warning"),
        (0.8, "warning", "advisory"),
        (0.9, "advisory", "none"),
    ]


def test_minimum_on_time():
    sys_ = V2VTimeGapWarning(TimeGapParams(min_on_s=1.0))
    assert sys_.update(0.0, ego(), cam_at_gap(15.0, 0.0)).level == "warning"
    assert sys_.update(0.5, ego(), cam_at_gap(50.0, 0.5)).level == "warning"
    assert sys_.update(0.99, ego(), cam_at_gap(50.0, 0.99)).level == "warning"
    assert sys_.update(1.0, ego(), cam_at_gap(50.0, 1.0)).level == "none"
    # escalation is never delayed
    assert sys_.update(1.1, ego(), cam_at_gap(25.0, 1.1)).level == "advisory"
    assert sys_.update(1.2, ego(), cam_at_gap(15.0, 1.2)).level == "warning"


def test_single_level_paper_variant():
    sys_ = V2VTimeGapWarning(TimeGapParams(advisory_below_s=None, warning_below_s=3.0, min_on_s=0.0))
    assert sys_.update(0.0, ego(), cam_at_gap(25.0, 0.0)).level == "warning"
    assert sys_.update(0.1, ego(), cam_at_gap(31.0, 0.1)).level == "warning"
    assert sys_.update(0.2, ego(), cam_at_gap(32.5, 0.2)).level == "none"


def test_low_speed_handling():
    sys_ = V2VTimeGapWarning()
    slow = sys_.update(0.0, ego(speed=1.0), cam_at_gap(2.0, 0.0, speed=1.0))
    assert slow.time_gap_s == pytest.approx(2.0) and slow.level == "none"  # shown, not warned
    stopped = sys_.update(0.1, ego(speed=0.0), cam_at_gap(2.0, 0.1, speed=0.0))
    assert stopped.time_gap_s == 10.0  # saturated at the cap
    assert time_gap_s(20.0, 1.0, 10.0) == 10.0 and time_gap_s(5.0, 1.0, 10.0) == 5.0
    assert time_gap_s(-3.0, 10.0, 10.0) == 0.0


def test_lost_cams_give_no_data_not_a_stale_gap():
    sys_ = V2VTimeGapWarning()  # max data age 3 s
    last = cam_at_gap(12.0, 0.0)  # 1.2 s: warning
    assert sys_.update(0.0, ego(), last).level == "warning"
    # channel cut: the OBU keeps handing over the same last CAM while time runs on
    outs = [sys_.update(0.1 * k, ego(), last) for k in range(1, 51)]
    for out in outs:
        assert out.data_age_s == pytest.approx(out.t_s)
        if out.data_age_s <= 3.0 + 1e-9:
            assert out.time_gap_s is not None and out.status == "ok"
        else:
            assert out.time_gap_s is None and out.gap_m is None
            assert out.status == "stale" and out.level == "none"
    assert outs[-1].time_gap_s is None
    data = [(round(e.t_s, 3), e.old, e.new) for e in sys_.events if e.kind == "data"]
    assert data == [(0.0, "no_cam", "ok"), (3.1, "ok", "stale")]
    # a fresh CAM restores the display
    back = sys_.update(5.1, ego(), cam_at_gap(40.0, 5.05))
    assert back.status == "ok" and back.time_gap_s == pytest.approx((40.0 + 0.05 * 10.0) / 10.0)


def test_no_cam_at_all():
    out = V2VTimeGapWarning().update(0.0, ego(), None)
    assert (
        out.time_gap_s is None and out.data_age_s is None and out.status == "no_cam" and out.level == "none"
    )


def test_staleness_parameter():
    sys_ = V2VTimeGapWarning(TimeGapParams(max_data_age_s=0.5))
    cam = cam_at_gap(30.0, 0.0)
    assert sys_.update(0.5, ego(), cam).time_gap_s is not None
    assert sys_.update(0.6, ego(), cam).time_gap_s is None


def test_cam_from_the_future_is_an_error():
    with pytest.raises(ValueError, match="newer than now"):
        V2VTimeGapWarning().update(1.0, ego(), cam_at_gap(20.0, 1.5))


def test_deterministic():
    def run():
        s = V2VTimeGapWarning()
        return [
            s.update(0.1 * k, ego(), cam_at_gap(10.0 + (k % 37), 0.1 * (k - k % 3))) for k in range(200)
        ], s.events

    assert run() == run()


def test_params_validation_and_config_loading():
    with pytest.raises(ValueError, match="advisory_below_s"):
        TimeGapParams(advisory_below_s=2.0, warning_below_s=2.0)
    with pytest.raises(ValueError, match="time_gap_cap_s"):
        TimeGapParams(time_gap_cap_s=3.1)
    with pytest.raises(ValueError, match="max_data_age_s"):
        TimeGapParams(max_data_age_s=0.0)
    p = from_dict(TimeGapParams, {"advisory_below_s": None, "warning_below_s": 3, "extrapolation": "none"})
    assert p.advisory_below_s is None and p.warning_below_s == 3.0 and p.extrapolation == "none"
    with pytest.raises(ConfigError, match="extrapolation"):
        from_dict(TimeGapParams, {"extrapolation": "kalman"})
    with pytest.raises(ValueError, match="finite"):
        CamData(0.0, math.nan, 0.0, 0.0, 1.0, 4.0)

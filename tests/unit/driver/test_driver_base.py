import math

import numpy as np
import pytest

from cosim.driver.base import Controls, Percept, path_errors

STRAIGHT = np.array([[0.0, 0.0], [100.0, 0.0]])


def percept(**kw) -> Percept:
    base = dict(
        t_s=0.0, speed_mps=10.0, x_m=10.0, y_m=0.0, yaw_rad=0.0, path_xy_m=STRAIGHT, speed_limit_mps=13.9
    )
    base.update(kw)
    return Percept(**base)


def test_controls_ranges_and_clipping():
    assert Controls(0.5, 0.0, -1.0).steer == -1.0
    for bad in (dict(throttle=1.1), dict(brake=-0.1), dict(steer=1.5), dict(throttle=math.nan)):
        with pytest.raises(ValueError):
            Controls(**bad)
    c = Controls.clipped(2.0, -3.0, math.nan)
    assert (c.throttle, c.brake, c.steer) == (1.0, 0.0, 0.0)
    assert Controls.clipped(0.2, 0.3, -7.0) == Controls(0.2, 0.3, -1.0)


def test_path_errors_signs_left_positive():
    lat, herr, s = path_errors(STRAIGHT, 30.0, 1.5, 0.1)
    assert lat == pytest.approx(1.5) and herr == pytest.approx(0.1) and s == pytest.approx(30.0)
    lat, herr, _ = path_errors(STRAIGHT, 30.0, -0.7, -0.2)
    assert lat == pytest.approx(-0.7) and herr == pytest.approx(-0.2)
    # before the first point the first segment is extended; heading error wraps
    lat, herr, s = path_errors(STRAIGHT, -3.0, 0.4, math.pi + 0.1)
    assert lat == pytest.approx(0.4) and s == pytest.approx(-3.0) and herr == pytest.approx(-math.pi + 0.1)


def test_path_errors_on_circle():
    r = 50.0
    th = np.linspace(0.0, math.pi / 2, 60)
    arc = np.stack([r * np.sin(th), r - r * np.cos(th)], axis=1)  # left turn around (0, r)
    # a point 0.8 m inside the turn (to the left) at 45 degrees, heading along the tangent
    a = math.pi / 4
    x, y = (r - 0.8) * math.sin(a), r - (r - 0.8) * math.cos(a)
    lat, herr, s = path_errors(arc, x, y, a)
    assert lat == pytest.approx(0.8, abs=0.02)
    assert abs(herr) < 0.03
    assert s == pytest.approx(r * a, abs=0.1)


def test_percept_validation_and_derived_errors():
    p = percept(y_m=-0.3, yaw_rad=0.05)
    assert p.lateral_error_m == pytest.approx(-0.3)
    assert p.heading_error_rad == pytest.approx(0.05)
    assert p.path_progress_m == pytest.approx(10.0)
    assert p.path_xy_m.dtype == np.float64
    with pytest.raises(ValueError, match="path_xy_m"):
        percept(path_xy_m=np.zeros((1, 2)))
    with pytest.raises(ValueError, match="path_xy_m"):
        percept(path_xy_m=np.zeros((5, 3)))
    with pytest.raises(ValueError, match="speed_limit"):
        percept(speed_limit_mps=0.0)
    with pytest.raises(ValueError, match="tls_state"):
        percept(tls_state="red", tls_dist_m=10.0)
    with pytest.raises(ValueError, match="tls_dist_m"):
        percept(tls_state="r")
    with pytest.raises(ValueError, match="sign_kind"):
        percept(sign_kind="priority", sign_dist_m=10.0)
    with pytest.raises(ValueError, match="sign_dist_m"):
        percept(sign_kind="stop")
    with pytest.raises(ValueError, match="sys_b_level"):
        percept(sys_b_level="red")
    with pytest.raises(ValueError, match="leader_gap_m"):
        percept(leader_present=True)
    with pytest.raises(ValueError, match="finite"):
        percept(x_m=math.nan)
    # defaults mean "nothing there"
    p = percept()
    assert not p.leader_present and p.tls_state is None and p.sign_kind is None and p.sys_b_gap_s is None
    assert math.isinf(p.tls_dist_m) and math.isinf(p.route_end_dist_m)

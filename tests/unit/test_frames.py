"""cosim.frames: SUMO front bumper + compass angle <-> MuJoCo centre + yaw, origins, wrap-around."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim import frames

ANGLE_PAIRS = [  # (SUMO compass deg, MuJoCo yaw rad): north = +y, east = +x
    (0.0, math.pi / 2),
    (90.0, 0.0),
    (180.0, -math.pi / 2),
    (270.0, math.pi),
    (45.0, math.pi / 4),
    (315.0, 3 * math.pi / 4),
]


@pytest.mark.parametrize(("angle_deg", "yaw_rad"), ANGLE_PAIRS)
def test_angle_conventions(angle_deg: float, yaw_rad: float) -> None:
    assert float(frames.sumo_angle_to_yaw(angle_deg)) == pytest.approx(yaw_rad, abs=1e-12)
    assert float(frames.yaw_to_sumo_angle(yaw_rad)) == pytest.approx(angle_deg, abs=1e-12)
    # Both conventions describe the same heading vector.
    a = math.radians(angle_deg)
    assert (math.sin(a), math.cos(a)) == pytest.approx((math.cos(yaw_rad), math.sin(yaw_rad)), abs=1e-12)


def test_wrap_ranges() -> None:
    yaw = frames.sumo_angle_to_yaw(np.array([-90.0, 270.0, 630.0, -450.0, 90.0 - 180.0]))
    np.testing.assert_allclose(yaw, [np.pi, np.pi, np.pi, np.pi, np.pi])  # -pi maps to +pi: range (-pi, pi]
    ang = frames.yaw_to_sumo_angle(np.array([-np.pi / 2, 3 * np.pi / 2, 5 * np.pi / 2, np.pi / 2, 1e-18]))
    np.testing.assert_allclose(ang, [180.0, 180.0, 0.0, 0.0, 90.0], atol=1e-12)
    tiny = frames.wrap_deg360(np.array([-1e-17, 359.9999999999]))
    assert np.all((tiny >= 0.0) & (tiny < 360.0))
    w = frames.wrap_rad(np.linspace(-20, 20, 1001))
    assert np.all((w > -np.pi) & (w <= np.pi))
    np.testing.assert_allclose(np.sin(w), np.sin(np.linspace(-20, 20, 1001)), atol=1e-12)


def test_centre_is_half_a_length_behind_the_bumper() -> None:
    # Heading east (SUMO 90 deg): the centre is 2.25 m west of the front bumper.
    cx, cy, yaw = frames.sumo_to_mujoco(100.0, 50.0, 90.0, 4.5)
    assert (float(cx), float(cy), float(yaw)) == pytest.approx((97.75, 50.0, 0.0), abs=1e-12)
    # Heading south-west (SUMO 225 deg): bumper is ahead along (-1, -1)/sqrt(2).
    cx, cy, _ = frames.sumo_to_mujoco(0.0, 0.0, 225.0, 2.0 * math.sqrt(2.0))
    assert (float(cx), float(cy)) == pytest.approx((1.0, 1.0), abs=1e-12)


def test_origin_shift() -> None:
    cx, cy, _ = frames.sumo_to_mujoco(1000.0, 2000.0, 0.0, 4.0, origin_xy=(990.0, 1990.0))
    assert (float(cx), float(cy)) == pytest.approx((10.0, 8.0))  # 2 m behind the bumper (north heading)
    x, y, angle = frames.mujoco_to_sumo(10.0, 8.0, np.pi / 2, 4.0, origin_xy=np.array([990.0, 1990.0]))
    assert (float(x), float(y), float(angle)) == pytest.approx((1000.0, 2000.0, 0.0))


def test_round_trip_arrays_with_wrap_around() -> None:
    rng = np.random.default_rng(7)
    n = 1000
    x = rng.uniform(-5e4, 5e4, n)
    y = rng.uniform(-5e4, 5e4, n)
    angle = rng.uniform(0.0, 360.0, n)
    angle[:4] = [0.0, 359.999999, 180.0, 1e-9]  # edges of the range
    length = rng.uniform(2.0, 18.0, n)
    origin = (12345.6, -789.0)
    cx, cy, yaw = frames.sumo_to_mujoco(x, y, angle, length, origin)
    assert cx.shape == cy.shape == yaw.shape == (n,)
    assert np.all((yaw > -np.pi) & (yaw <= np.pi))
    x2, y2, angle2 = frames.mujoco_to_sumo(cx, cy, yaw, length, origin)
    np.testing.assert_allclose(x2, x, atol=1e-8)
    np.testing.assert_allclose(y2, y, atol=1e-8)
    d = (angle2 - angle + 180.0) % 360.0 - 180.0  # angular difference, robust at 0/360
    np.testing.assert_allclose(d, 0.0, atol=1e-9)
    assert np.all((angle2 >= 0.0) & (angle2 < 360.0))
    # The other direction, with yaw outside (-pi, pi] on input.
    yaw_in = rng.uniform(-4 * np.pi, 4 * np.pi, n)
    xs, ys, a = frames.mujoco_to_sumo(cx, cy, yaw_in, length, origin)
    cx3, cy3, yaw3 = frames.sumo_to_mujoco(xs, ys, a, length, origin)
    np.testing.assert_allclose(cx3, cx, atol=1e-8)
    np.testing.assert_allclose(cy3, cy, atol=1e-8)
    np.testing.assert_allclose(np.angle(np.exp(1j * (yaw3 - yaw_in))), 0.0, atol=1e-12)


def test_scalars_and_broadcasting() -> None:
    cx, cy, yaw = frames.sumo_to_mujoco(1.0, 2.0, 30.0, 4.0)
    assert cx.shape == () and yaw.shape == ()
    # One length for many vehicles broadcasts.
    cx, _, _ = frames.sumo_to_mujoco(np.zeros(3), np.zeros(3), np.array([0.0, 90.0, 180.0]), 4.0)
    np.testing.assert_allclose(cx, [0.0, -2.0, 0.0], atol=1e-12)


def test_network_offset_round_trip() -> None:
    off = (-512000.25, -5400000.5)  # a typical netconvert netOffset (UTM -> network)
    px, py = frames.network_to_projected(np.array([0.0, 10.0]), np.array([0.0, -3.0]), off)
    np.testing.assert_allclose(px, [512000.25, 512010.25])
    np.testing.assert_allclose(py, [5400000.5, 5399997.5])
    nx, ny = frames.projected_to_network(px, py, off)
    np.testing.assert_allclose(nx, [0.0, 10.0])
    np.testing.assert_allclose(ny, [0.0, -3.0])


def test_frames_does_not_import_mujoco() -> None:
    import subprocess
    import sys

    code = "import sys, cosim.frames; assert 'mujoco' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)

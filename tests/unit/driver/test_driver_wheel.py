import importlib.util

import numpy as np
import pytest

from cosim.driver.base import Percept
from cosim.driver.wheel import (
    PedalParams,
    PygameJoystickSource,
    WheelDriver,
    WheelMapper,
    WheelParams,
    combined_pedal_values,
    pedal_value,
    steer_value,
)
from cosim.errors import CosimError


def test_pedal_calibration_maps_released_to_0_and_pressed_to_1():
    cal = PedalParams(
        axis=1, raw_released=1.0, raw_pressed=-1.0, dead_zone=0.0, saturation=0.0
    )  # inverted pedal
    assert pedal_value(1.0, cal) == 0.0
    assert pedal_value(-1.0, cal) == 1.0
    assert pedal_value(0.0, cal) == pytest.approx(0.5)
    assert pedal_value(1.05, cal) == 0.0 and pedal_value(-1.2, cal) == 1.0  # out-of-range raw values clip
    # a partially travelling pedal: calibrated on its real range
    short = PedalParams(axis=1, raw_released=-0.8, raw_pressed=0.6, dead_zone=0.0, saturation=0.0)
    assert pedal_value(-0.8, short) == 0.0 and pedal_value(0.6, short) == 1.0
    assert pedal_value(-0.1, short) == pytest.approx(0.5)


def test_pedal_dead_zone_and_saturation():
    cal = PedalParams(axis=2, raw_released=-1.0, raw_pressed=1.0, dead_zone=0.05, saturation=0.05)
    assert pedal_value(-1.0 + 2 * 0.04, cal) == 0.0  # resting noise inside the dead zone
    assert pedal_value(-1.0 + 2 * 0.5, cal) == pytest.approx(0.5)  # the middle stays the middle
    assert pedal_value(1.0 - 2 * 0.04, cal) == 1.0  # full although the sensor does not quite reach 1
    assert 0.0 < pedal_value(-1.0 + 2 * 0.06, cal) < 0.02  # continuous just above the dead zone


def test_steering_inversion_dead_zone_exponent_gain():
    q = WheelParams(steer_dead_zone=0.1)
    assert steer_value(-1.0, q) == 1.0  # SDL: left is negative; Controls: left is +1
    assert steer_value(0.05, q) == 0.0 and steer_value(-0.09, q) == 0.0
    assert steer_value(0.55, q) == pytest.approx(-0.5)
    assert steer_value(-0.55, WheelParams(steer_dead_zone=0.1, steer_invert=False)) == pytest.approx(-0.5)
    assert steer_value(-0.5, WheelParams(steer_dead_zone=0.0, steer_exponent=2.0)) == pytest.approx(0.25)
    assert steer_value(-0.5, WheelParams(steer_dead_zone=0.0, steer_gain=3.0)) == 1.0  # saturates


def test_combined_pedal_axis():
    q = WheelParams(combined_pedal_axis=1, combined_invert=True, combined_dead_zone=0.0)
    assert combined_pedal_values(-1.0, q) == (1.0, 0.0)  # stick up (negative) = throttle after inversion
    assert combined_pedal_values(0.5, q) == (0.0, 0.5)
    m = WheelMapper(q)
    c = m.map([0.0, -0.6], [])
    assert (c.throttle, c.brake, c.steer) == pytest.approx((0.6, 0.0, 0.0))


def test_mapper_with_gamepad_defaults_buttons_and_zero_until_moved():
    m = WheelMapper()  # steer 0, brake trigger axis 2, throttle trigger axis 5; triggers rest at -1
    axes = [-0.5, 0.0, -1.0, 0.0, 0.0, 1.0]
    c = m.map(axes, [False] * 4)
    assert c.steer == pytest.approx((0.5 - 0.02) / 0.98) and c.throttle == 1.0 and c.brake == 0.0
    # an untouched axis reporting exactly 0.0 is a pedal at rest until it first moves
    m2 = WheelMapper()
    assert m2.map([0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).throttle == 0.0
    assert m2.map([0.0, 0.0, 0.0, 0.0, 0.0, 0.2]).throttle == pytest.approx(
        pedal_value(0.2, m2.params.throttle)
    )
    assert m2.map([0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).throttle == pytest.approx(
        pedal_value(0.0, m2.params.throttle)
    )
    # digital pedals on buttons
    mb = WheelMapper(WheelParams(throttle_button=0, brake_button=1))
    c = mb.map([0.0, 0.0, -1.0, 0.0, 0.0, -1.0], [True, False])
    assert c.throttle == 1.0 and c.brake == 0.0
    assert mb.map([0.0, 0.0, -1.0, 0.0, 0.0, -1.0], [False, 1]).brake == 1.0


def test_mapping_errors_name_the_key():
    with pytest.raises(ValueError, match="throttle.axis=5 but the device reports only 3 axes"):
        WheelMapper().map([0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="brake_button"):
        WheelMapper(WheelParams(brake_button=4)).map([0.0] * 6, [False])
    with pytest.raises(ValueError, match="two controls"):
        WheelParams(steer_axis=2)
    with pytest.raises(ValueError, match="no brake"):
        WheelParams(brake=PedalParams(axis=None))
    with pytest.raises(ValueError, match="calibration"):
        PedalParams(axis=1, raw_released=0.5, raw_pressed=0.55)
    with pytest.raises(ValueError, match="dead_zone"):
        PedalParams(axis=1, dead_zone=0.6)


def test_wheel_driver_reads_its_source():
    frames = [([0.3, 0.0, 0.0, 0.0, 0.0, 0.5], [False]), ([-1.0, 0.0, 0.4, 0.0, 0.0, -1.0], [False])]
    drv = WheelDriver(source=lambda: frames.pop(0))
    path = np.array([[0.0, 0.0], [50.0, 0.0]])
    p = Percept(t_s=0.0, speed_mps=3.0, x_m=0.0, y_m=0.0, yaw_rad=0.0, path_xy_m=path, speed_limit_mps=10.0)
    c1, c2 = drv.act(p, 0.1), drv.act(p, 0.1)
    assert c1.steer < 0.0 and c1.throttle > 0.5 and c1.brake == 0.0
    assert c2.steer == 1.0 and c2.throttle == 0.0 and c2.brake > 0.6


@pytest.mark.skipif(importlib.util.find_spec("pygame") is not None, reason="pygame is installed")
def test_without_pygame_the_adapter_says_how_to_install_it():
    with pytest.raises(CosimError, match=r"cosim\[input\]"):
        PygameJoystickSource(WheelParams())

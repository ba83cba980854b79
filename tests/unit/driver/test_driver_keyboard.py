import importlib.util

import numpy as np
import pytest

from cosim.driver.base import Percept
from cosim.driver.keyboard import KeyboardDriver, KeyboardMapper, KeyboardParams, PygameKeySource
from cosim.errors import CosimError

DT = 0.05  # [s] a 20-Hz frame


def hold(mapper, keys, seconds, speed=0.0):
    c = None
    for _ in range(round(seconds / DT)):
        c = mapper.update(keys, DT, speed)
    return c


def test_throttle_and_brake_ramp_up_and_release():
    m = KeyboardMapper()  # throttle: full after 0.8 s, released 4/s; brake: full after 0.5 s
    assert hold(m, {"up"}, 0.4).throttle == pytest.approx(0.5)
    assert hold(m, {"up"}, 0.4).throttle == pytest.approx(1.0)
    assert hold(m, {"up"}, 1.0).throttle == 1.0
    assert hold(m, set(), 0.1).throttle == pytest.approx(0.6)
    assert hold(m, set(), 0.2).throttle == 0.0
    assert hold(m, {"s"}, 0.25).brake == pytest.approx(0.5)  # WASD works too
    c = hold(m, {"s"}, 0.3)
    assert c.brake == 1.0 and c.throttle == 0.0
    assert hold(m, set(), 0.2).brake == 0.0


def test_steering_ramps_self_centres_and_narrows_with_speed():
    m = KeyboardMapper()
    assert hold(m, {"left"}, 0.2).steer == pytest.approx(0.3)  # 1.5 /s, left positive
    assert hold(m, {"left"}, 1.0).steer == pytest.approx(1.0)
    assert hold(m, set(), 0.2).steer == pytest.approx(0.5)  # self-centring 2.5 /s
    assert hold(m, {"left", "right"}, 0.2).steer == pytest.approx(0.0)  # both: centre
    # reversing is faster than steering out of centre: 4 /s instead of 1.5 /s
    hold(m, {"a"}, 1.0)
    assert hold(m, {"d"}, 0.25).steer == pytest.approx(0.0, abs=1e-9)
    assert hold(m, {"d"}, 0.2).steer == pytest.approx(-0.3)
    # at 12 m/s the range is halved; at 36 m/s a tenth
    m.reset()
    assert hold(m, {"left"}, 2.0, speed=12.0).steer == pytest.approx(0.5)
    assert hold(m, {"left"}, 0.05, speed=36.0).steer == pytest.approx(0.1)  # clamped when the range narrows


def test_custom_bindings_and_validation():
    m = KeyboardMapper(
        KeyboardParams(throttle_keys=("i",), brake_keys=("k",), left_keys=("j",), right_keys=("l",))
    )
    assert hold(m, {"up"}, 0.5).throttle == 0.0
    assert hold(m, {"i"}, 0.5).throttle > 0.0
    with pytest.raises(ValueError, match="bound to both"):
        KeyboardParams(throttle_keys=("up",), brake_keys=("up",))
    with pytest.raises(ValueError, match="at least one"):
        KeyboardParams(left_keys=())
    with pytest.raises(ValueError, match="throttle_rise_per_s"):
        KeyboardParams(throttle_rise_per_s=0.0)
    with pytest.raises(ValueError, match="dt_s"):
        m.update(set(), 0.0)


def test_keyboard_driver_reads_its_key_source_each_step():
    keys = [{"up"}, {"up"}, {"up", "left"}, set()]
    drv = KeyboardDriver(key_source=lambda: keys.pop(0))
    path = np.array([[0.0, 0.0], [50.0, 0.0]])
    out = []
    for k in range(4):
        p = Percept(
            t_s=0.1 * k, speed_mps=3.0, x_m=0.0, y_m=0.0, yaw_rad=0.0, path_xy_m=path, speed_limit_mps=10.0
        )
        out.append(drv.act(p, 0.1))
    assert [c.throttle for c in out] == pytest.approx([0.125, 0.25, 0.375, 0.0])
    assert out[2].steer > 0.0 and out[3].steer == 0.0
    drv.reset()
    assert drv.mapper.throttle == 0.0


@pytest.mark.skipif(importlib.util.find_spec("pygame") is not None, reason="pygame is installed")
def test_without_pygame_the_adapter_says_how_to_install_it():
    with pytest.raises(CosimError, match=r"cosim\[input\]"):
        PygameKeySource(KeyboardParams())

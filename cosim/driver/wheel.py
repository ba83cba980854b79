"""Steering wheel / gamepad driving through pygame's joystick API.

Raw joystick axes are in [-1, 1]; what they mean differs per device and driver, so everything is a parameter:
axis indices, inversion, dead zones, and per-pedal calibration (the raw value with the pedal released and fully
pressed, which also handles inverted pedals). ``WheelMapper.map`` is pure (plain lists of axis values and
button states); ``PygameJoystickSource`` is the thin adapter reading one device each frame.

Defaults fit an Xbox-layout gamepad under SDL2 (left stick X steers, right trigger = axis 5 throttle, left
trigger = axis 2 brake, triggers rest at -1). For a wheel, set the axes from the device's axis monitor
(``describe_joysticks()`` lists what is connected). Example for a wheel whose pedals rest at +1 and read -1
when floored: ``throttle: {axis: 2, raw_released: 1.0, raw_pressed: -1.0}``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from cosim.driver.base import Controls, Driver, Percept
from cosim.driver.keyboard import import_pygame
from cosim.errors import CosimError


def _check_fraction(owner: str, name: str, value: float, hi: float = 0.5) -> None:
    if not (math.isfinite(value) and 0.0 <= value < hi):
        raise ValueError(f"{owner}.{name} must be within [0, {hi}), got {value!r}")


def _check_index(owner: str, name: str, value: int | None) -> None:
    if value is not None and (not isinstance(value, int) or value < 0):
        raise ValueError(f"{owner}.{name} must be an index >= 0 or null, got {value!r}")


@dataclass(frozen=True)
class PedalParams:
    """One pedal on its own axis: raw_released -> 0, raw_pressed -> 1, linear in between."""

    axis: int | None = None  # joystick axis index; None = not on an axis
    raw_released: float = -1.0  # raw axis value with the pedal released
    raw_pressed: float = 1.0  # raw axis value with the pedal fully pressed
    dead_zone: float = 0.03  # [0, 0.5) share of travel near "released" that reads 0 (resting noise)
    saturation: float = 0.02  # [0, 0.5) share of travel near "pressed" that reads 1 (cannot quite reach)

    def __post_init__(self) -> None:
        _check_index("PedalParams", "axis", self.axis)
        for name in ("raw_released", "raw_pressed"):
            v = getattr(self, name)
            if not (math.isfinite(v) and -1.0 <= v <= 1.0):
                raise ValueError(f"PedalParams.{name} must be within [-1, 1], got {v!r}")
        if abs(self.raw_pressed - self.raw_released) < 0.1:
            raise ValueError(
                "PedalParams: raw_pressed and raw_released must differ by at least 0.1 (calibration)"
            )
        _check_fraction("PedalParams", "dead_zone", self.dead_zone)
        _check_fraction("PedalParams", "saturation", self.saturation)


def pedal_value(raw: float, cal: PedalParams) -> float:
    """[0, 1] pedal travel from a raw axis value, after calibration, dead zone and saturation."""
    x = (raw - cal.raw_released) / (cal.raw_pressed - cal.raw_released)
    x = (x - cal.dead_zone) / (1.0 - cal.dead_zone - cal.saturation)
    return min(max(x, 0.0), 1.0)


@dataclass(frozen=True)
class WheelParams:
    """Axis / button mapping of a wheel or gamepad."""

    device_index: int = 0  # which joystick (pygame index)
    steer_axis: int = 0
    steer_invert: bool = True  # SDL reports left as negative; Controls.steer is +1 = left
    steer_dead_zone: float = 0.02  # [0, 0.5) |raw| below this reads 0 (centre play, stick drift)
    steer_gain: float = 1.0  # > 1 reaches full lock before the end of the wheel's travel
    steer_exponent: float = 1.0  # 1 = linear; > 1 = finer around centre (useful for gamepad sticks)
    throttle: PedalParams = field(default_factory=lambda: PedalParams(axis=5))
    brake: PedalParams = field(default_factory=lambda: PedalParams(axis=2))
    combined_pedal_axis: int | None = None  # one axis for both pedals; overrides throttle.axis / brake.axis
    combined_invert: bool = False  # after inversion: positive = throttle, negative = brake
    combined_dead_zone: float = 0.05  # [0, 0.5)
    throttle_button: int | None = None  # a digital throttle (gamepad button): pressed = full throttle
    brake_button: int | None = None  # a digital brake
    pedal_zero_until_moved: bool = True  # some wheels report exactly 0.0 for a pedal until it first moves

    def __post_init__(self) -> None:
        for name in ("device_index", "steer_axis", "combined_pedal_axis", "throttle_button", "brake_button"):
            _check_index("WheelParams", name, getattr(self, name))
        if self.steer_axis is None:
            raise ValueError("WheelParams.steer_axis must be an index >= 0")
        _check_fraction("WheelParams", "steer_dead_zone", self.steer_dead_zone)
        _check_fraction("WheelParams", "combined_dead_zone", self.combined_dead_zone)
        if not (math.isfinite(self.steer_gain) and 0.1 <= self.steer_gain <= 10.0):
            raise ValueError(f"WheelParams.steer_gain must be within [0.1, 10], got {self.steer_gain!r}")
        if not (math.isfinite(self.steer_exponent) and 0.2 <= self.steer_exponent <= 5.0):
            raise ValueError(
                f"WheelParams.steer_exponent must be within [0.2, 5], got {self.steer_exponent!r}"
            )
        if self.combined_pedal_axis is None:
            if self.throttle.axis is None and self.throttle_button is None:
                raise ValueError(
                    "WheelParams: no throttle (set throttle.axis, throttle_button or combined_pedal_axis)"
                )
            if self.brake.axis is None and self.brake_button is None:
                raise ValueError(
                    "WheelParams: no brake (set brake.axis, brake_button or combined_pedal_axis)"
                )
            axes = [a for a in (self.steer_axis, self.throttle.axis, self.brake.axis) if a is not None]
        else:
            axes = [self.steer_axis, self.combined_pedal_axis]
        if len(set(axes)) != len(axes):
            raise ValueError(f"WheelParams: one axis is mapped to two controls ({axes})")

    def axes_used(self) -> list[tuple[str, int]]:
        """(config key, axis index) of every axis read."""
        if self.combined_pedal_axis is not None:
            return [("steer_axis", self.steer_axis), ("combined_pedal_axis", self.combined_pedal_axis)]
        out = [("steer_axis", self.steer_axis)]
        out += [
            (f"{n}.axis", p.axis)
            for n, p in (("throttle", self.throttle), ("brake", self.brake))
            if p.axis is not None
        ]
        return out

    def buttons_used(self) -> list[tuple[str, int]]:
        return [(n, b) for n, b in (("throttle_button", self.throttle_button), ("brake_button", self.brake_button))
                if b is not None]  # fmt: skip


def steer_value(raw: float, q: WheelParams) -> float:
    """[-1, 1] steering from the raw steering axis: inversion, dead zone (rescaled), exponent, gain."""
    x = -raw if q.steer_invert else raw
    mag = (abs(x) - q.steer_dead_zone) / (1.0 - q.steer_dead_zone)
    if mag <= 0.0:
        return 0.0
    mag = min(mag, 1.0) ** q.steer_exponent * q.steer_gain
    return math.copysign(min(mag, 1.0), x)


def combined_pedal_values(raw: float, q: WheelParams) -> tuple[float, float]:
    """(throttle, brake) from one axis: positive half -> throttle, negative half -> brake (after inversion)."""
    x = -raw if q.combined_invert else raw
    mag = (abs(x) - q.combined_dead_zone) / (1.0 - q.combined_dead_zone)
    mag = min(max(mag, 0.0), 1.0)
    return (mag, 0.0) if x > 0 else (0.0, mag)


class WheelMapper:
    """Pure axes/buttons -> Controls. Keeps only the 'pedal has moved' flags for pedal_zero_until_moved."""

    def __init__(self, params: WheelParams | None = None) -> None:
        self.params = params or WheelParams()
        self.reset()

    def reset(self) -> None:
        self._moved: set[int] = set()

    def map(self, axes: Sequence[float], buttons: Sequence[bool | int] = ()) -> Controls:
        """axes: raw values in [-1, 1] indexed like the device; buttons: pressed states."""
        q = self.params
        for key, idx in q.axes_used():
            if idx >= len(axes):
                raise ValueError(f"wheel {key}={idx} but the device reports only {len(axes)} axes")
        for key, idx in q.buttons_used():
            if idx >= len(buttons):
                raise ValueError(f"wheel {key}={idx} but the device reports only {len(buttons)} buttons")
        steer = steer_value(float(axes[q.steer_axis]), q)
        if q.combined_pedal_axis is not None:
            throttle, brake = combined_pedal_values(float(axes[q.combined_pedal_axis]), q)
        else:
            throttle = self._pedal(axes, q.throttle)
            brake = self._pedal(axes, q.brake)
        if q.throttle_button is not None and buttons[q.throttle_button]:
            throttle = 1.0
        if q.brake_button is not None and buttons[q.brake_button]:
            brake = 1.0
        return Controls.clipped(throttle, brake, steer)

    def _pedal(self, axes: Sequence[float], cal: PedalParams) -> float:
        if cal.axis is None:
            return 0.0
        raw = float(axes[cal.axis])
        if self.params.pedal_zero_until_moved and cal.axis not in self._moved:
            if raw == 0.0:
                return 0.0
            self._moved.add(cal.axis)
        return pedal_value(raw, cal)


def describe_joysticks() -> list[str]:
    """One line per connected joystick: index, name, number of axes and buttons (for writing the config)."""
    pg = import_pygame()
    pg.joystick.init()
    lines = []
    for i in range(pg.joystick.get_count()):
        js = pg.joystick.Joystick(i)
        lines.append(f"{i}: {js.get_name()!r} axes={js.get_numaxes()} buttons={js.get_numbuttons()}")
    return lines


class PygameJoystickSource:
    """Reads all axes and buttons of one joystick each call; checks the mapping against the device at start."""

    def __init__(self, params: WheelParams, pump_events: bool = True) -> None:
        self._pg = pg = import_pygame()
        self._pump = pump_events
        pg.joystick.init()
        count = pg.joystick.get_count()
        if params.device_index >= count:
            raise CosimError(
                f"wheel: no joystick #{params.device_index} ({count} connected); plug it in or set wheel.device_index"
            )
        self._js = js = pg.joystick.Joystick(params.device_index)
        n_axes, n_buttons = js.get_numaxes(), js.get_numbuttons()
        for key, idx in params.axes_used():
            if idx >= n_axes:
                raise CosimError(
                    f"wheel.{key}={idx} but {js.get_name()!r} has {n_axes} axes; fix the wheel config"
                )
        for key, idx in params.buttons_used():
            if idx >= n_buttons:
                raise CosimError(
                    f"wheel.{key}={idx} but {js.get_name()!r} has {n_buttons} buttons; fix the wheel config"
                )

    def __call__(self) -> tuple[list[float], list[bool]]:
        if self._pump:
            self._pg.event.pump()
        js = self._js
        axes = [js.get_axis(i) for i in range(js.get_numaxes())]
        buttons = [bool(js.get_button(i)) for i in range(js.get_numbuttons())]
        return axes, buttons


class WheelDriver(Driver):
    """A person at a wheel or gamepad. ``source`` returns (axes, buttons) (default: pygame joystick)."""

    def __init__(
        self,
        params: WheelParams | None = None,
        source: Callable[[], tuple[Sequence[float], Sequence[bool | int]]] | None = None,
    ) -> None:
        self.mapper = WheelMapper(params)
        self._source = source if source is not None else PygameJoystickSource(self.mapper.params)

    def reset(self, rng: np.random.Generator | None = None) -> None:
        self.mapper.reset()

    def act(self, percept: Percept, dt_s: float) -> Controls:
        axes, buttons = self._source()
        return self.mapper.map(axes, buttons)

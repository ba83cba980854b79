"""Keyboard driving: key states -> smoothly ramped pedals and steering.

Keys are on/off, so a car driven by them directly is undrivable (full throttle, full lock). The mapper ramps
each control toward its target at a configurable rate, self-centres the steering and narrows the steering
range with speed (as a driver does with a wheel). The mapping is pure (``KeyboardMapper.update`` takes a set of
key names); ``PygameKeySource`` is the thin adapter that reads pygame's key state each frame.
Key names are pygame's (``pygame.key.name``): "up", "down", "left", "right", "w", "a", "s", "d", "space"...
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection
from dataclasses import dataclass
from typing import Any

import numpy as np

from cosim.driver.base import Controls, Driver, Percept
from cosim.errors import CosimError


def import_pygame() -> Any:
    """pygame, imported on first use only (it is an optional dependency: ``pip install 'cosim[input]'``)."""
    try:
        import pygame
    except ImportError:
        raise CosimError(
            "keyboard / wheel input needs pygame: install it with  pip install 'cosim[input]'"
        ) from None
    return pygame


def _check_rate(owner: str, name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{owner}.{name} must be a finite number > 0, got {value!r}")


@dataclass(frozen=True)
class KeyboardParams:
    """Key bindings and ramp rates (rates in control units per second; controls span [0, 1] or [-1, 1])."""

    throttle_keys: tuple[str, ...] = ("up", "w")
    brake_keys: tuple[str, ...] = ("down", "s")
    left_keys: tuple[str, ...] = ("left", "a")
    right_keys: tuple[str, ...] = ("right", "d")
    throttle_max: float = 1.0  # [0, 1] throttle reached when the key is held
    throttle_rise_per_s: float = 1.25  # full throttle after 0.8 s
    throttle_fall_per_s: float = 4.0
    brake_max: float = 1.0  # [0, 1]
    brake_rise_per_s: float = 2.0  # full brake after 0.5 s
    brake_fall_per_s: float = 5.0
    steer_rate_per_s: float = 1.5  # while a steering key is held
    steer_return_per_s: float = 2.5  # self-centring when none is held (added when reversing direction)
    steer_speed_ref_mps: float = 12.0  # [m/s] steering range = 1 / (1 + (v / ref)^2); 0 = always full lock
    steer_min_range: float = 0.1  # [0, 1] the range never gets narrower than this

    def __post_init__(self) -> None:
        groups = {
            "throttle_keys": self.throttle_keys,
            "brake_keys": self.brake_keys,
            "left_keys": self.left_keys,
            "right_keys": self.right_keys,
        }
        seen: dict[str, str] = {}
        for group, keys in groups.items():
            if not keys:
                raise ValueError(f"KeyboardParams.{group} must name at least one key")
            for key in keys:
                if not isinstance(key, str) or not key or key != key.lower():
                    raise ValueError(
                        f"KeyboardParams.{group}: key names are non-empty lower-case strings, got {key!r}"
                    )
                if key in seen and seen[key] != group:
                    raise ValueError(f"KeyboardParams: key {key!r} is bound to both {seen[key]} and {group}")
                seen[key] = group
        for name in ("throttle_rise_per_s", "throttle_fall_per_s", "brake_rise_per_s", "brake_fall_per_s",
                     "steer_rate_per_s", "steer_return_per_s"):  # fmt: skip
            _check_rate("KeyboardParams", name, getattr(self, name))
        for name in ("throttle_max", "brake_max", "steer_min_range"):
            v = getattr(self, name)
            if not 0.0 < v <= 1.0:
                raise ValueError(f"KeyboardParams.{name} must be within (0, 1], got {v!r}")
        if not (math.isfinite(self.steer_speed_ref_mps) and self.steer_speed_ref_mps >= 0):
            raise ValueError(
                f"KeyboardParams.steer_speed_ref_mps must be >= 0, got {self.steer_speed_ref_mps!r}"
            )


def _ramp(value: float, target: float, up: float, down: float) -> float:
    return min(target, value + up) if target > value else max(target, value - down)


class KeyboardMapper:
    """Pure key-state -> Controls mapping with ramps; one instance per driver (it keeps the ramp state)."""

    def __init__(self, params: KeyboardParams | None = None) -> None:
        self.params = params or KeyboardParams()
        self.reset()

    def reset(self) -> None:
        self.throttle = 0.0
        self.brake = 0.0
        self.steer = 0.0

    def steer_range(self, speed_mps: float) -> float:
        """Largest |steer| the keys reach at this speed."""
        ref = self.params.steer_speed_ref_mps
        if ref == 0.0:
            return 1.0
        return max(self.params.steer_min_range, 1.0 / (1.0 + (max(speed_mps, 0.0) / ref) ** 2))

    def update(self, pressed: Collection[str], dt_s: float, speed_mps: float = 0.0) -> Controls:
        """Advance the ramps by dt_s [s] given the currently pressed key names; speed_mps narrows steering."""
        if not (math.isfinite(dt_s) and dt_s > 0):
            raise ValueError(f"dt_s must be > 0, got {dt_s!r}")
        q = self.params
        on = set(pressed)

        def held(keys: tuple[str, ...]) -> bool:
            return any(k in on for k in keys)

        t_target = q.throttle_max if held(q.throttle_keys) else 0.0
        b_target = q.brake_max if held(q.brake_keys) else 0.0
        self.throttle = _ramp(
            self.throttle, t_target, q.throttle_rise_per_s * dt_s, q.throttle_fall_per_s * dt_s
        )
        self.brake = _ramp(self.brake, b_target, q.brake_rise_per_s * dt_s, q.brake_fall_per_s * dt_s)

        left, right = held(q.left_keys), held(q.right_keys)
        rng = self.steer_range(speed_mps)
        if left == right:  # none or both: centre
            target, rate = 0.0, q.steer_return_per_s
        else:
            target = rng if left else -rng
            rate = q.steer_rate_per_s
            if self.steer * target < 0:  # reversing: first back to centre, faster (steering plus centring)
                target, rate = 0.0, rate + q.steer_return_per_s
        step = rate * dt_s
        self.steer = _ramp(self.steer, target, step, step)
        if abs(self.steer) < 1e-12:
            self.steer = 0.0
        if abs(self.steer) > rng:  # speed rose: the range narrowed
            self.steer = math.copysign(rng, self.steer)
        return Controls.clipped(self.throttle, self.brake, self.steer)


class PygameKeySource:
    """Reads pygame's keyboard state; returns the set of pressed key names that the params bind.

    Needs an initialised pygame display (the 3D view owns the window). ``pump_events`` lets pygame update its
    key state when nobody else processes events this frame; it does not remove events from the queue.
    """

    def __init__(self, params: KeyboardParams, pump_events: bool = True) -> None:
        self._pg = import_pygame()
        self._pump = pump_events
        names = {*params.throttle_keys, *params.brake_keys, *params.left_keys, *params.right_keys}
        self._codes: dict[str, int] = {}
        for name in sorted(names):
            try:
                self._codes[name] = self._pg.key.key_code(name)
            except ValueError:
                raise CosimError(
                    f"keyboard: unknown key name {name!r} (use pygame key names such as 'up', 'w')"
                ) from None

    def __call__(self) -> set[str]:
        if self._pump:
            self._pg.event.pump()
        state = self._pg.key.get_pressed()
        return {name for name, code in self._codes.items() if state[code]}


class KeyboardDriver(Driver):
    """A person at the keyboard. ``key_source`` returns the pressed key names (default: pygame)."""

    def __init__(
        self, params: KeyboardParams | None = None, key_source: Callable[[], Collection[str]] | None = None
    ) -> None:
        self.mapper = KeyboardMapper(params)
        self._source = key_source if key_source is not None else PygameKeySource(self.mapper.params)

    def reset(self, rng: np.random.Generator | None = None) -> None:
        self.mapper.reset()

    def act(self, percept: Percept, dt_s: float) -> Controls:
        return self.mapper.update(self._source(), dt_s, percept.speed_mps)


__all__ = ["KeyboardDriver", "KeyboardMapper", "KeyboardParams", "PygameKeySource", "import_pygame"]

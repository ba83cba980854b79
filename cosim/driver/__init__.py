"""Who drives the ego car: a scripted human-like driver, or a person at the keyboard / a wheel.

Every driver implements ``Driver.act(percept, dt_s) -> Controls`` once per SUMO step. The loop builds the
``Percept`` (see base.py for the fields and their units) from the world, the ego's route and the ADAS outputs.
pygame is imported only when a keyboard or wheel driver is built.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from cosim.driver.base import Controls, Driver, PathGeometry, Percept, path_errors
from cosim.driver.keyboard import KeyboardDriver, KeyboardMapper, KeyboardParams
from cosim.driver.profiles import PROFILES, DriverProfile, profile_by_name
from cosim.driver.scripted import ControllerParams, DriverDebug, PedalModel, ScriptedDriver
from cosim.driver.wheel import PedalParams, WheelDriver, WheelMapper, WheelParams


@dataclass(frozen=True)
class DriverConfig:
    """The ``driver:`` section of a run config."""

    kind: Literal["scripted", "keyboard", "wheel"] = "scripted"
    profile: str = "daily_commuter"  # a name from PROFILES (scripted only)
    profile_overrides: dict[str, float] = field(default_factory=dict)  # e.g. {reaction_time_s: 1.2}
    car: PedalModel = field(
        default_factory=PedalModel
    )  # the scripted driver's pedal model; match the ego car
    control: ControllerParams = field(default_factory=ControllerParams)
    keyboard: KeyboardParams = field(default_factory=KeyboardParams)
    wheel: WheelParams = field(default_factory=WheelParams)

    def __post_init__(self) -> None:
        self.resolved_profile()  # raises ValueError for an unknown name, unknown override key or bad value

    def resolved_profile(self) -> DriverProfile:
        """The named profile with the overrides applied."""
        base = profile_by_name(self.profile)
        known = {f.name for f in dataclasses.fields(DriverProfile)}
        unknown = sorted(set(self.profile_overrides) - known)
        if unknown:
            raise ValueError(
                f"profile_overrides: unknown parameter {unknown[0]!r} (known: {', '.join(sorted(known))})"
            )
        return dataclasses.replace(base, **{k: float(v) for k, v in self.profile_overrides.items()})


def make_driver(
    cfg: DriverConfig,
    rng: np.random.Generator,
    max_steer_rad: float,
    wheelbase_m: float,
    car: PedalModel | None = None,
) -> Driver:
    """Build the configured driver. ``car`` (e.g. derived from the ego model) overrides ``cfg.car``."""
    if cfg.kind == "scripted":
        return ScriptedDriver(
            cfg.resolved_profile(), rng, max_steer_rad, wheelbase_m, car=car or cfg.car, control=cfg.control
        )
    if cfg.kind == "keyboard":
        return KeyboardDriver(cfg.keyboard)
    return WheelDriver(cfg.wheel)


__all__ = [
    "PROFILES",
    "PedalModel",
    "ControllerParams",
    "Controls",
    "Driver",
    "DriverConfig",
    "DriverDebug",
    "DriverProfile",
    "KeyboardDriver",
    "KeyboardMapper",
    "KeyboardParams",
    "PathGeometry",
    "PedalParams",
    "Percept",
    "ScriptedDriver",
    "WheelDriver",
    "WheelMapper",
    "WheelParams",
    "make_driver",
    "path_errors",
    "profile_by_name",
]

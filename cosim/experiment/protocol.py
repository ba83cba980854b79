"""The experiment protocol (paper VII.C): participants follow a lead vehicle through phases in which a
different assistance system is active (baseline, system A, system B), on one predefined route in
medium-to-high traffic. Every participant drives the same scenario (map, traffic, route, seed); only the
driver (profile and its own noise seed) and the order of the systems differ.
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from cosim.config import from_dict, read_yaml
from cosim.driver.profiles import PROFILES
from cosim.errors import ConfigError
from cosim.runconfig import RunConfig, run_config_from

MIN_PHASE_S = 1.0  # a phase shorter than ten base steps has no time-gap trace to speak of [s]


@dataclass(frozen=True)
class PhaseSpec:
    name: str
    system: Literal["none", "A", "B"] = "none"
    duration_s: float = 300.0

    def __post_init__(self):
        if not self.duration_s >= MIN_PHASE_S:  # also NaN
            raise ValueError(
                f"phase {self.name!r}: duration_s must be >= {MIN_PHASE_S:g} s (ten steps), got {self.duration_s}"
            )


@dataclass(frozen=True)
class ParticipantSpec:
    id: str
    profile: str = "daily_commuter"  # a driver profile name (cosim.driver.profiles)
    order: tuple[str, ...] = ()  # phase names in driving order; empty = the protocol's counterbalancing

    def __post_init__(self):
        if self.profile not in PROFILES:
            raise ValueError(
                f"participant {self.id!r}: unknown profile {self.profile!r} (known: {', '.join(PROFILES)})"
            )


@dataclass(frozen=True)
class ExperimentConfig:
    name: str = "experiment"
    seed: int = 1
    phases: tuple[PhaseSpec, ...] = (
        PhaseSpec("baseline", "none"), PhaseSpec("system_A", "A"), PhaseSpec("system_B", "B"),
    )  # fmt: skip
    # baseline first (as in the paper), then the order of the other phases rotates between participants
    counterbalance: Literal["rotate_after_first", "none"] = "rotate_after_first"
    participants: tuple[ParticipantSpec, ...] = (
        ParticipantSpec("P1", "daily_commuter"), ParticipantSpec("P2", "daily_commuter"),
        ParticipantSpec("P3", "daily_commuter"), ParticipantSpec("P4", "occasional_driver"),
    )  # fmt: skip
    run: dict[str, Any] = field(default_factory=dict)  # run-config keys (map, traffic, vanet, adas ...)

    def __post_init__(self):
        names = [p.name for p in self.phases]
        if not names or len(set(names)) != len(names):
            raise ValueError("phases: need at least one phase and unique names")
        ids = [p.id for p in self.participants]
        if not ids or len(set(ids)) != len(ids):
            raise ValueError("participants: need at least one participant and unique ids")
        for p in self.participants:
            if p.order and sorted(p.order) != sorted(names):
                raise ValueError(
                    f"participant {p.id!r}: order must list each phase once ({', '.join(names)})"
                )

    def order_of(self, index: int) -> tuple[PhaseSpec, ...]:
        part = self.participants[index]
        by_name = {p.name: p for p in self.phases}
        if part.order:
            return tuple(by_name[n] for n in part.order)
        if self.counterbalance == "none" or len(self.phases) < 3:
            return self.phases
        first, rest = self.phases[0], list(self.phases[1:])
        k = index % len(rest)
        return (first, *rest[k:], *rest[:k])


def load_experiment(path: str | Path, *, map_path: str | None = None, participants: int | None = None,
                    phase_duration_s: float | None = None,
                    participant_driver: str | None = None) -> tuple[ExperimentConfig, Path]:  # fmt: skip
    """Load an experiment config; command-line overrides are validated like the file."""
    data = read_yaml(path)
    base = Path(path).resolve().parent
    exp = from_dict(ExperimentConfig, data)
    if phase_duration_s is not None:
        if not phase_duration_s >= MIN_PHASE_S:
            raise ConfigError(
                "--phase-duration", f"must be >= {MIN_PHASE_S:g} s (ten steps), got {phase_duration_s}"
            )
        exp = dataclasses.replace(
            exp, phases=tuple(dataclasses.replace(p, duration_s=phase_duration_s) for p in exp.phases)
        )
    if participants is not None:
        if participants < 1:
            raise ConfigError("--participants", "must be >= 1")
        known = list(exp.participants)
        more = [
            dataclasses.replace(known[i % len(known)], id=f"P{i + 1}")
            for i in range(len(known), participants)
        ]
        exp = dataclasses.replace(exp, participants=tuple(known[:participants] + more))
    run = copy.deepcopy(exp.run)
    if map_path is not None:
        run.setdefault("scenario", {})["map"] = str(Path(map_path).resolve())
    if participant_driver is not None:  # people instead of scripted drivers (keyboard or steering wheel)
        run.setdefault("ego", {}).setdefault("driver", {})["kind"] = participant_driver
    exp = dataclasses.replace(exp, run=run)
    participant_config(exp, 0, base)  # validate the run part now, with its key paths
    return exp, base


def participant_config(exp: ExperimentConfig, index: int, base: Path) -> RunConfig:
    """The run config of one participant: the shared scenario, this driver, the sum of the phases."""
    part = exp.participants[index]
    run = copy.deepcopy(exp.run)
    run["name"] = f"{exp.name}-{part.id}"
    run["seed"] = exp.seed
    ego = run.setdefault("ego", {})
    ego.setdefault("depart_s", 0.0)
    ego["driver_seed"] = index + 1
    driver = ego.setdefault("driver", {})
    driver.setdefault("kind", "scripted")
    if driver["kind"] == "scripted":
        driver["profile"] = part.profile
    run["duration_s"] = start_time_s(exp, ego["depart_s"]) + sum(p.duration_s for p in exp.phases)
    try:
        return run_config_from(run, base)
    except ConfigError as exc:
        raise ConfigError(f"run.{exc.path}" if exc.path else "run", exc.problem) from None


def start_time_s(exp: ExperimentConfig, depart_s: float) -> float:
    """The protocol starts when the ego (and the lead ahead of it) are placed on the road."""
    return depart_s

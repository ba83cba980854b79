"""The run config: what ``cosim run CONFIG`` reads. Frozen dataclasses, filled by cosim.config.from_dict."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from cosim.adas.config import AdasConfig
from cosim.config import from_dict, read_yaml
from cosim.driver import DriverConfig
from cosim.ego_mujoco import CarParams
from cosim.errors import ConfigError
from cosim.scenario import ScenarioConfig
from cosim.vanet import VanetParams


def _is_multiple(value: float, base: float) -> bool:
    ratio = value / base
    return ratio >= 1 - 1e-9 and abs(ratio - round(ratio)) < 1e-6


@dataclass(frozen=True)
class TimingConfig:
    """Every rate is an integer multiple of the base step (the SUMO step); checked here at load."""

    sumo_step_s: float = 0.1  # base step [s]
    physics_timestep_s: float = 0.002  # MuJoCo timestep; sumo_step_s must be a multiple (>= 500 Hz) [s]

    def __post_init__(self):
        if not 0.001 <= self.sumo_step_s <= 1.0:
            raise ValueError(f"sumo_step_s must be in [0.001, 1] s, got {self.sumo_step_s}")
        if not _is_multiple(self.sumo_step_s, self.physics_timestep_s):
            raise ValueError(f"sumo_step_s ({self.sumo_step_s}) must be an integer multiple of physics_timestep_s "
                             f"({self.physics_timestep_s})")  # fmt: skip
        if self.physics_timestep_s > 0.002 + 1e-12:
            raise ValueError("physics_timestep_s must be <= 0.002 s (MuJoCo car at >= 500 Hz)")
        if self.sumo_step_s > 0.1 + 1e-9:  # the VANET layer checks the CAM conditions once per base step
            raise ValueError("sumo_step_s must be <= 0.1 s: CAM conditions are checked once per step, and ETSI "
                             "EN 302 637-2 wants them checked at least every 100 ms")  # fmt: skip


@dataclass(frozen=True)
class EgoConfig:
    enabled: bool = True
    physics: Literal["mujoco", "sumo"] = "mujoco"  # sumo: a plain SUMO vehicle flagged as ego
    route: tuple[str, ...] = ()  # edge ids; empty = the scenario's predefined route (scenario.demand)
    depart_s: float = 0.0  # when the ego and the lead ahead of it are placed on the route [s]
    lead_vehicle: bool = True  # a SUMO vehicle on the same route, ahead of the ego, to follow
    lead_waits_beyond_m: float = 40.0  # longest gap the lead lets grow (0 = never) [m]
    car: CarParams = field(default_factory=CarParams)  # the MuJoCo car (mass, tyres, power, brakes ...)
    driver: DriverConfig = field(
        default_factory=DriverConfig
    )  # who drives: scripted profile, keyboard, wheel
    driver_seed: int = 0  # the driver's own randomness (perception noise, wander): one per participant

    def __post_init__(self):
        if self.depart_s < 0:
            raise ValueError("depart_s must be >= 0")


@dataclass(frozen=True)
class LogConfig:
    # /traffic/vehicles every N base steps (0 = off); 20: every 2 s, the largest share of a default log (the
    # Foxglove boxes on /scene stay at 1 Hz; cosim render interpolates between the samples)
    traffic_every_steps: int = 20
    scene_every_steps: int = 10  # /scene (Foxglove boxes) every N steps (0 = off)
    scene_radius_m: float = 400.0  # vehicles farther from the ego are left out of /scene
    # a log chunk per this many simulated seconds at most (crash-safe flushes: a killed run loses at most this);
    # 5 s rather than 2 s: larger chunks compress ~15 % better [s]
    flush_every_s: float = 5.0

    def __post_init__(self):
        if self.traffic_every_steps < 0 or self.scene_every_steps < 0 or self.flush_every_s <= 0:
            raise ValueError("log rates must be >= 0 and flush_every_s > 0")


@dataclass(frozen=True)
class RunConfig:
    name: str = "run"
    seed: int = 0
    duration_s: float = 300.0
    scenario: ScenarioConfig = field(default_factory=ScenarioConfig)
    timing: TimingConfig = field(default_factory=TimingConfig)
    ego: EgoConfig = field(default_factory=EgoConfig)
    # every vehicle a VANET station; null turns the radio off. /vanet/rx logs the ego's receptions only
    # by default (rx_log: all for network-wide PDR studies: ~10^6 rows per simulated second at 1000), and
    # /vanet/tx the transmissions with a row in /vanet/rx (tx_log: all for network-wide slot statistics)
    vanet: VanetParams | None = field(default_factory=VanetParams)
    adas: AdasConfig = field(default_factory=AdasConfig)
    log: LogConfig = field(default_factory=LogConfig)

    def __post_init__(self):
        if self.duration_s <= 0:
            raise ValueError(f"duration_s must be > 0, got {self.duration_s}")
        if round(self.duration_s / self.timing.sumo_step_s) < 1:
            raise ValueError(f"duration_s ({self.duration_s} s) is shorter than one step: give at least "
                             f"timing.sumo_step_s ({self.timing.sumo_step_s} s)")  # fmt: skip
        if self.vanet is not None and self.adas.v2v.max_data_age_s > self.vanet.obu.map_memory_s:
            # system B's "no data" must come from its own timeout while the OBU map still holds the leader
            # (cosim.vanet.obu: the map memory and B's timeout)
            raise ValueError(
                f"adas.v2v.max_data_age_s ({self.adas.v2v.max_data_age_s} s) must not exceed "
                f"vanet.obu.map_memory_s ({self.vanet.obu.map_memory_s} s): the OBU map forgets a leader "
                "after map_memory_s, before system B would call its data stale"
            )
        if self.scenario.demand.area == "around_ego" and not self.ego.enabled:
            raise ValueError(
                "scenario.demand.area: around_ego generates traffic around the ego: needs ego.enabled"
            )


def load_run_config(path: str | Path | None = None, **overrides) -> RunConfig:
    """Load a run config; ``scenario.map`` is resolved relative to the config file's folder.

    ``overrides`` are top-level or dotted keys (``{"scenario.demand.density": "high"}``) applied before
    validation, so that command-line options are checked like the file.
    """
    data = read_yaml(path) if path else {}
    return run_config_from(data, Path(path).resolve().parent if path else None, **overrides)


def run_config_from(data: dict, base: Path | None, **overrides) -> RunConfig:
    """Validate a run-config mapping; a relative map path is looked up in ``base``, then its parent (so
    that configs/*.yaml may name maps as ``maps/x.osm.gz`` or ``configs/maps/x.osm.gz``), then the cwd."""
    import copy

    data = copy.deepcopy(data)
    for key, value in overrides.items():
        if value is None:
            continue
        node = data
        parts = key.split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
            if not isinstance(node, dict):
                raise ConfigError(key, "cannot override inside a non-mapping value")
        node[parts[-1]] = value
    config = from_dict(RunConfig, data)
    map_path = Path(config.scenario.map)
    if not map_path.is_absolute():
        candidates = [b / map_path for b in (base, base.parent) if b is not None] if base else []
        map_path = next(
            (c for c in candidates if c.exists()), candidates[0] if candidates else map_path
        ).resolve()
    return dataclasses.replace(config, scenario=dataclasses.replace(config.scenario, map=str(map_path)))

"""The sweep file: a base run config, a grid and/or a list of overrides, seeds, plots.

A sweep expands to runs: every combination of the ``grid`` (cartesian product of its value lists), crossed
with every entry of ``runs`` (explicit override mappings, e.g. assistance variants), crossed with every
seed. Each run has a stable id, a hash of its overrides and seed, so that re-running a sweep finds the
runs it already finished (resume) no matter in which order they are listed.

YAML::

    name: density_shadowing
    base: ../default.yaml            # run config, relative to this file (omit: built-in defaults)
    duration_s: 60                   # overrides duration_s of every run
    overrides: {ego.physics: sumo}   # applied to every run
    grid:
      scenario.demand.density: [low, medium, high]
    runs:                            # crossed with the grid; omit for the grid alone
      - {vanet.channel.shadowing: none}
      - {vanet.channel.shadowing: los}
    seeds: [1, 2, 3]
    plots:
      - {metric: pdr_100_300m, x: scenario.demand.density, hue: vanet.channel.shadowing}
"""

from __future__ import annotations

import hashlib
import itertools
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cosim.config import check_seed, from_dict, read_yaml
from cosim.errors import CosimError

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")
RESERVED_KEYS = ("seed", "name")  # set by the sweep itself for every run


def _check_key(key: str, where: str) -> None:
    if not _KEY.match(key):
        raise ValueError(f"{where}: {key!r} is not a dotted config key like scenario.demand.density")
    if key in RESERVED_KEYS:
        raise ValueError(f"{where}: {key!r} is set by the sweep for every run (use 'seeds' for seeds)")


@dataclass(frozen=True)
class PlotSpec:
    """One plot: ``metric`` (a table.csv column) against the swept parameter ``x``, one line per ``hue``."""

    metric: str
    x: str  # a swept key (grid / runs) or "seed"
    hue: str | None = None  # a swept key; one line per value
    logy: bool = False

    def __post_init__(self) -> None:
        if not self.metric or not self.x:
            raise ValueError("a plot needs a metric and an x parameter")
        if self.hue is not None and self.hue == self.x:
            raise ValueError(f"plot of {self.metric}: hue and x are both {self.x!r}")


@dataclass(frozen=True)
class SweepSpec:
    name: str
    base: str | None = None  # run config YAML, relative to the sweep file; None = built-in defaults
    grid: dict[str, tuple[Any, ...]] = field(default_factory=dict)  # dotted key -> values (cartesian product)
    runs: tuple[dict[str, Any], ...] = ()  # explicit override mappings, crossed with the grid
    seeds: tuple[int, ...] = ()  # crossed with everything; empty = the base config's seed
    duration_s: float | None = None  # overrides every run's duration_s [s]
    overrides: dict[str, Any] = field(default_factory=dict)  # applied to every run (before grid / runs)
    plots: tuple[PlotSpec, ...] = ()
    pdr_bands_m: tuple[float, ...] = (0.0, 100.0, 300.0, 500.0)  # band edges of the PDR columns [m]

    def __post_init__(self) -> None:
        if not _NAME.match(self.name):
            raise ValueError(
                f"name {self.name!r} must be a plain folder name (letters, digits, '_', '-', '.')"
            )
        for key, values in self.grid.items():
            _check_key(key, "grid")
            if len(values) == 0:
                raise ValueError(f"grid {key}: needs at least one value")
            if len({_canon(v) for v in values}) != len(values):
                raise ValueError(f"grid {key}: values repeat")
        for i, run in enumerate(self.runs):
            for key in run:
                _check_key(str(key), f"runs[{i}]")
                if key in self.grid:
                    raise ValueError(f"runs[{i}]: {key!r} is also a grid key; set it in one place only")
        for key in self.overrides:
            _check_key(str(key), "overrides")
        if len(set(self.seeds)) != len(self.seeds):
            raise ValueError("seeds repeat")
        for i, seed in enumerate(self.seeds):
            check_seed(seed, f"seeds[{i}]")
        if self.duration_s is not None and self.duration_s <= 0:
            raise ValueError(f"duration_s must be > 0, got {self.duration_s}")
        edges = self.pdr_bands_m
        if len(edges) < 2 or any(b <= a for a, b in zip(edges, edges[1:], strict=False)) or edges[0] < 0:
            raise ValueError("pdr_bands_m must be at least two increasing distances >= 0")
        swept = set(self.swept_keys) | {"seed"}
        for p in self.plots:
            for role, key in (("x", p.x), ("hue", p.hue)):
                if key is not None and key not in swept:
                    raise ValueError(f"plot of {p.metric}: {role} {key!r} is not swept "
                                     f"(swept: {', '.join(sorted(swept))})")  # fmt: skip

    @property
    def swept_keys(self) -> list[str]:
        """The keys that vary between runs, in the order they first appear (grid, then runs)."""
        keys = list(self.grid)
        for run in self.runs:
            keys += [k for k in run if k not in keys]
        return keys


def _canon(value: Any) -> str:
    """A canonical text of a YAML value (for hashing and comparing): JSON with sorted keys."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), default=str)


def run_id(overrides: dict[str, Any], seed: int | None) -> str:
    """Stable id of a run: a hash of its swept overrides and seed (order of keys does not matter)."""
    return hashlib.sha256(_canon({"overrides": overrides, "seed": seed}).encode()).hexdigest()[:12]


@dataclass(frozen=True)
class RunSpec:
    """One run of a sweep: ``overrides`` are the swept values (what the table shows), plus the seed."""

    run_id: str
    overrides: dict[str, Any]  # swept dotted key -> value
    seed: int | None  # None = the base config's seed

    def label(self) -> str:
        parts = [f"{k}={_short(v)}" for k, v in self.overrides.items()]
        if self.seed is not None:
            parts.append(f"seed={self.seed}")
        return " ".join(parts) or "(base config)"


def _short(value: Any) -> str:
    return value if isinstance(value, str) else _canon(value)


def expand(spec: SweepSpec) -> list[RunSpec]:
    """All runs of the sweep, in a stable order (grid order, then runs, then seeds)."""
    keys = list(spec.grid)
    combos = [dict(zip(keys, values, strict=True)) for values in itertools.product(*spec.grid.values())] or [
        {}
    ]
    entries = list(spec.runs) or [{}]
    seeds: list[int | None] = list(spec.seeds) or [None]
    out: list[RunSpec] = []
    seen: dict[str, RunSpec] = {}
    for combo, entry, seed in itertools.product(combos, entries, seeds):
        overrides = {**combo, **entry}
        rid = run_id(overrides, seed)
        run = RunSpec(rid, overrides, seed)
        if rid in seen:
            raise ValueError(f"runs {seen[rid].label()} and {run.label()} are the same run (listed twice)")
        seen[rid] = run
        out.append(run)
    return out


@dataclass(frozen=True)
class Sweep:
    """A loaded sweep file: the spec plus where it came from (to resolve relative paths)."""

    spec: SweepSpec
    path: Path | None  # the sweep file; None when built in code
    base_config: Path | None  # the resolved base run config

    @property
    def folder(self) -> Path:
        return self.path.parent if self.path else Path.cwd()

    def runs(self) -> list[RunSpec]:
        return expand(self.spec)


def load_sweep(path: str | Path) -> Sweep:
    """Read and validate a sweep file; unknown keys and impossible values are ConfigErrors naming the key."""
    path = Path(path).resolve()
    return _bind(from_dict(SweepSpec, read_yaml(path)), path)


def sweep_from_spec(spec: SweepSpec, folder: str | Path | None = None) -> Sweep:
    """A sweep built in code; ``base`` and relative map paths resolve against ``folder`` (default: cwd)."""
    path = (Path(folder).resolve() / "sweep.yaml") if folder else None
    return _bind(spec, path)


def _bind(spec: SweepSpec, path: Path | None) -> Sweep:
    base = None
    if spec.base:
        base = Path(spec.base)
        if not base.is_absolute():
            base = ((path.parent if path else Path.cwd()) / base).resolve()
        if not base.is_file():
            raise CosimError(f"sweep {spec.name}: base config {base} does not exist")
    try:
        expand(spec)
    except ValueError as exc:
        raise CosimError(f"sweep {spec.name}: {exc}") from None
    return Sweep(spec, path, base)

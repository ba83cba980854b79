"""Frozen dataclasses for run configs and the one YAML loader that fills them.

The loader is generic: any frozen dataclass whose fields have type hints (int, float, bool, str, Literal,
tuple[...], X | None, nested dataclasses, dict[str, X]) can be filled from a mapping. Unknown keys and
wrong types are rejected with the key's full path, e.g. ``config vanet.channel.tx_power_mw: expected a
number, got 'high'``. Every number must be finite (no nan / inf), and every seed (a key named ``seed`` or
``*_seed``) within SUMO's range (``check_seed``), so a bad value fails here, before anything is built. Each package owns the parameter dataclass of its own logic; this module composes them
into the run config.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from pathlib import Path
from typing import Any, Literal, TypeVar, get_args, get_origin, get_type_hints

import yaml

from cosim.errors import ConfigError, CosimError

T = TypeVar("T")

SEED_MAX = 2**31 - 1  # SUMO's --seed is a 32-bit signed integer; numpy takes any integer >= 0


def check_seed(value: int, path: str = "seed") -> int:
    """A seed every consumer accepts (numpy: >= 0, SUMO: a 32-bit integer); else a ConfigError naming it."""
    if not 0 <= value <= SEED_MAX:
        raise ConfigError(path, f"must be an integer from 0 to {SEED_MAX} (SUMO's seed range), got {value}")
    return value


def _is_seed(name: str) -> bool:
    return name == "seed" or name.endswith("_seed")


def _type_name(tp: Any) -> str:
    origin = get_origin(tp)
    if origin is Literal:
        return " | ".join(repr(a) for a in get_args(tp))
    if origin in (typing.Union, types.UnionType):
        return " | ".join(_type_name(a) for a in get_args(tp))
    if tp is float:
        return "a number"
    if tp is int:
        return "an integer"
    if tp is bool:
        return "true or false"
    if tp is str:
        return "a string"
    if tp is type(None):
        return "null"
    if dataclasses.is_dataclass(tp):
        return "a mapping"
    return getattr(tp, "__name__", str(tp))


def _convert(value: Any, tp: Any, path: str) -> Any:
    origin = get_origin(tp)
    if tp is Any:
        return value
    if origin is Literal:
        if value in get_args(tp):
            return value
        raise ConfigError(path, f"expected {_type_name(tp)}, got {value!r}")
    if origin in (typing.Union, types.UnionType):
        args = get_args(tp)
        if value is None and type(None) in args:
            return None
        others = [a for a in args if a is not type(None)]
        if len(others) == 1:  # X | None: report X's own, precise error
            return _convert(value, others[0], path)
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _convert(value, arg, path)
            except ConfigError as exc:
                errors.append(exc)
        raise ConfigError(path, f"expected {_type_name(tp)}, got {value!r}")
    if dataclasses.is_dataclass(tp):
        return from_dict(tp, value, path)
    if tp is bool:
        if isinstance(value, bool):
            return value
        raise ConfigError(path, f"expected true or false, got {value!r}")
    if tp is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise ConfigError(path, f"expected an integer, got {value!r}")
    if tp is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            if not math.isfinite(value):  # nan / inf: no duration, rate or distance is infinite
                raise ConfigError(path, f"expected a finite number, got {value!r}")
            return float(value)
        raise ConfigError(path, f"expected a number, got {value!r}")
    if tp is str:
        if isinstance(value, str):
            return value
        raise ConfigError(path, f"expected a string, got {value!r}")
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(path, f"expected a list, got {value!r}")
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(v, args[0], f"{path}[{i}]") for i, v in enumerate(value))
        if len(args) != len(value):
            raise ConfigError(path, f"expected a list of {len(args)} items, got {len(value)}")
        return tuple(_convert(v, a, f"{path}[{i}]") for i, (v, a) in enumerate(zip(args, value, strict=True)))
    if origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(path, f"expected a mapping, got {value!r}")
        key_tp, val_tp = get_args(tp)
        return {_convert(k, key_tp, path): _convert(v, val_tp, f"{path}.{k}") for k, v in value.items()}
    raise TypeError(f"config type {tp!r} at {path} is not supported by the loader")


def from_dict(cls: type[T], data: Any, path: str = "") -> T:
    """Build the frozen dataclass ``cls`` from a mapping; unknown keys and bad types raise ConfigError."""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(path, f"expected a mapping, got {data!r}")
    hints = get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(map(str, data)) - set(fields))
    if unknown:
        key = unknown[0]
        where = f"{path}.{key}" if path else key
        raise ConfigError(where, f"unknown key (known keys here: {', '.join(sorted(fields))})")
    kwargs = {}
    for name, field in fields.items():
        where = f"{path}.{name}" if path else name
        if name in data:
            kwargs[name] = _convert(data[name], hints[name], where)
            if _is_seed(name) and isinstance(kwargs[name], int):
                check_seed(kwargs[name], where)
        elif field.default is dataclasses.MISSING and field.default_factory is dataclasses.MISSING:
            raise ConfigError(where, "missing (this key is required)")
    try:
        obj = cls(**kwargs)
    except ConfigError:
        raise
    except (ValueError, TypeError) as exc:  # __post_init__ validation of impossible values
        raise ConfigError(path, str(exc)) from None
    return obj


def to_dict(obj: Any) -> Any:
    """The inverse of from_dict: plain dicts / lists that YAML or JSON can write."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_dict(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, (list, tuple)):
        return [to_dict(v) for v in obj]
    if isinstance(obj, dict):
        return {k: to_dict(v) for k, v in obj.items()}
    return obj


def read_yaml(path: str | Path) -> dict:
    """Read a YAML mapping; a missing file or bad YAML is a CosimError naming the file."""
    path = Path(path)
    if not path.is_file():
        raise CosimError(f"config file {path} does not exist")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        raise CosimError(
            f"config file {path} is not valid YAML{where}: {getattr(exc, 'problem', exc)}"
        ) from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise CosimError(f"config file {path} must hold a mapping of keys, not {type(data).__name__}")
    return data


def load(cls: type[T], path: str | Path) -> T:
    """Load a YAML file into the frozen dataclass ``cls``."""
    return from_dict(cls, read_yaml(path))

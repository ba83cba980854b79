"""Locating and running SUMO's command-line tools (netconvert, polyconvert, duarouter, sumo).

The binaries come from the ``eclipse-sumo`` wheel; SUMO_HOME is taken from it and PROJ's data directory is
set so that netconvert/polyconvert can project OSM coordinates.
"""

from __future__ import annotations

import os
import re
import subprocess
from collections import Counter
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from cosim.errors import CosimError


@cache
def sumo_home() -> Path:
    import sumo  # the eclipse-sumo wheel

    return Path(sumo.SUMO_HOME)


def sumo_env() -> dict[str, str]:
    home = sumo_home()
    env = dict(os.environ)
    env["SUMO_HOME"] = str(home)
    env["PROJ_DATA"] = env["PROJ_LIB"] = str(home / "data" / "proj")
    return env


def binary(name: str) -> str:
    path = sumo_home() / "bin" / name
    if not path.exists():
        raise CosimError(
            f"SUMO tool {name} not found at {path}; reinstall the eclipse-sumo wheel (make clean test)"
        )
    return str(path)


@cache
def sumo_version() -> str:
    out = subprocess.run([binary("sumo"), "--version"], capture_output=True, text=True, env=sumo_env()).stdout
    match = re.search(r"(?:Version|sumo) (\d[\w.+-]*)", out)
    return match.group(1) if match else "unknown"


@dataclass(frozen=True)
class ToolRun:
    returncode: int
    warnings: Counter  # message pattern (numbers and quoted ids stripped) -> count
    errors: list[str]
    log: str


_VARYING = re.compile(r"'[^']*'|\"[^\"]*\"|-?\d+(\.\d+)?")


def _pattern(line: str) -> str:
    return _VARYING.sub("…", line.split(":", 1)[-1].strip())[:90]


def run_tool(name: str, args: list[str], cwd: Path | None = None) -> ToolRun:
    """Run a SUMO tool, collecting its warnings by pattern instead of dumping them."""
    proc = subprocess.run([binary(name), *args], capture_output=True, text=True, cwd=cwd, env=sumo_env())
    log = proc.stdout + proc.stderr
    warnings: Counter = Counter()
    errors = []
    for line in log.splitlines():
        if line.startswith("Warning:"):
            warnings[_pattern(line)] += 1
        elif line.startswith("Error:"):
            errors.append(line[len("Error:") :].strip())
    return ToolRun(proc.returncode, warnings, errors, log)


def summarise_warnings(tool: str, run: ToolRun, top: int = 3) -> str:
    """One line: how many warnings and the most frequent kinds."""
    total = sum(run.warnings.values())
    if not total:
        return f"{tool}: no warnings"
    common = "; ".join(f"{n}x {p}" for p, n in run.warnings.most_common(top))
    return f"{tool}: {total} warnings ({common})"

"""``build_scenario``: OSM file -> a runnable SUMO scenario directory, cached by content and options."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from cosim.config import to_dict
from cosim.errors import CosimError
from cosim.scenario.behaviour import ScvBehaviour
from cosim.scenario.buildings import build_buildings
from cosim.scenario.demand import DemandParams, build_demand
from cosim.scenario.driving_side import lookup_version as side_lookup_version
from cosim.scenario.driving_side import resolve as resolve_driving_side
from cosim.scenario.network import OPTIONS_DIR, build_network, pass1_options
from cosim.scenario.osm import read_osm
from cosim.scenario.routetable import RouteTable
from cosim.scenario.signs import SIGN_KINDS, derive_signs, write_signs
from cosim.sumo_bridge.network import read_network
from cosim.sumo_bridge.tools import summarise_warnings, sumo_version

CACHE_FORMAT = 27  # bump when the layout of the cached files changes
# the code a build runs: any change to it builds anew. A number bumped by hand was not enough: a change tried
# and reverted under one number left its networks in the cache for the next change that took that number
PIPELINE_SOURCES = (  # check.py runs a built scenario in plain SUMO and builds nothing
    *sorted(p for p in Path(__file__).parent.glob("*.py") if p.name != "check.py"),
    Path(__file__).parents[1] / "sumo_bridge" / "network.py",
    Path(__file__).parents[1] / "sumo_bridge" / "tools.py",
)
NETWORK_FILES = ("network.net.xml", "buildings.poly.xml", "signs.add.xml", "network.json", "netconvert.log")
SCENARIO_FILES = (*NETWORK_FILES, "routes.rou.xml", "scenario.sumocfg", "report.json")


@dataclass(frozen=True)
class ScenarioConfig:
    map: str = "configs/maps/krems.osm.gz"  # OSM file (.osm or .osm.gz), relative to the config's folder
    demand: DemandParams = field(default_factory=DemandParams)
    behaviour: ScvBehaviour = field(default_factory=ScvBehaviour)
    # which side traffic keeps to: auto = the country the extract lies in (cosim.scenario.driving_side)
    driving_side: Literal["auto", "right", "left"] = "auto"


@dataclass(frozen=True)
class Scenario:
    dir: Path
    report: dict

    net_file = property(lambda self: self.dir / "network.net.xml")
    routes_file = property(lambda self: self.dir / "routes.rou.xml")
    buildings_file = property(lambda self: self.dir / "buildings.poly.xml")
    signs_file = property(lambda self: self.dir / "signs.add.xml")
    sumocfg = property(lambda self: self.dir / "scenario.sumocfg")


def cache_dir() -> Path:
    """Where built networks, scenarios and the route table live ($COSIM_CACHE_DIR or ~/.cache/cosim)."""
    return Path(os.environ.get("COSIM_CACHE_DIR") or Path.home() / ".cache" / "cosim")


# the cache keeps this many scenarios ($COSIM_CACHE_MAX_SCENARIOS): a sweep builds one per seed and density,
# 5-7 MB each on the benchmark maps, so without a bound it grows by gigabytes. Beyond it the scenarios unused
# longest go, and networks no scenario kept refers to, with their routes in the route table
CACHE_MAX_SCENARIOS = 200
# ... but never one used within this time: an experiment's participants and a replay read a scenario long
# after it was built or last looked up [s]
CACHE_KEEP_S = 86400.0


def _touch(path: Path) -> None:
    """Mark a cache entry used now (its last use orders the eviction)."""
    try:
        os.utime(path)
    except OSError:
        pass  # evicted meanwhile, or a read-only cache: nothing to order


def evict_stale(root: Path, keep: frozenset[str] = frozenset(), now: float | None = None) -> list[str]:
    """Remove the scenarios unused longest beyond CACHE_MAX_SCENARIOS (never ``keep``, never one used within
    CACHE_KEEP_S), then networks no remaining scenario refers to, unused as long, and their routes. Safe
    beside other processes: an entry leaves by an atomic rename before it is deleted. Returns the keys
    removed."""
    limit = int(os.environ.get("COSIM_CACHE_MAX_SCENARIOS") or CACHE_MAX_SCENARIOS)
    now = time.time() if now is None else now
    entries = []
    for d in (root / "scenarios").glob("*/report.json"):
        try:
            entries.append((d.stat().st_mtime, d.parent))
        except OSError:
            continue
    entries.sort()
    removed, left = [], len(entries)
    for used, d in entries:
        if left <= limit:
            break
        if d.name in keep or now - used < CACHE_KEEP_S:
            continue
        if _discard(d, root):
            removed.append(d.name)
            left -= 1
    if not removed:
        return removed
    needed = set()
    for d in (root / "scenarios").glob("*/report.json"):
        try:
            needed.add(json.loads(d.read_text())["cache"]["network_key"])
        except (OSError, ValueError, KeyError):
            continue
    gone = []
    for n in (root / "networks").glob("*/network.json"):
        try:
            stale = n.parent.name not in needed and now - n.stat().st_mtime >= CACHE_KEEP_S
        except OSError:
            continue
        if stale and _discard(n.parent, root):
            gone.append(n.parent.name)
    if gone and (root / "routes.sqlite").exists():
        table = RouteTable(root / "routes.sqlite", "")
        try:
            table.forget(gone)
        finally:
            table.close()
    return removed + gone


def _discard(d: Path, root: Path) -> bool:
    """Take a cache entry out of view (atomically) and delete it; False when another process was first."""
    trash = root / f".evicted-{d.name}-{os.getpid()}"
    try:
        os.replace(d, trash)
    except OSError:
        return False
    shutil.rmtree(trash, ignore_errors=True)
    return True


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _key(*parts) -> str:
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()[:24]


def pipeline_digest() -> str:
    """sha256 over the source of the scenario pipeline (``PIPELINE_SOURCES``)."""
    h = hashlib.sha256()
    for path in PIPELINE_SOURCES:
        h.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


def _network_key(osm_sha: str, behaviour: ScvBehaviour, driving_side: str) -> str:
    option_files = sorted((p.name, _sha256(p)) for p in OPTIONS_DIR.iterdir())
    side = f"auto ({side_lookup_version()})" if driving_side == "auto" else driving_side
    return _key(
        CACHE_FORMAT, pipeline_digest(), osm_sha, option_files, pass1_options(Path("X"), Path("Y")),
        behaviour.give_way_approach_speed_kmh, side, sumo_version(),
    )  # fmt: skip


def _publish(tmp: Path, final: Path) -> None:
    """Move a finished build into place atomically; a concurrent identical build may have won the race."""
    final.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.replace(tmp, final) if not final.exists() else shutil.rmtree(tmp)
    except OSError:
        shutil.rmtree(tmp, ignore_errors=True)
        if not final.exists():
            raise


def _network_counts(net) -> dict:
    junctions = Counter(n.getType() for n in net.getNodes())
    edges = [e for e in net.getEdges() if e.getFunction() != "internal"]
    turn_lane_edges = [e for e in edges if e.getParams().get("turn:lanes")]
    return {
        "edges": len(edges),
        "lane_km": round(sum(e.getLength() * e.getLaneNumber() for e in edges) / 1000.0, 2),
        "junctions": sum(junctions.values()),
        "junctions_by_type": dict(sorted(junctions.items())),
        "traffic_lights": len(net.getTrafficLights()),
        "stop_junctions": junctions.get("priority_stop", 0),
        "allway_stop_junctions": junctions.get("allway_stop", 0),
        "turn_lane_edges": len(turn_lane_edges),
        "turn_lane_connections": sum(len(c) for e in turn_lane_edges for c in e.getOutgoing().values()),
    }


def _build_network_dir(osm, behaviour: ScvBehaviour, driving_side: str, tmp: Path) -> dict:
    t0 = time.perf_counter()
    lefthand, side_how = resolve_driving_side(driving_side, osm.centre)
    nb = build_network(osm, behaviour, tmp, lefthand=lefthand)
    t1 = time.perf_counter()
    net = read_network(nb.net_file)
    signs = derive_signs(net, nb.placements, nb.junction_kind, nb.tls_approaches, osm.signs)
    write_signs(signs, tmp / "signs.add.xml")
    n_buildings, height_sources, poly_run = build_buildings(osm.path, nb.net_file, tmp / "buildings.poly.xml")
    counts = _network_counts(net)
    counts["yield_junctions"] = sum(1 for k in nb.junction_kind.values() if k == "give_way")
    counts["signed_approaches"] = dict(Counter(nb.signed_approaches.values()))
    counts["junction_fixes"] = nb.fixes
    counts["osm_signs_unplaced"] = [
        {"node": p.sign.node_id, "kind": p.sign.kind, "why": p.note} for p in nb.placements if p.note
    ]
    counts["driving_side"] = side_how
    info = {
        "network": counts,
        "signs": {k: sum(1 for s in signs if s.kind == k) for k in SIGN_KINDS},
        "speed_limit_sources": dict(Counter(s.source for s in signs if s.kind == "speed_limit")),
        "buildings": {"count": n_buildings, "height_from": height_sources},
        "warnings": [summarise_warnings(f"netconvert {name}", run) for name, run in nb.runs]
        + [summarise_warnings("polyconvert", poly_run)],
        "timing_s": {"netconvert": round(t1 - t0, 2), "signs_buildings": round(time.perf_counter() - t1, 2)},
    }
    (tmp / "network.json").write_text(json.dumps(info, indent=1))
    return info


def _sumocfg(seed: int) -> str:
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<!-- cosim scenario: open with `sumo-gui -c scenario.sumocfg` -->
<configuration>
    <input>
        <net-file value="network.net.xml"/>
        <route-files value="routes.rou.xml"/>
        <additional-files value="buildings.poly.xml,signs.add.xml"/>
    </input>
    <time>
        <step-length value="0.1"/>
    </time>
    <routing>
        <routing-algorithm value="astar"/>
    </routing>
    <processing>
        <time-to-teleport value="120"/>
        <!-- no ignore-junction-blocker: a car that ignores a vehicle standing in the junction drives into it
             (sumo.dlr.de/docs/sumo.html: "Ignore vehicles which block the junction after they have been
             standing for SECONDS"); with 20 s, 6 of the 14 Krems collisions in 600 s were a right turn
             merging into a car that stood at the end of the straight lane (271871456). Default -1 = never -->
        <!-- a driver waiting at a minor link accepts smaller gaps as the wait grows, reaching full impatience
             after 60 s instead of SUMO's 180 s, i.e. before time-to-teleport (120 s) removes it
             (sumo.dlr.de/docs/Simulation/Intersections.html, impatience; sumo.dlr.de/docs/sumo.html
             time-to-impatience). Resolves right-before-left and merge standoffs that stood until a teleport
             or, with ignore-junction-blocker, ended in a collision (Krems 860978174, 600 s, seeds 1-3:
             collisions 4/5/3 -> 0/0/1) -->
        <time-to-impatience value="60"/>
        <!-- collisions are reported (cosim logs them), on junctions too, and only as a real overlap -->
        <collision.action value="warn"/>
        <collision.check-junctions value="true"/>
        <collision.mingap-factor value="0"/>
    </processing>
    <random_number>
        <seed value="{seed}"/>
    </random_number>
    <report>
        <no-step-log value="true"/>
    </report>
</configuration>
"""


def build_scenario(osm_path: str | Path, out: str | Path | None = None, *, density: str | None = None,
                   seed: int = 0, config: ScenarioConfig | None = None, log=print) -> Scenario:  # fmt: skip
    """Build (or fetch from the cache) the scenario for an OSM file; copy it into ``out`` if given.

    ``density`` overrides ``config.demand.density``. ``log`` receives the human-readable summary lines.
    """
    import dataclasses

    config = config or ScenarioConfig(map=str(osm_path))
    demand = config.demand
    if density is not None:
        try:
            demand = dataclasses.replace(demand, density=density)
        except ValueError as exc:
            raise CosimError(str(exc)) from None
    osm_path = Path(osm_path)
    t_start = time.perf_counter()
    if not osm_path.is_file():
        raise CosimError(f"OSM file {osm_path} does not exist")
    osm_sha = _sha256(osm_path)
    root = cache_dir()
    net_key = _network_key(osm_sha, config.behaviour, config.driving_side)
    scn_key = _key(net_key, to_dict(demand), to_dict(config.behaviour), seed)
    scn_dir = root / "scenarios" / scn_key
    cached = (scn_dir / "report.json").exists()  # only complete, valid builds are ever published
    if cached:
        _touch(scn_dir / "report.json")
    else:
        osm = read_osm(osm_path)  # validates: truncated / not OSM / no roads -> CosimError
        net_dir = root / "networks" / net_key
        net_hit = (net_dir / "network.json").exists()
        if net_hit:
            _touch(net_dir / "network.json")
        else:
            tmp = Path(tempfile.mkdtemp(prefix="net-", dir=_mkdir(root)))
            try:
                _build_network_dir(osm, config.behaviour, config.driving_side, tmp)
                _publish(tmp, net_dir)
            finally:
                shutil.rmtree(tmp, ignore_errors=True)
        info = json.loads((net_dir / "network.json").read_text())
        tmp = Path(tempfile.mkdtemp(prefix="scn-", dir=root))
        try:
            for name in NETWORK_FILES:
                shutil.copy2(net_dir / name, tmp / name)
            net = read_network(tmp / "network.net.xml")
            t0 = time.perf_counter()
            table = RouteTable(root / "routes.sqlite", net_key)
            try:
                d = build_demand(net, tmp / "network.net.xml", demand, config.behaviour,
                                 np.random.default_rng(seed), table, tmp / "routes.rou.xml", tmp)  # fmt: skip
            finally:
                table.close()
            (tmp / "scenario.sumocfg").write_text(_sumocfg(seed))
            report = {
                "osm": {
                    "file": osm_path.name,
                    "sha256": osm_sha,
                    "nodes": osm.n_nodes,
                    "ways": osm.n_ways,
                    "buildings_tagged": osm.n_buildings,
                    "drivable_ways": osm.n_drivable_ways,
                    "sign_nodes": dict(Counter(s.kind for s in osm.signs)),
                },  # fmt: skip
                **info,
                "demand": {
                    **dataclasses.asdict(d),
                    "density": demand.density,
                    "radius_m": demand.radius_m if demand.area == "around_ego" else None,
                    "horizon_s": demand.horizon_s,
                    "seed": seed,
                },  # fmt: skip
                "cache": {
                    "network": "hit" if net_hit else "built",
                    "scenario_key": scn_key,
                    "network_key": net_key,
                },
                "sumo_version": sumo_version(),
            }
            report["timing_s"] = {**info["timing_s"], "demand": round(time.perf_counter() - t0, 2)}
            (tmp / "report.json").write_text(json.dumps(report, indent=1))
            _publish(tmp, scn_dir)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        evict_stale(root, keep=frozenset({scn_key}))
    report = json.loads((scn_dir / "report.json").read_text())
    report["build_s"] = round(time.perf_counter() - t_start, 2)
    report["scenario_cache"] = "hit" if cached else "built"
    target = scn_dir
    if out is not None:
        target = Path(out)
        _copy_atomically(scn_dir, target)
    for line in summary_lines(report, target):
        log(line)
    return Scenario(target, report)


def _mkdir(p: Path) -> Path:
    p.mkdir(parents=True, exist_ok=True)
    return p


def _copy_atomically(src: Path, dst: Path) -> None:
    dst = dst.resolve()
    _mkdir(dst.parent)
    tmp = Path(tempfile.mkdtemp(prefix=f".{dst.name}-", dir=dst.parent))
    try:
        for name in SCENARIO_FILES:
            shutil.copy2(src / name, tmp / name)
        if dst.exists():
            if not (dst / "scenario.sumocfg").exists() and any(dst.iterdir()):
                raise CosimError(f"{dst} exists and is not a cosim scenario directory; choose another --out")
            shutil.rmtree(dst)
        os.replace(tmp, dst)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _traffic_line(d: dict) -> str:
    routes = f"routes: {d['routes_from_table']} from the table, {d['routes_computed']} computed"
    if d.get("area") == "around_ego":
        return (
            f"  traffic: generated around the ego at run time, {d['target_per_lane_km']} veh/lane-km "
            f"'{d['density']}' within {d['radius_m']:g} m, from a pool of {d['route_pool']} routes; {routes}"
        )
    where = ""
    if d.get("area") == "ego_route":
        where = (f" along the ego's route ({d['area_lane_km']} lane-km; `scenario.demand.area: network` fills the "
                 "whole map)")  # fmt: skip
    return (
        f"  traffic: {d['vehicles']} vehicles ({d['initial_vehicles']} at start, {d['arrival_rate_per_h']:.0f}/h), "
        f"{d['target_per_lane_km']} veh/lane-km '{d['density']}'{where}, {routes}"
    )


def summary_lines(report: dict, where: Path) -> list[str]:
    n, s, d = report["network"], report["signs"], report["demand"]
    jt = n["junctions_by_type"]
    return [
        f"scenario {where} ({report['scenario_cache']}, {report['build_s']:.1f} s) from {report['osm']['file']}",
        f"  network: {n['edges']} edges, {n['lane_km']} lane-km, {n['junctions']} junctions "
        f"({', '.join(f'{k} {v}' for k, v in jt.items())}); traffic keeps "
        f"{n['driving_side']}",
        f"  control: {n['traffic_lights']} traffic lights, {n['stop_junctions']} stop, {n['allway_stop_junctions']} "
        f"all-way stop, {n['yield_junctions']} yield junctions; {n['turn_lane_connections']} turn-lane connections",
        "  signs: " + ", ".join(f"{k} {v}" for k, v in s.items()),
        f"  buildings: {report['buildings']['count']} (height from {report['buildings']['height_from']})",
        _traffic_line(d),
        *[f"  {w}" for w in report["warnings"]],
    ]

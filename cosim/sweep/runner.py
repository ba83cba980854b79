"""Run a sweep: plan (resolve every run's config, find finished runs), pre-build scenarios, fan out, collect.

Layout of ``results/<sweep>/``::

    <run-id>/config.yaml   the resolved run config (a valid ``cosim run`` config)
    <run-id>/run.mcap      the run's log
    <run-id>/result.json   status ok | degraded | failed, error, metrics, simulation stats, wall time
                           (degraded: the run finished but its drive health is not ok; error says why)
    table.csv              one row per run (``cosim.sweep.aggregate``)
    plots/*.png            the sweep file's plots
    sweep.json             the sweep as run (spec, base config, run ids)

``result.json`` is written last and atomically, so it marks a finished run. On a re-run, a run whose
``result.json`` says ok and whose resolved config is unchanged (same ``config_sha``) is skipped; any other
run directory (failed, cut short by a crash or a killed worker, or config changed) is removed and redone.

A run whose overrides are wrong (unknown key, impossible value) fails alone at planning time with the
config loader's one-line message; it never reaches a worker.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import platform
import shutil
import time
import traceback
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cosim.config import to_dict
from cosim.errors import CosimError
from cosim.sweep.backends import WorkerLost
from cosim.sweep.spec import RunSpec, Sweep

RESULT = "result.json"
MAX_ATTEMPTS = 2  # a run in flight when its worker died is retried once within the sweep


@dataclass(frozen=True)
class RunTask:
    """Everything a worker needs for one run (plain data: it is pickled to a pool process or a Ray task)."""

    run_id: str
    run_dir: str  # absolute
    label: str
    overrides: dict[str, Any]  # the swept values
    config: dict[str, Any]  # the resolved RunConfig as plain data (cosim.config.to_dict)
    config_sha: str
    pdr_bands_m: tuple[float, ...]
    cache_dir: str | None  # COSIM_CACHE_DIR for the worker; None = the worker's own default
    radio_process: bool = False  # the run's radio in a process of its own (a core to spare per run)


@dataclass(frozen=True)
class ScenarioTask:
    """One distinct scenario (map, demand, behaviour, seed) to build before the runs fan out."""

    map: str
    scenario: dict[str, Any]  # ScenarioConfig as plain data
    seed: int
    cache_dir: str | None


@dataclass
class SweepResult:
    out_dir: Path
    results: list[dict]  # result.json contents, in the sweep's run order
    skipped: int  # runs already done before this call
    table: Path | None = None
    plots: list[Path] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # plots left out, and why

    @property
    def ok(self) -> int:
        return sum(r["status"] == "ok" for r in self.results)

    @property
    def failed(self) -> list[dict]:
        return [r for r in self.results if r["status"] == "failed"]

    @property
    def degraded(self) -> list[dict]:
        return [r for r in self.results if r["status"] == "degraded"]


def config_sha(config_dict: dict) -> str:
    return hashlib.sha256(json.dumps(config_dict, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted (Ctrl-C)"
    text = str(exc).strip().splitlines()
    msg = text[0] if text else ""
    return msg if isinstance(exc, CosimError) and msg else f"{type(exc).__name__}: {msg}".rstrip(": ")


def _write_json_atomic(path: Path, data: dict) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(data, indent=1, default=str) + "\n")
    os.replace(tmp, path)


def read_result(run_dir: str | Path) -> dict | None:
    try:
        return json.loads((Path(run_dir) / RESULT).read_text())
    except (OSError, ValueError):
        return None


def _failed(run_id: str, label: str, overrides: dict, error: str, **extra) -> dict:
    return {"run_id": run_id, "status": "failed", "error": error, "label": label, "overrides": overrides,
            "metrics": {}, **extra}  # fmt: skip


# -- in the worker ---------------------------------------------------------------------------------------------
def _use_cache(cache_dir: str | None) -> None:
    if cache_dir:
        os.environ["COSIM_CACHE_DIR"] = cache_dir


def prebuild_scenario(task: ScenarioTask) -> str | None:
    """Build (or find in the cache) one scenario; returns None, or the one-line error."""
    _use_cache(task.cache_dir)
    try:
        from cosim.config import from_dict
        from cosim.scenario import ScenarioConfig, build_scenario

        cfg = from_dict(ScenarioConfig, task.scenario)
        build_scenario(task.map, config=cfg, seed=task.seed, log=lambda *a: None)
        return None
    except BaseException as exc:  # noqa: BLE001 - reported against the runs that use this scenario
        return _one_line(exc)


def execute_run(task: RunTask) -> dict:
    """Run one simulation into ``task.run_dir`` and write its ``result.json``; never raises for a run's own
    failure (the error goes into the result)."""
    t0 = time.perf_counter()
    _use_cache(task.cache_dir)
    run_dir = Path(task.run_dir)
    result = {"run_id": task.run_id, "label": task.label, "overrides": task.overrides,
              "seed": task.config.get("seed"), "config_sha": task.config_sha, "host": platform.node(),
              "pid": os.getpid(), "metrics": {}}  # fmt: skip
    try:
        import yaml

        from cosim.config import from_dict
        from cosim.runconfig import RunConfig
        from cosim.sim import Simulation
        from cosim.sweep.aggregate import run_metrics

        if run_dir.exists():  # a partial directory of an unfinished run: start clean
            shutil.rmtree(run_dir)
        run_dir.mkdir(parents=True)
        (run_dir / "config.yaml").write_text(yaml.safe_dump(task.config, sort_keys=False))
        config = from_dict(RunConfig, task.config)
        with Simulation(config, out_dir=run_dir, quiet=True, log=lambda *a: None,
                        radio_process=task.radio_process) as sim:  # fmt: skip
            stats = sim.run()
        if stats.get("interrupted"):
            raise KeyboardInterrupt
        result["stats"] = stats
        result["metrics"] = run_metrics(run_dir / "run.mcap", stats=stats, pdr_bands_m=task.pdr_bands_m,
                                        run_dir=run_dir)  # fmt: skip
        health = stats["health"]
        if health["status"] == "ok":
            result.update(status="ok", error=None)
        else:  # finished, but its numbers stand on a drive that did not happen as planned
            result.update(status="degraded", error="degraded drive: " + "; ".join(health["problems"]))
    except BaseException as exc:  # noqa: BLE001 - a run's failure (or Ctrl-C) is recorded, the sweep goes on
        result.update(status="failed", error=_one_line(exc))
        if not isinstance(exc, (CosimError, KeyboardInterrupt)):
            result["traceback"] = traceback.format_exc()
    result["wall_s"] = round(time.perf_counter() - t0, 3)
    result["finished_at"] = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
        _write_json_atomic(run_dir / RESULT, result)
    except OSError as exc:
        result.update(status="failed", error=f"cannot write {run_dir / RESULT}: {exc}")
    return result


# -- in the parent -----------------------------------------------------------------------------------------------
@dataclass
class PlannedRun:
    run: RunSpec
    run_dir: Path
    task: RunTask | None  # None when the config could not be resolved
    state: str  # "done" (skip) | "todo" | "redo" (finished with another config) | "failed" (bad config)
    result: dict | None = None  # for done / failed


def _resolve_overrides(sweep: Sweep, run: RunSpec) -> dict[str, Any]:
    spec = sweep.spec
    values: dict[str, Any] = {**spec.overrides, **run.overrides}
    if spec.duration_s is not None:
        values["duration_s"] = spec.duration_s
    if run.seed is not None:
        values["seed"] = run.seed
    values["name"] = f"{spec.name}-{run.run_id}"
    m = values.get("scenario.map")
    if isinstance(m, str) and not Path(m).is_absolute() and (sweep.folder / m).exists():
        values["scenario.map"] = str((sweep.folder / m).resolve())  # a map named in the sweep file
    return values


def load_config(base: Path | None, overrides: dict[str, Any]):
    """The resolved RunConfig of one run. Like ``load_run_config`` (map paths resolved the same way), but a
    null override is applied too (``vanet: null`` turns the radio off) instead of meaning "not given"."""
    from cosim.config import from_dict
    from cosim.errors import ConfigError
    from cosim.runconfig import RunConfig, load_run_config

    config = load_run_config(base, **{k: v for k, v in overrides.items() if v is not None})
    nulls = [k for k, v in overrides.items() if v is None]
    if not nulls:
        return config
    data = to_dict(config)
    for key in nulls:
        *parents, leaf = key.split(".")
        node: dict | None = data
        for p in parents:
            if node.get(p, {}) is None:  # a parent is null already: nothing left to null
                node = None
                break
            node = node.setdefault(p, {})  # an unknown key is created here and rejected by from_dict
            if not isinstance(node, dict):
                raise ConfigError(key, "cannot override inside a non-mapping value")
        if node is not None:
            node[leaf] = None
    return from_dict(RunConfig, data)


def plan(sweep: Sweep, out_dir: Path) -> list[PlannedRun]:
    """Resolve every run's config and decide what to do with it (no side effects)."""
    from cosim.scenario import cache_dir

    explicit_cache = os.environ.get("COSIM_CACHE_DIR")
    cache = str(cache_dir().resolve()) if explicit_cache else None
    planned = []
    for run in sweep.runs():
        run_dir = (out_dir / run.run_id).resolve()
        try:
            config = load_config(sweep.base_config, _resolve_overrides(sweep, run))
        except Exception as exc:  # noqa: BLE001 - ConfigError mostly; anything else is still this run's fault
            res = _failed(run.run_id, run.label(), run.overrides, _one_line(exc), seed=run.seed)
            planned.append(PlannedRun(run, run_dir, None, "failed", res))
            continue
        data = to_dict(config)
        task = RunTask(run.run_id, str(run_dir), run.label(), run.overrides, data, config_sha(data),
                       sweep.spec.pdr_bands_m, cache)  # fmt: skip
        prev = read_result(run_dir)
        finished = prev and prev.get("status") in ("ok", "degraded")
        if finished and prev.get("config_sha") == task.config_sha:
            planned.append(PlannedRun(run, run_dir, task, "done", prev))
        else:
            state = "redo" if finished else "todo"
            planned.append(PlannedRun(run, run_dir, task, state))
    return planned


def _scenario_key(task: RunTask) -> str:
    return json.dumps([task.config["scenario"], task.config["seed"]], sort_keys=True)


class Reporter:
    """Progress lines: one per finished run, ``[k/n] ok|FAILED id label ...``."""

    def __init__(self, total: int, out: Callable[[str], None]):
        self.total = total
        self.k = 0
        self.out = out

    def run(self, res: dict) -> None:
        self.k += 1
        head = f"[{self.k:>{len(str(self.total))}}/{self.total}]"
        if res["status"] == "ok":
            st = res.get("stats", {})
            rtf = st.get("real_time_factor")
            extra = f"{res.get('wall_s', 0):.1f} s" + (f", {rtf:g}x real time" if rtf else "")
            self.out(f"{head} ok     {res['run_id']}  {res['label']}  ({extra})")
        elif res["status"] == "degraded":
            self.out(f"{head} DEGRADED {res['run_id']}  {res['label']}: {res['error']}")
        else:
            self.out(f"{head} FAILED {res['run_id']}  {res['label']}: {res['error']}")


def _prebuild(planned: list[PlannedRun], backend, say: Callable[[str], None]) -> dict[str, str]:
    """Build every distinct scenario once before the runs fan out; returns scenario key -> error.

    One scenario per distinct network (map + SCV behaviour) is built first, in this process: that runs
    netconvert, the slow part that parallel workers must not race on. The other scenarios (demand for other
    seeds / densities on an already built network) are built in parallel on the backend."""
    tasks: dict[str, ScenarioTask] = {}
    for p in planned:
        t = p.task
        sc = t.config["scenario"]
        tasks.setdefault(_scenario_key(t), ScenarioTask(sc["map"], sc, t.config["seed"], t.cache_dir))
    networks: dict[str, list[str]] = {}
    for key, st in tasks.items():
        networks.setdefault(json.dumps([st.map, st.scenario["behaviour"]], sort_keys=True), []).append(key)
    errors: dict[str, str] = {}
    rest: list[str] = []
    for keys in networks.values():
        st = tasks[keys[0]]
        say(f"building scenario {Path(st.map).name} (seed {st.seed}) ...")
        err = prebuild_scenario(st)
        if err:  # the network itself failed: every scenario on it fails the same way
            errors.update(dict.fromkeys(keys, err))
        else:
            rest += keys[1:]
    if rest:
        say(f"building {len(rest)} more scenario(s) (other seeds / demand) on {backend.describe()} ...")
        for st, outcome in backend.map_unordered(prebuild_scenario, [tasks[k] for k in rest]):
            if isinstance(outcome, str):
                errors[json.dumps([st.scenario, st.seed], sort_keys=True)] = outcome
            # None: built. WorkerLost or another exception: not fatal, the run builds the scenario itself
    return errors


def _execute(
    tasks: list[RunTask], backend, on_result: Callable[[dict], None], say: Callable[[str], None]
) -> None:
    """Run the tasks; a run whose worker died is retried once, then recorded as failed."""
    attempts: Counter[str] = Counter()
    spare = getattr(backend, "spare_core_per_run", False)
    pending = [dataclasses.replace(t, radio_process=spare) for t in tasks]
    while pending:
        lost: list[RunTask] = []
        progress = False
        for task, outcome in backend.map_unordered(execute_run, pending):
            if isinstance(outcome, dict):
                on_result(outcome)
                progress = True
                continue
            if isinstance(outcome, WorkerLost):
                prev = read_result(task.run_dir)
                if prev is not None and prev.get("config_sha") == task.config_sha:
                    on_result(prev)  # it finished just before its worker went
                    progress = True
                    continue
                if Path(task.run_dir).exists():  # it had started
                    attempts[task.run_id] += 1
                    progress = True
                if attempts[task.run_id] < MAX_ATTEMPTS:
                    if Path(task.run_dir).exists():
                        say(f"worker died while running {task.run_id} ({outcome}); running it again")
                    lost.append(task)
                    continue
                error = f"worker process died while running this run ({MAX_ATTEMPTS} attempts): {outcome}"
            else:
                error = f"worker error: {_one_line(outcome)}"
            res = _failed(task.run_id, task.label, task.overrides, error, seed=task.config.get("seed"),
                          config_sha=task.config_sha)  # fmt: skip
            _record(task, res)
            on_result(res)
            progress = True
        if lost and not progress:  # workers die before starting anything: do not loop forever
            for task in lost:
                res = _failed(task.run_id, task.label, task.overrides, "worker processes die before starting a run",
                              seed=task.config.get("seed"), config_sha=task.config_sha)  # fmt: skip
                _record(task, res)
                on_result(res)
            lost = []
        for task in lost:  # so that an existing folder means "started" again in the next round
            shutil.rmtree(task.run_dir, ignore_errors=True)
        pending = lost


def _record(task: RunTask, res: dict) -> None:
    try:
        Path(task.run_dir).mkdir(parents=True, exist_ok=True)
        _write_json_atomic(Path(task.run_dir) / RESULT, res)
    except OSError:
        pass


def run_sweep(sweep: Sweep, *, backend=None, out_dir: str | Path | None = None, say: Callable[[str], None] = print,
              aggregate: bool = True) -> SweepResult:  # fmt: skip
    """Run every unfinished run of ``sweep`` on ``backend`` (default: a local pool), then write table.csv
    and the plots. Returns what happened; failed runs are in ``result.failed`` (they do not raise)."""
    from cosim.sweep.backends import make_backend

    out = Path(out_dir) if out_dir else Path("results") / sweep.spec.name
    out.mkdir(parents=True, exist_ok=True)
    planned = plan(sweep, out)
    todo = [p for p in planned if p.state in ("todo", "redo")]
    done = [p for p in planned if p.state == "done"]
    bad = [p for p in planned if p.state == "failed"]
    _write_json_atomic(out / "sweep.json", {
        "spec": to_dict(sweep.spec), "sweep_file": str(sweep.path) if sweep.path else None,
        "base_config": str(sweep.base_config) if sweep.base_config else None,
        "runs": [{"run_id": p.run.run_id, "overrides": p.run.overrides, "seed": p.run.seed} for p in planned],
    })  # fmt: skip
    own_backend = backend is None
    if own_backend and todo:
        backend = make_backend("local", jobs=None, n_runs=len(todo))
    redo = sum(p.state == "redo" for p in todo)
    say(f"sweep {sweep.spec.name}: {len(planned)} runs, {len(done)} already done"
        + (f", {redo} redone (config changed)" if redo else "")
        + (f", {len(bad)} with a bad config" if bad else "")
        + (f"; {len(todo)} to run on {backend.describe()}" if todo else "") + f" -> {out}")  # fmt: skip
    results: dict[str, dict] = {p.run.run_id: p.result for p in done}
    reporter = Reporter(len(todo) + len(bad), say)

    def finished(res: dict) -> None:
        results[res["run_id"]] = res
        reporter.run(res)

    try:
        for p in bad:
            if p.run_dir.exists():
                shutil.rmtree(p.run_dir)
            p.run_dir.mkdir(parents=True)
            _write_json_atomic(p.run_dir / RESULT, p.result)
            finished(p.result)
        if todo:
            for p in todo:  # partial directories are redone cleanly (the worker also starts clean)
                if p.run_dir.exists():
                    shutil.rmtree(p.run_dir)
            errors = _prebuild(todo, backend, say)
            ready = []
            for p in todo:
                err = errors.get(_scenario_key(p.task))
                if err:
                    res = _failed(p.run.run_id, p.task.label, p.run.overrides, f"scenario: {err}",
                                  seed=p.task.config.get("seed"), config_sha=p.task.config_sha)  # fmt: skip
                    _record(p.task, res)
                    finished(res)
                else:
                    ready.append(p.task)
            _execute(ready, backend, finished, say)
    finally:
        if own_backend and backend is not None:
            backend.close()
    ordered = [results[p.run.run_id] for p in planned if p.run.run_id in results]
    result = SweepResult(out, ordered, skipped=len(done))
    if aggregate:
        from cosim.sweep.aggregate import aggregate as agg

        result.table, result.plots, result.notes = agg(sweep, ordered, out)
    return result

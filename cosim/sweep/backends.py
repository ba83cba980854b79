"""Where the runs of a sweep execute: a local process pool, or Ray tasks on a cluster.

A backend has one job: ``map_unordered(fn, items)`` yields ``(item, outcome)`` as each call finishes,
where outcome is fn's return value or the exception it raised. A worker that died under a call (killed,
out of memory, crashed inside SUMO) gives ``WorkerLost``; the runner decides whether to retry.

libsumo runs one simulation per process, so a run is the unit of work: every worker process (pool
process or Ray worker) runs one simulation at a time; consecutive runs in one process are fine (libsumo
closes and restarts cleanly).
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from cosim.childproc import available_cores
from cosim.errors import CosimError


class WorkerLost(RuntimeError):
    """The process running a call died before returning (killed, out of memory, crashed)."""


def _die_with_parent() -> None:
    """Pool initializer: on Linux, the worker gets SIGKILL when the sweep process dies (no orphan runs)."""
    try:
        import ctypes
        import signal

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


class LocalBackend:
    """A ``concurrent.futures`` process pool with the spawn start method (no state forked from the parent:
    libsumo, open files and threads do not survive ``fork`` well)."""

    name = "local"

    def __init__(self, jobs: int):
        if jobs < 1:
            raise CosimError(f"--jobs must be >= 1, got {jobs}")
        self.jobs = jobs
        self._pool: ProcessPoolExecutor | None = None

    def describe(self) -> str:
        return f"a local process pool ({self.jobs} worker{'s' if self.jobs > 1 else ''})"

    @property
    def spare_core_per_run(self) -> bool:
        """Each run can have a second core (for its radio process: cosim.phases.vanet_process)."""
        return 2 * self.jobs <= available_cores()

    def _get_pool(self) -> ProcessPoolExecutor:
        if self._pool is None:
            self._pool = ProcessPoolExecutor(max_workers=self.jobs, mp_context=multiprocessing.get_context("spawn"),
                                             initializer=_die_with_parent)  # fmt: skip
        return self._pool

    def _abort(self) -> None:
        """Stop now (Ctrl-C, an error in the caller): cancel what is queued and end the running workers; their
        runs have no result.json and are redone by the next call."""
        if self._pool is None:
            return
        procs = list((getattr(self._pool, "_processes", None) or {}).values())
        self._pool.shutdown(wait=False, cancel_futures=True)
        for proc in procs:
            proc.terminate()
        for proc in procs:
            proc.join(10)
        self._pool = None

    def map_unordered(self, fn: Callable, items: Iterable) -> Iterator[tuple[Any, Any]]:
        items = list(items)
        if not items:
            return
        pool = self._get_pool()
        futures: dict[Future, Any] = {pool.submit(fn, item): item for item in items}
        pending = set(futures)
        broken = False
        try:
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for fut in done:
                    item = futures[fut]
                    try:
                        yield item, fut.result()
                    except BrokenProcessPool:
                        broken = True
                        yield item, WorkerLost("a worker process died (killed or crashed)")
                    except Exception as exc:  # noqa: BLE001 - the runner reports it against the run
                        yield item, exc
        except BaseException:  # KeyboardInterrupt, or the caller closed the generator early
            self._abort()
            raise
        if broken:  # a broken pool cannot be reused: the next map starts a fresh one
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


def _import_ray():
    try:
        import ray
    except ImportError:
        raise CosimError(
            "the Ray backend needs Ray: pip install 'cosim[ray]' (or use --backend local)"
        ) from None
    return ray


class RayBackend:
    """Each call is a Ray task with ``num_cpus=1``: joins the cluster at ``address`` or starts a local one.

    Workers find scenario builds and the route table in the cache (``cosim.scenario.cache_dir()``); on a
    cluster of several machines point ``COSIM_CACHE_DIR`` (and the sweep's results folder and maps) to a
    shared filesystem, otherwise each node builds every scenario once for itself.
    """

    name = "ray"

    def __init__(self, address: str | None = None, jobs: int | None = None):
        if jobs is not None and jobs < 1:
            raise CosimError(f"--jobs must be >= 1, got {jobs}")
        ray = _import_ray()
        self.ray = ray
        self.jobs = jobs
        self.address = address
        self._owns = not ray.is_initialized()  # a caller that already called ray.init keeps its session
        self._remote: dict[Callable, Any] = {}
        if self._owns:
            kwargs: dict[str, Any] = {"include_dashboard": False, "logging_level": "WARNING", "log_to_driver": False,
                                      "configure_logging": True}  # fmt: skip
            if address:
                kwargs["address"] = address
            else:
                kwargs["num_cpus"] = jobs or available_cores()
            try:
                ray.init(**kwargs)
            except Exception as exc:  # noqa: BLE001 - connection refused, bad address, version mismatch ...
                where = f"join the Ray cluster at {address}" if address else "start a local Ray instance"
                raise CosimError(f"could not {where}: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}"
                                 ) from None  # fmt: skip

    def describe(self) -> str:
        cpus = int(self.ray.cluster_resources().get("CPU", 0))
        where = f"cluster {self.address}" if self.address else "a local instance"
        cap = f", at most {self.jobs} at a time" if self.jobs and self.address else ""
        return f"Ray ({where}, {cpus} CPUs{cap})"

    def _task(self, fn: Callable):
        if fn not in self._remote:
            # no retries by Ray itself: a lost worker is reported as WorkerLost and the runner retries the run
            # once, as with the local pool
            self._remote[fn] = self.ray.remote(num_cpus=1, max_retries=0)(fn)
        return self._remote[fn]

    def map_unordered(self, fn: Callable, items: Iterable) -> Iterator[tuple[Any, Any]]:
        ray = self.ray
        from ray.exceptions import RayTaskError

        task = self._task(fn)
        queue = list(items)
        queue.reverse()
        window = (
            self.jobs if (self.jobs and self.address) else len(queue)
        )  # a local instance has num_cpus=jobs
        refs: dict[Any, Any] = {}
        try:
            while queue or refs:
                while queue and len(refs) < max(1, window):
                    item = queue.pop()
                    refs[task.remote(item)] = item
                done, _ = ray.wait(list(refs), num_returns=1)
                for ref in done:
                    item = refs.pop(ref)
                    try:
                        yield item, ray.get(ref)
                    except RayTaskError as exc:  # fn raised: report the original exception
                        cause = exc.as_instanceof_cause()
                        yield item, getattr(exc, "cause", None) or cause
                    except Exception as exc:  # noqa: BLE001 - WorkerCrashedError, node lost, object lost ...
                        yield (
                            item,
                            WorkerLost(f"Ray worker lost: {type(exc).__name__}: {str(exc).splitlines()[0]}"),
                        )
        finally:
            for ref in refs:
                ray.cancel(ref, force=True)

    def close(self) -> None:
        if self._owns and self.ray.is_initialized():
            self.ray.shutdown()


def make_backend(kind: str, *, jobs: int | None, n_runs: int, address: str | None = None):
    """The backend for ``--backend kind``; ``jobs`` defaults to min(cores, runs)."""
    if kind == "local":
        if address:
            raise CosimError("--address joins a Ray cluster: use it with --backend ray")
        return LocalBackend(jobs if jobs is not None else max(1, min(available_cores(), n_runs)))
    if kind == "ray":
        default = None if address else max(1, min(available_cores(), n_runs))
        return RayBackend(address, jobs if jobs is not None else default)
    raise CosimError(f"unknown backend {kind!r} (local | ray)")

"""Parameter sweeps: many runs of one base config (grid x runs x seeds) on a process pool or a Ray cluster.

``load_sweep(path)`` reads a sweep file, ``run_sweep(sweep, backend=...)`` runs what is not done yet and
writes ``results/<sweep>/table.csv`` and plots; ``cosim sweep`` is ``cosim.sweep.cli``.
"""

from cosim.sweep.aggregate import metrics_from_topics, run_metrics
from cosim.sweep.backends import LocalBackend, RayBackend, WorkerLost, make_backend
from cosim.sweep.runner import SweepResult, execute_run, plan, run_sweep
from cosim.sweep.spec import PlotSpec, RunSpec, Sweep, SweepSpec, expand, load_sweep, run_id, sweep_from_spec

__all__ = [
    "LocalBackend",
    "PlotSpec",
    "RayBackend",
    "RunSpec",
    "Sweep",
    "SweepResult",
    "SweepSpec",
    "WorkerLost",
    "execute_run",
    "expand",
    "load_sweep",
    "make_backend",
    "metrics_from_topics",
    "plan",
    "run_id",
    "run_metrics",
    "run_sweep",
    "sweep_from_spec",
]

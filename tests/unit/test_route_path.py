"""The ego's route path: projection of the car onto it."""

from __future__ import annotations

import numpy as np

from cosim.phases.ego import RoutePath


def path_through(points: list[tuple[float, float]]) -> RoutePath:
    """A RoutePath over a hand-made centre line (the network part is not needed to project)."""
    p = RoutePath.__new__(RoutePath)
    p.xy = np.asarray(points, dtype=np.float64)
    p.s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p.xy, axis=0).T))])
    p.length_m = float(p.s[-1])
    p._last_s = 0.0
    return p


def test_a_later_pass_close_by_does_not_capture_the_projection():
    """A route that comes back 1.5 m beside itself a few points later (a block round, then the parallel
    road): the car 1 m off its current pass stays on it, though the later pass is nearer."""
    p = path_through([(0, 0), (100, 0), (100, 200), (300, 200), (300, 1.5), (-50, 1.5)])
    for x in np.arange(0.0, 95.0, 2.0):
        s, offset = p.project(float(x), 1.0)
        assert abs(s - x) < 1e-9 and abs(offset - 1.0) < 1e-9
    # driving the whole route, the car is found on each pass in turn
    p._last_s = 0.0
    for s_true in np.arange(0.0, p.length_m, 2.0):
        x, y = np.interp(s_true, p.s, p.xy[:, 0]), np.interp(s_true, p.s, p.xy[:, 1])
        s, offset = p.project(float(x), float(y))
        assert abs(s - s_true) < 1e-6 and abs(offset) < 1e-6

"""The ego's route path: projection of the car onto it."""

from __future__ import annotations

import numpy as np

from cosim.driver.route import RoutePath


def path_through(points: list[tuple[float, float]]) -> RoutePath:
    """A RoutePath over a hand-made centre line (the network part is not needed to project)."""
    return RoutePath(points)


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


def test_a_second_point_tracked_near_its_own_arc_position_leaves_the_ego_projection_alone():
    """The lead's rear is projected near its own arc position; the ego's last hit stays where it was."""
    p = path_through([(0, 0), (100, 0), (100, 200), (300, 200), (300, 1.5), (-50, 1.5)])
    s_ego, _ = p.project(10.0, 0.5)
    s_lead, off = p.project(100.5, 30.0, near_s=120.0)
    assert abs(s_lead - 130.0) < 1e-9 and abs(off + 0.5) < 1e-9  # right of the northward pass
    assert p._last_s == s_ego

"""A collision SUMO reports for the ego counts only when the car's own body touches the other vehicle: the
twin sits on the lane SUMO matched the car's pose to, which may be a neighbouring internal lane."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from cosim.sumo_bridge.bridge import SumoBridge, _footprint
from cosim.world import EGO_ID


def test_a_footprint_lies_behind_the_front_bumper():
    body = _footprint(10.0, 20.0, 90.0, 4.5, 1.8)  # heading east: the body reaches 4.5 m west
    assert body.bounds == pytest.approx((5.5, 19.1, 10.0, 20.9))
    assert body.area == pytest.approx(4.5 * 1.8)


def _bridge(ego_pose, other_pose):
    """A bridge whose SUMO answers for one other vehicle ``scv1`` at ``other_pose`` (x, y, heading); the ego's
    car was written at ``ego_pose``."""
    poses = {"scv1": other_pose}
    veh = SimpleNamespace(getPosition=lambda v: poses[v][:2], getAngle=lambda v: poses[v][2],
                          getLength=lambda v: 4.5, getWidth=lambda v: 1.8)  # fmt: skip
    bridge = SumoBridge.__new__(SumoBridge)
    bridge._sumo = SimpleNamespace(vehicle=veh)
    bridge.ego_id, bridge._ego_pose, bridge._pose_off_road = EGO_ID, ego_pose, False
    return bridge


def test_an_overlap_of_the_twin_alone_is_not_a_collision_of_the_car():
    """Monaco seed 2: the car turning right 2.7 m from scv1 waiting at its line, the twin on the
    neighbouring internal lane on top of it."""
    waiting = (1050.7, 500.4, 243.0)
    assert not _bridge((1048.7, 497.3, 353.0), waiting)._bodies_touch(EGO_ID, "scv1")
    assert _bridge((1050.6, 500.2, 20.0), waiting)._bodies_touch(
        "scv1", EGO_ID
    )  # the car's nose in its front


def test_collisions_without_the_ego_are_sumos_own():
    assert _bridge((0.0, 0.0, 0.0), (500.0, 500.0, 0.0))._bodies_touch("scv1", "scv2")

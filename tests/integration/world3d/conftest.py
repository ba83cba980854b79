"""Fixtures for the 3D view: an OpenGL check, and a small map with one tall building beside the road.

The map (tests/osm_factory.OsmSketch, metres east / north of the sketch origin): a signalised crossroads of
an east-west primary road and a north-south residential road (arms of 300 m), and a 20 m x 20 m building
of 15 m height whose south-west corner is 30 m east and 20 m north of the junction.
"""

from __future__ import annotations

import os

import pytest

import cosim.world3d.render as render  # sets MUJOCO_GL=egl before MuJoCo is used for rendering
from cosim.errors import CosimError

BUILDING_SKETCH = ((30.0, 20.0), (50.0, 20.0), (50.0, 40.0), (30.0, 40.0))  # [m] x east, y north
BUILDING_HEIGHT_M = 15.0


@pytest.fixture(scope="session")
def gl():
    """Skip (with the reason) when this machine cannot make an offscreen OpenGL context."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><geom type='box' size='1 1 1'/></worldbody></mujoco>"
    )
    try:
        r = render.open_renderer(model, 32, 32)
    except CosimError as exc:
        pytest.skip(f"no offscreen OpenGL (MUJOCO_GL={os.environ.get('MUJOCO_GL')}): {exc}")
    r.render()
    r.close()
    return True


def small_map():
    from osm_factory import crossroads

    sk = crossroads(major="primary", minor="residential", centre_tags={"highway": "traffic_signals"})
    names = []
    for i, (x, y) in enumerate(BUILDING_SKETCH):
        names.append(sk.node(f"b{i}", x, y))
    sk.ways.append(("900", [*names, names[0]], {"building": "yes", "height": f"{BUILDING_HEIGHT_M:g}"}))
    return sk


@pytest.fixture(scope="session")
def small_scenario(tmp_path_factory):
    """(Scenario, sketch): the small map built once per session (into the session's test cache)."""
    from cosim.scenario import build_scenario

    sk = small_map()
    d = tmp_path_factory.mktemp("world3d-map")
    osm = sk.write(d / "crossroads_building.osm")
    scn = build_scenario(osm, density="low", seed=1, log=lambda *a: None)
    return scn, sk, osm

"""Log payloads: the template-encoded /scene equals json.dumps of its dict form, and the background writer
process writes the same messages as writing in-process."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cosim.log import McapLog, read
from cosim.log.recorder import _json_floats, _scene, _traffic
from cosim.log.writer import encode


def _scene_dict(t, ids, cx, cy, heading, length, width, is_ego) -> dict:
    """The SceneUpdate as a dict, one entity per vehicle (the form the template encoding must reproduce)."""
    sec = int(t)
    stamp = {"sec": sec, "nsec": int(round((t - sec) * 1e9))}
    entities = []
    for i, vid in enumerate(ids):
        yaw = math.radians(90.0 - float(heading[i]))
        color = (
            {"r": 0.9, "g": 0.1, "b": 0.1, "a": 1.0}
            if is_ego[i]
            else {"r": 0.3, "g": 0.5, "b": 0.9, "a": 0.9}
        )
        entities.append({
            "timestamp": stamp, "frame_id": "map", "id": vid, "lifetime": {"sec": 0, "nsec": 0},
            "frame_locked": False, "metadata": [], "arrows": [],
            "cubes": [{"pose": {"position": {"x": round(float(cx[i]), 2), "y": round(float(cy[i]), 2), "z": 0.75},
                                "orientation": {"x": 0.0, "y": 0.0, "z": round(math.sin(yaw / 2), 6),
                                                "w": round(math.cos(yaw / 2), 6)}},
                       "size": {"x": float(length[i]), "y": float(width[i]), "z": 1.5}, "color": color}],
            "spheres": [], "cylinders": [], "lines": [], "triangles": [], "texts": [], "models": [],
        })  # fmt: skip
    return {"deletions": [{"timestamp": stamp, "type": 1, "id": ""}], "entities": entities}


def _vehicles(n: int, seed: int):
    rng = np.random.default_rng(seed)
    ids = [f"scv{i}" for i in range(n)] + ['odd "id" \u00e9']
    n += 1
    cx, cy = rng.uniform(-2000, 2000, n), rng.uniform(-2000, 2000, n)
    cx[:6] = [0.0, -0.0, -0.004, 2.675, 1.005, -1073741824.0]  # signed zero, ties, SUMO's invalid position
    heading = rng.uniform(0, 360, n)
    length, width = rng.choice([4.3, 5.0, 12.0], n), rng.choice([1.8, 2.55], n)
    is_ego = np.zeros(n, bool)
    is_ego[3] = True
    return ids, cx, cy, heading, length, width, is_ego


@pytest.mark.parametrize("t", [0.0, 12.3, 3.0000000001, 599.9])
def test_scene_template_matches_the_dict_encoding(t):
    cols = _vehicles(300, seed=int(t * 10))
    assert _scene(t, *cols) == encode(_scene_dict(t, *cols))


def test_scene_non_finite_values_become_null_like_the_dict_encoding():
    ids, cx, cy, heading, length, width, is_ego = _vehicles(20, seed=1)
    cx[4], cy[7], heading[9], length[2] = np.nan, np.inf, np.nan, -np.inf
    cols = (ids, cx, cy, heading, length, width, is_ego)
    assert _scene(1.5, *cols) == encode(_scene_dict(1.5, *cols))
    assert _scene(1.5, [], *(np.zeros(0),) * 5, np.zeros(0, bool)) == encode(_scene_dict(1.5, [], *([],) * 6))


def test_json_floats_are_what_json_dumps_writes():
    rng = np.random.default_rng(3)
    values = [*rng.normal(0, 1000, 5000).tolist(), *rng.normal(0, 1e-4, 200).tolist(), 0.0, -0.0, 0.125, -0.005, 1e-9,
              -7.1e-05, 9.99996e-05, 123456789.995, 1e15, -3e17]  # fmt: skip
    assert _json_floats(values) == [json.dumps(v) for v in values]
    for nd in (1, 2, 3, 6):
        assert _json_floats(values, nd) == [json.dumps(round(v, nd)) for v in values]
    assert _json_floats([1.0, math.nan, -math.inf], 2) == ["1.0", "null", "null"]


@pytest.mark.parametrize("background", [True, False])
def test_writer_process_writes_what_the_in_process_writer_writes(tmp_path, background):
    ids, cx, cy, heading, length, width, is_ego = _vehicles(50, seed=2)
    idx = np.arange(len(ids))
    path = tmp_path / f"{background}.mcap"
    with McapLog(path, background=background) as log:
        log.metadata("cosim", {"seed": 3, "step_s": 0.1})
        for step in range(30):
            t = step * 0.1
            log.write("/ego/state", t, {"t_s": t, "step": step, "x_m": float(cx[0]) + step, "gap": math.nan})
            log.write_deferred("/traffic/vehicles", t, _traffic, t, step, ids, idx, cx, cy, heading, cx, cy,
                               ["e1"] * len(ids), np.zeros(len(ids), np.int16), np.zeros(len(ids), np.int32))  # fmt: skip
            log.write_deferred("/scene", t, _scene, t, ids, cx, cy, heading, length, width, is_ego)
    got = read(path, keep_raw=True)
    assert not got.truncated and got.metadata["cosim"] == {"seed": "3", "step_s": "0.1"}
    assert got.counts == {"/ego/state": 30, "/traffic/vehicles": 30, "/scene": 30}
    assert got.raw["/scene"][7] == encode(
        _scene_dict(0.7000000000000001, ids, cx, cy, heading, length, width, is_ego)
    )
    assert json.loads(got.raw["/ego/state"][0])["gap"] is None
    traffic = json.loads(got.raw["/traffic/vehicles"][4])
    assert traffic["x_m"] == np.round(cx, 2).tolist() and traffic["id"] == ids and traffic["step"] == 4

"""The channel schemas: valid JSON schemas, in step with what the code writes, and the stored Foxglove schema
equal to the one generated from Foxglove's official package."""

from __future__ import annotations

import pytest

jsonschema = pytest.importorskip("jsonschema")

from cosim.log import foxglove_schemas, schemas  # noqa: E402


@pytest.mark.parametrize("topic", sorted(schemas.TOPIC_SCHEMAS))
def test_each_topic_schema_is_a_valid_json_schema(topic):
    jsonschema.Draft202012Validator.check_schema(schemas.TOPIC_SCHEMAS[topic])
    assert schemas.TOPIC_SCHEMAS[topic]["title"] != schemas.GENERIC["title"]


def test_stored_foxglove_schema_is_the_official_one():
    pytest.importorskip("foxglove_schemas_protobuf")
    for name in foxglove_schemas.NAMES:
        assert foxglove_schemas.stored(name) == foxglove_schemas.from_protobuf(name), (
            f"{name}: regenerate with `python cosim/log/foxglove_schemas.py`"
        )


def test_radio_schemas_follow_the_layer_columns_and_codes():
    from cosim.vanet import cam, channel, layer

    for spec, schema in ((layer.TX_COLUMNS, schemas.VANET_TX), (layer.RX_COLUMNS, schemas.VANET_RX),
                         (layer.LOAD_COLUMNS, schemas.VANET_LOAD), (layer.STEP_COLUMNS, schemas.VANET_STEP)):  # fmt: skip
        assert list(schema["properties"]) == list(spec)
    assert schemas.RX_OUTCOMES == channel.OUTCOME_NAMES
    assert [getattr(channel, n.upper()) for n in schemas.RX_OUTCOMES] == list(range(len(schemas.RX_OUTCOMES)))
    codes = [cam.TRIGGER_NONE, cam.TRIGGER_FIRST, cam.TRIGGER_DYNAMICS, cam.TRIGGER_TIMER]
    assert codes == list(range(len(schemas.CAM_TRIGGERS)))


def test_rx_outcome_is_a_named_enum_and_nullable_fields_accept_null():
    rx = jsonschema.Draft202012Validator(schemas.VANET_RX)
    row = {k: [0] for k in schemas.VANET_RX["properties"]}
    assert rx.is_valid({**row, "outcome": [2], "rx_power_dbm": [None]})
    assert not rx.is_valid({**row, "outcome": [9]})
    titles = [o["title"] for o in schemas.VANET_RX["properties"]["outcome"]["items"]["oneOf"]]
    assert titles == ["ok", "below_sensitivity", "shadowed", "collided", "damaged"]
    ego = jsonschema.Draft202012Validator(schemas.EGO_STATE)
    base = {"t_s": 0.1, "step": 1, "id": "ego", "x_m": 0, "y_m": 0, "heading_deg": 0, "speed_mps": 0,
            "accel_mps2": 0, "edge": "e", "lane_index": 0, "lane_pos_m": 0, "lateral_offset_m": 0, "on_road": True}  # fmt: skip
    assert ego.is_valid({**base, "leader_id": None, "leader_gap_m": None, "sign": None})
    assert not ego.is_valid({**base, "unknown_field": 1})  # a field added to the log must be declared


def test_scene_with_vehicles_and_lit_lamps_is_a_valid_scene_update():
    import json

    import numpy as np

    from cosim.log.recorder import _scene

    lamps = [(np.array([10.0, 20.0, 2.98]), "r"), (np.array([11.5, 20.0, 2.42]), "g")]
    data = _scene(3.5, ["scv1", "ego"], np.array([1.0, 2.0]), np.array([3.0, 4.0]), np.array([0.0, 90.0]),
                  np.array([5.0, 4.5]), np.array([1.8, 1.8]), np.array([False, True]), lamps)  # fmt: skip
    msg = json.loads(data)
    jsonschema.validate(msg, schemas.SCENE_UPDATE)
    assert [e["id"] for e in msg["entities"]] == ["scv1", "ego", "traffic_light_lamps"]
    spheres = msg["entities"][2]["spheres"]
    assert [s["pose"]["position"]["z"] for s in spheres] == [2.98, 2.42]
    assert spheres[0]["color"]["r"] == 1.0 and spheres[1]["color"]["g"] == 1.0
    only_lamps = json.loads(_scene(0.0, [], *(np.zeros(0),) * 5, np.zeros(0, bool), lamps))
    assert [e["id"] for e in only_lamps["entities"]] == ["traffic_light_lamps"]

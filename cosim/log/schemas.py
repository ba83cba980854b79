"""JSON schemas of the MCAP channels. Per-vehicle channels carry columns (lists of equal length) so that a
step of 1000 vehicles is one message; ``cosim.log.read`` explodes them back into rows."""

from __future__ import annotations


def _obj(title: str, props: dict[str, str | dict], required: tuple[str, ...] = ()) -> dict:
    def one(t):
        return t if isinstance(t, dict) else {"type": t}

    return {"title": title, "type": "object", "properties": {k: one(v) for k, v in props.items()},
            "required": list(required)}  # fmt: skip


def _cols(kind: str) -> dict:
    return {"type": "array", "items": {"type": kind}}


EGO_STATE = _obj(
    "cosim.EgoState",
    {"t_s": "number", "step": "integer", "id": "string", "x_m": "number", "y_m": "number",
     "heading_deg": "number", "speed_mps": "number", "accel_mps2": "number", "edge": "string",
     "lane_index": "integer", "lane_pos_m": "number", "lateral_offset_m": "number", "on_road": "boolean",
     "leader_id": "string", "leader_gap_m": "number", "throttle": "number", "brake": "number", "steer": "number"},
    ("t_s", "step"),
)  # fmt: skip
TRAFFIC_VEHICLES = _obj(
    "cosim.TrafficVehicles",
    {"t_s": "number", "step": "integer", "id": _cols("string"), "slot": _cols("integer"), "x_m": _cols("number"),
     "y_m": _cols("number"), "heading_deg": _cols("number"), "speed_mps": _cols("number"),
     "accel_mps2": _cols("number"), "edge": _cols("string"), "lane_index": _cols("integer"),
     "signals": _cols("integer")},
    ("t_s", "step"),
)  # fmt: skip
TRAFFIC_LIGHTS = _obj(
    "cosim.TrafficLights",
    {"t_s": "number", "step": "integer", "id": _cols("string"), "state": _cols("string")},
    ("t_s", "step"),
)
EVENT = _obj(
    "cosim.Event",
    {"t_s": "number", "step": "integer", "kind": "string", "vehicle": "string", "detail": "string",
     "value": "number"},
    ("t_s", "kind"),
)  # fmt: skip
GENERIC = {"title": "cosim.Record", "type": "object", "additionalProperties": True}

_VEC3 = _obj("Vector3", {"x": "number", "y": "number", "z": "number"})
_QUAT = _obj("Quaternion", {"x": "number", "y": "number", "z": "number", "w": "number"})
_COLOR = _obj("Color", {"r": "number", "g": "number", "b": "number", "a": "number"})
_TIME = _obj("Time", {"sec": "integer", "nsec": "integer"})
# foxglove.SceneUpdate as published by Foxglove (the parts cosim uses: cube primitives).
SCENE_UPDATE = {
    "title": "foxglove.SceneUpdate",
    "type": "object",
    "properties": {
        "deletions": {"type": "array", "items": _obj("foxglove.SceneEntityDeletion",
                                                       {"timestamp": _TIME, "type": "integer", "id": "string"})},
        "entities": {"type": "array", "items": _obj(
            "foxglove.SceneEntity",
            {"timestamp": _TIME, "frame_id": "string", "id": "string", "lifetime": _obj("Duration", {"sec": "integer", "nsec": "integer"}),
             "frame_locked": "boolean",
             "metadata": {"type": "array", "items": _obj("KeyValuePair", {"key": "string", "value": "string"})},
             "cubes": {"type": "array", "items": _obj(
                 "foxglove.CubePrimitive",
                 {"pose": _obj("Pose", {"position": _VEC3, "orientation": _QUAT}), "size": _VEC3, "color": _COLOR})}},
        )},
    },
}  # fmt: skip

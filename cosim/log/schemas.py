"""JSON schemas of the MCAP channels, one per topic (``TOPIC_SCHEMAS``).

Per-vehicle and per-radio-event channels carry columns (lists of equal length) so that a step of 1000
vehicles is one message; ``cosim.log.read`` explodes them back into rows. Every cosim schema lists every
field the run writes (``additionalProperties: false``), and a field that can be null says so (JSON has no
NaN/inf: the writer stores them as null). Coded values are enums with names (``oneOf`` of ``const`` +
``title``, the form Foxglove's own schemas use), e.g. ``/vanet/rx``'s ``outcome``. ``/map`` and ``/scene``
use Foxglove's official ``foxglove.SceneUpdate`` schema, ``/tf`` ``foxglove.FrameTransform``
(``cosim.log.foxglove_schemas``).

tests/integration/test_log_schemas_run.py validates every message of a short default run against these.
"""

from __future__ import annotations

from cosim.log import foxglove_schemas

NUM, INT, STR, BOOL = "number", "integer", "string", "boolean"


def nullable(t: str | dict) -> dict:
    """A value that may be null (a missing reading, or a NaN/inf the writer stored as null)."""
    if isinstance(t, str):
        return {"type": [t, "null"]}
    return {"anyOf": [t, {"type": "null"}]}


def named_enum(title: str, names: tuple[str, ...] | dict[int, str]) -> dict:
    """An integer code with a name per value, as Foxglove's schemas write enums."""
    items = names.items() if isinstance(names, dict) else enumerate(names)
    return {"title": title, "oneOf": [{"title": name, "const": code} for code, name in items]}


def string_enum(*values: str) -> dict:
    return {"type": "string", "enum": list(values)}


def _obj(title: str, props: dict[str, str | dict], required: tuple[str, ...] | None = None,
         description: str = "") -> dict:  # fmt: skip
    """An object schema; ``required`` defaults to every field (cosim always writes all of them)."""

    def one(t):
        return t if isinstance(t, dict) else {"type": t}

    out = {"title": title, "type": "object", "properties": {k: one(v) for k, v in props.items()},
           "required": list(props) if required is None else list(required), "additionalProperties": False}  # fmt: skip
    if description:
        out["description"] = description
    return out


def cols(t: str | dict) -> dict:
    """A column: one value per row."""
    return {"type": "array", "items": t if isinstance(t, dict) else {"type": t}}


EGO_STATE = _obj(
    "cosim.EgoState",
    {"t_s": NUM, "step": INT, "id": STR, "x_m": NUM, "y_m": NUM, "heading_deg": NUM, "speed_mps": NUM,
     "accel_mps2": NUM, "edge": STR, "lane_index": INT, "lane_pos_m": NUM, "lateral_offset_m": NUM,
     "on_road": BOOL,
     # the ego phase (controls, the physics car, the driver's percept): null before the driver perceived
     "throttle": NUM, "brake": NUM, "steer": NUM, "physics_speed_mps": NUM, "path_offset_m": nullable(NUM),
     "leader_id": nullable(STR), "leader_gap_m": nullable(NUM), "tls_state": nullable(STR),
     "sign": nullable(STR), "sign_dist_m": nullable(NUM), "junction_conflict": BOOL,
     "junction_gap_s": nullable(NUM), "driver_mode": STR,
     # with a lead car: the ego set its pace this step (it waited or was held below its lane's limit)
     "lead_paced": BOOL},
    ("t_s", "step", "id", "x_m", "y_m", "heading_deg", "speed_mps", "accel_mps2", "edge", "lane_index",
     "lane_pos_m", "lateral_offset_m", "on_road"),
    "The ego vehicle, one message per step (SUMO's view of it, plus the MuJoCo ego's controls and percept).",
)  # fmt: skip
TRAFFIC_VEHICLES = _obj(
    "cosim.TrafficVehicles",
    {"t_s": NUM, "step": INT, "id": cols(STR), "slot": cols(INT), "x_m": cols(NUM), "y_m": cols(NUM),
     "heading_deg": cols(NUM), "speed_mps": cols(NUM), "accel_mps2": cols(NUM), "edge": cols(STR),
     "lane_index": cols(INT), "signals": cols(INT)},
    description="Every SUMO vehicle but the ego, as columns (one row per vehicle).",
)  # fmt: skip
TRAFFIC_LIGHTS = _obj(
    "cosim.TrafficLights",
    {"t_s": NUM, "step": INT, "id": cols(STR), "state": cols(STR)},
    description="Traffic lights whose SUMO state string changed at this step.",
)
EVENT = _obj(
    "cosim.Event",
    {"t_s": NUM, "step": INT, "kind": STR, "vehicle": STR, "detail": STR, "value": nullable(NUM)},
    description="A SUMO event: teleport, collision, emergency_stop, ego_off_road, ...",
)  # fmt: skip

# -- radio (cosim.vanet.layer: TX_COLUMNS, RX_COLUMNS, LOAD_COLUMNS, STEP_COLUMNS) ---------------------------
RX_OUTCOMES = (
    "ok",
    "below_sensitivity",
    "shadowed",
    "collided",
    "damaged",
)  # cosim.vanet.channel.OUTCOME_NAMES
CAM_TRIGGERS = ("none", "first", "dynamics", "timer")  # cosim.vanet.cam.TRIGGER_*
VANET_TX = _obj(
    "cosim.VanetTx",
    {"t_s": cols(NUM), "sender_slot": cols(INT), "sender_station_id": cols(INT), "frame": cols(INT),
     "slot": cols(INT), "size_bytes": cols(INT), "gen_t_s": cols(NUM), "has_lf": cols(BOOL),
     "n_path_points": cols(INT), "trigger": cols(named_enum("cosim.CamTrigger", CAM_TRIGGERS)),
     "timeout": cols(INT), "offset": cols(INT)},
    description="CAM transmissions of the step, one row per transmission: those with a row in /vanet/rx "
                "(vanet.tx_log: rx, the default; with rx_log: ego the CAMs the ego's receiver evaluated) or every "
                "station's (tx_log: all).",
)  # fmt: skip
VANET_RX = _obj(
    "cosim.VanetRx",
    {"t_s": cols(NUM), "sender_slot": cols(INT), "sender_station_id": cols(INT), "receiver_slot": cols(INT),
     "receiver_station_id": cols(INT), "frame": cols(INT), "slot": cols(INT), "distance_m": cols(NUM),
     "outcome": cols(named_enum("cosim.RxOutcome", RX_OUTCOMES)),
     "rx_power_dbm": cols(nullable(NUM)), "gen_t_s": cols(NUM)},
    description="Receptions of the step (one row per transmission and receiver); rx_power_dbm is null "
                "where line of sight is blocked.",
)  # fmt: skip
VANET_LOAD = _obj(
    "cosim.VanetLoad",
    {"frame": cols(INT), "t_s": cols(NUM), "n_slots": cols(INT), "busy_slots": cols(INT),
     "multi_tx_slots": cols(INT), "tx_count": cols(INT), "busy_ratio": cols(NUM), "airtime_ratio": cols(NUM),
     "cbr_mean": cols(nullable(NUM)), "cbr_p95": cols(nullable(NUM)), "cbr_ego": cols(nullable(NUM))},
    description="Channel load, one row per completed SOTDMA frame: map-wide slot use (busy_ratio, "
                "airtime_ratio) and the channel busy ratio the stations sense (cbr_*; null without stations / ego).",
)  # fmt: skip
VANET_STEP = _obj(
    "cosim.VanetStep",
    {"t_s": cols(NUM), "n_stations": cols(INT), "cams_generated": cols(INT), "cams_dropped": cols(INT),
     "tx_count": cols(INT), "rx_count": cols(INT), "links_evaluated": cols(INT)},
    description="Radio layer counters, one row per step.",
)  # fmt: skip

# -- assistance systems (cosim.phases.adas) --------------------------------------------------------------
SYSTEMS = string_enum("none", "A", "B")
B_LEVELS = string_enum("none", "advisory", "warning")
ADAS_STATE = _obj(
    "cosim.AdasState",
    {"t_s": NUM, "phase": STR, "system": SYSTEMS, "time_gap_true_s": nullable(NUM),
     "time_gap_displayed_s": nullable(NUM), "warning": string_enum("none", "advisory", "warning"),
     "leader_id": STR, "leader_speed_mps": nullable(NUM), "gap_true_m": nullable(NUM), "a_lit": BOOL,
     "a_perceived": BOOL, "a_measured_m": nullable(NUM), "a_reason": STR, "b_gap_s": nullable(NUM),
     "b_level": B_LEVELS, "b_status": string_enum("ok", "no_cam", "stale"), "b_age_s": nullable(NUM),
     "b_station": INT, "b_leader_id": STR},
    description="What systems A and B would show, next to the true time gap, one message per step. "
                "system: what the driver sees; warning: its state; b_gap_s: system B's time gap [s].",
)  # fmt: skip
ADAS_EVENT = _obj(
    "cosim.AdasEvent",
    {"t_s": NUM, "system": string_enum("A", "B"), "kind": string_enum("display", "perceived", "level", "data"),
     "old": STR, "new": STR, "value": nullable(NUM)},
)  # fmt: skip
ADAS_EVENTS = _obj(
    "cosim.AdasEvents", {"t_s": NUM, "events": {"type": "array", "items": ADAS_EVENT}},
    description="Transitions of what systems A and B show.",
)  # fmt: skip

# -- the run's own verdict (cosim.health.DriveHealth.report), written once when the run closes ---------------
HEALTH = _obj(
    "cosim.Health",
    {"t_s": NUM, "window_s": NUM, "ego_present_at_s": nullable(NUM), "ego_states": INT, "ego_distance_m": NUM,
     "longest_standstill_s": NUM, "longest_standstill_not_red_s": NUM, "stalls": INT,
     "following_share": nullable(NUM), "lead_leader_share": nullable(NUM),
     "lead_paced_share": nullable(NUM), "cut_ins": nullable(INT), "collisions": INT, "ego_collisions": INT,
     "teleports": INT, "vehicles_departed": INT,
     "teleport_share": NUM, "ego_off_road": INT, "off_road_s": NUM,
     "problems": {"type": "array", "items": {"type": STR}}, "status": string_enum("ok", "degraded")},
    description="The drive's health over the whole run: ego presence and distance, standstills, following, "
                "cut-ins, collisions, teleports, time off the road; status 'degraded' with the problems "
                "found.",
)  # fmt: skip

SCENE_UPDATE = foxglove_schemas.stored("foxglove.SceneUpdate")
FRAME_TRANSFORM = foxglove_schemas.stored("foxglove.FrameTransform")

TOPIC_SCHEMAS: dict[str, dict] = {
    "/ego/state": EGO_STATE,
    "/traffic/vehicles": TRAFFIC_VEHICLES,
    "/traffic/lights": TRAFFIC_LIGHTS,
    "/events": EVENT,
    "/vanet/tx": VANET_TX,
    "/vanet/rx": VANET_RX,
    "/vanet/load": VANET_LOAD,
    "/vanet/step": VANET_STEP,
    "/adas/state": ADAS_STATE,
    "/adas/events": ADAS_EVENTS,
    "/health": HEALTH,  # written by cosim.sim when the run closes
    "/map": SCENE_UPDATE,  # the static map, once at t = 0
    "/scene": SCENE_UPDATE,  # the vehicles, every log.scene_every_steps
    "/tf": FRAME_TRANSFORM,  # the ego's frame "ego" in "map", every step (a 3D panel can follow it)
}
FOXGLOVE_TOPICS = ("/map", "/scene", "/tf")

# Catch-all for a topic nobody declared yet (cosim.log.writer falls back to it). Every topic a run writes
# should be in TOPIC_SCHEMAS: the schema test fails on a topic that uses this.
GENERIC = {"title": "cosim.Record", "type": "object", "additionalProperties": True}

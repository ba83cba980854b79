"""The log phase: what a step writes to the run's MCAP file.

Every topic's channel is registered with its schema from ``cosim.log.schemas.TOPIC_SCHEMAS`` when it is
first written. With the Foxglove scene on (``log.scene_every_steps`` > 0), ``/map`` gets the scenario's
static map once at t = 0 (``cosim.log.map_scene``) and ``/scene`` the vehicles every that many steps.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from cosim.log.map_scene import map_scene_json, signal_lamps
from cosim.log.schemas import TOPIC_SCHEMAS
from cosim.log.writer import McapLog
from cosim.outputs import StepOutputs
from cosim.runconfig import LogConfig
from cosim.world import EGO_ID, SumoEvent, World


def _r(a: np.ndarray, nd: int) -> list:
    """Round for a compact, deterministic JSON payload."""
    return np.round(a, nd).tolist()


class LogBridge(Protocol):
    """What the log reads of SUMO beyond the snapshot (``cosim.sumo_bridge.SumoBridge`` provides it)."""

    ego_on_road: bool

    def traffic_lights(self) -> tuple[list[str], list[str]]: ...


class Recorder:
    """The log phase. Ports: the MCAP writer (``log``), its config,
    SUMO's light states and the ego's on-road verdict (``bridge``), the scenario's folder (for ``/map``),
    the read-only network view (``network``, called only when the scene is on: the signal lamps) and whether
    the run writes ``/health`` when it closes. ``step`` is given the snapshot, the phases' outputs of the
    step and its events."""

    def __init__(self, log: McapLog, config: LogConfig, *, bridge: LogBridge, scenario_dir: str | Path,
                 network: Callable[[], Any], health: bool):  # fmt: skip
        self.log = log
        self.cfg = config
        self.bridge = bridge
        self._tls_state: dict[str, str] = {}
        self._channels: set[str] = set()
        if health:  # cosim.sim writes /health itself, when the run closes
            self._channel("/health")
        self._lamps: list[tuple[str, int, np.ndarray]] = []
        if self.cfg.scene_every_steps:
            self._channel("/map")
            self.log.write_deferred("/map", 0.0, map_scene_json, str(scenario_dir))
            self._lamps = signal_lamps(network())  # the lamps /scene lights (the poles are on /map)

    def _channel(self, topic: str) -> None:
        """Register ``topic`` with its declared schema before its first message."""
        self._channels.add(topic)
        self.log.channel(topic, TOPIC_SCHEMAS.get(topic))

    def step(self, w: World, outputs: StepOutputs, events: Sequence[SumoEvent],
             lights: tuple[list[str], list[str]] | None = None) -> None:  # fmt: skip
        """The step into the log: the ego, the traffic, the lights, the events, the phases' messages and the
        Foxglove scene. ``lights``: the traffic lights' (ids, states) of the step, when SUMO has gone on
        since (default: asked now)."""
        t, step, log = w.t_s, w.step, self.log
        ego = w.ego_slot
        if ego >= 0:
            msg = {
                "t_s": t, "step": step, "id": EGO_ID, "x_m": round(float(w.x_m[ego]), 3), "y_m": round(float(w.y_m[ego]), 3),
                "heading_deg": round(float(w.heading_deg[ego]), 3), "speed_mps": round(float(w.speed_mps[ego]), 4),
                "accel_mps2": round(float(w.accel_mps2[ego]), 4),
                "edge": w.edge_of(ego),
                "lane_index": int(w.lane_index[ego]), "lane_pos_m": round(float(w.lane_pos_m[ego]), 3),
                "lateral_offset_m": round(float(w.lateral_offset_m[ego]), 3),
                "on_road": bool(self.bridge.ego_on_road),
            }  # fmt: skip
            msg.update(outputs.ego_log)
            if "/ego/state" not in self._channels:
                self._channel("/ego/state")
            log.write("/ego/state", t, msg)
            if self.cfg.scene_every_steps:  # the ego's frame for Foxglove's 3D panel (follow "ego")
                if "/tf" not in self._channels:
                    self._channel("/tf")
                log.write("/tf", t, _ego_frame(t, w, ego))
        every = self.cfg.traffic_every_steps
        if every and step % every == 0:  # built and encoded by the writer, from copies of the columns
            if "/traffic/vehicles" not in self._channels:
                self._channel("/traffic/vehicles")
            idx = np.flatnonzero(w.valid & ~w.is_ego)
            names = w.edge_names
            log.write_deferred("/traffic/vehicles", t, _traffic, t, step, [w.ids[i] for i in idx.tolist()], idx,
                               w.x_m[idx], w.y_m[idx], w.heading_deg[idx], w.speed_mps[idx], w.accel_mps2[idx],
                               [names[c] if c >= 0 else "" for c in w.edge_code[idx].tolist()], w.lane_index[idx],
                               w.signals[idx])  # fmt: skip
        ids, states = lights if lights is not None else self.bridge.traffic_lights()
        changed = [(i, s) for i, s in zip(ids, states, strict=True) if self._tls_state.get(i) != s]
        if changed:
            self._tls_state.update(changed)
            if "/traffic/lights" not in self._channels:
                self._channel("/traffic/lights")
            log.write("/traffic/lights", t, {"t_s": t, "step": step, "id": [c[0] for c in changed],
                                             "state": [c[1] for c in changed]})  # fmt: skip
        for ev in events:
            if "/events" not in self._channels:
                self._channel("/events")
            log.write("/events", t, {"t_s": t, "step": step, "kind": ev.kind, "vehicle": ev.vehicle,
                                     "detail": ev.detail, "value": ev.value})  # fmt: skip
        for topic, msg in outputs.log.items():  # other phases' (/vanet/*, /adas/*, ...)
            if topic not in self._channels:
                self._channel(topic)
            log.write(topic, t, msg)
        scene_every = self.cfg.scene_every_steps
        if scene_every and step % scene_every == 0:
            if "/scene" not in self._channels:
                self._channel("/scene")
            cx, cy = w.centre_xy()
            idx = np.flatnonzero(w.valid)
            ego = w.ego_slot
            if ego >= 0 and self.cfg.scene_radius_m > 0:
                d = np.hypot(cx[idx] - cx[ego], cy[idx] - cy[ego])
                idx = idx[d <= self.cfg.scene_radius_m]
            state = dict(zip(ids, states, strict=True))
            lamps = []
            for tls, link, pos in self._lamps:
                st = state.get(tls, "")
                lamp = _SUMO_LAMP.get(st[link]) if link < len(st) else None
                if lamp is not None:
                    lamps.append((pos[_LAMP_SLOT[lamp]], lamp))
            log.write_deferred("/scene", t, _scene, t, [w.ids[i] for i in idx.tolist()], cx[idx], cy[idx],
                               w.heading_deg[idx], w.length_m[idx], w.width_m[idx], w.is_ego[idx], lamps)  # fmt: skip
        log.end_step()

    def close(self) -> None:
        pass  # the writer is the run's (cosim.sim closes it after writing /health)


def _ego_frame(t: float, w, ego: int) -> dict:
    """``foxglove.FrameTransform``: frame "ego" (footprint centre, x forward) in "map"."""
    sec = int(t)
    yaw = math.radians(90.0 - float(w.heading_deg[ego]))
    half = 0.5 * float(w.length_m[ego])
    x = float(w.x_m[ego]) - math.cos(yaw) * half
    y = float(w.y_m[ego]) - math.sin(yaw) * half
    return {
        "timestamp": {"sec": sec, "nsec": int(round((t - sec) * 1e9))}, "parent_frame_id": "map",
        "child_frame_id": "ego", "translation": {"x": round(x, 3), "y": round(y, 3), "z": 0.0},
        "rotation": {"x": 0.0, "y": 0.0, "z": round(math.sin(yaw / 2), 6), "w": round(math.cos(yaw / 2), 6)},
    }  # fmt: skip


def _traffic(t, step, ids, slots, x, y, heading, speed, accel, edges, lane_index, signals) -> dict:
    """The ``/traffic/vehicles`` message: every SCV as columns, rounded for a compact payload."""
    return {
        "t_s": t, "step": step, "id": ids, "slot": slots.tolist(), "x_m": _r(x, 2), "y_m": _r(y, 2),
        "heading_deg": _r(heading, 1), "speed_mps": _r(speed, 2), "accel_mps2": _r(accel, 2), "edge": edges,
        "lane_index": lane_index.tolist(), "signals": signals.tolist(),
    }  # fmt: skip


def _scene(t: float, ids, cx, cy, heading, length, width, is_ego, lamps=()) -> bytes:
    """The ``foxglove.SceneUpdate`` payload: the given vehicles (front-bumper centre ``cx``, ``cy``) as boxes,
    and the lit traffic-light lamps (``lamps``: (position (3,), 'r' | 'y' | 'g')) as spheres of one entity.

    Encoded from templates rather than by ``json.dumps`` over a dict per vehicle (a quarter of the cost);
    the bytes are the same as the dict form would give (tests/unit/test_log_payloads.py checks it).
    """
    sec = int(t)
    stamp = f'{{"sec":{sec},"nsec":{int(round((t - sec) * 1e9))}}}'
    yaws = [math.radians(90.0 - h) for h in heading.tolist()]  # compass -> counter-clockwise from +x
    cols = zip(
        map(_json_str, ids),
        _json_floats(cx.tolist(), 2),
        _json_floats(cy.tolist(), 2),
        _json_floats([math.sin(y / 2) for y in yaws], 6),  # 6 decimals, as /tf: ~25 % of /scene's bytes
        _json_floats([math.cos(y / 2) for y in yaws], 6),
        _json_floats(length.tolist()),
        _json_floats(width.tolist()),
        [_EGO_COLOR if e else _SCV_COLOR for e in is_ego.tolist()],
        strict=True,
    )
    entities = ",".join([_ENTITY % (stamp, *c) for c in cols])
    if lamps:
        spheres = ",".join([_LAMP % (*_json_floats([float(v) for v in p]), _LAMP_COLOR[k]) for p, k in lamps])
        entities += ("," if entities else "") + _LAMPS % (stamp, spheres)
    return f'{{"deletions":[{{"timestamp":{stamp},"type":1,"id":""}}],"entities":[{entities}]}}'.encode()


_json_str = json.encoder.encode_basestring_ascii  # a str as json.dumps writes it (quoted, ASCII-escaped)
_EGO_COLOR = '{"r":0.9,"g":0.1,"b":0.1,"a":1.0}'
_SCV_COLOR = '{"r":0.3,"g":0.5,"b":0.9,"a":0.9}'
# one foxglove.SceneEntity with a single cube; fields: stamp, id, x, y, qz, qw, length, width, colour
_ENTITY = (
    '{"timestamp":%s,"frame_id":"map","id":%s,"lifetime":{"sec":0,"nsec":0},"frame_locked":false,'
    '"metadata":[],"arrows":[],"cubes":[{"pose":{"position":{"x":%s,"y":%s,"z":0.75},'
    '"orientation":{"x":0.0,"y":0.0,"z":%s,"w":%s}},"size":{"x":%s,"y":%s,"z":1.5},"color":%s}],'
    '"spheres":[],"cylinders":[],"lines":[],"triangles":[],"texts":[],"models":[]}'
)


# the lit lamps of every signalised approach: one entity of spheres; fields: stamp, spheres
_LAMPS = (
    '{"timestamp":%s,"frame_id":"map","id":"traffic_light_lamps","lifetime":{"sec":0,"nsec":0},'
    '"frame_locked":false,"metadata":[],"arrows":[],"cubes":[],"spheres":[%s],"cylinders":[],"lines":[],'
    '"triangles":[],"texts":[],"models":[]}'
)
_LAMP = (
    '{"pose":{"position":{"x":%s,"y":%s,"z":%s},"orientation":{"x":0.0,"y":0.0,"z":0.0,"w":1.0}},'
    '"size":{"x":0.5,"y":0.5,"z":0.5},"color":%s}'
)
_LAMP_COLOR = {"r": '{"r":1.0,"g":0.08,"b":0.05,"a":1.0}', "y": '{"r":1.0,"g":0.65,"b":0.0,"a":1.0}',
               "g": '{"r":0.1,"g":1.0,"b":0.3,"a":1.0}'}  # fmt: skip
_SUMO_LAMP = {"r": "r", "R": "r", "s": "r", "y": "y", "Y": "y", "u": "y", "g": "g", "G": "g"}  # 'o'/'O': dark
_LAMP_SLOT = {"r": 0, "y": 1, "g": 2}


def _json_floats(values: list[float], decimals: int | None = None) -> list[str]:
    """Floats as json.dumps writes them (repr), or of ``round(v, decimals)`` (decimals >= 1); NaN/inf as
    null, like ``McapLog.write``. The per-value work stays in C (map, one %-format over the whole list)."""
    if decimals is None:
        out = list(map(float.__repr__, values))
    elif values and max(map(abs, values)) < 1e15:  # below repr's switch to exponents
        # fixed point rounds like round(); cutting one zero per pass leaves repr's form ("12.30" -> "12.3")
        text = (f"%.{decimals}f," * len(values)) % tuple(values)
        for _ in range(decimals - 1):
            text = text.replace("0,", ",")
        out = text[:-1].split(",")
        for i in [i for i, v in enumerate(values) if 0 < abs(v) < 1e-4]:  # repr writes these as 7.1e-05
            out[i] = repr(round(values[i], decimals))
    else:
        out = [repr(round(v, decimals)) for v in values]
    if not all(map(math.isfinite, values)):
        out = [s if math.isfinite(v) else "null" for s, v in zip(out, values, strict=True)]
    return out

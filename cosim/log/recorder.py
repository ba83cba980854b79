"""The log phase: what a step writes to the run's MCAP file."""

from __future__ import annotations

import math

import numpy as np

from cosim.sumo_bridge.bridge import EGO_ID


def _r(a: np.ndarray, nd: int) -> list:
    """Round for a compact, deterministic JSON payload."""
    return np.round(a, nd).tolist()


def _yaw_quat(heading_deg: float) -> dict:
    yaw = math.radians(90.0 - heading_deg)  # compass heading -> counter-clockwise from +x
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}


class Recorder:
    def __init__(self, sim):
        self.sim = sim
        self.log = sim.mcap
        self.cfg = sim.config.log
        self._tls_state: dict[str, str] = {}

    def __call__(self, sim) -> None:
        w, t, step, log = sim.world, sim.world.t_s, sim.world.step, self.log
        ego = w.ego_slot
        if ego >= 0:
            msg = {
                "t_s": t, "step": step, "id": EGO_ID, "x_m": round(float(w.x_m[ego]), 3), "y_m": round(float(w.y_m[ego]), 3),
                "heading_deg": round(float(w.heading_deg[ego]), 3), "speed_mps": round(float(w.speed_mps[ego]), 4),
                "accel_mps2": round(float(w.accel_mps2[ego]), 4),
                "edge": w.edge_names[w.edge_code[ego]] if w.edge_code[ego] >= 0 else "",
                "lane_index": int(w.lane_index[ego]), "lane_pos_m": round(float(w.lane_pos_m[ego]), 3),
                "lateral_offset_m": round(float(w.lateral_offset_m[ego]), 3),
                "on_road": bool(sim.bridge.ego_on_road),
            }  # fmt: skip
            msg.update(sim.outputs.get("ego_log", {}))
            log.write("/ego/state", t, msg)
        every = self.cfg.traffic_every_steps
        if every and step % every == 0:
            idx = np.flatnonzero(w.valid & ~w.is_ego)
            log.write("/traffic/vehicles", t, {
                "t_s": t, "step": step, "id": [w.ids[i] for i in idx], "slot": idx.tolist(),
                "x_m": _r(w.x_m[idx], 2), "y_m": _r(w.y_m[idx], 2), "heading_deg": _r(w.heading_deg[idx], 1),
                "speed_mps": _r(w.speed_mps[idx], 2), "accel_mps2": _r(w.accel_mps2[idx], 2),
                "edge": [w.edge_names[c] if c >= 0 else "" for c in w.edge_code[idx]],
                "lane_index": w.lane_index[idx].tolist(), "signals": w.signals[idx].tolist(),
            })  # fmt: skip
        ids, states = sim.bridge.traffic_lights()
        changed = [(i, s) for i, s in zip(ids, states, strict=True) if self._tls_state.get(i) != s]
        if changed:
            self._tls_state.update(changed)
            log.write("/traffic/lights", t, {"t_s": t, "step": step, "id": [c[0] for c in changed],
                                             "state": [c[1] for c in changed]})  # fmt: skip
        for ev in sim.events:
            log.write("/events", t, {"t_s": t, "step": step, "kind": ev.kind, "vehicle": ev.vehicle,
                                     "detail": ev.detail, "value": ev.value})  # fmt: skip
        for topic, msg in sim.outputs.get(
            "log", {}
        ).items():  # other phases' records (/vanet/*, /adas/*, ...)
            log.write(topic, t, msg)
        scene_every = self.cfg.scene_every_steps
        if scene_every and step % scene_every == 0:
            log.write("/scene", t, self._scene(w, t))

    def _scene(self, w, t: float) -> dict:
        cx, cy = w.centre_xy()
        idx = np.flatnonzero(w.valid)
        ego = w.ego_slot
        if ego >= 0 and self.cfg.scene_radius_m > 0:
            d = np.hypot(cx[idx] - cx[ego], cy[idx] - cy[ego])
            idx = idx[d <= self.cfg.scene_radius_m]
        sec = int(t)
        stamp = {"sec": sec, "nsec": int(round((t - sec) * 1e9))}
        entities = []
        for i in idx:
            is_ego = bool(w.is_ego[i])
            color = (
                {"r": 0.9, "g": 0.1, "b": 0.1, "a": 1.0}
                if is_ego
                else {"r": 0.3, "g": 0.5, "b": 0.9, "a": 0.9}
            )
            entities.append({
                "timestamp": stamp, "frame_id": "map", "id": w.ids[i], "lifetime": {"sec": 0, "nsec": 0},
                "frame_locked": False, "metadata": [],
                "cubes": [{"pose": {"position": {"x": round(float(cx[i]), 2), "y": round(float(cy[i]), 2), "z": 0.75},
                                    "orientation": _yaw_quat(float(w.heading_deg[i]))},
                           "size": {"x": float(w.length_m[i]), "y": float(w.width_m[i]), "z": 1.5}, "color": color}],
            })  # fmt: skip
        return {"deletions": [{"timestamp": stamp, "type": 1, "id": ""}], "entities": entities}


def attach_recorder(sim) -> None:
    sim.add_hook("log", Recorder(sim))

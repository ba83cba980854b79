"""Helpers shared by the VANET unit tests: small Worlds and hand-made CAM records."""

from __future__ import annotations

import numpy as np

from cosim.vanet.obu import RECORD_FIELDS
from cosim.world import World


def make_world(xy, heading_deg=0.0, speed_mps=0.0, lane_index=0, capacity=16, ego=None) -> World:
    """A World with one vehicle per row of xy (front-bumper positions [m])."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    n = len(xy)
    w = World(capacity=max(capacity, n))
    for i in range(n):
        w.add(f"v{i}", is_ego=(i == ego))
    w.x_m[:n], w.y_m[:n] = xy[:, 0], xy[:, 1]
    w.heading_deg[:n] = heading_deg
    w.speed_mps[:n] = speed_mps
    w.length_m[:n] = 4.5
    w.width_m[:n] = 1.8
    w.lane_index[:n] = lane_index
    return w


def advance(w: World, dt: float) -> None:
    """Move every valid vehicle along its heading at its speed."""
    v = w.valid
    h = np.radians(w.heading_deg[v])
    w.x_m[v] += np.sin(h) * w.speed_mps[v] * dt
    w.y_m[v] += np.cos(h) * w.speed_mps[v] * dt


def records(rows: list[dict]) -> dict[str, np.ndarray]:
    """RECORD_FIELDS arrays from rows in SI units (x_m, y_m, heading_deg, speed_mps, accel_mps2, length_m,
    lane_position, accel_control, gen_ms, rx_us, station_id)."""
    n = len(rows)
    rec = {k: np.zeros(n, dtype=dt) for k, dt in RECORD_FIELDS.items()}
    for i, r in enumerate(rows):
        rec["station_id"][i] = r.get("station_id", i + 1)
        rec["sender_slot"][i] = r.get("sender_slot", i + 1)
        rec["ref_x_cm"][i] = round(r["x_m"] * 100)
        rec["ref_y_cm"][i] = round(r["y_m"] * 100)
        rec["heading_01deg"][i] = round((r.get("heading_deg", 0.0) % 360) * 10)
        rec["speed_001mps"][i] = round(r.get("speed_mps", 0.0) * 100)
        rec["long_accel_01mps2"][i] = round(r.get("accel_mps2", 0.0) * 10)
        rec["length_01m"][i] = round(r.get("length_m", 4.5) * 10)
        rec["width_01m"][i] = 18
        rec["lane_position"][i] = r.get("lane_position", 1)
        rec["accel_control"][i] = r.get("accel_control", 0)
        rec["gen_ms"][i] = r.get("gen_ms", 0)
        rec["rx_us"][i] = r.get("rx_us", r.get("gen_ms", 0) * 1000)
    return rec

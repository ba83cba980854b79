"""A :class:`FrameState` from a running :class:`cosim.sim.Simulation` (after ``sim.step()``).

What it reads (all optional except the world):

- ``sim.world``: SCVs (front bumper + compass angle -> centre + yaw), brake lights from the signal bits;
- ``sim.ego`` (MuJoCo physics): the car's pose incl. pitch / roll / bounce, its brake pedal, its percept
  (speed limit, leader id); without it the ego slot of the world;
- ``sim.bridge.traffic_lights()``: every light's state string;
- ``sim.outputs.adas_displays`` (``cosim.outputs.StepOutputs``): the Percept kwargs the ADAS phase gives the
  driver (``sys_a_lit``: the driver perceives system A's display; ``sys_b_gap_s`` / ``sys_b_level``: system
  B's display; system B counts as switched on when either key is present);
- ``sim.outputs.adas``: cosim.phases.adas's record of the step: ``system`` in use ('none' | 'A' | 'B'),
  ``a_lit`` (system A's display is lit, readable or not), ``leader_id`` and the experiment ``phase``;
  the leader carries a display panel only while system A is in use (lit or dark).

System A's warning is shown only where the paper puts it, on the leader's rear display (``rear_display_lit``);
the HUD gets ``sys_a_perceived`` as data but draws nothing for it unless ``observer_overlay`` is set, which
``cosim drive`` and a participant's view never do.
"""

from __future__ import annotations

import math

import numpy as np

from cosim import frames
from cosim.world import SIGNAL_BRAKELIGHT
from cosim.world3d.hud import HudState
from cosim.world3d.state import EgoPose, FrameState, VehicleFrame


class LiveSource:
    """Turns the simulation's state into frames; keeps small caches (lane speeds) between calls."""

    def __init__(self, sim, observer_overlay: bool = False) -> None:
        self.sim = sim
        self.observer_overlay = observer_overlay  # an observer's note of system A on the HUD (not a driver's)
        self._lane_speed: dict[tuple[str, int], float | None] = {}

    def lane_speed(self, edge: str, lane: int) -> float | None:
        key = (edge, lane)
        if key not in self._lane_speed:
            try:
                self._lane_speed[key] = float(self.sim.net.getEdge(edge).getLane(lane).getSpeed())
            except (KeyError, IndexError, AttributeError):
                self._lane_speed[key] = None
        return self._lane_speed[key]

    def ego_pose(self) -> tuple[EgoPose | None, float, float | None, str | None]:
        """(pose, speed [m/s], speed limit [m/s] or None, leader id or None)."""
        sim, w = self.sim, self.sim.world
        ctl = sim.ego
        if ctl is not None and getattr(ctl, "started", False):
            st = ctl.car.state()
            p = ctl.car.params
            pose = EgoPose(st.x_m + ctl.origin[0], st.y_m + ctl.origin[1], st.yaw_rad,
                           z_m=st.z_m - p.wheel_radius_m, pitch_rad=st.pitch_rad, roll_rad=st.roll_rad,
                           braking=ctl.controls.brake > 0.05)  # fmt: skip
            pc = ctl.percept
            limit = pc.speed_limit_mps if pc is not None else None
            leader = pc.leader_id if pc is not None and pc.leader_present else None
            return pose, st.speed_mps, limit, leader
        i = w.ego_slot
        if i < 0:
            return None, 0.0, None, None
        length = float(w.length_m[i]) or 4.5
        cx, cy, yaw = frames.sumo_to_mujoco(w.x_m[i], w.y_m[i], w.heading_deg[i], length)
        pose = EgoPose(float(cx), float(cy), float(yaw), braking=bool(w.signals[i] & SIGNAL_BRAKELIGHT))
        limit = (
            self.lane_speed(w.edge_names[w.edge_code[i]], int(w.lane_index[i]))
            if w.edge_code[i] >= 0
            else None
        )
        leader = None
        if sim.bridge is not None:
            lead = sim.bridge.leader(w.ids[i], 160.0)
            leader = lead[0] if lead else None
        return pose, float(w.speed_mps[i]), limit, leader

    def vehicles(self, near: tuple[float, float] | None = None, nearest: int | None = None,
                 max_distance_m: float = math.inf) -> VehicleFrame:  # fmt: skip
        """The SCVs; with ``near`` (a network point): only the ``nearest`` ones (all if None) within
        ``max_distance_m`` of it (the scene's vehicle pool shows no others; fewer to send to a viewer)."""
        w = self.sim.world
        idx = np.flatnonzero(w.valid & ~w.is_ego)
        cx, cy, yaw = frames.sumo_to_mujoco(w.x_m[idx], w.y_m[idx], w.heading_deg[idx], w.length_m[idx])
        if near is not None:
            dist = np.hypot(cx - near[0], cy - near[1])
            keep = np.flatnonzero(dist <= max_distance_m)
            if nearest is not None and len(keep) > nearest:
                keep = keep[np.argpartition(dist[keep], nearest - 1)[:nearest]]
                keep.sort()
            idx, cx, cy, yaw = idx[keep], cx[keep], cy[keep], yaw[keep]
        return VehicleFrame(
            tuple(w.ids[i] for i in idx.tolist()), cx, cy, yaw, (w.signals[idx] & SIGNAL_BRAKELIGHT) != 0
        )

    def frame(self, real_time_factor: float | None = None, note: str | None = None, nearest: int | None = None,
              max_distance_m: float = math.inf) -> FrameState:  # fmt: skip
        """The state to show now; ``nearest`` / ``max_distance_m``: only those SCVs around the ego
        (:meth:`vehicles`)."""
        sim = self.sim
        if note is None and sim.bridge is not None and not getattr(sim.bridge, "ego_on_road", True):
            note = "off the road"
        pose, speed, limit, leader = self.ego_pose()
        lights: dict[str, str] = {}
        if sim.bridge is not None:
            ids, states = sim.bridge.traffic_lights()
            lights = dict(zip(ids, states, strict=True))
        adas = dict(sim.outputs.adas_displays)
        rec = sim.outputs.adas or {}  # cosim.phases.adas's record of this step
        sys_b_active = "sys_b_gap_s" in adas or "sys_b_level" in adas
        gap = adas.get("sys_b_gap_s")
        phase = rec.get("phase") or None
        hud = HudState(
            t_s=sim.world.t_s, speed_mps=speed if math.isfinite(speed) else 0.0, speed_limit_mps=limit,
            sys_b_active=sys_b_active, sys_b_gap_s=None if gap is None else float(gap),
            sys_b_level=str(adas.get("sys_b_level") or "none"), sys_a_perceived=bool(adas.get("sys_a_lit", False)),
            observer_overlay=self.observer_overlay, phase=phase, real_time_factor=real_time_factor, note=note,
        )  # fmt: skip
        if rec.get("system") == "A":  # the display is only on while system A is the one in use
            lit = bool(rec.get("a_lit"))
        else:
            lit = True if adas.get("sys_a_lit") else None
        leader = rec.get("leader_id") or leader
        near = (
            None if pose is None or (nearest is None and math.isinf(max_distance_m)) else (pose.x_m, pose.y_m)
        )
        vehicles = self.vehicles(near, nearest, max_distance_m)
        return FrameState(sim.world.t_s, pose, vehicles, lights, leader, lit, hud)

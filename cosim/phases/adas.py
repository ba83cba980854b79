"""The assistance phase: system A (rear-mounted stereo warning on the leader) and system B (V2V time gap).

Which system the driver sees is ``AdasPhase.active`` ('none' | 'A' | 'B'), set by the config or, in an
experiment, by the protocol's current phase. Both systems are evaluated every step so that the log shows
what each would have displayed, next to the ground-truth time gap: SUMO's along-the-road gap to the
vehicle ahead on the ego's lane, divided by the ego's speed.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from cosim.adas import RearStereoWarning, V2VTimeGapWarning, VehicleState
from cosim.adas.common import time_gap_s
from cosim.adas.config import AdasConfig, System
from cosim.adas.v2v_timegap import CamData
from cosim.scenario.buildings import load_buildings
from cosim.seeds import stream
from cosim.world import EGO_ID

__all__ = ["AdasConfig", "AdasPhase", "System"]  # AdasConfig lives in cosim.adas.config


class AdasPhase:
    def __init__(self, sim, config: AdasConfig):
        self.sim = sim
        self.config = config
        self.active: System = config.system
        self.phase_name = ""
        buildings, _ = load_buildings(sim.scenario.buildings_file)
        self.system_a = RearStereoWarning(config.rear, buildings, rng=stream(sim.config.seed, "system_a"))
        self.system_b = V2VTimeGapWarning(config.v2v)
        self._b_station: int | None = None
        self._b_seq: int | None = None  # record number of the leader CAM decoded last, and that CAM
        self._b_cam: CamData | None = None
        sim.add_hook("adas", self.step)

    def _state(self, slot: int) -> VehicleState:
        return VehicleState.from_world(self.sim.world, slot)

    def step(self, sim) -> None:
        w = sim.world
        ego = w.slot_of.get(EGO_ID)
        if ego is None:
            return
        me = self._state(ego)
        lead = sim.bridge.leader(EGO_ID, self.config.leader_search_m)
        leader_slot = w.slot_of.get(lead[0]) if lead else None
        true_gap_s = math.nan
        gap_m = None
        a_out = None
        if leader_slot is not None:
            leader = self._state(leader_slot)
            gap_m = lead[1] + sim.bridge.min_gap(EGO_ID)  # along the road, bumper to bumper
            true_gap_s = time_gap_s(gap_m, me.speed_mps, self.config.v2v.time_gap_cap_s)
            a_out = self.system_a.update(w.t_s, leader, me)
        b_out = self.system_b.update(w.t_s, me, self._cam_of_leader(sim))
        a_lit = bool(a_out and a_out.display_lit)
        a_seen = bool(a_out and a_out.perceived)
        displays = {}
        if self.active == "A":
            displays = {"sys_a_lit": a_seen}
        elif self.active == "B":
            displays = {"sys_b_gap_s": b_out.time_gap_s, "sys_b_level": b_out.level}
        sim.outputs["adas_displays"] = displays
        warning = {"A": "warning" if a_seen else "none", "B": b_out.level}.get(self.active, "none")
        shown = b_out.time_gap_s if self.active == "B" else None
        record = {
            "t_s": w.t_s, "phase": self.phase_name, "system": self.active,
            "time_gap_true_s": _r(true_gap_s), "time_gap_displayed_s": _r(shown), "warning": warning,
            "leader_id": lead[0] if lead else "",
            "leader_speed_mps": _r(w.speed_mps[leader_slot]) if leader_slot is not None else None,
            "gap_true_m": _r(gap_m), "a_lit": a_lit, "a_perceived": a_seen,
            "a_measured_m": _r(a_out.measured_distance_m if a_out else None), "a_reason": a_out.reason if a_out else "",
            "b_gap_s": _r(b_out.time_gap_s), "b_level": b_out.level, "b_status": b_out.status,
            "b_age_s": _r(b_out.data_age_s), "b_station": self._b_station if self._b_station is not None else -1,
            "b_leader_id": self._vehicle_of_station(sim, self._b_station),
        }  # fmt: skip
        sim.outputs["adas"] = record
        if sim.mcap is not None:
            log = sim.outputs.setdefault("log", {})
            log["/adas/state"] = record
            events = [dataclasses.asdict(e) for e in self.system_a.pop_events() + self.system_b.pop_events()]
            if events:
                log["/adas/events"] = {"t_s": w.t_s, "events": events}

    @staticmethod
    def _vehicle_of_station(sim, station: int | None) -> str:
        """The vehicle id behind a station id (for the log; system B itself never uses it)."""
        if station is None or sim.vanet is None:
            return ""
        ids = sim.vanet.layer.station_id
        hits = np.flatnonzero(ids[: sim.world.capacity] == station)
        return next((sim.world.ids[h] for h in hits if sim.world.valid[h]), "") or ""

    def _cam_of_leader(self, sim) -> CamData | None:
        """System B sees only CAM data: the OBU picks the leader by criteria a-d, g, then its newest CAM."""
        vanet = getattr(sim, "vanet", None)
        obu = vanet.ego_obu() if vanet else None
        if obu is None:
            return None
        found = obu.find_leader(self.config.leader_criteria)
        if found is not None:
            self._b_station = int(found.station_id)
            # a station keeps its sender slot for life, and the table holds a slot's newest CAM: this one.
            # A stored CAM never changes, and a leader's newest one usually stays for several steps (CAMs
            # come at 1-10 Hz): decode each one once.
            if found.seq != self._b_seq:
                self._b_seq, self._b_cam = found.seq, _cam_data(obu.cam(found.seq))
            return self._b_cam
        if self._b_station is None:
            return None
        # no leader this step: B keeps showing the last one's newest CAM (as it ages into "stale")
        cam, _age = obu.latest_from(self._b_station, max_age_s=math.inf)
        return None if cam is None else _cam_data(cam)


def _cam_data(cam) -> CamData:
    """What system B reads of a decoded CAM (a ``cosim.vanet.obu.ReceivedCam``)."""
    return CamData(generation_t_s=cam.generation_t_s, x_m=cam.x_m, y_m=cam.y_m, heading_deg=cam.heading_deg,
                   speed_mps=cam.speed_mps, length_m=cam.length_m, accel_mps2=cam.accel_mps2,
                   station_id=int(cam.station_id))  # fmt: skip


def _r(v, nd: int = 4):
    return None if v is None or not math.isfinite(v) else round(float(v), nd)

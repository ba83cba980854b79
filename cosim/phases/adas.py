"""The assistance phase: system A (rear-mounted stereo warning on the leader) and system B (V2V time gap).

Which system the driver sees is ``AdasPhase.active`` ('none' | 'A' | 'B'), set by the config or, in an
experiment, by the protocol's current phase. Both systems are evaluated every step so that the log shows
what each would have displayed, next to the ground-truth time gap: SUMO's along-the-road gap to the
vehicle ahead on the ego's lane, divided by the ego's speed.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from cosim.adas import RearStereoWarning, V2VTimeGapWarning, VehicleState
from cosim.adas.common import time_gap_s
from cosim.adas.config import AdasConfig, System
from cosim.adas.v2v_timegap import CamData
from cosim.buildings import Buildings
from cosim.world import EGO_ID, World

__all__ = ["AdasConfig", "AdasPhase", "AdasStepOutput", "System"]  # AdasConfig lives in cosim.adas.config


class AdasBridge(Protocol):
    """What the assistance phase asks SUMO (``cosim.sumo_bridge.SumoBridge`` provides it)."""

    def leader(self, vid: str, dist_m: float) -> tuple[str, float] | None: ...

    def min_gap(self, vid: str) -> float: ...


class Radio(Protocol):
    """What the assistance phase reads of the VANET phase (``cosim.phases.vanet.VanetPhase``)."""

    def ego_obu(self, world: World): ...

    def vehicle_of_station(self, world: World, station: int | None) -> str: ...


@dataclass(frozen=True)
class AdasStepOutput:
    record: dict  # the /adas/state message
    displays: dict  # what the driver is shown: Percept kwargs
    events: dict | None  # the /adas/events message, or None without transitions


class AdasPhase:
    """Ports: its config, the shared building footprints, its random stream (system A's camera noise),
    SUMO's ground-truth leader (``bridge``) and the ego's OBU (``radio``, None without a radio)."""

    def __init__(self, config: AdasConfig, buildings: Buildings, rng: np.random.Generator, bridge: AdasBridge,
                 radio: Radio | None):  # fmt: skip
        self.config = config
        self.bridge = bridge
        self.radio = radio
        self.active: System = config.system  # set by an experiment's protocol (cosim.experiment.runner)
        self.phase_name = ""
        self.system_a = RearStereoWarning(config.rear, buildings, rng=rng)
        self.system_b = V2VTimeGapWarning(config.v2v)
        self._b_station: int | None = None
        self._b_seq: int | None = None  # record number of the leader CAM decoded last, and that CAM
        self._b_cam: CamData | None = None

    def step(self, w: World) -> AdasStepOutput | None:
        """Both systems on the snapshot (None when the ego is absent)."""
        ego = w.slot_of.get(EGO_ID)
        if ego is None:
            return None
        me = VehicleState.from_world(w, ego)
        lead = self.bridge.leader(EGO_ID, self.config.leader_search_m)
        leader_slot = w.slot_of.get(lead[0]) if lead else None
        true_gap_s = math.nan
        gap_m = None
        a_out = None
        if leader_slot is not None:
            leader = VehicleState.from_world(w, leader_slot)
            gap_m = lead[1] + self.bridge.min_gap(EGO_ID)  # along the road, bumper to bumper
            true_gap_s = time_gap_s(gap_m, me.speed_mps, self.config.v2v.time_gap_cap_s)
            a_out = self.system_a.update(w.t_s, leader, me)
        b_out = self.system_b.update(w.t_s, me, self._cam_of_leader(w))
        a_lit = bool(a_out and a_out.display_lit)
        a_seen = bool(a_out and a_out.perceived)
        displays = {}
        if self.active == "A":
            displays = {"sys_a_lit": a_seen}
        elif self.active == "B":
            displays = {"sys_b_gap_s": b_out.time_gap_s, "sys_b_level": b_out.level}
        warning = {"A": "warning" if a_seen else "none", "B": b_out.level}.get(self.active, "none")
        shown = b_out.time_gap_s if self.active == "B" else None
        b_leader = self.radio.vehicle_of_station(w, self._b_station) if self.radio is not None else ""
        record = {
            "t_s": w.t_s, "phase": self.phase_name, "system": self.active,
            "time_gap_true_s": _r(true_gap_s), "time_gap_displayed_s": _r(shown), "warning": warning,
            "leader_id": lead[0] if lead else "",
            "leader_speed_mps": _r(w.speed_mps[leader_slot]) if leader_slot is not None else None,
            "gap_true_m": _r(gap_m), "a_lit": a_lit, "a_perceived": a_seen,
            "a_measured_m": _r(a_out.measured_distance_m if a_out else None), "a_reason": a_out.reason if a_out else "",
            "b_gap_s": _r(b_out.time_gap_s), "b_level": b_out.level, "b_status": b_out.status,
            "b_age_s": _r(b_out.data_age_s), "b_station": self._b_station if self._b_station is not None else -1,
            "b_leader_id": b_leader,
        }  # fmt: skip
        events = [dataclasses.asdict(e) for e in self.system_a.pop_events() + self.system_b.pop_events()]
        return AdasStepOutput(record, displays, {"t_s": w.t_s, "events": events} if events else None)

    def _cam_of_leader(self, w: World) -> CamData | None:
        """System B sees only CAM data: the OBU picks the leader by criteria a-d, g, then its newest CAM."""
        obu = self.radio.ego_obu(w) if self.radio is not None else None
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

    def close(self) -> None:
        pass


def _cam_data(cam) -> CamData:
    """What system B reads of a decoded CAM (a ``cosim.vanet.obu.ReceivedCam``)."""
    return CamData(generation_t_s=cam.generation_t_s, x_m=cam.x_m, y_m=cam.y_m, heading_deg=cam.heading_deg,
                   speed_mps=cam.speed_mps, length_m=cam.length_m, accel_mps2=cam.accel_mps2,
                   station_id=int(cam.station_id))  # fmt: skip


def _r(v, nd: int = 4):
    return None if v is None or not math.isfinite(v) else round(float(v), nd)

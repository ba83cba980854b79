"""The per-step snapshot of every vehicle: struct-of-arrays with a fixed capacity and a validity mask.

A vehicle keeps its slot from departure to arrival, so per-slot state kept by other modules (VANET
stations, OBU tables) stays aligned without dictionaries in the hot path. Slots freed by arrivals are
reused lowest-first, which keeps slot assignment deterministic.

Positions follow SUMO's convention: (x_m, y_m) is the centre of the FRONT bumper in network coordinates
and heading_deg is SUMO's angle (compass degrees, clockwise from north). ``cosim.frames`` converts to the
MuJoCo convention (centre of the car, yaw in radians counter-clockwise from +x).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# the vehicles cosim itself puts into SUMO, and their vTypes (the one place these names are spelled)
EGO_ID = "ego"
LEAD_ID = "lead"
EGO_VTYPE = "ego_car"  # the scenario's routes define it (cosim.scenario.demand), never teleported
LEAD_VTYPE = "lead_car"  # the lead vehicle of the following task (cosim.phases.lead)
SCV_VTYPE = "scv"  # the SCVs cosim inserts itself (cosim.phases.traffic)


@dataclass(frozen=True)
class SumoEvent:
    """A traffic event of one step (from SUMO, or decided by a phase), logged on ``/events``."""

    kind: str  # teleport | collision | emergency_stop | ego_off_road | red_light_violation | ...
    vehicle: str
    detail: str = ""
    value: float = float("nan")


# SUMO vehicle signal bits (https://sumo.dlr.de/docs/TraCI/Vehicle_Signalling.html)
SIGNAL_BLINKER_RIGHT = 1 << 0
SIGNAL_BLINKER_LEFT = 1 << 1
SIGNAL_BLINKER_EMERGENCY = 1 << 2
SIGNAL_BRAKELIGHT = 1 << 3

# name -> (dtype, fill value for an empty slot)
_ARRAYS: dict[str, tuple[type, float | int | bool]] = {
    "valid": (np.bool_, False),  # (N,) slot holds a live vehicle
    "is_ego": (np.bool_, False),  # (N,) the user-controlled vehicle
    "x_m": (np.float64, np.nan),  # (N,) front-bumper centre, network x [m]
    "y_m": (np.float64, np.nan),  # (N,) front-bumper centre, network y [m]
    "heading_deg": (np.float64, np.nan),  # (N,) compass heading, clockwise from north [deg]
    "speed_mps": (np.float64, 0.0),  # (N,) speed along the heading [m/s]
    "accel_mps2": (np.float64, 0.0),  # (N,) longitudinal acceleration [m/s^2]
    "length_m": (np.float64, 0.0),  # (N,) vehicle length [m]
    "width_m": (np.float64, 0.0),  # (N,) vehicle width [m]
    "lane_pos_m": (np.float64, np.nan),  # (N,) front position along the current lane [m]
    "lateral_offset_m": (np.float64, 0.0),  # (N,) offset from the lane centre, left positive [m]
    "edge_code": (np.int32, -1),  # (N,) index into World.edge_names; -1 unknown
    "lane_index": (np.int16, -1),  # (N,) lane index on the edge, 0 = rightmost; -1 unknown
    "signals": (np.int32, 0),  # (N,) SUMO signal bit field (blinkers, brake light ...)
    "depart_step": (np.int64, -1),  # (N,) step at which the vehicle entered the world
}


@dataclass
class World:
    """All vehicles at one step. Every array has shape (capacity,); only rows with ``valid`` are live."""

    capacity: int = 256
    step: int = 0  # integer step counter (base step = SUMO step)
    t_s: float = 0.0  # simulated time [s]
    ids: list[str | None] = field(default_factory=list)  # slot -> vehicle id
    slot_of: dict[str, int] = field(default_factory=dict)  # vehicle id -> slot
    edge_names: list[str] = field(default_factory=list)  # edge_code -> SUMO edge id
    edge_code_of: dict[str, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name, (dtype, fill) in _ARRAYS.items():
            setattr(self, name, np.full(self.capacity, fill, dtype=dtype))
        self.ids = [None] * self.capacity
        self._free: list[int] = list(range(self.capacity - 1, -1, -1))  # pop() gives the lowest
        self._live: tuple[np.ndarray, list[str]] | None = None  # (slots, ids) cache, dropped on add/remove

    # -- slots ---------------------------------------------------------------------------------------------
    def add(self, vehicle_id: str, *, is_ego: bool = False) -> int:
        """Give a departing vehicle the lowest free slot (growing the arrays if full)."""
        if vehicle_id in self.slot_of:
            return self.slot_of[vehicle_id]
        if not self._free:
            self._grow(self.capacity * 2)
        slot = self._free.pop()
        self.ids[slot] = vehicle_id
        self.slot_of[vehicle_id] = slot
        self.valid[slot] = True
        self.is_ego[slot] = is_ego
        self.depart_step[slot] = self.step
        self._live = None
        return slot

    def remove(self, vehicle_id: str) -> int | None:
        """Free an arrived vehicle's slot; returns the slot or None if the id was unknown."""
        slot = self.slot_of.pop(vehicle_id, None)
        if slot is None:
            return None
        for name, (_, fill) in _ARRAYS.items():
            getattr(self, name)[slot] = fill
        self.ids[slot] = None
        self._free.append(slot)
        self._free.sort(reverse=True)
        self._live = None
        return slot

    def _grow(self, capacity: int) -> None:
        old = self.capacity
        for name, (dtype, fill) in _ARRAYS.items():
            arr = np.full(capacity, fill, dtype=dtype)
            arr[:old] = getattr(self, name)
            setattr(self, name, arr)
        self.ids.extend([None] * (capacity - old))
        self._free = sorted(set(self._free) | set(range(old, capacity)), reverse=True)
        self.capacity = capacity

    def intern_edge(self, edge_id: str) -> int:
        """The code of an edge id in edge_names (added on first sight)."""
        code = self.edge_code_of.get(edge_id)
        if code is None:
            code = self.edge_code_of[edge_id] = len(self.edge_names)
            self.edge_names.append(edge_id)
        return code

    def edge_of(self, slot: int) -> str:
        """The SUMO edge id of the vehicle in ``slot`` ("" where unknown)."""
        code = int(self.edge_code[slot])
        return self.edge_names[code] if code >= 0 else ""

    def edges_of(self, slots: np.ndarray) -> list[str]:
        """The SUMO edge ids of the vehicles in ``slots`` ("" where unknown)."""
        return [self.edge_of(slot) for slot in slots.tolist()]

    # -- views ---------------------------------------------------------------------------------------------
    def live(self) -> tuple[np.ndarray, list[str]]:
        """(slots, ids) of the live vehicles in slot order; cached until the next add/remove (the per-step
        snapshot read walks it every step)."""
        if self._live is None:
            slots = np.flatnonzero(self.valid)
            self._live = (slots, [self.ids[i] for i in slots.tolist()])
        return self._live

    @property
    def ego_slot(self) -> int:
        """Slot of the ego vehicle, or -1 when it is not in the world."""
        hits = np.flatnonzero(self.is_ego & self.valid)
        return int(hits[0]) if hits.size else -1

    @property
    def n_valid(self) -> int:
        return int(np.count_nonzero(self.valid))

    def heading_unit(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit vectors (ux, uy) of the heading in network coordinates; SUMO angle 0 = +y, 90 = +x."""
        rad = np.radians(self.heading_deg)
        return np.sin(rad), np.cos(rad)

    def centre_xy(self) -> tuple[np.ndarray, np.ndarray]:
        """Centre of each vehicle's footprint [m] (front bumper moved back by half the length)."""
        ux, uy = self.heading_unit()
        half = 0.5 * self.length_m
        return self.x_m - ux * half, self.y_m - uy * half

"""The on-board unit: what a vehicle knows from the CAMs it decoded.

Which reading each default follows
----------------------------------
* Neighbour map (paper §VI.C): every station whose newest CAM was delivered within the last ``map_memory_s``
  (5 s), its position extrapolated to "now" from the CAM (constant acceleration, stopping at standstill, by
  default; the paper computes "the position of the vehicle ... into the current transmission slot"). The
  paper keeps the stations heard in the last "five frames"; its frames are the SOTDMA frames of 1 s
  (``sotdma.frame_s``), so five frames = 5 s. The memory is a time, not a frame count, so that it stays the
  same when the frame length changes and means the same for MACs without frames (802.11p, C-V2X). It is
  measured from the delivery of the newest CAM (a station is "heard" when one of its CAMs is decoded).
* Consistency with system B (``cosim.adas.v2v_timegap``): B shows "no data" once the leader's newest CAM is
  older than ``adas.v2v.max_data_age_s`` (3 s since generation). The run config requires that timeout, and
  ``stale_after_s`` below, to be at most ``map_memory_s``: B's "no data" comes from its own timeout while the
  map still holds the leader (from 3 s to 5 s B says "stale" about a vehicle the map still places), never
  from the map having forgotten a leader whose data B would still call fresh.
* Leader criteria a-g (paper §VI.C), each switchable in ``LeaderCriteria``:
  a) close: distance <= ``close_range_m`` (100 m; the paper says "close proximity");
  b) same direction: heading difference <= ``same_direction_max_deg`` (30 deg);
  c) in front: the sender's rear is ahead of the receiver's front along the receiver's heading (gap > 0);
  d) same lane: equal CAM lanePosition and, because a CAM has no road id, a lateral offset from the
     receiver's predicted course (a circle of its current curvature) <= ``same_lane_max_lateral_m`` (2.5 m,
     half a lane plus half a car; None disables that gate);
  e) the sender's longitudinal acceleration < the receiver's;
  f) time gap (gap / receiver speed) < ``time_gap_max_s`` (2 s);
  g) the sender's emergencyBrakeEngaged bit is not set.
  Among the matches, the one with the smallest gap is returned.
* ``ObuView.latest_from(station_id)``: the newest decoded CAM of one station as sent (SI units, not
  extrapolated: field names match ``cosim.adas.v2v_timegap.CamData``) and its age since generation; None
  ("no data") when older than ``stale_after_s`` (3 s = 3 x T_GenCamMax: two CAMs in a row lost even at the
  slowest generation rate).
Deliveries become visible one base step after the slot they were sent in (see VanetLayer).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Literal

import numpy as np

from cosim.vanet.cam import ACC_EMERGENCY_BRAKE, CAM_FIELDS, decode_cam


@dataclass(frozen=True)
class LeaderCriteria:
    """The paper's criteria a-g; each flag switches one criterion on or off."""

    close: bool = True  # a
    close_range_m: float = 100.0
    same_direction: bool = True  # b
    same_direction_max_deg: float = 30.0
    in_front: bool = True  # c
    same_lane: bool = True  # d
    same_lane_max_lateral_m: float | None = 2.5
    accel_smaller: bool = True  # e
    time_gap: bool = True  # f
    time_gap_max_s: float = 2.0
    no_emergency_brake: bool = True  # g

    def __post_init__(self) -> None:
        if not self.close_range_m > 0 or not self.time_gap_max_s > 0:
            raise ValueError("obu.criteria: close_range_m and time_gap_max_s must be > 0")
        if not 0 <= self.same_direction_max_deg <= 180:
            raise ValueError("obu.criteria.same_direction_max_deg must be in [0, 180]")
        if self.same_lane_max_lateral_m is not None and not self.same_lane_max_lateral_m > 0:
            raise ValueError("obu.criteria.same_lane_max_lateral_m must be > 0 or null")


@dataclass(frozen=True)
class ObuParams:
    # neighbour map memory: stations whose newest CAM was delivered within this time [s]; the paper's "five
    # frames" (§VI.C) of 1 s (see the module docstring)
    map_memory_s: float = 5.0
    extrapolation: Literal["none", "constant_velocity", "constant_acceleration"] = "constant_acceleration"
    stale_after_s: float = 3.0  # latest_from(): older data is "no data" [s]
    criteria: LeaderCriteria = field(default_factory=LeaderCriteria)
    table_frames: int | None = None  # replaced by map_memory_s; refused with the conversion when given

    def __post_init__(self) -> None:
        if self.table_frames is not None:
            raise ValueError(
                f"obu.table_frames was replaced by obu.map_memory_s, in seconds: {self.table_frames} frames of "
                f"sotdma.frame_s (1 s by default) = {self.table_frames:g} s"
            )
        if not 0 < self.map_memory_s <= 60:
            raise ValueError(f"obu.map_memory_s must be in (0, 60] s, got {self.map_memory_s}")
        if not self.stale_after_s > 0:
            raise ValueError("obu.stale_after_s must be > 0")
        if self.stale_after_s > self.map_memory_s:
            raise ValueError(
                f"obu.stale_after_s ({self.stale_after_s} s) must not exceed obu.map_memory_s "
                f"({self.map_memory_s} s): data the map has forgotten cannot be fresh"
            )


# A transmitted CAM as stored for receivers: the CAM fields plus where/when it went on the air.
RECORD_FIELDS: dict[str, np.dtype] = {
    **CAM_FIELDS,
    "sender_slot": np.dtype(np.int32),  # World slot of the sender
    "g": np.dtype(np.int64),  # global slot index (frame * N + slot)
    "tx_us": np.dtype(np.int64),  # slot start [us]
    "rx_us": np.dtype(np.int64),  # delivery time: one slot later [us]
    "timeout": np.dtype(np.int8),  # announced slot timeout [frames]
    "offset": np.dtype(np.int32),  # announced slot offset [slots]
}
RECORD_DTYPE = np.dtype(list(RECORD_FIELDS.items()))  # CAM_DTYPE's fields first, then the ones above


def record_array(rec: dict[str, np.ndarray] | np.ndarray) -> np.ndarray:
    """Records as a RECORD_DTYPE array (from a dict of RECORD_FIELDS arrays of shape (n,) or as is)."""
    if isinstance(rec, np.ndarray):
        return rec
    out = np.zeros(len(rec["rx_us"]), dtype=RECORD_DTYPE)
    for name in RECORD_FIELDS:
        out[name] = rec[name]
    return out


class RecordStore:
    """Ring buffer of transmitted CAMs addressed by a global sequence number.

    Records are kept ``horizon_us`` after delivery (the buffer grows rather than overwrite a younger one),
    so OBU tables can hold plain sequence numbers; an OBU forgets a CAM older than that (``held``), however
    long the ring happens to keep it. That makes what an OBU holds independent of the step's own
    transmissions, so its view is final before the medium access runs (``VanetLayer.step``'s ``on_view``).
    """

    def __init__(self, horizon_us: int, capacity: int = 8192):
        self.horizon_us = int(horizon_us)
        self.cap = int(capacity)
        self.next_seq = 0
        self.data = np.zeros(self.cap, dtype=RECORD_DTYPE)

    def _grow(self, need: int) -> None:
        cap = self.cap
        while cap < need:
            cap *= 2
        old = self.cap
        first = max(0, self.next_seq - old)
        seqs = np.arange(first, self.next_seq)
        new = np.zeros(cap, dtype=RECORD_DTYPE)
        new[seqs % cap] = self.data[seqs % old]
        self.data = new
        self.cap = cap

    def append(self, rec: dict[str, np.ndarray] | np.ndarray, now_us: int) -> np.ndarray:
        """Store n records (see ``record_array``); returns their sequence numbers."""
        n = len(rec["rx_us"])
        if n == 0:
            return np.zeros(0, dtype=np.int64)
        # would we overwrite something delivered less than horizon_us ago?
        overwritten = np.arange(self.next_seq, self.next_seq + n) - self.cap
        overwritten = overwritten[overwritten >= 0]
        if n > self.cap or (
            overwritten.size and (self.data["rx_us"][overwritten % self.cap] > now_us - self.horizon_us).any()
        ):
            self._grow(2 * (self.cap + n))
        seqs = np.arange(self.next_seq, self.next_seq + n, dtype=np.int64)
        self.data[seqs % self.cap] = record_array(rec)
        self.next_seq += n
        return seqs

    def valid(self, seqs: np.ndarray) -> np.ndarray:
        """In the ring (the record of that number is still stored)."""
        return (seqs >= 0) & (seqs >= self.next_seq - self.cap) & (seqs < self.next_seq)

    def held(self, seqs: np.ndarray, now_us: int) -> np.ndarray:
        """Stored and delivered less than the horizon before ``now_us`` (the ring never overwrites those)."""
        ok = self.valid(seqs)
        ok[ok] = self.data["rx_us"][seqs[ok] % self.cap] > now_us - self.horizon_us
        return ok

    def get(self, seqs: np.ndarray) -> dict[str, np.ndarray]:
        rec = self.data[np.asarray(seqs, dtype=np.int64) % self.cap]
        return {name: rec[name] for name in RECORD_FIELDS}


class ObuTables:
    """For every receiver slot, the sequence number of the newest CAM decoded from every sender slot.

    Stored sender-major (``by_sender[sender, receiver]``): one window's deliveries come grouped by
    transmission, so they are written almost sequentially; a receiver's row is read only for an OBU view."""

    def __init__(self, capacity: int):
        self.capacity = 0
        self.by_sender = np.zeros((0, 0), dtype=np.int64)
        self.ensure_capacity(capacity)

    def ensure_capacity(self, capacity: int) -> None:
        if capacity > self.capacity:
            by_sender = np.full((capacity, capacity), -1, dtype=np.int64)
            by_sender[: self.capacity, : self.capacity] = self.by_sender
            self.by_sender = by_sender
            self.capacity = capacity

    def heard(self, rx_slot: int) -> np.ndarray:
        """(capacity,) sequence numbers of the newest CAM the receiver decoded from each sender slot (-1)."""
        return self.by_sender[:, rx_slot].copy()

    def reset(self, rx_slots: np.ndarray) -> None:
        self.by_sender[:, rx_slots] = -1

    def deliver(self, rx_slots: np.ndarray, sender_slots: np.ndarray, seqs: np.ndarray) -> None:
        """Record decoded CAMs: one window's, so newer than any held and at most one per (receiver,
        sender) pair (a station sends once per window)."""
        if rx_slots.size:
            idx = sender_slots.astype(np.int64) * self.capacity
            idx += rx_slots
            self.by_sender.reshape(-1)[idx] = seqs


@dataclass(frozen=True)
class OwnState:
    """What the receiving vehicle knows about itself (its own sensors), SUMO conventions."""

    x_m: float  # front-bumper centre [m]
    y_m: float
    heading_deg: float  # compass, clockwise from north [deg]
    speed_mps: float
    accel_mps2: float = 0.0
    lane_position: int = -1  # SUMO lane index + 1, -1 unknown (same convention as the CAM field)
    yaw_rate_dps: float = 0.0  # counter-clockwise positive [deg/s]


@dataclass
class NeighbourTable:
    """The receiver's map of stations heard recently; every array has shape (n,)."""

    sender_slot: np.ndarray  # int32 World slot of the sender when it sent
    station_id: np.ndarray  # uint32
    seq: np.ndarray  # int64 record sequence number
    rx_age_s: np.ndarray  # float64 time since the CAM was delivered [s]
    data_age_s: np.ndarray  # float64 time since the CAM was generated [s]
    x_m: np.ndarray  # float64 front centre extrapolated to now [m]
    y_m: np.ndarray
    heading_deg: np.ndarray  # float64 compass [deg]
    speed_mps: np.ndarray  # float64 extrapolated [m/s]
    accel_mps2: np.ndarray  # float64 as sent [m/s^2]
    length_m: np.ndarray  # float64
    width_m: np.ndarray  # float64
    lane_position: np.ndarray  # int8
    accel_control: np.ndarray  # uint8 ACC_* bits
    exterior_lights: np.ndarray  # uint8 LIGHT_* bits (0 when that CAM had no LF container)
    distance_m: np.ndarray  # float64 front-to-front distance [m]
    longitudinal_m: np.ndarray  # float64 sender front along the receiver's heading [m]
    lateral_m: np.ndarray  # float64 offset from the receiver's predicted course, left positive [m]
    gap_m: np.ndarray  # float64 receiver front to sender rear along the heading [m]
    time_gap_s: np.ndarray  # float64 gap / receiver speed [s] (inf when standing)

    def __len__(self) -> int:
        return int(self.station_id.size)

    def row(self, i: int) -> Neighbour:
        return Neighbour(**{f.name: getattr(self, f.name)[i].item() for f in fields(self)})

    def take(self, idx: np.ndarray) -> NeighbourTable:
        return NeighbourTable(**{f.name: getattr(self, f.name)[idx] for f in fields(self)})


@dataclass(frozen=True)
class Neighbour:
    """One row of a NeighbourTable as Python scalars (same fields and units)."""

    sender_slot: int
    station_id: int
    seq: int
    rx_age_s: float
    data_age_s: float
    x_m: float
    y_m: float
    heading_deg: float
    speed_mps: float
    accel_mps2: float
    length_m: float
    width_m: float
    lane_position: int
    accel_control: int
    exterior_lights: int
    distance_m: float
    longitudinal_m: float
    lateral_m: float
    gap_m: float
    time_gap_s: float

    @property
    def emergency_brake(self) -> bool:
        return bool(self.accel_control & ACC_EMERGENCY_BRAKE)


@dataclass(frozen=True)
class ReceivedCam:
    """One decoded CAM exactly as sent, converted from ETSI units to SI / SUMO conventions."""

    station_id: int
    generation_t_s: float  # simulated time of generation [s]
    rx_t_s: float  # delivery time [s]
    x_m: float  # reference position = front-bumper centre, network x [m]
    y_m: float
    heading_deg: float  # compass, clockwise from north [deg]
    speed_mps: float  # negative when driving backwards [m/s]
    accel_mps2: float  # longitudinal acceleration [m/s^2]
    length_m: float
    width_m: float
    lane_position: int  # SUMO lane index + 1, -1 unknown
    accel_control: int  # ACC_* bits
    exterior_lights: int  # LIGHT_* bits (0 when the CAM had no LF container)
    sender_slot: int  # World slot of the sender when it sent

    @property
    def emergency_brake(self) -> bool:
        return bool(self.accel_control & ACC_EMERGENCY_BRAKE)


def received_cam(rec: dict[str, np.ndarray], i: int) -> ReceivedCam:
    """Record i of stored records ``rec`` (RECORD_FIELDS arrays) as a ReceivedCam."""
    one = {k: v[i : i + 1] for k, v in rec.items()}
    phys = decode_cam(one)
    return ReceivedCam(
        station_id=int(one["station_id"][0]),
        generation_t_s=int(one["gen_ms"][0]) / 1e3,
        rx_t_s=int(one["rx_us"][0]) / 1e6,
        x_m=float(phys["x_m"][0]),
        y_m=float(phys["y_m"][0]),
        heading_deg=float(phys["heading_deg"][0]),
        speed_mps=float(phys["speed_mps"][0]),
        accel_mps2=float(phys["accel_mps2"][0]),
        length_m=float(phys["length_m"][0]),
        width_m=float(phys["width_m"][0]),
        lane_position=int(one["lane_position"][0]),
        accel_control=int(one["accel_control"][0]),
        exterior_lights=int(one["exterior_lights"][0]),
        sender_slot=int(one["sender_slot"][0]),
    )


def _wrap_deg(d):
    return 180.0 - np.mod(180.0 - d, 360.0)


def neighbour_table(
    rec: dict[str, np.ndarray], seqs: np.ndarray, now_us: int, own: OwnState, extrapolation: str
) -> NeighbourTable:
    """Build the table from stored records ``rec`` (RECORD_FIELDS arrays of shape (n,)) seen by ``own``."""
    phys = decode_cam(rec)
    data_age = (now_us - rec["gen_ms"].astype(np.int64) * 1000) / 1e6
    rx_age = (now_us - rec["rx_us"]) / 1e6
    v, a = phys["speed_mps"], phys["accel_mps2"]
    dt = np.maximum(data_age, 0.0)
    if extrapolation == "none":
        travel = np.zeros_like(v)
        v_now = v
    elif extrapolation == "constant_velocity":
        travel = v * dt
        v_now = v
    else:  # constant acceleration, stopping at standstill instead of reversing
        v_now = v + a * dt
        stops = (a < 0) & (v_now < 0) & (v > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            travel = np.where(stops, -v * v / (2.0 * np.where(a < 0, a, -1.0)), v * dt + 0.5 * a * dt * dt)
        v_now = np.where(stops, 0.0, v_now)
    h = np.radians(phys["heading_deg"])
    x = phys["x_m"] + np.sin(h) * travel
    y = phys["y_m"] + np.cos(h) * travel
    # receiver frame: longitudinal along its heading, lateral to the left
    oh = np.radians(own.heading_deg)
    fx, fy = np.sin(oh), np.cos(oh)
    rx_, ry_ = x - own.x_m, y - own.y_m
    lon = rx_ * fx + ry_ * fy
    lat = -rx_ * fy + ry_ * fx
    # offset from the predicted course: a circle of the receiver's curvature (left turn = positive)
    kappa = np.radians(own.yaw_rate_dps) / own.speed_mps if own.speed_mps > 0.5 else 0.0
    if abs(kappa) > 1e-5:
        radius = 1.0 / kappa
        lat = np.sign(radius) * (abs(radius) - np.hypot(lon, lat - radius))
    gap = lon - phys["length_m"] * np.cos(np.radians(_wrap_deg(phys["heading_deg"] - own.heading_deg)))
    with np.errstate(divide="ignore", invalid="ignore"):
        tg = np.where(own.speed_mps > 0.1, gap / max(own.speed_mps, 1e-9), np.inf)
    return NeighbourTable(
        sender_slot=rec["sender_slot"].astype(np.int32),
        station_id=rec["station_id"].astype(np.uint32),
        seq=np.asarray(seqs, dtype=np.int64),
        rx_age_s=rx_age,
        data_age_s=data_age,
        x_m=x,
        y_m=y,
        heading_deg=phys["heading_deg"],
        speed_mps=v_now,
        accel_mps2=a,
        length_m=phys["length_m"],
        width_m=phys["width_m"],
        lane_position=rec["lane_position"].astype(np.int8),
        accel_control=rec["accel_control"].astype(np.uint8),
        exterior_lights=rec["exterior_lights"].astype(np.uint8),
        distance_m=np.hypot(rx_, ry_),
        longitudinal_m=lon,
        lateral_m=lat,
        gap_m=gap,
        time_gap_s=tg,
    )


def criteria_masks(table: NeighbourTable, own: OwnState, c: LeaderCriteria) -> dict[str, np.ndarray]:
    """Per-criterion boolean masks (n,) for criteria a-g; a switched-off criterion is all True."""
    n = len(table)
    on = np.ones(n, dtype=bool)
    lane_eq = (table.lane_position == own.lane_position) & (table.lane_position >= 0)
    if c.same_lane_max_lateral_m is not None:
        lane_eq &= np.abs(table.lateral_m) <= c.same_lane_max_lateral_m
    return {
        "a_close": table.distance_m <= c.close_range_m if c.close else on,
        "b_same_direction": (
            np.abs(_wrap_deg(table.heading_deg - own.heading_deg)) <= c.same_direction_max_deg
            if c.same_direction
            else on
        ),
        "c_in_front": table.gap_m > 0.0 if c.in_front else on,
        "d_same_lane": lane_eq if c.same_lane else on,
        "e_accel_smaller": table.accel_mps2 < own.accel_mps2 if c.accel_smaller else on,
        "f_time_gap": table.time_gap_s < c.time_gap_max_s if c.time_gap else on,
        "g_no_emergency_brake": (
            (table.accel_control & ACC_EMERGENCY_BRAKE) == 0 if c.no_emergency_brake else on
        ),
    }


def find_leader(table: NeighbourTable, own: OwnState, criteria: LeaderCriteria) -> int:
    """Index of the matching vehicle with the smallest gap, or -1 when none matches."""
    if len(table) == 0:
        return -1
    ok = np.logical_and.reduce(list(criteria_masks(table, own, criteria).values()))
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return -1
    return int(idx[np.argmin(table.gap_m[idx])])


class ObuView:
    """One receiver's view at one step: its neighbour map, criteria a-g, per-station lookups."""

    def __init__(
        self,
        records: RecordStore,
        heard_row: np.ndarray,
        now_us: int,
        own: OwnState,
        params: ObuParams,
        frame_us: int,
        receiver_slot: int,
    ):
        self.records = records
        self.heard_row = heard_row
        self.now_us = int(now_us)
        self.own = own
        self.params = params
        self.frame_us = int(frame_us)
        self.receiver_slot = receiver_slot

    @property
    def now_s(self) -> float:
        return self.now_us / 1e6

    def _table(self, seqs: np.ndarray) -> NeighbourTable:
        return neighbour_table(self.records.get(seqs), seqs, self.now_us, self.own, self.params.extrapolation)

    def neighbours(self, max_age_s: float | None = None) -> NeighbourTable:
        """Stations whose newest CAM was delivered within max_age_s (default: the map memory)."""
        max_age_us = round((self.params.map_memory_s if max_age_s is None else max_age_s) * 1e6)
        seqs = self.heard_row[self.records.held(self.heard_row, self.now_us)]
        if seqs.size:
            fresh = self.records.get(seqs)["rx_us"] >= self.now_us - max_age_us
            seqs = np.sort(seqs[fresh])
        return self._table(seqs)

    def find_leader(self, criteria: LeaderCriteria | None = None) -> Neighbour | None:
        table = self.neighbours()
        i = find_leader(table, self.own, criteria or self.params.criteria)
        return None if i < 0 else table.row(i)

    def cam(self, seq: int) -> ReceivedCam:
        """The decoded CAM with sequence number ``seq`` (e.g. a NeighbourTable row's), as sent."""
        return received_cam(self.records.get(np.array([seq])), 0)

    def latest_from(
        self, station_id: int, max_age_s: float | None = None
    ) -> tuple[ReceivedCam | None, float]:
        """(newest decoded CAM of that station as sent, its age since generation [s]).

        (None, inf) when nothing from it is held; (None, age) when the newest is older than max_age_s
        (default ``stale_after_s``): "no data".
        """
        seqs = self.heard_row[self.records.held(self.heard_row, self.now_us)]
        if seqs.size == 0:
            return None, float("inf")
        ids = self.records.get(seqs)["station_id"]
        mine = seqs[ids == station_id]
        if mine.size == 0:
            return None, float("inf")
        cam = self.cam(int(mine.max()))
        age = self.now_s - cam.generation_t_s
        limit = self.params.stale_after_s if max_age_s is None else max_age_s
        if age > limit:
            return None, age
        return cam, age

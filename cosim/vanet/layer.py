"""The lockstep VANET layer: one call per base step, every valid World vehicle is a station.

Step k covers the time window [t_k, t_k + dt) with t_k = k dt, the time of the World snapshot:

0. CAMs decoded during window k-1 are put into the receivers' OBU tables (so everything an OBU shows at
   step k was received before t_k: "visible to OBUs from the next step");
1. stations appear / leave (a World slot whose ``depart_step`` changed holds a new vehicle: new station id,
   fresh CAM state, empty slot map, listening again);
2. CAM generation check (every ``cam.check_period_s``) on the snapshot; a new CAM replaces an unsent one;
   the SOTDMA report rate follows T_GenCam;
3. SOTDMA: network entry of stations done listening, then every reserved slot starting inside the window
   is used; a station with a pending CAM sends it in its first one;
4. the aether decides each (transmission, receiver) outcome; receptions are timed one slot after the slot
   start (the paper: "distributed into one time slot after they were created");
5. decoded messages update the receivers' SOTDMA slot maps at once, and their OBU tables at step k+1.

Log topics (``VanetStepResult.columns()``), one row per item, arrays of equal length per topic:

* ``/vanet/tx``: t_s f8 (slot start), sender_slot i4, sender_station_id u4, frame i8, slot i4, size_bytes u2,
  gen_t_s f8, has_lf bool, n_path_points u1, trigger u1, timeout i1, offset i4
* ``/vanet/rx``: t_s f8 (delivery), sender_slot i4, sender_station_id u4, receiver_slot i4,
  receiver_station_id u4, frame i8, slot i4, distance_m f4, outcome u1 (channel.OUTCOME_NAMES),
  rx_power_dbm f4 (-inf when line of sight is blocked), gen_t_s f8
* ``/vanet/load`` (one row per completed frame): frame i8, t_s f8 (frame start), n_slots i4, busy_slots i4,
  multi_tx_slots i4, tx_count i4, busy_ratio f4, airtime_ratio f4, cbr_mean f4, cbr_p95 f4, cbr_ego f4.
  busy_ratio / airtime_ratio are map-wide slot use; cbr_* the channel busy ratio each station senses (the
  time the energy of a slot's senders reaches ``channel.cs_threshold_dbm`` at it, over the frame; its own
  slots excluded): mean and 95th percentile over the stations present at the frame's end, and the ego's
  (NaN without an ego). A station that appeared during the frame counts from then on.
* ``/vanet/step`` (one row per step): t_s f8, n_stations i4, cams_generated i4, cams_dropped i4,
  tx_count i4, rx_count i4, links_evaluated i4
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import shapely

from cosim.vanet.cam import CAM_FIELDS, CamGenerator, CamParams, empty_cam_arrays
from cosim.vanet.channel import Aether, ChannelParams
from cosim.vanet.mac_80211p import Mac80211pParams
from cosim.vanet.mac_cv2x import Cv2xParams
from cosim.vanet.obu import RECORD_DTYPE, ObuParams, ObuTables, ObuView, OwnState, RecordStore
from cosim.vanet.sotdma import SotdmaMac, SotdmaParams, report_rate
from cosim.world import World


@dataclass(frozen=True)
class VanetParams:
    """Everything the VANET layer needs; nested sections map to YAML ``vanet.cam``, ``vanet.sotdma`` ..."""

    cam: CamParams = field(default_factory=CamParams)
    sotdma: SotdmaParams = field(default_factory=SotdmaParams)
    channel: ChannelParams = field(default_factory=ChannelParams)
    obu: ObuParams = field(default_factory=ObuParams)
    rx_log: Literal["all", "ego", "none"] = (
        "ego"  # which receptions go to /vanet/rx ("all": ~10^6 rows/s at 1000)
    )
    # which transmissions go to /vanet/tx: "rx" those with a row in /vanet/rx (with rx_log: ego, the CAMs the
    # ego's receiver evaluated), "all" every station's (network-wide slot statistics: ~4x a default log)
    tx_log: Literal["all", "rx", "none"] = "rx"
    # medium access (issue 18): SOTDMA (the paper), IEEE 802.11p EDCA (mac_80211p) or C-V2X mode 4 SB-SPS
    # (mac_cv2x); the last two through the common interface (mac.py, mac_path.py), same channel and receiver
    mac: Literal["sotdma", "80211p", "cv2x"] = "sotdma"
    ieee80211p: Mac80211pParams = field(default_factory=Mac80211pParams)  # vanet.ieee80211p
    cv2x: Cv2xParams = field(default_factory=Cv2xParams)  # vanet.cv2x

    def __post_init__(self) -> None:
        # the frame must hold the largest CAM: frame_layout raises ValueError otherwise (the 1-s frame also
        # paces the load rows and OBU horizons of the other MACs)
        self.sotdma.frame_layout(self.cam.max_size_bytes)
        if self.mac == "cv2x" and int(self.cv2x.subchannels_for(self.cam.max_size_bytes)) == 0:
            raise ValueError(
                f"vanet.cv2x: a {self.cam.max_size_bytes}-B CAM does not fit {self.cv2x.n_subchannels} "
                f"subchannels of {self.cv2x.subchannel_rbs} RBs at MCS 7"
            )


TX_COLUMNS = {
    "t_s": np.float64,
    "sender_slot": np.int32,
    "sender_station_id": np.uint32,
    "frame": np.int64,
    "slot": np.int32,
    "size_bytes": np.uint16,
    "gen_t_s": np.float64,
    "has_lf": np.bool_,
    "n_path_points": np.uint8,
    "trigger": np.uint8,
    "timeout": np.int8,
    "offset": np.int32,
}
RX_COLUMNS = {
    "t_s": np.float64,
    "sender_slot": np.int32,
    "sender_station_id": np.uint32,
    "receiver_slot": np.int32,
    "receiver_station_id": np.uint32,
    "frame": np.int64,
    "slot": np.int32,
    "distance_m": np.float32,
    "outcome": np.uint8,
    "rx_power_dbm": np.float32,
    "gen_t_s": np.float64,
}
LOAD_COLUMNS = {
    "frame": np.int64,
    "t_s": np.float64,
    "n_slots": np.int32,
    "busy_slots": np.int32,
    "multi_tx_slots": np.int32,
    "tx_count": np.int32,
    "busy_ratio": np.float32,
    "airtime_ratio": np.float32,
    "cbr_mean": np.float32,
    "cbr_p95": np.float32,
    "cbr_ego": np.float32,
}
STEP_COLUMNS = {
    "t_s": np.float64,
    "n_stations": np.int32,
    "cams_generated": np.int32,
    "cams_dropped": np.int32,
    "tx_count": np.int32,
    "rx_count": np.int32,
    "links_evaluated": np.int32,
}


@dataclass
class VanetStepResult:
    """What one step produced; ``columns()`` gives the log topics (see the module docstring)."""

    step_index: int
    t_s: float  # window start [s]
    tx: dict[str, np.ndarray]
    rx: dict[str, np.ndarray]
    load: dict[str, np.ndarray]
    stats: dict[str, np.ndarray]
    timing_s: dict[str, float]  # wall-clock per phase (diagnostics; not deterministic, not logged)

    def columns(self) -> dict[str, dict[str, np.ndarray]]:
        return {
            "/vanet/tx": self.tx,
            "/vanet/rx": self.rx,
            "/vanet/load": self.load,
            "/vanet/step": self.stats,
        }


def _empty(spec: dict) -> dict[str, np.ndarray]:
    return {k: np.zeros(0, dtype=v) for k, v in spec.items()}


class VanetLayer:
    """CAM -> SOTDMA -> aether -> OBU for every station, one base step per call."""

    def __init__(self, params: VanetParams, buildings: Sequence[shapely.Polygon], rng: np.random.Generator,
                 map_store: Path | None = None):  # fmt: skip
        """``map_store``: the visibility maps kept between runs (``Aether``; None: none)."""
        self.params = params
        self.rng = rng
        # the shadowing field has its own stream (spawned: the MAC's draws stay as they were)
        self.aether = Aether(params.channel, buildings, rng=rng.spawn(1)[0], map_store=map_store)
        self.frame_us, self.slot_us, self.n_slots = params.sotdma.frame_layout(params.cam.max_size_bytes)
        self.frame_ms = self.frame_us // 1000
        self.cam = CamGenerator(params.cam, 1)
        self.mac_path = None
        if params.mac == "sotdma":
            self.mac = SotdmaMac(params.sotdma, self.n_slots, 1, rng)
        else:  # 802.11p / C-V2X through the common MAC interface (mac_path.py)
            from cosim.vanet.mac_path import MacPath

            self.mac_path = MacPath(params, self.aether, rng, self.frame_us)
            self.mac = self.mac_path
        self.obu = ObuTables(1)
        horizon = round(max(params.obu.map_memory_s, params.obu.stale_after_s) * 1e6)
        self.records = RecordStore(horizon + 2 * self.frame_us)
        self.capacity = 0
        self._busy_us = np.zeros(0)  # per World slot: sensed-busy time in the current frame [us]
        self._ensure_capacity(1)
        self._next_station_id = 1
        self._inbox: tuple[np.ndarray, ...] | None = None
        self._dt_us: int | None = None
        self._now_us = 0
        self._frame_acc: dict[int, list[int]] = {}  # frame -> [busy, multi, tx, airtime_us]
        self._no_load_rows = _empty(LOAD_COLUMNS)  # most steps complete no frame (zero-length: shareable)
        self._next_load_frame: int | None = None
        self._ego_slot = -1
        self._valid_now = np.zeros(0, dtype=np.int64)

    # -- capacity / stations ---------------------------------------------------------------------------------
    def _ensure_capacity(self, capacity: int) -> None:
        if capacity <= self.capacity:
            return
        old = self.capacity

        def grow(arr, fill):
            new = np.full(capacity, fill, dtype=arr.dtype) if arr is not None else None
            if arr is not None and old:
                new[:old] = arr[:old]
            return new

        if old == 0:
            self.station_id = np.zeros(capacity, dtype=np.uint32)
            self.known_valid = np.zeros(capacity, dtype=bool)
            self.known_depart = np.full(capacity, -1, dtype=np.int64)
            self.pending = np.zeros(capacity, dtype=bool)
            self.pending_cam = empty_cam_arrays(capacity)
        else:
            self.station_id = grow(self.station_id, 0)
            self.known_valid = grow(self.known_valid, False)
            self.known_depart = grow(self.known_depart, -1)
            self.pending = grow(self.pending, False)
            pending_cam = empty_cam_arrays(capacity)
            pending_cam[:old] = self.pending_cam[:old]
            self.pending_cam = pending_cam
        busy = np.zeros(capacity)
        busy[: self._busy_us.size] = self._busy_us
        self._busy_us = busy
        self.cam.ensure_capacity(capacity)
        self.mac.ensure_capacity(capacity)
        self.obu.ensure_capacity(capacity)
        self.capacity = capacity

    def first_slot_at(self, t_us: int) -> int:
        """Global index of the first slot starting at or after t_us."""
        f, rem = divmod(int(t_us), self.frame_us)
        k = -(-rem // self.slot_us)
        if k >= self.n_slots:
            f, k = f + 1, 0
        return f * self.n_slots + k

    def slot_start_us(self, g: np.ndarray) -> np.ndarray:
        g = np.asarray(g, dtype=np.int64)
        return (g // self.n_slots) * self.frame_us + (g % self.n_slots) * self.slot_us

    def _lifecycle(self, world: World, g_lo: int) -> None:
        cap = world.capacity
        valid = world.valid[:cap]
        kv = self.known_valid[:cap]
        replaced = valid & kv & (world.depart_step[:cap] != self.known_depart[:cap])
        left = (kv & (~valid | replaced)).nonzero()[0]
        came = (valid & (~kv | replaced)).nonzero()[0]
        if left.size:
            self.mac.stop(left)
            self.pending[left] = False
            self.obu.reset(left)
            self.station_id[left] = 0
        if came.size:
            self.cam.reset(came)
            if self.mac_path is None:
                self.mac.start(came, g_lo)
            else:
                self.mac_path.start(came, self._now_us, self._dt_us)
            self.pending[came] = False
            self.obu.reset(came)
            self.station_id[came] = np.arange(self._next_station_id, self._next_station_id + came.size)
            self._next_station_id += came.size
        self.known_valid[:cap] = valid
        self.known_depart[:cap] = world.depart_step[:cap]

    # -- one step --------------------------------------------------------------------------------------------
    def step(self, world: World, step_index: int, dt_s: float, on_view: Callable[[], None] | None = None
             ) -> VanetStepResult:  # fmt: skip
        """Run window [step_index dt, (step_index + 1) dt) on the snapshot ``world``.

        ``on_view`` is called as soon as the OBU views of the step are final (``obu_view``, ``station_id``):
        with SOTDMA after the deliveries, the stations and the yaw rates, before the CAMs are generated
        (what an OBU holds does not depend on the step's own transmissions: ``RecordStore``); with an
        interface MAC after the MAC's step. A radio process hands the ego's view back then and goes on
        (``cosim.phases.vanet_process``)."""
        clock = time.perf_counter
        t0 = clock()
        dt_us = round(dt_s * 1e6)
        if self._dt_us is None:
            if dt_us <= 0 or dt_us % 1000:
                raise ValueError(f"vanet: the base step must be a positive whole number of ms, got {dt_s} s")
            check_us = self.cam.check_ms * 1000
            if check_us % dt_us:
                raise ValueError(
                    f"vanet: cam.check_period_s ({check_us / 1e6} s) must be a multiple of the base step "
                    f"({dt_s} s)"
                )
            if dt_us > self.frame_us:
                raise ValueError("vanet: the base step must not be longer than a SOTDMA frame")
            self._dt_us = dt_us
        elif dt_us != self._dt_us:
            raise ValueError("vanet: the base step changed between calls")
        now_us = step_index * dt_us
        self._now_us = now_us
        t_hi = now_us + dt_us
        g_lo, g_hi = self.first_slot_at(now_us), self.first_slot_at(t_hi)
        if self._next_load_frame is None:
            self._next_load_frame = now_us // self.frame_us
        self._ensure_capacity(world.capacity)
        cap = world.capacity
        timing: dict[str, float] = {}

        # 0. deliveries of the previous window become visible (a receiver replaced since is reset below)
        if self.mac_path is not None:  # frames of an earlier window that ended by now: older, so first
            late = self.mac_path.due(now_us)
            if late is not None:
                self.obu.deliver(*late)
        if self._inbox is not None:
            self.obu.deliver(*self._inbox)
            self._inbox = None
        # 1. stations
        self._lifecycle(world, g_lo)
        valid = world.valid[:cap].copy()
        t1 = clock()
        timing["lifecycle"] = t1 - t0

        # 2. CAM generation
        now_ms = now_us // 1000
        x, y = world.x_m[:cap], world.y_m[:cap]
        self.cam.observe(now_ms, valid, x, y, world.heading_deg[:cap])  # the yaw rates, own state of a view
        if on_view is not None and self.mac_path is None:
            on_view()
        n_gen = n_drop = 0
        if now_ms % self.cam.check_ms == 0:
            dec = self.cam.check(now_ms, valid, x, y, world.heading_deg[:cap], world.speed_mps[:cap])
            slots = dec.generate[:cap].nonzero()[0]
            if slots.size:
                f = self.cam.build(
                    slots,
                    now_ms,
                    self.station_id,
                    dec.lf,
                    dec.trigger,
                    x,
                    y,
                    world.heading_deg[:cap],
                    world.speed_mps[:cap],
                    world.accel_mps2[:cap],
                    world.length_m[:cap],
                    world.width_m[:cap],
                    world.lane_index[:cap],
                    world.signals[:cap],
                )
                n_gen = int(slots.size)
                n_drop = int(np.count_nonzero(self.pending[slots]))
                self.pending_cam[slots] = f
                self.pending[slots] = True
                if self.mac_path is None:
                    rates = report_rate(
                        self.cam.t_gen_cam_ms[slots], self.frame_ms, self.params.sotdma.max_report_rate
                    )
                    self.mac.set_rates(slots, rates, g_lo)
        t2 = clock()
        timing["cam"] = t2 - t1
        if self.mac_path is not None:
            return self._step_mac(world, step_index, valid, now_us, t_hi, n_gen, n_drop, timing, t2, on_view)

        # 3. SOTDMA
        self.mac.enter(g_lo)
        tx = self.mac.transmissions(g_lo, g_hi, self.pending)
        tx_us = self.slot_start_us(tx.g)
        rec = np.empty(tx.g.size, dtype=RECORD_DTYPE)
        rec[list(CAM_FIELDS)] = self.pending_cam[tx.station]  # RECORD_DTYPE starts with the CAM fields
        rec["sender_slot"] = tx.station
        rec["g"] = tx.g
        rec["tx_us"] = tx_us
        rec["rx_us"] = tx_us + self.slot_us
        rec["timeout"] = tx.timeout
        rec["offset"] = tx.offset
        seqs = self.records.append(rec, now_us)
        t3 = clock()
        timing["sotdma"] = t3 - t2

        # 4. channel
        active = valid.nonzero()[0]
        st_xy = np.stack([x[active], y[active]], axis=1)
        tx_xy = np.stack([x[tx.station], y[tx.station]], axis=1)
        links = self.aether.links(tx_xy, tx.station, tx.g, st_xy, active)
        t4 = clock()
        timing["channel"] = t4 - t3

        air_us = self.params.sotdma.air_times_us(rec["size_bytes"])
        self._busy_us[active] += links.sensed_busy_us(air_us)
        self._ego_slot = int(world.ego_slot) if world.ego_slot >= 0 and world.valid[world.ego_slot] else -1
        self._valid_now = active

        # 5. slot reselections in slot order (each chooser knows what it decoded before its slot), then the
        # decoded messages: slot maps now, OBU tables next step
        def decoded_by(stations: np.ndarray):
            t_i, r_i, d_m = links.decoded_at(np.searchsorted(active, stations))
            return active[r_i], t_i, d_m

        self.mac.resolve(tx, decoded_by)
        lt, lr, dist = links.decoded()
        rx_slot = active[lr]
        self.mac.hear(rx_slot, lt, tx.g, tx.timeout, tx.offset, dist)
        self._inbox = (rx_slot, tx.station[lt], seqs[lt])
        t5 = clock()
        timing["deliver"] = t5 - t4

        # 6. log columns
        result = VanetStepResult(
            step_index=step_index,
            t_s=now_us / 1e6,
            tx=self._tx_columns(tx, tx_us, rec),
            rx=self._rx_columns(world, tx, tx_us, rec, links, active),
            load=self._load_rows(tx, rec, t_hi),
            stats={
                "t_s": np.array([now_us / 1e6]),
                "n_stations": np.array([active.size], dtype=np.int32),
                "cams_generated": np.array([n_gen], dtype=np.int32),
                "cams_dropped": np.array([n_drop], dtype=np.int32),
                "tx_count": np.array([tx.g.size], dtype=np.int32),
                "rx_count": np.array([lt.size], dtype=np.int32),
                "links_evaluated": np.array([links.n_evaluated], dtype=np.int32),
            },
            timing_s=timing,
        )
        timing["log"] = clock() - t5
        return result

    def _step_mac(self, world, step_index, valid, now_us, t_hi, n_gen, n_drop, timing, t2, on_view
                  ) -> VanetStepResult:  # fmt: skip
        """Steps 3-6 for an interface MAC (802.11p, C-V2X): see mac_path.py."""
        clock = time.perf_counter
        path = self.mac_path
        cap = world.capacity
        x, y = world.x_m[:cap], world.y_m[:cap]
        active = valid.nonzero()[0]
        xy = np.stack([x[active], y[active]], axis=1)
        out, rec, seqs, tx_slot, inbox = path.step(self, active, xy, now_us, self._dt_us)
        self._inbox = inbox
        if on_view is not None:  # the step's records are stored inside the MAC's step: only now
            on_view()
        t3 = clock()
        timing["mac"] = t3 - t2
        self._busy_us[active] += out.busy_us
        self._ego_slot = int(world.ego_slot) if world.ego_slot >= 0 and world.valid[world.ego_slot] else -1
        self._valid_now = active
        n = tx_slot.size
        frame = out.tx_start_us // self.frame_us
        slot = path.slot_column(out)
        tx_cols = {
            "t_s": out.tx_start_us / 1e6,
            "sender_slot": tx_slot.astype(np.int32),
            "sender_station_id": rec["station_id"].astype(np.uint32),
            "frame": frame.astype(np.int64),
            "slot": slot,
            "size_bytes": rec["size_bytes"].astype(np.uint16),
            "gen_t_s": rec["gen_ms"] / 1e3,
            "has_lf": rec["has_lf"].astype(bool),
            "n_path_points": rec["n_path_points"].astype(np.uint8),
            "trigger": rec["trigger"].astype(np.uint8),
            "timeout": np.full(n, -1, dtype=np.int8),
            "offset": np.zeros(n, dtype=np.int32),
        }
        mode = self.params.rx_log
        if mode == "none":
            rx_cols = _empty(RX_COLUMNS)
        else:
            lt, lr = out.rx_tx, out.rx_rx
            if mode == "ego":
                keep = world.is_ego[active][lr]
                lt, lr = lt[keep], lr[keep]
                sel = keep
            else:
                sel = slice(None)
            rs = active[lr]
            dxy = xy[lr] - xy[out.tx_station[lt]]
            rx_cols = {
                "t_s": rec["rx_us"][lt] / 1e6,
                "sender_slot": tx_slot[lt].astype(np.int32),
                "sender_station_id": rec["station_id"][lt].astype(np.uint32),
                "receiver_slot": rs.astype(np.int32),
                "receiver_station_id": self.station_id[rs],
                "frame": frame[lt].astype(np.int64),
                "slot": slot[lt],
                "distance_m": np.hypot(dxy[:, 0], dxy[:, 1]).astype(np.float32),
                "outcome": out.rx_outcome[sel].astype(np.uint8),
                "rx_power_dbm": out.rx_power_dbm[sel].astype(np.float32),
                "gen_t_s": rec["gen_ms"][lt] / 1e3,
            }
        path.load_add(out, self._frame_acc)
        n_res = path.n_resources
        result = VanetStepResult(
            step_index=step_index,
            t_s=now_us / 1e6,
            tx=tx_cols,
            rx=rx_cols,
            load=self._load_rows_from_acc(t_hi, n_res),
            stats={
                "t_s": np.array([now_us / 1e6]),
                "n_stations": np.array([active.size], dtype=np.int32),
                "cams_generated": np.array([n_gen], dtype=np.int32),
                "cams_dropped": np.array([n_drop], dtype=np.int32),
                "tx_count": np.array([n], dtype=np.int32),
                "rx_count": np.array([np.count_nonzero(out.rx_outcome == 0)], dtype=np.int32),
                "links_evaluated": np.array([out.rx_tx.size], dtype=np.int32),
            },
            timing_s=timing,
        )
        timing["log"] = clock() - t3
        return result

    def _tx_columns(self, tx, tx_us, rec) -> dict[str, np.ndarray]:
        n = self.n_slots
        return {
            "t_s": tx_us / 1e6,
            "sender_slot": tx.station.astype(np.int32),
            "sender_station_id": rec["station_id"].astype(np.uint32),
            "frame": tx.g // n,
            "slot": (tx.g % n).astype(np.int32),
            "size_bytes": rec["size_bytes"].astype(np.uint16),
            "gen_t_s": rec["gen_ms"] / 1e3,
            "has_lf": rec["has_lf"].astype(bool),
            "n_path_points": rec["n_path_points"].astype(np.uint8),
            "trigger": rec["trigger"].astype(np.uint8),
            "timeout": tx.timeout.astype(np.int8),
            "offset": tx.offset.astype(np.int32),
        }

    def _rx_columns(self, world, tx, tx_us, rec, links, active) -> dict[str, np.ndarray]:
        mode = self.params.rx_log
        if mode == "none":
            return _empty(RX_COLUMNS)
        batch = links.batch(world.is_ego[active].nonzero()[0] if mode == "ego" else None)
        lt, rs = batch.tx, active[batch.rx]
        dist, outcome, power = batch.distance_m, batch.outcome, batch.power_dbm
        # per-transmission values first, then one gather per column
        per_tx = {
            "t_s": (tx_us + self.slot_us) / 1e6,
            "sender_slot": tx.station.astype(np.int32),
            "sender_station_id": rec["station_id"].astype(np.uint32),
            "frame": tx.g // self.n_slots,
            "slot": (tx.g % self.n_slots).astype(np.int32),
            "gen_t_s": rec["gen_ms"] / 1e3,
        }
        return {
            "t_s": per_tx["t_s"][lt],
            "sender_slot": per_tx["sender_slot"][lt],
            "sender_station_id": per_tx["sender_station_id"][lt],
            "receiver_slot": rs.astype(np.int32),
            "receiver_station_id": self.station_id[rs],
            "frame": per_tx["frame"][lt],
            "slot": per_tx["slot"][lt],
            "distance_m": dist,
            "outcome": outcome,
            "rx_power_dbm": power,
            "gen_t_s": per_tx["gen_t_s"][lt],
        }

    def _load_rows(self, tx, rec, t_hi: int) -> dict[str, np.ndarray]:
        n = self.n_slots
        if tx.g.size:
            air = self.params.sotdma.air_times_us(rec["size_bytes"])
            frames = tx.g // n
            # tx.g is sorted: a window inside one frame (the usual case) needs no per-frame masks
            one_frame = frames[0] == frames[-1]
            for f in [int(frames[0])] if one_frame else np.unique(frames).tolist():
                g, a = (tx.g, air) if one_frame else (tx.g[frames == f], air[frames == f])
                per_slot = Counter(g.tolist())  # a few dozen transmissions: cheaper than np.unique
                add = (len(per_slot), sum(c >= 2 for c in per_slot.values()), g.size, int(a.sum()))
                self._frame_acc[f] = [
                    x + y for x, y in zip(self._frame_acc.get(f, [0, 0, 0, 0]), add, strict=True)
                ]
        return self._load_rows_from_acc(t_hi, n)

    def _load_rows_from_acc(self, t_hi: int, n: int) -> dict[str, np.ndarray]:
        """/vanet/load rows of the frames completed by t_hi, from the per-frame accumulators (n: resources
        per frame; 0: a MAC without slots, busy_ratio NaN)."""
        done_until = t_hi // self.frame_us  # frames < done_until are complete
        rows = []
        while self._next_load_frame is not None and self._next_load_frame < done_until:
            f = self._next_load_frame
            acc = self._frame_acc.pop(f, [0, 0, 0, 0])
            rows.append((f, acc))
            self._next_load_frame += 1
        if not rows:
            return dict(self._no_load_rows)
        fr = np.array([r[0] for r in rows], dtype=np.int64)
        a = np.array([r[1] for r in rows], dtype=np.int64)
        # the sensed busy time accumulated so far belongs to the (last) completed frame
        cbr = self._busy_us[self._valid_now] / self.frame_us
        ego = self._busy_us[self._ego_slot] / self.frame_us if self._ego_slot >= 0 else np.nan
        self._busy_us[:] = 0.0
        nan = np.full(fr.size, np.nan, dtype=np.float32)
        mean, p95, ego_col = nan.copy(), nan.copy(), nan.copy()
        if cbr.size:
            mean[-1], p95[-1] = cbr.mean(), np.percentile(cbr, 95)
        ego_col[-1] = ego
        return {
            "frame": fr,
            "t_s": fr * self.frame_us / 1e6,
            "n_slots": np.full(fr.size, n, dtype=np.int32),
            "busy_slots": a[:, 0].astype(np.int32),
            "multi_tx_slots": a[:, 1].astype(np.int32),
            "tx_count": a[:, 2].astype(np.int32),
            "busy_ratio": (a[:, 0] / n if n else np.full(fr.size, np.nan)).astype(np.float32),
            "airtime_ratio": (a[:, 3] / self.frame_us).astype(np.float32),
            "cbr_mean": mean,
            "cbr_p95": p95,
            "cbr_ego": ego_col,
        }

    # -- OBU access ------------------------------------------------------------------------------------------
    def obu_view(self, world: World, slot: int | None = None) -> ObuView | None:
        """The OBU of ``slot`` (default: the ego) at the last step; None when that vehicle is absent.

        Own state comes from the snapshot (the vehicle's own sensors), neighbours from decoded CAMs only.
        """
        s = world.ego_slot if slot is None else int(slot)
        if s < 0 or s >= min(world.capacity, self.capacity) or not world.valid[s]:
            return None
        lane = int(world.lane_index[s])
        own = OwnState(
            x_m=float(world.x_m[s]),
            y_m=float(world.y_m[s]),
            heading_deg=float(world.heading_deg[s]),
            speed_mps=float(world.speed_mps[s]),
            accel_mps2=float(world.accel_mps2[s]),
            lane_position=min(lane + 1, 14) if lane >= 0 else -1,
            yaw_rate_dps=float(self.cam.yaw_rate_dps[s]),
        )
        return ObuView(self.records, self.obu.heard(s), self._now_us, own, self.params.obu, self.frame_us, s)

    def close(self) -> None:
        self.aether.close()

    def station_id_of(self, slot: int) -> int:
        """Current station id of a World slot (0 = no station)."""
        return int(self.station_id[slot]) if 0 <= slot < self.capacity else 0

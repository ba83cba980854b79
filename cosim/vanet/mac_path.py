"""The VANET layer's path for the MACs behind the common interface (``vanet.mac: 80211p | cv2x``).

SOTDMA keeps its own path in ``layer.py`` (its logs are unchanged); IEEE 802.11p (``mac_80211p``) and
C-V2X mode 4 (``mac_cv2x``) are called once per base step through ``mac.Mac.step`` with the run's aether
as the link budget (``mac.aether_link_budget``: the same path loss, log-normal and building shadowing as
SOTDMA's links) and the run's receiver (``channel.receiver``: the same noise floor, sensitivity, carrier
sense and SINR capture). What the layer does around the MAC is the same for every MAC: CAM generation,
records, OBU tables (decoded CAMs visible from the next step on, once their frame has ended), log topics.

Log columns as ``layer.py`` describes them, with these readings for a MAC without SOTDMA slots:

* ``/vanet/tx``: t_s = frame start; frame = the 1-s SOTDMA frame (``sotdma.frame_s``) the start falls in;
  slot = the resource within that frame: C-V2X (subframe within the frame) x subchannels + first subchannel,
  802.11p -1; timeout -1, offset 0 (no slot announcements).
* ``/vanet/rx``: t_s = end of the frame (delivery); outcome: collided = half duplex (the receiver was
  transmitting), damaged = SINR below the threshold or (802.11p) the receiver locked onto another frame.
* ``/vanet/load`` per completed frame: n_slots = resources per frame (C-V2X subframes x subchannels;
  802.11p 0), busy_slots = resources used, multi_tx_slots = resources used by two or more transmissions,
  busy_ratio = busy_slots / n_slots (NaN for 802.11p), airtime_ratio = air time of all transmissions / frame;
  cbr_* the busy time each station sensed (the MAC's: 802.11p frames at >= the CS threshold, C-V2X
  subchannels whose S-RSSI exceeds the CBR threshold), as for SOTDMA.
"""

from __future__ import annotations

import numpy as np

from cosim.vanet.cam import CAM_FIELDS, empty_cam_arrays
from cosim.vanet.mac import MacInput, aether_link_budget
from cosim.vanet.obu import RECORD_DTYPE

MAC_NAMES = ("sotdma", "80211p", "cv2x")


def make_mac(params, capacity: int, rng: np.random.Generator):
    """The MAC object of ``params.mac`` (VanetParams) for the interface path."""
    if params.mac == "80211p":
        from cosim.vanet.mac_80211p import Mac80211p

        return Mac80211p(params.ieee80211p, capacity, rng)
    if params.mac == "cv2x":
        from cosim.vanet.mac_cv2x import MacCv2x

        return MacCv2x(params.cv2x, capacity, rng)
    raise ValueError(f"vanet.mac: {params.mac!r} has no interface MAC (one of {', '.join(MAC_NAMES[1:])})")


class MacPath:
    """State the layer keeps for an interface MAC: the MAC, the link budget, CAMs the MAC took over."""

    def __init__(self, params, aether, rng: np.random.Generator, frame_us: int):
        self.params = params
        self.mac = make_mac(params, 1, rng)
        self.link = aether_link_budget(aether)
        self.receiver = aether.rx
        self.frame_us = frame_us
        self.capacity = 0
        self.held = np.zeros(0, dtype=bool)
        self.held_cam = empty_cam_arrays(0)
        self._late: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        cv = params.cv2x
        self.n_resources = (frame_us // 1000) * cv.n_subchannels if params.mac == "cv2x" else 0

    def ensure_capacity(self, capacity: int) -> None:
        if capacity <= self.capacity:
            return
        held = np.zeros(capacity, dtype=bool)
        held[: self.capacity] = self.held
        cams = empty_cam_arrays(capacity)
        cams[: self.capacity] = self.held_cam
        self.held, self.held_cam = held, cams
        self.mac.ensure_capacity(capacity)
        self.capacity = capacity

    def start(self, stations: np.ndarray, t_us: int, dt_us: int) -> None:
        self.mac.start(stations, t_us, dt_us)
        self.held[stations] = False

    def stop(self, stations: np.ndarray) -> None:
        self.mac.stop(stations)
        self.held[stations] = False

    def due(self, t_hi_us: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Deliveries held back from the previous step whose frame ends by ``t_hi_us`` (802.11p frames that
        run past a step's end are delivered one step later)."""
        if self._late is None:
            return None
        rx, snd, seqs, rx_us = self._late
        now = rx_us <= t_hi_us
        self._late = (rx[~now], snd[~now], seqs[~now], rx_us[~now]) if not now.all() else None
        return rx[now], snd[now], seqs[now]

    def step(self, layer, active: np.ndarray, xy: np.ndarray, now_us: int, dt_us: int):
        """One window: (out, rec, seqs, tx_slot, inbox) with the MacOutput, the transmitted records (start
        order), their sequence numbers, the sender slot of each and the deliveries of the next step."""
        pending_cam = layer.pending_cam
        inp = MacInput(
            t0_us=now_us,
            dt_us=dt_us,
            stations=active,
            xy=xy,
            pending=layer.pending[active],
            size_bytes=pending_cam["size_bytes"][active].astype(np.int64),
            gen_us=pending_cam["gen_ms"][active].astype(np.int64) * 1000,
            link=self.link,
            sensitivity_dbm=self.receiver.sensitivity_dbm,
            noise_dbm=self.receiver.noise_floor_dbm,
            receiver=self.receiver,
        )
        out = self.mac.step(inp)
        tx_slot = active[out.tx_station]
        held_tx = out.tx_held if out.tx_held is not None else np.zeros(tx_slot.size, dtype=bool)
        rec = np.empty(tx_slot.size, dtype=RECORD_DTYPE)
        cams = pending_cam[tx_slot]
        if held_tx.any():
            cams[held_tx] = self.held_cam[tx_slot[held_tx]]
            self.held[tx_slot[held_tx]] = False
        rec[list(CAM_FIELDS)] = cams
        rec["sender_slot"] = tx_slot
        rec["g"] = out.tx_resource
        rec["tx_us"] = out.tx_start_us
        rec["rx_us"] = out.tx_start_us + out.tx_duration_us
        rec["timeout"] = -1
        rec["offset"] = 0
        seqs = layer.records.append(rec, now_us)
        # the pending CAMs that went on the air, and those the MAC took over (C-V2X: a later reservation)
        layer.pending[active[out.sent]] = False
        if out.taken is not None and out.taken.any():
            took = active[out.taken]
            self.held_cam[took] = pending_cam[took]
            self.held[took] = True
            layer.pending[took] = False
        lt, lr = out.decoded()
        rx_us = rec["rx_us"][lt]
        t_hi = now_us + dt_us
        inbox = (active[lr], tx_slot[lt], seqs[lt])
        late = rx_us > t_hi
        if late.any():
            keep = ~late
            new = (active[lr][late], tx_slot[lt][late], seqs[lt][late], rx_us[late])
            if self._late is not None:
                new = tuple(np.concatenate([o, v]) for o, v in zip(self._late, new, strict=True))
            self._late = new
            inbox = (inbox[0][keep], inbox[1][keep], inbox[2][keep])
        return out, rec, seqs, tx_slot, inbox

    def slot_column(self, out) -> np.ndarray:
        """The ``slot`` log column of each transmission (see the module docstring)."""
        if self.params.mac != "cv2x":
            return np.full(out.tx_station.size, -1, dtype=np.int32)
        per_frame = self.n_resources
        return (out.tx_resource % per_frame).astype(np.int32)

    def load_add(self, out, acc: dict[int, list[int]]) -> None:
        """Accumulate [busy resources, multi-tx resources, transmissions, air time us] per frame."""
        if out.tx_station.size == 0:
            return
        frames = out.tx_start_us // self.frame_us
        for f in np.unique(frames).tolist():
            m = frames == f
            dur = out.tx_duration_us[m].astype(np.int64)
            busy = multi = 0
            if self.params.mac == "cv2x" and out.tx_width is not None:
                res, width = out.tx_resource[m], out.tx_width[m].astype(np.int64)
                keys = np.repeat(res, width) + (
                    np.arange(width.sum()) - np.repeat(np.cumsum(width) - width, width)
                )
                _, counts = np.unique(keys, return_counts=True)
                busy, multi = int(counts.size), int(np.count_nonzero(counts >= 2))
            old = acc.get(f, [0, 0, 0, 0])
            acc[f] = [old[0] + busy, old[1] + multi, old[2] + int(m.sum()), old[3] + int(dur.sum())]

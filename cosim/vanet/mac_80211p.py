"""IEEE 802.11p / ETSI ITS-G5 EDCA broadcast MAC, event-ordered within each base step.

Sources of every constant (IEEE Std 802.11-2016 unless said otherwise):

* CAMs travel with DCC profile DP2 (ETSI TS 102 724 V1.1.1, Table 1: CAM -> DP2), which maps onto
  access category AC_BE (ETSI EN 302 663 V1.2.1 Annex B; the same mapping as vanetza's
  ``dcc::map_profile_onto_ac``; WiLabV2Xsim's CAM default AIFSN 6 is AC_BE too).
* EDCA parameters with dot11OCBActivated (Table 9-137; ETSI EN 302 663 V1.2.1 Table B.3 repeats them):
  AC_BK AIFSN 9, CW 15..1023; AC_BE AIFSN 6, CW 15..1023; AC_VI AIFSN 3, CW 7..15; AC_VO AIFSN 2, CW 3..7.
* 10-MHz OFDM PHY (Clause 17, Table 17-21): aSlotTime 13 us, aSIFSTime 32 us, aCCATime < 8 us (we use 8),
  preamble 32 us, SIGNAL 8 us, symbol 8 us; AIFS = aSIFSTime + AIFSN x aSlotTime (10.22.2.4), 110 us for AC_BE.
* 6 Mbit/s = QPSK 1/2 at 10 MHz: N_DBPS = 48 bits per 8-us symbol (Table 17-4, rates halved at 10 MHz);
  PSDU bits = 16 SERVICE + 8 x length + 6 tail (17.3.5.4), padded to whole symbols.
* MAC overhead per CAM 80 B (as sotdma.py: MAC header 24, LLC/SNAP 8, GeoNetworking 40, BTP-B 4, FCS 4).
* Carrier sense (17.3.10.6): a frame whose preamble arrives at >= the shared receiver's CS threshold
  (-85 dBm: the minimum sensitivity of the lowest rate at 10 MHz) makes CCA busy for its duration; so does a weaker frame the station can decode
  (>= the shared sensitivity: its PHY syncs and is in RX, as ns-3's and Veins' PHYs report busy); energy
  detection at -65 dBm (20 dB above) is then implied for single frames and not modelled for sums of weaker
  ones. The busy time reported for the CBR counts frames at >= -85 dBm only (ETSI TS 102 687 §5.2).
* Broadcast: no ACK, no retry, CW stays at CWmin; after every transmission a post-backoff of U{0..CWmin}
  slots (10.22.2.2) runs down while the medium is idle and frozen while it is busy.
* Channel access (10.22.2.2-10.22.2.4, as ns-3's ChannelAccessManager does it): a frame arriving at an idle
  MAC whose medium has been idle for AIFS goes at once; idle for less: after AIFS; busy: a backoff of
  U{0..CW} slots is drawn and counted down after AIFS of idle medium, one per idle slot, frozen while busy.
  Two stations whose counters end at the same slot boundary transmit together; a station notices another's
  transmission aCCATime after it starts, so starts less than 8 us apart collide too.
* Reception: the receiver locks onto the first frame it can decode the preamble of (power >= the shared
  sensitivity) while it is neither transmitting nor locked; a frame starting while it is locked is lost
  (no frame capture, as ns-3's default and Veins); a frame overlapping the receiver's own transmission is a
  half-duplex loss; the locked frame is decoded when S / (N + sum of every overlapping frame) >= the SINR
  threshold (the sum over the whole frame: Veins' minimum-SINR reading, conservative when interferers do
  not overlap each other). Noise floor, sensitivity, CS threshold and the SINR test are the shared
  receiver's (``receiver.capture``; ``MacInput.receiver``): its 6-dB capture threshold is that of this
  very PHY (QPSK 1/2, 6 Mb/s at 10 MHz), which SOTDMA uses too. ``sinr_threshold_db`` overrides it; Wu et
  al. 2022 (mac.py) would give 0.8 dB for the 190-B reference CAM (``wu_sinr_db``).

Event order inside a window: CAMs reach the MAC at t0 + a per-station phase drawn once per station
(uniform over the base step: each OBU's own CAM clock; the layer checks CAM generation at step
boundaries), then starts are decided in time order; a frame may end in the next window (its interference
there is counted; its own outcome is decided with the frames known when it is decided).
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass
from typing import Literal

import numpy as np

from cosim.vanet.dcc import DccParams, ReactiveDcc
from cosim.vanet.mac import (
    DAMAGED,
    HALF_DUPLEX,
    OK,
    MacInput,
    MacOutput,
    StationArrays,
    empty_output,
    loss_labels,
    receiver_of,
    shannon_sinr_threshold_db,
)
from cosim.vanet.receiver import ReceiverParams, capture

# IEEE 802.11-2016 Table 9-137 (dot11OCBActivated true): AIFSN, CWmin, CWmax
EDCA_OCB = {
    "AC_BK": (9, 15, 1023),
    "AC_BE": (6, 15, 1023),
    "AC_VI": (3, 7, 15),
    "AC_VO": (2, 3, 7),
}

NEVER = np.iinfo(np.int64).min // 4  # "long ago" [us]


@dataclass(frozen=True)
class Mac80211pParams:
    access_category: Literal["AC_BK", "AC_BE", "AC_VI", "AC_VO"] = "AC_BE"  # CAM: DP2 -> AC_BE
    slot_us: int = 13  # aSlotTime, 10 MHz (Table 17-21)
    sifs_us: int = 32  # aSIFSTime, 10 MHz (Table 17-21)
    cca_time_us: int = 8  # aCCATime, 10 MHz (Table 17-21: < 8 us)
    preamble_us: int = 32  # PLCP preamble, 10 MHz (Table 17-21)
    signal_us: int = 8  # SIGNAL field, one symbol (Table 17-21)
    symbol_us: int = 8  # OFDM symbol, 10 MHz (Table 17-21)
    bit_rate_mbps: float = 6.0  # QPSK 1/2 at 10 MHz
    mac_overhead_bytes: int = 80  # MAC 24 + LLC/SNAP 8 + GN 40 + BTP 4 + FCS 4 [B]
    cs_threshold_dbm: float | None = None  # CCA preamble detection [dBm]; None: the shared receiver's (-85)
    sinr_threshold_db: float | None = None  # minimum SINR [dB]; None: the shared receiver's capture rule
    ref_payload_bytes: int = 190  # reference CAM of ``wu_sinr_db`` [B]
    post_backoff: bool = True  # 10.22.2.2: a backoff after every transmission
    dcc: DccParams = DccParams()

    def __post_init__(self) -> None:
        if self.access_category not in EDCA_OCB:
            raise ValueError(f"80211p.access_category must be one of {sorted(EDCA_OCB)}")
        if min(self.slot_us, self.sifs_us, self.preamble_us, self.symbol_us) <= 0 or self.cca_time_us < 0:
            raise ValueError("80211p: PHY times must be > 0")
        if self.cca_time_us >= self.slot_us:
            raise ValueError("80211p.cca_time_us must be shorter than slot_us")
        ndbps = self.bit_rate_mbps * self.symbol_us
        if abs(ndbps - round(ndbps)) > 1e-9 or round(ndbps) < 1:
            raise ValueError("80211p.bit_rate_mbps must give a whole number of data bits per symbol")

    @property
    def aifsn(self) -> int:
        return EDCA_OCB[self.access_category][0]

    @property
    def cw_min(self) -> int:
        return EDCA_OCB[self.access_category][1]

    @property
    def aifs_us(self) -> int:
        return self.sifs_us + self.aifsn * self.slot_us

    @property
    def ndbps(self) -> int:
        return round(self.bit_rate_mbps * self.symbol_us)

    def air_time_us(self, payload_bytes) -> np.ndarray:
        """Frame duration [us] of CAMs of ``payload_bytes`` (array) plus the MAC overhead."""
        nbits = 16 + 8 * (np.asarray(payload_bytes, dtype=np.int64) + self.mac_overhead_bytes) + 6
        nsym = -(-nbits // self.ndbps)
        return self.preamble_us + self.signal_us + nsym * self.symbol_us

    def receiver(self, shared: ReceiverParams) -> ReceiverParams:
        """The shared receiver with this MAC's overrides (CS threshold, SINR threshold) applied."""
        import dataclasses

        kw = {}
        if self.cs_threshold_dbm is not None:
            kw["cs_threshold_dbm"] = float(self.cs_threshold_dbm)
        if self.sinr_threshold_db is not None:
            kw["capture_threshold_db"] = float(self.sinr_threshold_db)
            kw["per_curve"] = None
        return dataclasses.replace(shared, **kw) if kw else shared

    @property
    def wu_sinr_db(self) -> float:
        """Minimum SINR of the reference CAM by Wu et al. 2022 (mac.py) [dB]; not the default (see above)."""
        bits = 8 * (self.ref_payload_bytes + self.mac_overhead_bytes)
        t = self.preamble_us + self.signal_us + self.aifs_us + self.symbol_us * -(-bits // self.ndbps)
        return shannon_sinr_threshold_db(bits, t * 1e-6, 10e6)


class Mac80211p(StationArrays):
    """EDCA state of every station (arrays indexed by station key = World slot)."""

    name = "80211p"

    def __init__(self, params: Mac80211pParams, capacity: int, rng: np.random.Generator):
        self.p = params
        self.rng = rng
        self.capacity = 0
        self.dcc = ReactiveDcc(params.dcc)
        self._tail: list[
            tuple[int, int, int]
        ] = []  # (station, start_us, dur_us) running into the next window
        self.ensure_capacity(capacity)

    _STATE = {
        "idle_us": (np.int64, NEVER),  # medium idle at this station since [us] (end of the last busy period)
        "bo": (np.int32, 0),  # backoff slots left
        "bo_active": (np.bool_, False),  # a backoff is running (or frozen)
        "ref_us": (np.int64, NEVER),  # the running backoff counts down from ref_us + AIFS [us]
        "queued": (np.bool_, False),  # the pending CAM is already in the MAC (arrived in an earlier window)
        "phase_us": (np.int64, 0),  # CAM hand-over phase within the base step [us]
        "alive": (np.bool_, False),
    }

    def start(self, stations: np.ndarray, t_us: int = 0, dt_us: int = 100_000) -> None:
        stations = self._fresh(stations)
        if stations.size == 0:
            return
        self.alive[stations] = True
        self.phase_us[stations] = self.rng.integers(0, max(dt_us, 1), size=stations.size)
        self.dcc.start(stations)

    # -- one window ------------------------------------------------------------------------------------------
    def step(self, inp: MacInput) -> MacOutput:
        n = inp.stations.size
        st = np.asarray(inp.stations, dtype=np.int64)
        if n and not self.alive[st].all():  # stations the caller did not start: start them now
            self.start(st[~self.alive[st]], inp.t0_us, inp.dt_us)
        self._rx = self.p.receiver(receiver_of(inp))
        t0, t1 = int(inp.t0_us), int(inp.t0_us + inp.dt_us)
        pending = np.asarray(inp.pending, dtype=bool)
        self.queued[st] &= pending
        # frames to contend for: arrival time of each pending CAM (t0 + phase; earlier ones already queued)
        arrival = np.where(self.queued[st], NEVER, t0 + self.phase_us[st] % max(inp.dt_us, 1))
        arrival = np.maximum(arrival, self.dcc.earliest_us(st))
        has_frame = pending & (arrival < t1)
        # the loop set: stations with a frame or a running backoff (others only need their idle time)
        loop = np.flatnonzero(has_frame | self.bo_active[st])
        frames = np.flatnonzero(has_frame)
        tail = [(s, a, d) for s, a, d in self._tail if a + d > t0]
        tail_idx = np.searchsorted(st, np.array([s for s, _, _ in tail], dtype=np.int64))
        keep_tail = [
            i for i, (s, _, _) in enumerate(tail) if tail_idx[i] < n and st[min(tail_idx[i], n - 1)] == s
        ]
        tail = [tail[i] for i in keep_tail]
        tail_idx = tail_idx[keep_tail] if len(keep_tail) else np.zeros(0, dtype=np.int64)
        if frames.size == 0 and loop.size == 0:
            self._tail = tail
            out = empty_output(n)
            self._busy_from_tail(out, inp, tail, tail_idx, t0, t1)
            self.dcc.update(st, out.busy_us / max(inp.dt_us, 1))
            return out
        # received power from every potential transmitter (frames + tails) at every station
        rows = np.concatenate([frames, tail_idx]).astype(np.int64)
        lp = inp.link(inp.xy[rows], inp.xy, tx_rows=rows)
        power = lp.power_dbm
        tx_row_of = np.full(n, -1, dtype=np.int64)
        tx_row_of[frames] = np.arange(frames.size)
        tx = self._contend(inp, st, loop, frames, arrival, power, tx_row_of, t0, t1)
        # tx: (station index, start, duration) in start order
        tx_station, tx_start, tx_dur = tx
        sent = np.zeros(n, dtype=bool)
        sent[tx_station] = True
        self.dcc.sent(st[tx_station], tx_start)
        out = self._receive(inp, tx_station, tx_start, tx_dur, power, lp, tx_row_of, tail, t0, t1)
        out.sent = sent
        self._tail = [
            (int(st[s]), int(a), int(d))
            for s, a, d in zip(tx_station, tx_start, tx_dur, strict=True)
            if a + d > t1
        ]
        self.dcc.update(st, out.busy_us / max(inp.dt_us, 1))
        return out

    def _contend(self, inp, st, loop, frames, arrival, power, tx_row_of, t0, t1):
        """The event loop: returns (station index (T,), start [us] (T,), duration [us] (T,)) in start order.

        Events (a heap, in time order): a frame's arrival at the MAC, and a station's transmission attempt.
        Every transmission updates the medium-idle time of all stations that sense it (one array update);
        only stations with a running backoff need more (freeze / completion), a few at a time: plain Python.
        """
        p = self.p
        aifs, slot, delta = p.aifs_us, p.slot_us, p.cca_time_us
        cw = p.cw_min
        n = st.size
        idle = self.idle_us[st].copy()  # medium idle since [us], per station (all stations sense)
        idle_prev = idle.copy()  # its value before the last busy period sensed (for arrivals inside aCCATime)
        last_s = np.full(n, NEVER, dtype=np.int64)  # when that last busy period was sensed
        running = self.bo_active[st].copy()
        bo = self.bo[st].astype(np.int64).tolist()
        ref = self.ref_us[st].tolist()  # the countdown runs from ref + AIFS, one slot per idle aCCATime
        has = np.zeros(n, dtype=bool)
        has[frames] = True
        has_l = has.tolist()
        arrived = [False] * n
        late_end = [NEVER] * n
        ver = [0] * n
        # random draws fixed per station and window whatever the event order: backoff for a frame arriving
        # on a busy medium and the post-backoff after the transmission
        draw_arr = self.rng.integers(0, cw + 1, size=n).tolist()
        draw_post = self.rng.integers(0, cw + 1, size=n).tolist()
        dur = p.air_time_us(np.asarray(inp.size_bytes, dtype=np.int64)).astype(np.int64).tolist()
        # a station senses a frame it can decode (its PHY syncs and reports busy, as in ns-3 and Veins) or
        # one at or above the CCA threshold: the lower of the receiver's sensitivity and CS threshold
        rx = self._rx
        hear_all = power >= np.float32(min(rx.cs_threshold_dbm, rx.sensitivity_dbm))  # (rows, N)
        heap = []
        for k in frames.tolist():
            a = int(arrival[k])
            if a <= NEVER:  # queued in an earlier window: its backoff continues
                arrived[k] = True
                if running[k]:
                    heapq.heappush(heap, (max(ref[k] + aifs + bo[k] * slot, t0), 0, k, 0))
                else:
                    heapq.heappush(heap, (max(int(idle[k]) + aifs, t0), 0, k, 0))
            else:
                heapq.heappush(heap, (a, 1, k, 0))
        out_s, out_t = [], []
        while heap:
            t, kind, k, v = heapq.heappop(heap)
            if t >= t1:
                heapq.heappush(heap, (t, kind, k, v))
                break
            if v != ver[k]:
                continue
            if kind == 1:  # arrival: channel access rule (10.22.2.2 - 10.22.2.4)
                arrived[k] = True
                i = int(idle_prev[k]) if t < last_s[k] else int(idle[k])
                if running[k]:
                    end = ref[k] + aifs + bo[k] * slot
                    if end <= t:  # the post-backoff is over: the medium idle for AIFS, go at once
                        running[k] = False
                        bo[k] = 0
                        start = t
                    else:
                        start = end
                elif i <= t - aifs:
                    start = t
                elif i <= t:
                    running[k], bo[k], ref[k] = True, 0, i
                    start = i + aifs
                else:
                    running[k], bo[k], ref[k] = True, draw_arr[k], i
                    start = i + aifs + bo[k] * slot
                heapq.heappush(heap, (start, 0, k, ver[k]))
                continue
            # transmission of station k at t
            d = dur[k]
            out_s.append(k)
            out_t.append(t)
            has_l[k] = False
            ver[k] += 1
            own_end = max(t + d, late_end[k])
            if p.post_backoff:
                running[k], bo[k], ref[k] = True, draw_post[k], own_end
            else:
                running[k], bo[k] = False, 0
            idle[k] = max(int(idle[k]), own_end)
            s_b, e_b = t + delta, t + d
            h = np.flatnonzero(hear_all[tx_row_of[k]])
            if h.size == 0:
                continue
            cur = idle[h]
            idle_prev[h] = cur
            last_s[h] = s_b
            idle[h] = np.maximum(cur, e_b)
            for j in h[running[h]].tolist():
                end = ref[j] + aifs + bo[j] * slot
                if end >= s_b:  # freeze: count the idle slots before the busy period, resume after it
                    used = (s_b - ref[j] - aifs) // slot
                    if used > 0:
                        bo[j] = max(bo[j] - used, 0)
                    ref[j] = max(ref[j], e_b)
                    if has_l[j] and arrived[j]:
                        ver[j] += 1
                        heapq.heappush(heap, (ref[j] + aifs + bo[j] * slot, 0, j, ver[j]))
                elif has_l[j] and arrived[j]:  # it starts before sensing this frame (same slot)
                    late_end[j] = max(late_end[j], e_b)
                else:  # a post-backoff that ended before this frame
                    running[j], bo[j] = False, 0
        # frames still waiting (their start lies beyond the window): the backoff continues in the next one
        self.idle_us[st] = idle
        self.bo_active[st] = running
        self.bo[st] = bo
        self.ref_us[st] = ref
        self.queued[st] = np.array(has_l, dtype=bool) & np.array(arrived, dtype=bool)
        if out_s:
            s_arr = np.array(out_s, dtype=np.int64)
            t_arr = np.array(out_t, dtype=np.int64)
            d_arr = np.array([dur[k] for k in out_s], dtype=np.int64)
            order = np.lexsort((s_arr, t_arr))
            return s_arr[order], t_arr[order], d_arr[order]
        e = np.zeros(0, dtype=np.int64)
        return e, e.copy(), e.copy()

    def _busy_from_tail(self, out, inp, tail, tail_idx, t0, t1) -> None:
        if not tail:
            return
        lp = inp.link(inp.xy[tail_idx], inp.xy, tx_rows=tail_idx)
        hear = lp.power_dbm >= np.float32(self._rx.cs_threshold_dbm)
        ends = np.array([min(a + d, t1) for _, a, d in tail], dtype=np.float64)
        out.busy_us = np.where(hear, (ends - t0)[:, None], 0.0).max(axis=0)

    def _receive(self, inp, tx_station, tx_start, tx_dur, power, lp, tx_row_of, tail, t0, t1) -> MacOutput:
        """Outcomes of the window's frames at every station (see the module docstring)."""
        rx = self._rx
        n = inp.stations.size
        nt = tx_station.size
        n_tail = len(tail)
        n_frames_rows = power.shape[0] - n_tail
        # all frames on the air: the window's (rows tx_row_of) and the tails of the previous window
        rows = np.concatenate([tx_row_of[tx_station], n_frames_rows + np.arange(n_tail)]).astype(np.int64)
        start = np.concatenate([tx_start, np.array([a for _, a, _ in tail], dtype=np.int64)])
        dur = np.concatenate([tx_dur, np.array([d for _, _, d in tail], dtype=np.int64)])
        sender = np.concatenate(
            [tx_station, np.searchsorted(inp.stations, np.array([s for s, _, _ in tail], dtype=np.int64))]
        ).astype(np.int64)
        end = start + dur
        pw = power[rows]  # (F, N) dBm
        mw = np.exp(pw * np.float32(np.log(10.0) / 10.0))  # float32 [mW]; -inf -> 0
        f = rows.size
        # interference: sum over frames overlapping each frame, by prefix sums (float64) in start / end order
        by_start = np.argsort(start, kind="stable")
        by_end = np.argsort(end, kind="stable")
        s_sorted, e_sorted = start[by_start], end[by_end]
        a = np.searchsorted(s_sorted, end[:nt], side="left")  # frames starting before this one ends
        b = np.searchsorted(e_sorted, start[:nt], side="right")  # frames ended by the time it starts
        a2 = np.searchsorted(s_sorted, start[:nt], side="left")  # frames starting strictly before it
        c = np.zeros((f + 1, n))
        np.cumsum(mw[by_start], axis=0, dtype=np.float64, out=c[1:])
        interf = c[a]
        np.cumsum(mw[by_end], axis=0, dtype=np.float64, out=c[1:])
        interf -= c[b]
        interf -= mw[:nt]
        np.maximum(interf, 0.0, out=interf)
        # preamble missed: another decodable frame started strictly earlier and is still on the air
        dec = pw >= np.float32(rx.sensitivity_dbm)
        k = np.zeros((f + 1, n), dtype=np.int32)
        np.cumsum(dec[by_start], axis=0, dtype=np.int32, out=k[1:])
        locked = k[a2]
        np.cumsum(dec[by_end], axis=0, dtype=np.int32, out=k[1:])
        locked = (locked - k[b]) > 0
        # half duplex: the receiver's own frame overlaps
        hd = np.zeros((nt, n), dtype=bool)
        dmax = int(dur.max()) if f else 0
        lo = np.searchsorted(s_sorted, start[:nt] - dmax, side="right")
        hi = np.searchsorted(s_sorted, end[:nt], side="left")
        cnt = hi - lo
        if cnt.sum():
            j = np.repeat(np.arange(nt), cnt)
            o = by_start[np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt) + np.repeat(lo, cnt)]
            ov = (end[o] > start[j]) & (start[o] < end[j]) & (o != j)
            hd[j[ov], sender[o[ov]]] = True
        p_tx = pw[:nt]
        above = p_tx >= np.float32(rx.sensitivity_dbm)
        tx_rows = tx_row_of[tx_station]
        in_rng = lp.in_range[tx_rows] if nt else np.zeros((0, n), dtype=bool)
        reported = (in_rng | above) & (np.arange(n)[None, :] != tx_station[:, None])
        ti, ri = np.nonzero(reported)
        outcome = np.full(ti.size, OK, dtype=np.uint8)
        ab = above[ti, ri]
        # the shared receiver's SINR test on the reported links: S / (N + every overlapping frame)
        ok = capture(mw[:nt][ti, ri].astype(np.float64), interf[ti, ri], rx, self.rng)[1]
        damaged = locked[ti, ri] | ~ok
        outcome[damaged] = DAMAGED
        outcome[hd[ti, ri]] = HALF_DUPLEX
        bad = np.flatnonzero(~ab)
        outcome[bad] = loss_labels(lp, tx_rows[ti[bad]], ri[bad])
        # sensed busy time in the window: union of the frames heard at >= CS (own frames excluded)
        busy = self._busy(start, end, pw >= np.float32(rx.cs_threshold_dbm), sender, t0, t1, n)
        return MacOutput(
            tx_station=tx_station.astype(np.int64),
            tx_start_us=tx_start.astype(np.int64),
            tx_duration_us=tx_dur.astype(np.int32),
            tx_resource=np.full(nt, -1, dtype=np.int64),
            rx_tx=ti.astype(np.int64),
            rx_rx=ri.astype(np.int64),
            rx_power_dbm=p_tx[ti, ri].astype(np.float32),
            rx_outcome=outcome,
            busy_us=busy,
            sent=np.zeros(n, dtype=bool),
            stats={"frames": float(nt)},
        )

    @staticmethod
    def _busy(start, end, heard, sender, t0, t1, n) -> np.ndarray:
        """Per station: length of the union of heard frame intervals clipped to [t0, t1) [us]."""
        if start.size == 0:
            return np.zeros(n)
        order = np.argsort(start, kind="stable")
        s = np.clip(start[order] - t0, 0, t1 - t0).astype(np.float32)  # relative: exact in float32
        e = np.clip(end[order] - t0, 0, t1 - t0).astype(np.float32)
        h = heard[order]
        h[np.arange(order.size), sender[order]] = False
        e_m = np.where(h, e[:, None], np.float32(-1.0))
        run_end = np.maximum.accumulate(e_m, axis=0)
        prev = np.empty_like(run_end)
        prev[0] = -1.0
        prev[1:] = run_end[:-1]
        np.maximum(prev, s[:, None], out=prev)
        np.subtract(e[:, None], prev, out=prev)
        np.maximum(prev, 0.0, out=prev)
        prev *= h
        return prev.sum(axis=0, dtype=np.float64)

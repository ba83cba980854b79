"""Self-Organised TDMA (ITU-R M.1371 Annex 2 §3.3, as proposed for vehicular networks by Bilstrup et al.).

Time is cut into frames (default 1 s) of N slots. One slot carries the largest CAM the CAM parameters can
produce plus the lower-layer headers at the PHY bit rate, plus a guard:

* air time: IEEE 802.11p OFDM, 10 MHz channel: preamble 32 us + SIGNAL 8 us + ceil((16 + 8 L + 6) / N_DBPS)
  symbols of 8 us, N_DBPS = bit rate x 8 us (48 bit at 6 Mbit/s); other widths scale these times by 10/MHz;
* L = CAM + ``mac_overhead_bytes`` (80 B: MAC header 24, LLC/SNAP 8, GeoNetworking basic+common+single-hop
  broadcast 40, BTP-B 4, FCS 4; no security header);
* guard 32 us (SIFS at 10 MHz): covers propagation (3.3 us/km), rx/tx turnaround and timing error.
With the default CAM parameters (243 B max) a slot lasts 512 us and a 1-s frame has 1953 slots.

Phases per station (each keeps its own slot map, built only from messages it decoded, so hidden terminals
arise naturally: a station cannot know slots used by stations it cannot hear):

1. initialization: listen for ``listen_frames`` frames (1; the paper skipped this phase, set 0 for that);
2. network entry + first frame: report rate r (slots per frame) -> nominal increment NI = N // r; nominal
   start slot NSS drawn uniformly within the next NI slots; nominal slots NS_j = NSS + j NI; each NS_j gets
   a selection interval SI = NS_j +- floor(``selection_interval_frac`` x NI) (+-10 %); inside it a slot is
   drawn uniformly from the candidate set and kept for a timeout drawn from U{3..7} frames. During the
   first frame every transmission announces the offset to the station's next slot (so neighbours learn the
   new reservations before they are used);
3. continuous operation: every use of a slot announces its remaining timeout and then counts it down; at
   timeout 0 the station picks a new slot in the same SI of the next frame and announces its offset in
   that last transmission. When that use carries no CAM (nothing is sent), the station's next transmission
   announces the offset instead (ITU-R M.1371 Annex 2 changes allocations with ITDMA, whose communication
   state carries the slot increment and the keep flag); receivers hold an announced slot for
   ``timeout_min_frames``.

Candidate set (ITU-R M.1371): the free slots of the SI (by the station's own map); when fewer than
``min_candidates`` (4) are free, the set is filled with slots reserved by the farthest stations heard; when
none is free at all, the slot of the farthest station is reused (issue 5's rule).

Report rate follows the CAM generation rate: r = clamp(ceil(frame / T_GenCam), 1, ``max_report_rate``),
applied at once when it rises and when it falls to half or less (hysteresis against CAM-interval jitter).
A station keeps its reservations and adds slots (each new nominal slot in the middle of the largest gap
between its nominal slots) or drops an evenly spread subset; the first frame after a change announces
offsets like the first frame after entry. This is our reading: ITU-R M.1371 changes the reporting
interval through ITDMA, which is not modelled.
A reserved slot with no fresh CAM stays silent (its timeout still counts down); a CAM waits at most one NI.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SotdmaParams:
    """Frame structure and SOTDMA access parameters."""

    frame_s: float = 1.0  # frame length [s]
    bit_rate_mbps: float = 6.0  # PHY data rate [Mbit/s] (QPSK 1/2 at 10 MHz)
    channel_mhz: float = 10.0  # channel width [MHz]; sets the OFDM timing
    guard_us: int = 32  # guard time per slot [us]
    mac_overhead_bytes: int = 80  # headers added to each CAM below the facilities layer [B]
    n_slots: int | None = None  # slots per frame; None = as many slots of the largest CAM as fit
    selection_interval_frac: float = 0.1  # SI half-width as a fraction of NI (+-10 %)
    min_candidates: int = 4  # minimum candidate-set size
    timeout_min_frames: int = 3  # slot timeout drawn from U{min..max} frames
    timeout_max_frames: int = 7
    max_report_rate: int = 10  # reports per frame at most (10 Hz CAMs)
    listen_frames: int = 1  # initialization phase length [frames]

    def __post_init__(self) -> None:
        if not self.frame_s > 0:
            raise ValueError("sotdma.frame_s must be > 0")
        if abs(self.frame_s * 1e6 - round(self.frame_s * 1e6)) > 1e-6:
            raise ValueError("sotdma.frame_s must be a whole number of microseconds")
        if not self.bit_rate_mbps > 0 or not self.channel_mhz > 0:
            raise ValueError("sotdma.bit_rate_mbps and sotdma.channel_mhz must be > 0")
        ndbps = self.bit_rate_mbps * 1e6 * self.symbol_us * 1e-6
        if abs(ndbps - round(ndbps)) > 1e-6 or round(ndbps) < 1:
            raise ValueError(
                f"sotdma.bit_rate_mbps = {self.bit_rate_mbps} gives {ndbps:g} data bits per OFDM symbol at "
                f"{self.channel_mhz} MHz; use an 802.11 rate (e.g. 3, 4.5, 6, 9, 12, 18, 24, 27 at 10 MHz)"
            )
        if self.guard_us < 0 or self.mac_overhead_bytes < 0:
            raise ValueError("sotdma.guard_us and sotdma.mac_overhead_bytes must be >= 0")
        if self.n_slots is not None and self.n_slots < 1:
            raise ValueError("sotdma.n_slots must be >= 1 (or null for automatic sizing)")
        if not 0 <= self.selection_interval_frac <= 0.5:
            raise ValueError("sotdma.selection_interval_frac must be in [0, 0.5]")
        if self.min_candidates < 1:
            raise ValueError("sotdma.min_candidates must be >= 1")
        if not 0 <= self.timeout_min_frames <= self.timeout_max_frames:
            raise ValueError("sotdma: need 0 <= timeout_min_frames <= timeout_max_frames")
        if self.max_report_rate < 1:
            raise ValueError("sotdma.max_report_rate must be >= 1")
        if self.listen_frames < 0:
            raise ValueError("sotdma.listen_frames must be >= 0")

    @property
    def symbol_us(self) -> float:
        return 8.0 * 10.0 / self.channel_mhz

    def air_time_us(self, payload_bytes: int) -> int:
        """802.11p OFDM frame duration [us] (rounded up) for a CAM of ``payload_bytes`` plus headers."""
        ndbps = round(self.bit_rate_mbps * self.symbol_us)
        nbits = 16 + 8 * (payload_bytes + self.mac_overhead_bytes) + 6
        nsym = -(-nbits // ndbps)
        preamble_us = 32.0 * 10.0 / self.channel_mhz
        return math.ceil(preamble_us + self.symbol_us + nsym * self.symbol_us - 1e-9)

    def air_times_us(self, payload_bytes: np.ndarray) -> np.ndarray:
        """Vectorised ``air_time_us`` (without rounding to whole us) for an array of CAM sizes [B]."""
        ndbps = round(self.bit_rate_mbps * self.symbol_us)
        nbits = 22 + 8 * (np.asarray(payload_bytes, dtype=np.int64) + self.mac_overhead_bytes)
        nsym = -(-nbits // ndbps)
        return 32.0 * 10.0 / self.channel_mhz + self.symbol_us * (1 + nsym)

    def frame_layout(self, max_cam_bytes: int) -> tuple[int, int, int]:
        """(frame_us, slot_us, n_slots) for CAMs of at most ``max_cam_bytes``."""
        frame_us = round(self.frame_s * 1e6)
        slot_us = self.air_time_us(max_cam_bytes) + self.guard_us
        n = frame_us // slot_us if self.n_slots is None else self.n_slots
        if n < 1 or n * slot_us > frame_us:
            raise ValueError(
                f"sotdma: {n} slots of {slot_us} us do not fit a {frame_us} us frame; lower n_slots or "
                "the CAM size (path_history_max_points)"
            )
        return frame_us, slot_us, int(n)


def report_rate(t_gen_cam_ms: np.ndarray, frame_ms: int, max_rate: int) -> np.ndarray:
    """Slots per frame that carry a CAM every T_GenCam: clamp(ceil(frame / T_GenCam), 1, max_rate)."""
    t = np.maximum(np.asarray(t_gen_cam_ms, dtype=np.int64), 1)
    return np.minimum(np.maximum(-(-frame_ms // t), 1), max_rate).astype(np.int16)  # np.clip costs 3x


def _as_list(v) -> list:
    return v if isinstance(v, list) else np.asarray(v).tolist()


def select_slots(
    map_until: np.ndarray,
    map_dist: np.ndarray,
    stations: np.ndarray,
    lo_g: np.ndarray,
    hi_g: np.ndarray,
    own: np.ndarray,
    n_slots: int,
    min_candidates: int,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Pick one slot per request i in the global slot range [lo_g[i], hi_g[i]] (shorter than a frame),
    seen from the slot map of station ``stations[i]``.

    map_until: (S, N) int, frame through which each slot is reserved by another station (-1 none);
    map_dist: (S, N) float, distance to that station [m]; own: (B, R) slot numbers the requesting station
    already holds (-1 = none), never candidates. Returns (global slot index (B,), candidate-set size (B,)).
    Requests come a few at a time with intervals of 40-400 slots: plain Python beats array rounds here.
    """
    n = n_slots
    requests = []
    for st, lo, hi, own_row in zip(
        _as_list(stations), _as_list(lo_g), _as_list(hi_g), _as_list(own), strict=True
    ):
        f0, k0 = divmod(lo, n)
        width = hi - lo + 1
        # the interval is at most a frame (+1), so it wraps at most once: offsets from ``split`` on lie in
        # the next frame (a reservation through frame f0 still blocks them, one through f0 + 1 not)
        split = min(width, n - k0)
        row = map_until[st]
        is_free = row[k0 : k0 + split] < f0
        if split < width:
            is_free = np.concatenate((is_free, row[: width - split] <= f0))
        mine = {(o - lo) % n for o in own_row if o >= 0}
        for o in mine:
            if o < width:
                is_free[o] = False
        requests.append((st, lo, k0, width, mine, is_free.nonzero()[0]))
    u_all = rng.random(len(requests)).tolist()
    picks, sizes = [], []
    for (st, lo, k0, width, mine, free), u in zip(requests, u_all, strict=True):
        nf = free.size
        if nf >= min_candidates:
            picks.append(lo + int(free[int(u * nf)]))
            sizes.append(nf)
            continue
        free = free.tolist()
        # fill the candidate set with the slots of the farthest stations (stable: equal distances keep slot
        # order); none free: the farthest one (or the first slot when nobody reserved any)
        free_set = set(free)
        dist = map_dist[st]
        taken = [o for o in range(width) if o not in mine and o not in free_set]
        far = sorted(taken, key=lambda o: -float(dist[(k0 + o) % n]))
        total = nf + min(min_candidates - nf, len(taken))
        jj = int(u * total)
        if nf == 0:
            pos = far[0] if far else 0
            sizes.append(min(total, 1))
        else:
            pos = free[jj] if jj < nf else far[jj - nf]
            sizes.append(total)
        picks.append(lo + pos)
    return np.array(picks, dtype=np.int64), np.array(sizes, dtype=np.int64)


def select_slot(
    map_until: np.ndarray,
    map_dist: np.ndarray,
    own_slots: np.ndarray,
    lo_g: int,
    hi_g: int,
    n_slots: int,
    min_candidates: int,
    rng: np.random.Generator,
) -> tuple[int, int]:
    """``select_slots`` for one station's map row (N,) and one interval: (global slot, candidate-set size)."""
    own = np.asarray(own_slots, dtype=np.int64).reshape(1, -1)
    if own.shape[1] == 0:
        own = np.full((1, 1), -1, dtype=np.int64)
    g, n = select_slots(
        map_until[None, :],
        map_dist[None, :],
        np.array([0]),
        np.array([lo_g]),
        np.array([hi_g]),
        own,
        n_slots,
        min_candidates,
        rng,
    )
    return int(g[0]), int(n[0])


IDLE, LISTENING, ACTIVE = 0, 1, 2


@dataclass
class Transmissions:
    """Slot uses with a CAM in one window, sorted by global slot (arrays of shape (n,))."""

    station: np.ndarray  # int32 station slot
    g: np.ndarray  # int64 global slot index (frame * N + slot)
    timeout: np.ndarray  # int8 announced remaining timeout [frames]
    offset: np.ndarray  # int32 announced offset to a newly selected / next slot [slots]; 0 = none


class SotdmaMac:
    """SOTDMA state of every station (World slot), vectorised where it is hot.

    Reservations live in (capacity, max_report_rate) arrays; the slot map of each station is a
    (capacity, N) array of "reserved through frame" indices plus the distance to the reserving station.
    """

    def __init__(self, params: SotdmaParams, n_slots: int, capacity: int, rng: np.random.Generator):
        self.p = params
        self.n = n_slots
        self.rng = rng
        self.r_max = params.max_report_rate
        self.replans = 0  # rate-change re-plans so far (diagnostics)
        self.n_started = 0  # 1 + the highest slot ever started: stations from there on are idle (not scanned)
        self.capacity = 0
        self._deferred: list[tuple[int, int, int, int]] = []  # reselections left to resolve()
        # station -> new slots (global) chosen at a use that carried no CAM, to announce in its next transmission
        self._unannounced: dict[int, list[int]] = {}
        self._deferred_tx: Transmissions | None = None
        self._alloc(capacity)

    _STATION = {
        "state": (np.int8, IDLE),
        "listen_end_g": (np.int64, 0),
        "rate": (np.int16, 1),
        "nss": (np.int32, 0),  # nominal start slot number
        "first_frame_end_g": (np.int64, -1),  # offsets to the next slot are announced before this slot
    }
    _RES = {
        "res_slot": (np.int32, -1),  # reserved slot number
        "res_nominal": (np.int32, -1),  # its nominal slot number
        "res_next_g": (np.int64, -1),  # next global slot at which it is used
        "res_timeout": (np.int16, 0),  # remaining timeout [frames]
    }
    _MAP = {
        "map_until": (np.int32, -1),  # frame through which the slot is reserved by another station
        "map_dist": (np.float32, 0.0),  # its distance when heard [m]
    }

    def _alloc(self, capacity: int) -> None:
        old = self.capacity
        for name, (dt, fill) in self._STATION.items():
            arr = np.full(capacity, fill, dtype=dt)
            if old:
                arr[:old] = getattr(self, name)
            setattr(self, name, arr)
        for group, width in ((self._RES, self.r_max), (self._MAP, self.n)):
            for name, (dt, fill) in group.items():
                arr = np.full((capacity, width), fill, dtype=dt)
                if old:
                    arr[:old] = getattr(self, name)
                setattr(self, name, arr)
        self.capacity = capacity

    def ensure_capacity(self, capacity: int) -> None:
        if capacity > self.capacity:
            self._alloc(capacity)

    # -- lifecycle -------------------------------------------------------------------------------------------
    def start(self, slots: np.ndarray, g_now: int) -> None:
        """New stations: empty map, no reservations, listen for listen_frames frames."""
        self.stop(slots)
        if np.size(slots):
            self.n_started = max(self.n_started, int(np.max(slots)) + 1)
        self.state[slots] = LISTENING
        self.listen_end_g[slots] = g_now + self.p.listen_frames * self.n
        self.map_until[slots] = -1
        self.map_dist[slots] = 0.0

    def stop(self, slots: np.ndarray) -> None:
        for st in np.atleast_1d(slots).tolist():
            self._unannounced.pop(st, None)
        self.state[slots] = IDLE
        self.res_slot[slots] = -1
        self.res_nominal[slots] = -1
        self.res_next_g[slots] = -1
        self.res_timeout[slots] = 0
        self.first_frame_end_g[slots] = -1

    # -- slot selection --------------------------------------------------------------------------------------
    def _delta(self, rate):
        """Selection-interval half-width for a report rate (int, or array) [slots]."""
        if isinstance(rate, int):
            return int(self.p.selection_interval_frac * (self.n // rate))
        return (self.p.selection_interval_frac * (self.n // np.asarray(rate))).astype(np.int64)

    def _assign(self, s, j, nominal, centre, delta, after) -> np.ndarray:
        """Select and store reservation j of station s for a batch of requests (shape (B,); delta and
        after may be scalars): a slot in [centre - delta, centre + delta], not before ``after``; returns the
        chosen global slots (B,) int64. A few requests per call: plain Python around select_slots."""
        s, j = np.asarray(s).tolist(), np.asarray(j).tolist()
        b = len(s)
        nominal, centre = np.asarray(nominal).tolist(), np.asarray(centre).tolist()
        delta, after = ([int(v)] * b if np.ndim(v) == 0 else np.asarray(v).tolist() for v in (delta, after))
        lo = [max(c - d, a) for c, d, a in zip(centre, delta, after, strict=True)]
        hi = [max(c + d, x) for c, d, x in zip(centre, delta, lo, strict=True)]
        own = self.res_slot[s].tolist()
        for row, ji in zip(own, j, strict=True):
            row[ji] = -1  # the slot being replaced may be chosen again
        g = select_slots(
            self.map_until, self.map_dist, s, lo, hi, own, self.n, self.p.min_candidates, self.rng
        )[0].tolist()
        timeout = self.rng.integers(self.p.timeout_min_frames, self.p.timeout_max_frames + 1, size=b).tolist()
        n = self.n
        for si, ji, gi, nom, tau in zip(s, j, g, nominal, timeout, strict=True):
            self.res_slot[si, ji] = gi % n
            self.res_nominal[si, ji] = nom
            self.res_next_g[si, ji] = gi
            self.res_timeout[si, ji] = tau
        # requests of one station in one batch whose intervals overlap may have met: redo one by one
        for st in sorted(set(s)):
            held = [x for x in self.res_slot[st].tolist() if x >= 0]
            if len(set(held)) == len(held):
                continue
            for i in (i for i, si in enumerate(s) if si == st):
                row = self.res_slot[st].tolist()
                if row.count(row[j[i]]) > 1:
                    row[j[i]] = -1
                    gi = int(
                        select_slots(
                            self.map_until,
                            self.map_dist,
                            [st],
                            [lo[i]],
                            [hi[i]],
                            [row],
                            n,
                            self.p.min_candidates,
                            self.rng,
                        )[0][0]
                    )
                    g[i] = gi
                    self.res_slot[st, j[i]] = gi % n
                    self.res_next_g[st, j[i]] = gi
        return np.array(g, dtype=np.int64)

    def _next_centre(self, nominal, delta, g_now: int):
        """Global index of the next occurrence of a nominal slot whose SI still lies (partly) ahead."""
        return (g_now - delta) + ((np.asarray(nominal) - (g_now - delta)) % self.n)

    def _enter(self, stations: np.ndarray, g_now: int) -> None:
        """Network entry + first frame: one slot in the SI of each nominal slot NSS + j NI."""
        n = self.n
        rate = self.rate[stations].astype(np.int64)
        ni = n // rate
        self.nss[stations] = (g_now + self.rng.integers(0, ni)) % n
        s = np.repeat(stations, rate)
        j = np.arange(s.size) - np.repeat(np.cumsum(rate) - rate, rate)
        nominal = (self.nss[s] + j * np.repeat(ni, rate)) % n
        delta = np.repeat(self._delta(rate), rate)
        self._assign(s, j, nominal, self._next_centre(nominal, delta, g_now), delta, g_now)
        self.state[stations] = ACTIVE
        self.first_frame_end_g[stations] = g_now + n

    def _change_rate(self, stations: np.ndarray, g_now: int) -> None:
        """Adapt stations to their new ``rate``, keeping what they can.

        More slots: each new nominal slot goes to the middle of the largest gap between the current nominal
        slots, and a slot is selected in its SI. Fewer: keep an evenly spread subset of the reservations.
        A few stations with a few slots each: plain Python beats array rounds here.
        """
        n, r_max = self.n, self.r_max
        res = (self.res_slot, self.res_nominal, self.res_next_g, self.res_timeout)
        req_s, req_j, req_nominal = [], [], []
        for st in np.asarray(stations).tolist():
            slot, nom = self.res_slot[st].tolist(), self.res_nominal[st].tolist()
            used = [c for c in range(r_max) if slot[c] >= 0]
            cnt, new = len(used), int(self.rate[st])
            if new < cnt:
                # the reservations by nominal slot (stable: ties keep column order), every (cnt / new)-th
                # (rounded half to even) moved to the first columns
                by_nom = sorted(used, key=nom.__getitem__)
                keep = [by_nom[round(k * cnt / new)] for k in range(new)]
                for a, fill in zip(res, (-1, -1, -1, 0), strict=True):
                    row = a[st].tolist()
                    a[st] = [row[c] for c in keep] + [fill] * (r_max - new)
            elif new > cnt:
                # the new nominal slots one at a time, each in the middle of the largest gap (first of equal
                # ones), to the station's unused columns in order
                noms = sorted(nom[c] for c in used)
                free_cols = [c for c in range(r_max) if slot[c] < 0]
                for col in free_cols[: new - cnt]:
                    c = len(noms)
                    if c == 0:
                        nominal = int(self.nss[st])
                    else:
                        best_gap, best_k = -1, 0
                        for k in range(c):
                            gap = (noms[k + 1 if k + 1 < c else 0] - noms[k]) % n or n
                            if gap > best_gap:
                                best_gap, best_k = gap, k
                        nominal = (noms[best_k] + best_gap // 2) % n
                    bisect.insort(noms, nominal)
                    req_s.append(st)
                    req_j.append(col)
                    req_nominal.append(nominal)
                self.first_frame_end_g[st] = g_now + n
        if not req_s:
            return
        delta = [self._delta(int(self.rate[st])) for st in req_s]
        centre = self._next_centre(np.array(req_nominal), np.array(delta), g_now)
        self._assign(req_s, req_j, req_nominal, centre, delta, g_now)

    def set_rates(self, slots: np.ndarray, rates: np.ndarray, g_now: int) -> None:
        """Report-rate update after CAM generation.

        Active stations adapt when the rate must rise, or when it fell to half or less (hysteresis: a CAM
        interval jittering between 0.4 and 0.5 s would otherwise change it every few CAMs); stations that
        are still listening just take the new rate.
        """
        rates = np.minimum(np.maximum(rates, 1), self.r_max).astype(np.int16)
        cur = self.rate[slots]
        active = self.state[slots] == ACTIVE
        change = ~active | (rates > cur) | (rates <= cur // 2)
        slots, rates = slots[change], rates[change]
        replan = slots[self.state[slots] == ACTIVE]
        self.rate[slots] = rates
        self.replans += int(replan.size)
        if replan.size:
            self._change_rate(replan, g_now)

    def enter(self, g_now: int) -> np.ndarray:
        """Network entry for every listening station whose initialization phase is over; returns them."""
        ready = ((self.state == LISTENING) & (self.listen_end_g <= g_now)).nonzero()[0]
        if ready.size:
            self._enter(ready, g_now)
        return ready

    def force_reservation(self, station: int, j: int, slot: int, next_g: int, timeout: int) -> None:
        """Overwrite reservation j of a station (scripted scenarios and tests: a forced hidden terminal)."""
        self.res_slot[station, j] = slot
        self.res_next_g[station, j] = next_g
        self.res_timeout[station, j] = timeout
        if self.res_nominal[station, j] < 0:
            self.res_nominal[station, j] = slot

    # -- one window ------------------------------------------------------------------------------------------
    def transmissions(self, g_lo: int, g_hi: int, pending: np.ndarray) -> Transmissions:
        """Use every reserved slot in [g_lo, g_hi): stations with a pending CAM send it in their first one.

        ``pending`` (capacity,) bool is cleared for the stations that sent. Timeouts count down on every use
        (sent or silent); a use at timeout 0 needs a new slot in the same SI of the next frame. Those choices
        are *not* made here: ``resolve`` makes them in slot order once the window's receptions are known, so
        a station choosing at slot g sees every reservation it decoded before g, also earlier in this window
        (their announced offsets are 0 in the returned arrays until then).
        A window holds a few dozen uses: after the array scan, plain Python beats array rounds.
        """
        if self._deferred:  # the previous window was not resolved: its choosers decoded nothing
            self.resolve(self._deferred_tx)
        n = self.n
        next_g = self.res_next_g[: self.n_started]
        use = (next_g >= g_lo) & (next_g < g_hi)
        use &= (self.state[: self.n_started] == ACTIVE)[:, None]
        st, j = use.nonzero()
        # by slot, then station, then reservation column
        uses = sorted(zip(self.res_next_g[st, j].tolist(), st.tolist(), j.tolist(), strict=True))
        res_next_g, res_timeout = self.res_next_g, self.res_timeout
        sent, sent_tau = [], []
        resel = []  # (g, station, column, index among the sent transmissions or -1)
        seen = set()
        for g, s, jj in uses:
            # the first use of each station in the window carries its pending CAM
            k = -1
            if s not in seen:
                seen.add(s)
                if pending[s]:
                    pending[s] = False
                    k = len(sent)
                    sent.append((g, s))
            tau = int(res_timeout[s, jj])
            if k >= 0:
                sent_tau.append(tau)
            # continuous operation: count down, or reselect at timeout 0 (in ``resolve``)
            if tau > 0:
                res_timeout[s, jj] = tau - 1
                res_next_g[s, jj] = g + n
            else:
                resel.append((g, s, jj, k))
        # first frame after entry / re-plan: announce the offset to the station's next slot, the nearest
        # later one of a later use in this window or a next reservation (reselected slots lie a frame ahead)
        offsets = [0] * len(sent)
        later_uses: dict[int, list[int]] = {}
        for g, s, _ in uses:
            later_uses.setdefault(s, []).append(g)
        for k, (g, s) in enumerate(sent):
            if sent_tau[k] > 0 and g < self.first_frame_end_g[s]:
                later = [x for x in res_next_g[s].tolist() if x > g]
                later += [x for x in later_uses[s] if x > g]
                offsets[k] = min(later) - g if later else 0
        # a move decided at a use that sent nothing (no CAM waiting) is announced by the station's next
        # transmission with room for it (not one announcing its own move or next slot): ITU-R M.1371 Annex 2
        # changes allocations with ITDMA (§3.3.4), whose communication state carries the slot increment to the
        # allocated slot and the keep flag (held on: receivers keep it reserved, see ``hear``)
        if self._unannounced:
            for k, (g, s) in enumerate(sent):
                todo = self._unannounced.get(s)
                if todo is None or offsets[k] != 0 or sent_tau[k] == 0:
                    continue
                while todo and todo[0] <= g:  # its first use came first: announced by that use
                    todo.pop(0)
                if todo:
                    offsets[k] = todo.pop(0) - g
                if not todo:
                    del self._unannounced[s]
        tx = Transmissions(
            np.array([s for _, s in sent], dtype=np.int32),
            np.array([g for g, _ in sent], dtype=np.int64),
            np.array(sent_tau, dtype=np.int8),
            np.array(offsets, dtype=np.int32),
        )
        self._deferred, self._deferred_tx = resel, tx
        return tx

    def resolve(self, tx: Transmissions, decoded_by=None) -> None:
        """Make the window's deferred slot reselections in slot order (after ``transmissions``).

        ``decoded_by(stations) -> (rx_station (m,), link_tx (m,), dist_m (m,))``: the window's decoded
        messages at those stations (link_tx indexes ``tx``); None: nothing was decoded. Before the choices at slot g, the choosers' slot
        maps take in what they decoded from slots before g; each choice is then announced (``tx.offset``,
        filled in place) by the transmission in that slot, if it carried a CAM. Choices at the same slot
        are simultaneous and can meet. The caller then ``hear``s the whole window (idempotent for the part
        heard here).
        """
        resel, self._deferred = self._deferred, []
        if not resel:
            return
        n = self.n
        i = 0
        while i < len(resel):
            g = resel[i][0]
            k = i
            while k < len(resel) and resel[k][0] == g:
                k += 1
            group = resel[i:k]
            i = k
            rs = [u[1] for u in group]
            if decoded_by is not None:
                rx, lt, dist = decoded_by(np.array(sorted(set(rs)), dtype=np.int64))
                before = tx.g[lt] < g
            if decoded_by is not None and before.any():
                self.hear(rx[before], lt[before], tx.g, tx.timeout, tx.offset, dist[before])
            rj = [u[2] for u in group]
            delta = [self._delta(max(int(self.rate[s]), 1)) for s in rs]
            nominal = [int(self.res_nominal[s, jj]) for s, jj in zip(rs, rj, strict=True)]
            # the nominal occurrence this use belongs to, then the same one a frame later
            centre = [g + (nom - g % n + n // 2) % n - n // 2 + n for nom in nominal]
            new_g = self._assign(rs, rj, nominal, centre, delta, g + 1).tolist()
            for (_, s, _, kk), gn in zip(group, new_g, strict=True):
                if kk >= 0:
                    tx.offset[kk] = gn - g
                else:  # nothing sent in the slot left: the station's next transmission announces it
                    bisect.insort(self._unannounced.setdefault(s, []), gn)

    def hear(
        self,
        rx: np.ndarray,
        link_tx: np.ndarray,
        g: np.ndarray,
        timeout: np.ndarray,
        offset: np.ndarray,
        dist_m: np.ndarray,
    ) -> None:
        """Update receivers' slot maps from decoded messages: receiver rx (m,) decoded transmission
        link_tx (m,) at distance dist_m (m,); g, timeout, offset (T,) describe the transmissions."""
        if rx.size == 0:
            return
        n = self.n
        g = g.astype(np.int64)
        until = (g // n + timeout.astype(np.int64)).astype(np.int32)  # per transmission, then per link
        # a receiver decodes at most one message per slot, so these cells are unique
        cell = rx.astype(np.int64) * n
        cell += (g % n)[link_tx]
        mu, md = self.map_until.reshape(-1), self.map_dist.reshape(-1)
        mu[cell] = np.maximum(mu[cell], until[link_tx])
        md[cell] = dist_m
        ann_tx = offset != 0
        if ann_tx.any():
            ann = ann_tx[link_tx].nonzero()[0]
            gt = g[link_tx[ann]] + offset[link_tx[ann]].astype(np.int64)
            cell = rx[ann].astype(np.int64) * n + gt % n
            # a newly announced slot is held for at least timeout_min_frames more frames (its own timeout is
            # drawn from U{min..max} and first announced when it is used): marking it for its first frame only
            # let others pick it for the frame after, before its first use told them the timeout
            np.maximum.at(mu, cell, (gt // n + self.p.timeout_min_frames).astype(np.int32))
            md[cell] = dist_m[ann]

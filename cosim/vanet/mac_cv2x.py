"""C-V2X (LTE-V2X) sidelink mode 4: sensing-based semi-persistent scheduling (3GPP Rel-14), subframe-ordered.

Sources of every rule and constant:

* Resources (TS 36.211 / 36.213): 1-ms subframes; the 10-MHz pool is cut into ``n_subchannels`` (5)
  subchannels of ``subchannel_rbs`` (10) RBs, PSCCH (SCI format 1, 2 RBs) adjacent to the PSSCH in the first
  subchannel (TS 36.331 SL-CommResourcePoolV2X: numSubchannel {1,3,5,8,10,15,20}, sizeSubchannel with
  adjacency {5,6,10,15,20,25,50,75,100}; 5 x 10 fills the 50 RBs of 10 MHz).
* Size: a CAM plus ``overhead_bytes`` (52 B: GeoNetworking 40 + BTP 4 + PDCP/RLC/MAC ~8) must fit the
  transport block of its PSSCH RBs (L x 10 - 2) at MCS 7 (QPSK, I_TBS = 7: TS 36.213 Table 8.6.1-1);
  TBS from TS 36.213 Table 7.1.7.2.1-1, row I_TBS 7 (``TBS_ITBS7``). A 190-B CAM (242 B) needs 2 subchannels.
  MCS 9 (QPSK, I_TBS 9, ``TBS_ITBS9``) is tabulated too: 190 B in 10 RBs (code rate ~0.7), the configuration
  of Gonzalez-Martin et al. 2019 (``validation/cv2x/``).
* SB-SPS resource selection (TS 36.213 §14.1.1.6, steps 1-10; TS 36.321 §5.14.1.1): at a CAM arrival n
  the candidates are every L adjacent subchannels in every subframe of [n + T1, n + T2] (T1 = 1, T2 = 100,
  as WiLabV2Xsim's defaults; M_total = 100 x (C - L + 1)); exclude those in subframes the station could not
  monitor (its own transmissions, same phase of the 100-ms RRI: step 5) and those reserved by an SCI the
  station decoded in the previous RRI whose PSSCH-RSRP exceeds Th (step 6; PSSCH-RSRP = the received power
  per resource element, TS 36.214 §5.1.29); Th = ``rsrp_threshold_dbm`` (-110 dBm, WiLabV2Xsim's default),
  raised by 3 dB until at least 20 % of M_total remain (step 7); rank the rest by the linear average S-RSSI
  of the same subframe phase over the 1000-ms sensing window (step 8; TS 36.214 §5.1.28) and keep the 20 %
  M_total lowest (S_B, step 9); the MAC picks one of S_B uniformly (36.321).
* Reservation: every RRI (100 ms) for a counter drawn from U{5..15} transmissions (36.321 for RRI >= 100 ms);
  at counter 0 the resource is kept with probability ``prob_keep`` (probResourceKeep, 0..0.8; default 0.8
  as WiLabV2Xsim's), else the last SCI announces no reservation and the next CAM triggers a selection. A
  CAM that does not fit the reserved subchannels, or a reservation unused for 1 s, also triggers one
  (36.321 §5.14.1.1). A CAM waits for its reserved subframe (up to one RRI).
* Reception by the shared receiver (``receiver.capture``, ``MacInput.receiver``): half duplex (a station
  transmitting in a subframe receives nothing in it); PSSCH decoded when the power is at or above the
  receiver's sensitivity and S / (N + I) >= the SINR threshold, with N the receiver's noise floor scaled to
  the frame's RBs and I the power of every other transmission of the subframe in the same subchannels
  (interferers below the receiver's interference floor are not in the link budget). The threshold is that
  of MCS 7, not the receiver's (which is the 6-Mb/s OFDM PHY's): Wu et al. 2022 (mac.py) for a 190-B CAM
  at MCS 7: 2.8 dB (``sinr_threshold_db`` overrides it); or, with ``bler_curve`` ((SINR dB, BLER) points,
  linear in dB between them), decoded with probability 1 - BLER(SINR) (the MAC's random stream), as
  link-level curves are used (e.g. 3GPP R1-160284, in Gonzalez-Martin et al. 2019). The SCI (PSCCH, 2 RBs) is decoded
  when its SINR per RB >= ``sci_sinr_threshold_db`` (0 dB, WiLabV2Xsim's minSCIsinr).
* CBR (TS 36.214 §5.1.30): the share of subchannel-subframes whose S-RSSI exceeds ``cbr_rssi_threshold_dbm``
  (-94 dBm; threshS-RSSI-CBR, TS 36.331: -112..-60 dBm): ``busy_us`` counts 1000 / C us per busy one.

All stations are synchronised to the subframe grid. CAMs reach the MAC at a per-station phase within the
base step (uniform, drawn once per station), as in mac_80211p.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cosim.vanet.dcc import DccParams, ReactiveDcc
from cosim.vanet.mac import (
    DAMAGED,
    HALF_DUPLEX,
    OK,
    MacInput,
    MacOutput,
    StationArrays,
    dbm_to_mw,
    empty_output,
    loss_labels,
    receiver_of,
    shannon_sinr_threshold_db,
)
from cosim.vanet.receiver import capture

# TS 36.213 Table 7.1.7.2.1-1, I_TBS = 7, N_PRB = 1..50 [bits]
TBS_ITBS7 = (
    104, 224, 328, 472, 584, 712, 840, 968, 1096, 1224, 1320, 1480, 1608, 1672, 1800, 1928, 2088, 2216, 2344,
    2472, 2536, 2664, 2792, 2984, 3112, 3240, 3368, 3368, 3496, 3624, 3752, 3880, 4008, 4136, 4264, 4392, 4584,
    4584, 4776, 4968, 4968, 5160, 5352, 5352, 5544, 5736, 5736, 5992, 5992, 6200,
)  # fmt: skip
# TS 36.213 Table 7.1.7.2.1-1, I_TBS = 9, N_PRB = 1..50 [bits]
TBS_ITBS9 = (
    136, 296, 456, 616, 776, 936, 1096, 1256, 1416, 1544, 1736, 1864, 2024, 2216, 2344, 2536, 2664, 2856, 2984,
    3112, 3368, 3496, 3624, 3752, 4008, 4136, 4264, 4392, 4584, 4776, 4968, 5160, 5160, 5352, 5544, 5736, 5736,
    5992, 6200, 6200, 6456, 6712, 6712, 6968, 6968, 7224, 7480, 7480, 7736, 7992,
)  # fmt: skip
TBS_ROWS = {7: TBS_ITBS7, 9: TBS_ITBS9}  # QPSK MCS (I_TBS = I_MCS for I_MCS <= 10, TS 36.213 Table 8.6.1-1)
NEVER = -(10**9)  # "long ago" [subframes]


@dataclass(frozen=True)
class Cv2xParams:
    n_subchannels: int = 5  # numSubchannel (TS 36.331)
    subchannel_rbs: int = 10  # sizeSubchannel [RB] (TS 36.331)
    pscch_rbs: int = 2  # SCI format 1 on 2 RBs (TS 36.211 §9.4)
    channel_rbs: int = 50  # RBs of a 10-MHz channel
    mcs: int = 7  # PSSCH MCS (QPSK); I_TBS 7 and 9 are tabulated here (TBS_ROWS)
    overhead_bytes: int = 52  # GN 40 + BTP 4 + PDCP/RLC/MAC headers [B]
    rri_ms: int = 100  # resource reservation interval [ms]
    t1_ms: int = 1  # selection window start (TS 36.213: T1 <= 4)
    t2_ms: int = 100  # selection window end (20 <= T2 <= 100)
    sensing_ms: int = 1000  # sensing window (TS 36.213 §14.1.1.6: 10 x 100 ms)
    rsrp_threshold_dbm: float = -110.0  # Th (SL-ThresPSSCH-RSRP), step 6
    rsrp_step_db: float = 3.0  # step 7
    candidate_ratio: float = 0.2  # steps 7 and 9
    resel_min: int = 5  # SL_RESOURCE_RESELECTION_COUNTER for RRI >= 100 ms (TS 36.321)
    resel_max: int = 15
    prob_keep: float = 0.8  # probResourceKeep (TS 36.331: 0..0.8)
    unused_reselect_ms: int = 1000  # a reservation unused this long is dropped (TS 36.321)
    sci_sinr_threshold_db: float = 0.0  # PSCCH decoding [dB] (WiLabV2Xsim minSCIsinr)
    sinr_threshold_db: float | None = None  # None: Wu et al. 2022 for ref_payload_bytes at MCS 7 (2.8 dB)
    ref_payload_bytes: int = 190
    bler_curve: tuple[tuple[float, float], ...] | None = None  # ((SINR dB, BLER), ...) replaces it
    cbr_rssi_threshold_dbm: float = -94.0  # threshS-RSSI-CBR (TS 36.331)
    dcc: DccParams = DccParams()

    def __post_init__(self) -> None:
        if self.mcs not in TBS_ROWS:
            raise ValueError(f"cv2x.mcs: only MCS {', '.join(map(str, TBS_ROWS))} are tabulated")
        if self.bler_curve is not None:
            pts = [tuple(map(float, q)) for q in self.bler_curve]
            s = [q[0] for q in pts]
            if len(pts) < 2 or any(b <= a for a, b in zip(s[:-1], s[1:], strict=True)):
                raise ValueError("cv2x.bler_curve: >= 2 (SINR dB, BLER) points, SINR ascending")
            if any(not 0 <= q[1] <= 1 for q in pts):
                raise ValueError("cv2x.bler_curve: BLER in [0, 1]")
            object.__setattr__(self, "bler_curve", tuple(pts))
        if self.n_subchannels < 1 or self.subchannel_rbs <= self.pscch_rbs:
            raise ValueError("cv2x: need n_subchannels >= 1 and subchannel_rbs > pscch_rbs")
        if self.n_subchannels * self.subchannel_rbs > self.channel_rbs:
            raise ValueError("cv2x: n_subchannels x subchannel_rbs exceeds the channel's RBs")
        if not 1 <= self.t1_ms <= 4 or not self.t1_ms < self.t2_ms <= self.rri_ms:
            raise ValueError("cv2x: need 1 <= t1_ms <= 4 and t1_ms < t2_ms <= rri_ms")
        if self.sensing_ms % self.rri_ms:
            raise ValueError("cv2x.sensing_ms must be a multiple of rri_ms")
        if not 0 < self.candidate_ratio <= 1 or not 0 <= self.prob_keep <= 1:
            raise ValueError("cv2x: candidate_ratio in (0, 1], prob_keep in [0, 1]")
        if not 1 <= self.resel_min <= self.resel_max:
            raise ValueError("cv2x: need 1 <= resel_min <= resel_max")

    def subchannels_for(self, payload_bytes) -> np.ndarray:
        """Subchannels a CAM of ``payload_bytes`` (array) needs (0 = too large for the pool)."""
        bits = 8 * (np.asarray(payload_bytes, dtype=np.int64) + self.overhead_bytes)
        tbs = np.asarray(TBS_ROWS[self.mcs])
        need = np.zeros(bits.shape, dtype=np.int64)
        for L in range(self.n_subchannels, 0, -1):
            prb = min(L * self.subchannel_rbs - self.pscch_rbs, tbs.size)
            need[bits <= tbs[prb - 1]] = L
        return need

    @property
    def sinr_min_db(self) -> float:
        if self.sinr_threshold_db is not None:
            return float(self.sinr_threshold_db)
        bits = 8 * (self.ref_payload_bytes + self.overhead_bytes)
        prb = int(np.searchsorted(np.asarray(TBS_ROWS[self.mcs]), bits)) + 1  # fewest PRBs whose TBS holds it
        return shannon_sinr_threshold_db(bits, 1e-3, prb * 10e6 / self.channel_rbs)  # RB = 200 kHz of 10 MHz


class MacCv2x(StationArrays):
    """SB-SPS state of every station (arrays indexed by station key = World slot)."""

    name = "cv2x"

    _STATE = {
        "res_sf": (np.int64, NEVER),  # next subframe of the reservation (NEVER: none)
        "res_x": (np.int64, 0),  # first subchannel
        "res_L": (np.int64, 0),  # subchannels
        "counter": (np.int64, 0),  # reselection counter
        "last_tx_sf": (np.int64, NEVER),
        "phase_ms": (np.int64, 0),
        "held_sf": (np.int64, NEVER),  # a CAM the MAC took over, waiting for this reserved subframe
        "start_sf": (np.int64, 0),
        "alive": (np.bool_, False),
    }

    def __init__(self, params: Cv2xParams, capacity: int, rng: np.random.Generator):
        self.p = params
        self.rng = rng
        self.capacity = 0
        self.dcc = ReactiveDcc(params.dcc)
        self._sci_min = 10.0 ** (params.sci_sinr_threshold_db / 10.0)
        self._archive: list[dict] = []  # one entry per past window: what each station sensed in it
        self.stats = {"selections": 0, "keeps": 0, "threshold_raises": 0}
        self.ensure_capacity(capacity)

    def start(self, stations: np.ndarray, t_us: int = 0, dt_us: int = 100_000) -> None:
        stations = self._fresh(stations)
        if stations.size == 0:
            return
        self.alive[stations] = True
        self.start_sf[stations] = t_us // 1000
        self.phase_ms[stations] = self.rng.integers(0, max(dt_us // 1000, 1), size=stations.size)
        self.dcc.start(stations)

    # -- one window ------------------------------------------------------------------------------------------
    def step(self, inp: MacInput) -> MacOutput:
        p = self.p
        st = np.asarray(inp.stations, dtype=np.int64)
        n = st.size
        if n and not self.alive[st].all():
            self.start(st[~self.alive[st]], inp.t0_us, inp.dt_us)
        import dataclasses

        # the shared receiver with the MCS's threshold or BLER curve (a PER curve given for the OFDM PHY does
        # not apply)
        self._rx = dataclasses.replace(
            receiver_of(inp), capture_threshold_db=float(p.sinr_min_db), per_curve=p.bler_curve
        )
        if inp.t0_us % 1000 or inp.dt_us % 1000:
            raise ValueError("cv2x: the base step must be whole milliseconds")
        sf0, sf1 = inp.t0_us // 1000, (inp.t0_us + inp.dt_us) // 1000
        pending = np.asarray(inp.pending, dtype=bool)
        arrival = sf0 + self.phase_ms[st] % max(sf1 - sf0, 1)
        arrival = np.maximum(arrival, -(-self.dcc.earliest_us(st) // 1000))
        held = self.held_sf[st] > NEVER
        frames = np.flatnonzero((pending & (arrival < sf1)) | held)
        # drop the archive older than the sensing window
        self._archive = [a for a in self._archive if a["sf1"] > sf0 - p.sensing_ms]
        if frames.size == 0:
            self._archive.append(self._empty_archive(st, sf0, sf1))
            out = empty_output(n)
            out.taken = np.zeros(n, dtype=bool)
            out.tx_held = np.zeros(0, dtype=bool)
            return out
        lp = inp.link(inp.xy[frames], inp.xy, tx_rows=frames)
        self._power = lp.power_dbm
        self._in_range_all = lp.in_range
        self._lp = lp
        self._row_of = np.full(n, -1, dtype=np.int64)
        self._row_of[frames] = np.arange(frames.size)
        need_L = p.subchannels_for(np.asarray(inp.size_bytes)[frames])
        if np.any(need_L == 0):
            raise ValueError(
                "cv2x: a CAM does not fit the resource pool; raise n_subchannels or subchannel_rbs"
            )
        g = st[frames]
        # reservation uses, and the frames that need a selection (no reservation, unused 1 s, does not fit)
        txs = {"k": [], "sf": [], "x": [], "L": [], "keep": [], "held": []}
        sel_k, sel_n, sel_L = [], [], []
        # CAMs the MAC took over in an earlier window go in their reserved subframe
        for k in np.flatnonzero(held).tolist():
            gk = int(st[k])
            hs = int(self.held_sf[gk])
            self.held_sf[gk] = NEVER
            self._use(txs, k, gk, hs, int(self.res_x[gk]), int(self.res_L[gk]), held=True)
        new = pending & (arrival < sf1)
        for k, gk, a, L in zip(
            frames.tolist(), g.tolist(), arrival[frames].tolist(), need_L.tolist(), strict=True
        ):
            if not new[k]:
                continue
            r = int(self.res_sf[gk])
            if r > NEVER and a - int(self.last_tx_sf[gk]) > p.unused_reselect_ms and a > r:
                r = NEVER  # unused for 1 s
            if r > NEVER and int(self.res_L[gk]) >= L:
                if r < a:
                    r += -(-(a - r) // p.rri_ms) * p.rri_ms
                self.res_sf[gk] = r
                if r < sf1:
                    self._use(txs, k, gk, r, int(self.res_x[gk]), int(self.res_L[gk]))
                else:
                    self.held_sf[gk] = r
                continue
            self.res_sf[gk] = NEVER
            sel_k.append(k)
            sel_n.append(a)
            sel_L.append(L)
        self._sensed = []  # this window's folded chunks
        self._folded_to = sf0
        self._txs = txs
        self._st = st
        self._inp = inp
        self._outs = []
        order = np.argsort(np.asarray(sel_n, dtype=np.int64), kind="stable")
        sel_k, sel_n, sel_L = (np.asarray(v, dtype=np.int64)[order] for v in (sel_k, sel_n, sel_L))
        i = 0
        while i < sel_k.size:
            j = i
            while j < sel_k.size and sel_n[j] == sel_n[i]:
                j += 1
            nn = int(sel_n[i])
            self._fold(nn)  # everything before nn is final (new choices lie at nn + 1 or later)
            self._select(sel_k[i:j], nn, sel_L[i:j], sf1)
            i = j
        self._fold(sf1)
        out = self._collect(n, frames)
        self._archive.append(self._merge(sf0, sf1))
        out.taken = new & (self.held_sf[st] > NEVER) & ~out.sent
        self.dcc.sent(st[out.tx_station], out.tx_start_us)
        self.dcc.update(st, out.busy_us / max(inp.dt_us, 1))
        del self._power, self._inp, self._in_range_all, self._lp
        return out

    def _use(self, txs, k, gk, sf, x, L, held=False) -> None:
        """Station k (global gk) transmits in its reservation at subframe sf."""
        p = self.p
        self.counter[gk] -= 1
        keep = True
        if self.counter[gk] <= 0:
            if self.rng.random() < p.prob_keep:
                self.counter[gk] = self.rng.integers(p.resel_min, p.resel_max + 1)
                self.stats["keeps"] += 1
            else:
                keep = False
        txs["k"].append(k)
        txs["sf"].append(sf)
        txs["x"].append(x)
        txs["L"].append(L)
        txs["keep"].append(keep)
        txs["held"].append(held)
        self.last_tx_sf[gk] = sf
        self.res_sf[gk] = sf + p.rri_ms if keep else NEVER

    def _select(self, ks: np.ndarray, nn: int, Ls: np.ndarray, sf1: int) -> None:
        """TS 36.213 §14.1.1.6 for stations ks (step indices) arriving at subframe nn."""
        p = self.p
        C = p.n_subchannels
        W = p.t2_ms - p.t1_ms + 1  # candidate subframes
        B = ks.size
        cols = self._st[ks]
        # sensed S-RSSI sums per (candidate subframe offset, subchannel) and decoded SCIs of the last RRI
        rssi = np.zeros((B, W, C))
        sci_o, sci_x, sci_L, sci_rsrp, sci_b = [], [], [], [], []
        for a in self._archive + self._sensed:
            pos = np.searchsorted(a["st"], cols)
            pos = np.minimum(pos, max(a["st"].size - 1, 0))
            have = (a["st"].size > 0) & (a["st"][pos] == cols) if a["st"].size else np.zeros(B, dtype=bool)
            if not have.any():
                continue
            ksf, kc = a["key_sf"], a["key_c"]
            win = (ksf >= nn - p.sensing_ms) & (ksf < nn)
            if win.any() and a["rssi"].shape[0]:
                wi = np.flatnonzero(win)
                o = (ksf[wi] - nn - p.t1_ms) % p.rri_ms
                wi, o = wi[o < W], o[o < W]
                # the B columns first, then the rows: a (U, N) archive is never copied whole
                vals = a["rssi"][:, pos][wi] * have[None, :]
                rssi[:, o, kc[wi]] += vals.T  # (sf, c) keys of one archive (one RRI) are unique
            tsf = a["tx_sf"]
            rec = (tsf >= nn - p.rri_ms) & (tsf < nn) & a["tx_keep"]
            if rec.any():
                r = a["rsrp"][:, pos][rec]  # (K, B)
                r = np.where(have[None, :], r, -np.inf)
                kk, bb = np.nonzero(np.isfinite(r))
                sci_o.append((tsf[rec][kk] + p.rri_ms) - nn - p.t1_ms)
                sci_x.append(a["tx_x"][rec][kk])
                sci_L.append(a["tx_L"][rec][kk])
                sci_rsrp.append(r[kk, bb])
                sci_b.append(bb)
        if sci_o:
            sci_o, sci_x, sci_L, sci_rsrp, sci_b = (
                np.concatenate(v) for v in (sci_o, sci_x, sci_L, sci_rsrp, sci_b)
            )
            okr = (sci_o >= 0) & (sci_o < W)
            sci_o, sci_x, sci_L, sci_rsrp, sci_b = (v[okr] for v in (sci_o, sci_x, sci_L, sci_rsrp, sci_b))
        # own transmissions (step 5): the phase of the station's last transmission within the window
        own = self.last_tx_sf[cols]
        own_o = np.where(own >= nn - p.sensing_ms, (own - nn - p.t1_ms) % p.rri_ms, -1)
        sub = np.arange(C)
        for b in range(B):
            L = int(Ls[b])
            nx = C - L + 1
            m_total = W * nx
            # E per candidate: mean over the L subchannels of the summed S-RSSI of that phase
            csum = np.concatenate([np.zeros((W, 1)), np.cumsum(rssi[b], axis=1)], axis=1)
            E = (csum[:, L : L + nx] - csum[:, :nx]) / L  # (W, nx)
            blocked_own = np.zeros((W, nx), dtype=bool)
            if own_o[b] >= 0 and own_o[b] < W:
                blocked_own[own_o[b]] = True
            if isinstance(sci_b, np.ndarray) and sci_b.size:
                m = sci_b == b
                so, sx, sl, sr = sci_o[m], sci_x[m], sci_L[m], sci_rsrp[m]
            else:
                so = sx = sl = sr = np.zeros(0)
            # overlap of each SCI's subchannels with each candidate start x: (S, nx); per candidate the
            # strongest overlapping SCI's RSRP, so that each threshold raise is one comparison
            ov = (sx[:, None] < sub[None, :nx] + L) & (sub[None, :nx] < (sx + sl)[:, None])
            strongest = np.full((W, nx), -np.inf)
            if so.size:
                oo, xx = np.nonzero(ov)
                np.maximum.at(strongest, (so[oo].astype(np.int64), xx), sr[oo])
            th = p.rsrp_threshold_dbm
            while True:
                excl = blocked_own | (strongest > th)
                if (~excl).sum() >= p.candidate_ratio * m_total or th > 0:
                    break
                th += p.rsrp_step_db
                self.stats["threshold_raises"] += 1
            cand = np.flatnonzero(~excl.reshape(-1))
            n_b = max(int(np.ceil(p.candidate_ratio * m_total)), 1)
            # equal S-RSSI (above all resources nobody in range used: a UE measures them all at its noise
            # floor) ranks in random order: a stable sort would hand every station the earliest such subframes
            # after its CAM, so neighbours selecting at nearly the same time pick from the same few (validation
            # against Gonzalez-Martin et al. 2019, validation/cv2x/: half of S_B were such ties at 100 veh/km)
            cand = cand[self.rng.permutation(cand.size)]
            best = cand[np.argsort(E.reshape(-1)[cand], kind="stable")[:n_b]]
            pick = int(best[int(self.rng.integers(0, best.size))])
            o, x = divmod(pick, nx)
            y = nn + p.t1_ms + o
            gk = int(cols[b])
            self.counter[gk] = self.rng.integers(p.resel_min, p.resel_max + 1)
            self.res_sf[gk], self.res_x[gk], self.res_L[gk] = y, x, L
            self.stats["selections"] += 1
            if y < sf1:
                self._use(self._txs, int(ks[b]), gk, y, x, L)
            else:
                self.held_sf[gk] = y

    def _fold(self, until_sf: int) -> None:
        """Evaluate every transmission in [folded_to, until_sf): outcomes, what each station sensed."""
        a = self._folded_to
        if until_sf <= a:
            return
        self._folded_to = until_sf
        tx = self._txs
        sf = np.asarray(tx["sf"], dtype=np.int64)
        sel = np.flatnonzero((sf >= a) & (sf < until_sf))
        if sel.size == 0:
            return
        p = self.p
        C, rbs = p.n_subchannels, p.subchannel_rbs
        k = np.asarray(tx["k"], dtype=np.int64)[sel]
        sf = sf[sel]
        x = np.asarray(tx["x"], dtype=np.int64)[sel]
        L = np.asarray(tx["L"], dtype=np.int64)[sel]
        keep = np.asarray(tx["keep"], dtype=bool)[sel]
        hl = np.asarray(tx["held"], dtype=bool)[sel]
        o = np.lexsort((k, sf))
        k, sf, x, L, keep, hl = k[o], sf[o], x[o], L[o], keep[o], hl[o]
        n = self._st.size
        pw = self._power[self._row_of[k]]  # (K, N) dBm
        mw = dbm_to_mw(pw)
        # per (subframe, subchannel): the power every station receives there [mW per subchannel]
        rep = np.repeat(np.arange(k.size), L)
        sub = x[rep] + (np.arange(rep.size) - np.repeat(np.cumsum(L) - L, L))
        key = sf[rep] * C + sub
        ko = np.argsort(key, kind="stable")
        key_s = key[ko]
        first = np.flatnonzero(np.r_[True, key_s[1:] != key_s[:-1]])
        ukey = key_s[first]
        S = np.add.reduceat((mw / L[:, None])[rep[ko]], first, axis=0)  # (U, N)
        slot_of = np.searchsorted(ukey, key)  # row of S of each (tx, subchannel)
        band = np.add.reduceat(S[slot_of], np.cumsum(L) - L, axis=0)  # summed over each frame's subchannels
        interf = np.maximum(band - mw, 0.0)
        rx = self._rx
        noise_full = float(dbm_to_mw(rx.noise_floor_dbm))
        noise_rb = noise_full / p.channel_rbs
        # half duplex: the receiver transmits in the same subframe
        hd = np.zeros((k.size, n), dtype=bool)
        fs = np.flatnonzero(np.r_[True, sf[1:] != sf[:-1]])
        cnt = np.diff(np.r_[fs, sf.size])
        for g0, c in zip(fs.tolist(), cnt.tolist(), strict=True):
            if c > 1:
                hd[np.ix_(np.arange(g0, g0 + c), k[g0 : g0 + c])] = True
        hd[np.arange(k.size), k] = False
        above = pw >= np.float32(rx.sensitivity_dbm)
        in_range = self._link_in_range(k)
        reported = (in_range | above) & (np.arange(n)[None, :] != k[:, None])
        ti, ri = np.nonzero(reported)
        outcome = np.full(ti.size, OK, dtype=np.uint8)
        # S / (N_band + I) by the receiver's rule: scaled by N_full / N_band, its noise is the full floor
        scale = (p.channel_rbs / (L * rbs))[ti]
        ok = capture(mw[ti, ri] * scale, interf[ti, ri] * scale, rx, self.rng if p.bler_curve else None)[1]
        outcome[~ok] = DAMAGED
        outcome[hd[ti, ri]] = HALF_DUPLEX
        ab = above[ti, ri]
        bad = np.flatnonzero(~ab)
        outcome[bad] = loss_labels(self._lp, self._row_of[k][ti[bad]], ri[bad])
        self._outs.append((k, sf, x, L, ti, ri, pw[ti, ri].astype(np.float32), outcome, hl))
        # SCI (PSCCH, first subchannel) decoding and PSSCH-RSRP per resource element
        first_sub = S[np.searchsorted(ukey, sf * C + x)]  # (K, N) power per subchannel in the PSCCH's
        sig_rb = mw / (L[:, None] * rbs)
        sci_sinr = sig_rb / (noise_rb + np.maximum(first_sub - mw / L[:, None], 0.0) / rbs)
        rsrp = pw - (10.0 * np.log10(12.0 * L * rbs))[:, None].astype(np.float32)  # per resource element
        sci_ok = (sci_sinr >= self._sci_min) & ~hd & np.isfinite(pw)
        sci_ok[np.arange(k.size), k] = False
        # S-RSSI above the CBR threshold, compared in mW (no log of the (U, N) matrix)
        busy = ((S + noise_rb * rbs) > 10.0 ** (p.cbr_rssi_threshold_dbm / 10.0)).sum(axis=0) * (1000.0 / C)
        self._sensed.append(
            {
                "st": self._st,
                "key_sf": ukey // C,
                "key_c": ukey % C,
                "rssi": S.astype(np.float32),
                "tx_sf": sf,
                "tx_x": x,
                "tx_L": L,
                "tx_keep": keep,
                "rsrp": np.where(sci_ok, rsrp, -np.inf).astype(np.float32),
                "busy": busy,
                "sf1": until_sf,
            }
        )

    def _link_in_range(self, k: np.ndarray) -> np.ndarray:
        return self._in_range_all[self._row_of[k]]

    def _merge(self, sf0: int, sf1: int) -> dict:
        parts = self._sensed
        if not parts:
            return self._empty_archive(self._st, sf0, sf1)
        cat = {
            key: np.concatenate([q[key] for q in parts])
            for key in ("key_sf", "key_c", "tx_sf", "tx_x", "tx_L", "tx_keep")
        }
        cat["rssi"] = np.concatenate([q["rssi"] for q in parts], axis=0)
        cat["rsrp"] = np.concatenate([q["rsrp"] for q in parts], axis=0)
        cat["st"] = self._st
        cat["sf1"] = sf1
        return cat

    @staticmethod
    def _empty_archive(st, sf0, sf1) -> dict:
        n = st.size
        e = np.zeros(0, dtype=np.int64)
        return {
            "st": st,
            "key_sf": e,
            "key_c": e,
            "rssi": np.zeros((0, n), np.float32),
            "tx_sf": e,
            "tx_x": e,
            "tx_L": e,
            "tx_keep": np.zeros(0, dtype=bool),
            "rsrp": np.zeros((0, n), np.float32),
            "sf1": sf1,
        }

    def _collect(self, n: int, frames: np.ndarray) -> MacOutput:
        C = self.p.n_subchannels
        busy = np.zeros(n)
        for q in self._sensed:
            busy += q["busy"]
        if not self._outs:
            out = empty_output(n)
            out.busy_us = busy
            out.tx_held = np.zeros(0, dtype=bool)
            return out
        k = np.concatenate([o[0] for o in self._outs])
        sf = np.concatenate([o[1] for o in self._outs])
        hl = np.concatenate([o[8] for o in self._outs])
        x = np.concatenate([o[2] for o in self._outs])
        base = np.cumsum([0] + [o[0].size for o in self._outs[:-1]])
        ti = np.concatenate([o[4] + b for o, b in zip(self._outs, base, strict=True)])
        ri = np.concatenate([o[5] for o in self._outs])
        pwr = np.concatenate([o[6] for o in self._outs])
        oc = np.concatenate([o[7] for o in self._outs])
        # each chunk is sorted by (subframe, station) and chunks are in time order: usually no sort is needed
        if np.all((sf[1:] > sf[:-1]) | ((sf[1:] == sf[:-1]) & (k[1:] > k[:-1]))):
            order = np.arange(k.size)
            lo = np.arange(ti.size)  # nonzero() gives (ti, ri) sorted per chunk, chunks in tx order
        else:
            order = np.lexsort((k, sf))
            inv = np.empty_like(order)
            inv[order] = np.arange(order.size)
            ti = inv[ti]
            lo = np.lexsort((ri, ti))
        sent = np.zeros(n, dtype=bool)
        sent[k[~hl]] = True
        out = MacOutput(
            tx_station=k[order],
            tx_start_us=sf[order] * 1000,
            tx_duration_us=np.full(k.size, 1000, dtype=np.int32),
            tx_resource=(sf * C + x)[order],
            rx_tx=ti[lo].astype(np.int64),
            rx_rx=ri[lo].astype(np.int64),
            rx_power_dbm=pwr[lo],
            rx_outcome=oc[lo],
            busy_us=busy,
            sent=sent,
            stats=dict(self.stats),
        )
        out.tx_held = hl[order]
        out.tx_width = np.concatenate([o[3] for o in self._outs])[order]
        return out

"""The medium-access interface every MAC implements (SOTDMA, IEEE 802.11p EDCA, C-V2X mode 4 SB-SPS).

One call per base step (``Mac.step``). The MAC is given

* the window [t0_us, t0_us + dt_us) and the stations active in it: their keys (World slots, the index of
  every per-station state array the MAC keeps), positions, and which of them hold a CAM waiting to be sent
  (its size in bytes and generation time);
* a link budget: ``link(tx_xy (T,2), rx_xy (M,2)) -> LinkPowers`` with the received power [dBm] of every
  (transmitter, receiver) pair after path loss and shadowing (-inf: blocked or out of range) and whether the
  pair lies within the communication range by path loss alone (those links are reported, as the aether
  reports them). ``aether_link_budget`` builds one from the shared ``channel.Aether``; tests pass a plain
  function of the distance.

and returns a ``MacOutput``: the transmissions (station, start [us], duration [us], resource), the outcome
of every reported (transmission, receiver) link (``OUTCOME_NAMES`` of the channel: ok, below_sensitivity,
shadowed, collided = half duplex, damaged = interference) and the busy time each station sensed in the
window (channel busy ratio = busy_us / dt_us).

Within a window, each MAC decides in the order of its own microsecond / subframe times: what a station
senses earlier in the window shapes what it does later in it (no lockstep artefacts).

Reception is the shared receiver's (``cosim.vanet.receiver``, ``MacInput.receiver``: the run's
``channel.receiver``): its noise floor, sensitivity, carrier-sense threshold, interference floor and SINR
capture (``receiver.capture``: threshold or PER curve) decide every MAC's frames, so SOTDMA, 802.11p and
C-V2X are compared on one channel and one receiver; each MAC only says which transmissions interfere with
which (time overlap, same slot, same subchannels) and how much noise its band holds. IEEE 802.11p uses the
receiver's capture threshold as it is (6 dB: the same 6-Mb/s OFDM PHY as SOTDMA). C-V2X's MCS differs: its
threshold follows the PHY abstraction of Wu, Bartoletti, Martinez, Bazzi, "A Methodology for Abstracting
the Physical Layer of Direct V2X Communications Technologies", Sensors 22(23):9330, 2022 (the one
WiLabV2Xsim uses): the minimum SINR is the Shannon SINR of the frame's effective spectral efficiency
divided by an implementation loss of 0.37 (their value for both 802.11p and LTE-V2X):
``sinr_min = 2^(eta / 0.37) - 1``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from cosim.vanet.channel import BELOW_SENSITIVITY, COLLIDED, DAMAGED, OK, OUTCOME_NAMES, SHADOWED
from cosim.vanet.receiver import ReceiverParams

__all__ = [
    "BELOW_SENSITIVITY",
    "COLLIDED",
    "DAMAGED",
    "HALF_DUPLEX",
    "INTERFERENCE",
    "IMPLEMENTATION_LOSS",
    "LinkPowers",
    "Mac",
    "MacInput",
    "MacOutput",
    "OK",
    "OUTCOME_NAMES",
    "SHADOWED",
    "aether_link_budget",
    "distance_link_budget",
    "receiver_of",
    "shannon_sinr_threshold_db",
]

HALF_DUPLEX = COLLIDED  # the receiver was itself transmitting during the frame
INTERFERENCE = DAMAGED  # SINR below the threshold (or a missed preamble: 802.11p receiver already locked)

# Wu et al., Sensors 22(23):9330 (2022), Sec. 4: implementation loss of both 802.11p and LTE-V2X
IMPLEMENTATION_LOSS = 0.37


def shannon_sinr_threshold_db(bits: float, duration_s: float, bandwidth_hz: float) -> float:
    """Minimum SINR [dB] of a frame of ``bits`` occupying ``bandwidth_hz`` for ``duration_s`` (Wu et al.)."""
    eta = bits / duration_s / bandwidth_hz  # effective spectral efficiency [bit/s/Hz]
    return 10.0 * math.log10(2.0 ** (eta / IMPLEMENTATION_LOSS) - 1.0)


@dataclass
class LinkPowers:
    """Link budget of T transmitters at M receivers."""

    power_dbm: np.ndarray  # (T, M) float32 received power after shadowing [dBm]; -inf: none
    in_range: np.ndarray  # (T, M) bool within the communication range by path loss alone (reported links)
    # (T, M) bool at or above the sensitivity before building shadowing (None: in_range stands for it):
    # tells a ``below_sensitivity`` loss from a ``shadowed`` one
    above: np.ndarray | None = None


LinkBudget = Callable[..., LinkPowers]  # (tx_xy, rx_xy, tx_rows=None) -> LinkPowers


@dataclass
class MacInput:
    """What a MAC sees of one base step; per-station arrays have shape (N,) over the active stations."""

    t0_us: int  # window start [us]
    dt_us: int  # window length [us]
    stations: np.ndarray  # (N,) int64 station keys (World slots), ascending, unique
    xy: np.ndarray  # (N, 2) float64 antenna positions [m]
    pending: np.ndarray  # (N,) bool a CAM waits to be sent
    size_bytes: np.ndarray  # (N,) int CAM size [B] (facilities layer; lower-layer headers are the MAC's)
    gen_us: np.ndarray  # (N,) int64 CAM generation time [us]
    link: LinkBudget
    sensitivity_dbm: float = -89.0  # receiver sensitivity [dBm] when ``receiver`` is None (unit tests)
    noise_dbm: float = -110.0  # noise floor over the 10-MHz channel [dBm] when ``receiver`` is None
    # the shared receiver (channel.receiver: noise floor, sensitivity, CS, capture); None: a default
    # ReceiverParams with the two values above
    receiver: ReceiverParams | None = None


def receiver_of(inp: MacInput) -> ReceiverParams:
    """The receiver that decides a window's frames (``inp.receiver``, else one from its two plain values)."""
    if inp.receiver is not None:
        return inp.receiver
    return ReceiverParams(noise_dbm=inp.noise_dbm, sensitivity_dbm=inp.sensitivity_dbm)


@dataclass
class MacOutput:
    """What a MAC did in one base step. Transmissions are sorted by start time, then station."""

    tx_station: np.ndarray  # (T,) int64 index into MacInput.stations
    tx_start_us: np.ndarray  # (T,) int64 start of the frame [us]
    tx_duration_us: np.ndarray  # (T,) int32 air time [us]
    tx_resource: (
        np.ndarray
    )  # (T,) int64 MAC resource (SOTDMA: global slot; 802.11p: -1; C-V2X: sf * C + subch)
    rx_tx: np.ndarray  # (L,) int64 index into the transmissions, reported links sorted by (tx, rx)
    rx_rx: np.ndarray  # (L,) int64 index into MacInput.stations
    rx_power_dbm: np.ndarray  # (L,) float32 received power [dBm]
    rx_outcome: np.ndarray  # (L,) uint8 channel OUTCOME_NAMES code
    busy_us: np.ndarray  # (N,) float64 time the station sensed the medium busy in the window [us]
    sent: np.ndarray  # (N,) bool the station's pending CAM went on the air in this window
    stats: dict[str, float] = field(default_factory=dict)
    # (N,) bool the MAC took the pending CAM over, to send it in a later window (C-V2X: its reserved subframe
    # lies beyond the window); the caller keeps a copy of the CAM and clears its pending flag. None: none.
    taken: np.ndarray | None = None
    # (T,) bool the transmission carries a CAM taken over in an earlier window (not the pending one). None: none.
    tx_held: np.ndarray | None = None
    # (T,) int adjacent resources each transmission occupies (C-V2X: subchannels from tx_resource on). None: 1
    tx_width: np.ndarray | None = None

    def decoded(self) -> tuple[np.ndarray, np.ndarray]:
        """(transmission index, receiver index) of every decoded frame."""
        ok = self.rx_outcome == OK
        return self.rx_tx[ok], self.rx_rx[ok]

    def outcome_counts(self) -> dict[str, int]:
        c = np.bincount(self.rx_outcome.astype(np.int64), minlength=len(OUTCOME_NAMES))
        return {n: int(v) for n, v in zip(OUTCOME_NAMES, c, strict=False)}


class StationArrays:
    """Per-station state of a MAC: the numpy arrays named in ``_STATE`` (name -> (dtype, fresh value)),
    indexed by station key, grown on demand and reset when a station starts or stops. A subclass keeps its
    reactive DCC in ``self.dcc``, which grows and starts with it."""

    _STATE: dict[str, tuple[type, object]] = {}
    capacity: int = 0

    def ensure_capacity(self, capacity: int) -> None:
        if capacity <= self.capacity:
            return
        old = self.capacity
        for name, (dt, fill) in self._STATE.items():
            arr = np.full(capacity, fill, dtype=dt)
            if old:
                arr[:old] = getattr(self, name)
            setattr(self, name, arr)
        self.dcc.ensure_capacity(capacity)
        self.capacity = capacity

    def _fresh(self, stations: np.ndarray) -> np.ndarray:
        """Make room for ``stations`` and reset their state; returns them as int64 (empty: nothing to do)."""
        stations = np.asarray(stations, dtype=np.int64)
        if stations.size:
            self.ensure_capacity(int(stations.max()) + 1)
            for name, (_, fill) in self._STATE.items():
                getattr(self, name)[stations] = fill
        return stations

    def stop(self, stations: np.ndarray) -> None:
        self._fresh(stations)


class Mac(Protocol):
    """Per-station state is kept in arrays indexed by station key (World slot)."""

    name: str

    def ensure_capacity(self, capacity: int) -> None: ...

    def start(self, stations: np.ndarray, t_us: int) -> None:
        """New stations (fresh state: a new vehicle in the slot)."""

    def stop(self, stations: np.ndarray) -> None:
        """Stations that left."""

    def step(self, inp: MacInput) -> MacOutput: ...


def empty_output(n: int) -> MacOutput:
    e = np.zeros(0, dtype=np.int64)
    return MacOutput(
        e,
        e.copy(),
        np.zeros(0, np.int32),
        e.copy(),
        e.copy(),
        e.copy(),
        np.zeros(0, np.float32),
        np.zeros(0, np.uint8),
        np.zeros(n),
        np.zeros(n, dtype=bool),
    )


# ------------------------------------------------------------------------------------------------------------
# link budgets
# ------------------------------------------------------------------------------------------------------------
def _pairwise_d2(tx_xy: np.ndarray, rx_xy: np.ndarray) -> np.ndarray:
    tx = np.asarray(tx_xy, dtype=np.float64)
    rx = np.asarray(rx_xy, dtype=np.float64)
    dx = rx[None, :, 0] - tx[:, None, 0]
    dy = rx[None, :, 1] - tx[:, None, 1]
    return dx * dx + dy * dy


def distance_link_budget(
    power_of_distance: Callable[[np.ndarray], np.ndarray], comm_range_m: float
) -> LinkBudget:
    """A link budget from a function of the distance [m] -> received power [dBm] (tests, synthetic layouts).
    A transmitter never reaches itself (distance 0 pairs are -inf)."""

    def link(tx_xy: np.ndarray, rx_xy: np.ndarray, tx_rows: np.ndarray | None = None) -> LinkPowers:
        d = np.sqrt(_pairwise_d2(tx_xy, rx_xy))
        p = np.asarray(power_of_distance(np.maximum(d, 1e-3)), dtype=np.float32)
        p = np.where(d > 1e-6, p, np.float32(-np.inf)).astype(np.float32)
        return LinkPowers(p, (d <= comm_range_m) & (d > 1e-6))

    return link


def aether_link_budget(aether, floor_dbm: float | None = None) -> LinkBudget:
    """The link budget of the shared ``channel.Aether``, computed as its own ``_block`` does: path loss, the
    log-normal shadowing field (S = (X(tx) + X(rx)) / sqrt(2)), building shadowing (``los``: blocked ->
    -inf, or the model's NLOS formula and NLOS sigma for ``winner_b1`` / ``3gpp_urban``; ``veins``: dB per
    wall and metre). Pairs whose power before building shadowing is below ``floor_dbm`` (None: the aether's
    floor, the receiver's interference floor noise - 20 dB) are -inf: they neither decode nor interfere.
    ``in_range`` = within the aether's communication range (its reported links); ``above`` = at or above
    the sensitivity before building shadowing (else a loss is ``below_sensitivity``, not ``shadowed``)."""
    from cosim.vanet.pathloss import nlos_shadowing_sigma_db

    p = aether.p
    tx_dbm = np.float32(p.tx_power_dbm)
    comm2 = np.float32(aether.comm_range_m**2)
    floor = np.float32(aether.floor_dbm if floor_dbm is None else floor_dbm)
    field = aether.field
    nlos = bool(getattr(aether, "_nlos", False))
    nlos_extra_sigma = nlos_shadowing_sigma_db(p.path_loss) / 3.0 - 1.0
    shadow = aether.shadow
    has_buildings = type(shadow).__name__ != "NoShadowing"
    sens = np.float32(p.sensitivity_dbm)

    def link(tx_xy: np.ndarray, rx_xy: np.ndarray, tx_rows: np.ndarray | None = None) -> LinkPowers:
        """tx_rows (optional): the receiver row of each transmitter (tx_xy = rx_xy[tx_rows]), which spares
        evaluating the shadowing field at the transmitters again."""
        tx_xy = np.asarray(tx_xy, dtype=np.float64)
        rx_xy = np.asarray(rx_xy, dtype=np.float64)
        # float32 like the aether's blocks: ~1 mm at 10 km, half the memory traffic
        tx32, rx32 = tx_xy.astype(np.float32), rx_xy.astype(np.float32)
        d2 = np.subtract(rx32[None, :, 0], tx32[:, 0:1])
        d2 *= d2
        dy = np.subtract(rx32[None, :, 1], tx32[:, 1:2])
        d2 += dy * dy
        p0 = tx_dbm - aether.path_loss.loss_db_from_d2(d2)
        s_db = None
        if field is not None:
            x_rx = field.at(rx_xy)
            x_tx = x_rx[tx_rows] if tx_rows is not None else field.at(tx_xy)
            s_db = field.link_db(x_tx[:, None], x_rx[None, :]).astype(np.float32)
            p0 = p0 + s_db
        self_pair = d2 < np.float32(1e-6)
        cand = (p0 >= floor) & ~self_pair
        power = np.where(cand, p0, np.float32(-np.inf)).astype(np.float32)
        if has_buildings and cand.any():
            rx_x = rx_xy[:, 0].astype(np.float32)
            rx_y = rx_xy[:, 1].astype(np.float32)
            if not nlos and hasattr(shadow, "blocked_pairs") and getattr(shadow, "model", None) == "los":
                blocked = shadow.blocked_pairs(tx_xy, cand, rx_x, rx_y)
                power[blocked] = -np.inf
            else:
                flat = np.flatnonzero(cand)
                ti = flat // d2.shape[1]
                ri = flat - ti * d2.shape[1]
                loss = np.asarray(shadow.loss_db(tx_xy, ti, rx_x[ri], rx_y[ri]), dtype=np.float64)
                if nlos:  # blocked line of sight: the model's NLOS formula (and NLOS sigma) instead
                    nl = np.isinf(loss)
                    if nl.any():
                        d = np.sqrt(d2.reshape(-1)[flat[nl]].astype(np.float64))
                        extra = aether.path_loss.nlos_db(d) - aether.path_loss.loss_db(d)
                        if s_db is not None:
                            extra -= s_db.reshape(-1)[flat[nl]] * nlos_extra_sigma
                        loss[nl] = extra
                power.reshape(-1)[flat] = (p0.reshape(-1)[flat] - loss).astype(np.float32)
        in_range = (d2 <= comm2) & ~self_pair
        if p.path_loss == "two_ray":  # not monotone: the range test is the power test
            in_range = (p0 >= sens) & ~self_pair
        return LinkPowers(power, in_range, (p0 >= sens) & ~self_pair)

    return link


# ------------------------------------------------------------------------------------------------------------
# shared helpers
# ------------------------------------------------------------------------------------------------------------
def dbm_to_mw(x: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore"):
        return np.power(10.0, np.asarray(x, dtype=np.float64) / 10.0)


def loss_labels(lp: LinkPowers, ti: np.ndarray, ri: np.ndarray) -> np.ndarray:
    """Outcome of links (row ti of the link budget, receiver ri) whose power is below the sensitivity: SHADOWED when the path loss (and
    log-normal shadowing) alone would have reached it, BELOW_SENSITIVITY otherwise."""
    ref = lp.above if lp.above is not None else lp.in_range
    return np.where(ref[ti, ri], SHADOWED, BELOW_SENSITIVITY).astype(np.uint8)

"""The receiver: noise floor, sensitivity, carrier sense and SINR capture, shared by every MAC.

Any MAC (SOTDMA here; IEEE 802.11p or C-V2X mode 4 beside it) describes one window of transmissions as
received powers (T transmissions x M receivers, from ``pathloss`` and the aether's shadowing) plus which
transmissions overlap in time, and asks ``receive`` which receiver decodes which transmission.

Defaults (``ReceiverParams``), each with its source:

* bandwidth 10 MHz: the ITS-G5 / IEEE 802.11p control channel (ETSI EN 302 663 V1.3.1 §4.2; IEEE 802.11-2016
  §17, 10 MHz channel spacing); LTE-V2X sidelink is also evaluated on 10 MHz (3GPP TR 37.885 Table 6.1.1-1).
* noise figure 9 dB: the vehicle UE receiver of 3GPP TR 36.885 Table A.1.2-1 / TR 37.885 §6.1 evaluation
  assumptions. Noise floor = thermal -174 dBm/Hz (kT at 290 K) + 10 log10(B) + NF = -95.0 dBm.
* sensitivity -89 dBm: the link budget the project validated against its references (issue 5: 510 m free
  space at 13 dBm); IEEE 802.11-2016 Table 17-18 only requires -82 dBm for QPSK 1/2 at 10 MHz, chipsets do
  better. A frame weaker than this is not detected at all.
* carrier sense / energy threshold -85 dBm: IEEE 802.11-2016 §17.3.10.6 (CCA busy for a valid OFDM
  frame at or above the minimum sensitivity of the lowest rate: -85 dBm for 3 Mb/s at 10 MHz, Table 17-18);
  the same level ETSI TS 102 687 (DCC) uses for the channel busy ratio of ITS-G5 stations.
* capture threshold 6 dB: SINR needed to decode QPSK 1/2 (6 Mb/s at 10 MHz, the ITS-G5 default rate): the
  SNR a frame at the -89 dBm sensitivity has over the -95 dBm noise floor, so that the sensitivity and the
  SINR tests agree without interference; common simulators use 4-10 dB for this MCS (ns-3's
  ThresholdPreambleDetectionModel 4 dB; Killat & Hartenstein, EURASIP JWCN 2009, Table 1: 4 dB preamble,
  10 dB frame body capture). ``per_curve`` replaces the threshold by a PER curve of the MCS in use.
* interference floor: noise - 20 dB (-115 dBm): one such interferer raises noise + interference by 1 %
  (0.04 dB); SOTDMA puts at most a few senders in one slot, so what is left out stays below 0.2 dB.
  Every concurrent sender above the floor is summed.
* rule ``paper`` (the paper's §VI.E): no SINR; a receiver reached (above the sensitivity) by two or more
  concurrent senders loses all of them.

A receiver that transmits during a transmission cannot receive it (half duplex) and does not sense it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

THERMAL_NOISE_DBM_PER_HZ = -174.0  # kT at T0 = 290 K [dBm/Hz]


def noise_floor_dbm(bandwidth_hz: float, noise_figure_db: float) -> float:
    """Thermal noise over the bandwidth plus the receiver's noise figure [dBm]."""
    return THERMAL_NOISE_DBM_PER_HZ + 10.0 * math.log10(bandwidth_hz) + noise_figure_db


@dataclass(frozen=True)
class ReceiverParams:
    """What a receiver can detect, sense and decode (see the module docstring for each default)."""

    rule: Literal["sinr", "paper"] = "sinr"
    bandwidth_hz: float = 10e6  # [Hz]
    noise_figure_db: float = 9.0  # [dB]
    noise_dbm: float | None = None  # noise floor override [dBm]; None: thermal + noise figure
    sensitivity_dbm: float = -89.0  # weakest detectable frame [dBm]
    cs_threshold_dbm: float = -85.0  # carrier sense / energy detection: channel busy at or above [dBm]
    capture_threshold_db: float = 6.0  # minimum SINR to decode [dB]
    per_curve: tuple[tuple[float, float], ...] | None = None  # ((SINR dB, PER), ...) ascending SINR
    interference_floor_dbm: float | None = None  # weaker senders are not summed [dBm]; None: noise - 20 dB

    def __post_init__(self) -> None:
        if not self.bandwidth_hz > 0 or self.noise_figure_db < 0:
            raise ValueError("receiver: bandwidth_hz must be > 0 and noise_figure_db >= 0")
        if self.capture_threshold_db < 0:
            raise ValueError("receiver: capture_threshold_db must be >= 0 (one decoded message at a time)")
        if self.per_curve is not None:
            s = [p[0] for p in self.per_curve]
            per = [p[1] for p in self.per_curve]
            if (
                len(s) < 2
                or any(b <= a for a, b in zip(s[:-1], s[1:], strict=True))
                or any(not 0 <= p <= 1 for p in per)
            ):
                raise ValueError(
                    "receiver.per_curve: >= 2 (SINR dB, PER) points, SINR ascending, PER in [0, 1]"
                )

    @property
    def noise_floor_dbm(self) -> float:
        if self.noise_dbm is not None:
            return float(self.noise_dbm)
        return noise_floor_dbm(self.bandwidth_hz, self.noise_figure_db)

    @property
    def floor_dbm(self) -> float:
        """Interference floor [dBm]."""
        return (
            self.interference_floor_dbm
            if self.interference_floor_dbm is not None
            else self.noise_floor_dbm - 20.0
        )


@dataclass
class Reception:
    """``receive``'s answer; every array is (T, M)."""

    power_dbm: np.ndarray  # float64 received power [dBm] (-inf: nothing arrives)
    sinr_db: np.ndarray  # float64 S / (N + I) [dB] (-inf where the power is -inf)
    decoded: np.ndarray  # bool
    sensed: np.ndarray  # bool: the receiver senses the channel busy (total energy >= CS threshold) during it


def interference_mw(mw: np.ndarray, concurrent) -> np.ndarray:
    """Power of the other concurrent senders at each receiver [mW] (T, M).

    ``concurrent``: (T,) int group ids (equal = fully overlapping, e.g. one SOTDMA slot or one C-V2X
    subchannel-subframe) or a (T, T) bool matrix (True: the two transmissions overlap in time; the diagonal
    is ignored), e.g. for 802.11p frames that overlap partly.
    """
    c = np.asarray(concurrent)
    if c.ndim == 2:
        o = c.astype(np.float64)
        np.fill_diagonal(o, 0.0)
        return o @ mw
    _, inv = np.unique(c, return_inverse=True)
    inv = inv.reshape(-1)
    total = np.zeros((inv.max() + 1 if inv.size else 0, mw.shape[1]))
    np.add.at(total, inv, mw)
    return np.maximum(total[inv] - mw, 0.0)


def capture(signal_mw, interference_mw_, params: ReceiverParams, rng: np.random.Generator | None = None):
    """(SINR [dB], decoded by the SINR test) for signals and the interference they meet (same shapes).

    With ``params.per_curve`` a frame is decoded with probability 1 - PER(SINR) (linear in SINR between the
    points, the end values outside); that needs ``rng``.
    """
    noise = 10.0 ** (params.noise_floor_dbm / 10.0)
    with np.errstate(divide="ignore"):
        sinr_db = 10.0 * np.log10(signal_mw / (interference_mw_ + noise))
    if params.per_curve is None:
        return sinr_db, sinr_db >= params.capture_threshold_db
    if rng is None:
        raise ValueError("receiver: a PER curve needs a random generator")
    xs, per = zip(*params.per_curve, strict=True)
    p_fail = np.interp(np.where(np.isfinite(sinr_db), sinr_db, -1e9), xs, per)
    return sinr_db, rng.random(np.shape(sinr_db)) >= p_fail


def receive(
    power_dbm: np.ndarray,
    concurrent,
    params: ReceiverParams,
    tx_receiver: np.ndarray | None = None,
    rng: np.random.Generator | None = None,
) -> Reception:
    """Who decodes what, for one window of transmissions.

    power_dbm (T, M): received power of transmission t at receiver m [dBm] (path loss, shadowing, antenna
    gains already applied; -inf for none); concurrent: see ``interference_mw``; tx_receiver (T,): the
    receiver column of each transmission's sender (-1: not among the receivers); it never receives itself
    and cannot receive or sense while it transmits (half duplex).
    """
    p = np.asarray(power_dbm, dtype=np.float64)
    n_tx, n_rx = p.shape
    busy_tx = np.zeros((n_tx, n_rx), dtype=bool)  # receiver m transmits during transmission t
    if tx_receiver is not None:
        col = np.asarray(tx_receiver)
        own = np.flatnonzero(col >= 0)
        sending = np.zeros((n_tx, n_rx))
        sending[own, col[own]] = 1.0
        c = np.asarray(concurrent)
        if c.ndim == 2:
            ov = c.astype(np.float64)
            np.fill_diagonal(ov, 1.0)
        else:
            ov = (c[:, None] == c[None, :]).astype(np.float64)
        busy_tx = (ov @ sending) > 0
    mw = np.where(np.isfinite(p), 10.0 ** (np.where(np.isfinite(p), p, -300.0) / 10.0), 0.0)
    audible = np.where(p >= params.floor_dbm, mw, 0.0)
    interf = interference_mw(audible, concurrent)
    detected = (p >= params.sensitivity_dbm) & ~busy_tx
    if params.rule == "paper":
        above = (p >= params.sensitivity_dbm).astype(np.int64)
        others = interference_mw(above.astype(np.float64), concurrent)
        noise = 10.0 ** (params.noise_floor_dbm / 10.0)
        with np.errstate(divide="ignore"):
            sinr_db = 10.0 * np.log10(mw / (interf + noise))
        decoded = detected & (others < 0.5)
    else:
        sinr_db, ok = capture(mw, interf, params, rng)
        decoded = detected & ok
    energy = interf + mw  # everything concurrent with t, t included, at each receiver
    sensed = (10.0 * np.log10(np.maximum(energy, 1e-300)) >= params.cs_threshold_dbm) & ~busy_tx
    return Reception(p, sinr_db, decoded, sensed)

"""Per-link results of one window of the aether (``cosim.vanet.channel.Aether.links``) and the outcome codes.

Outcomes (``OUTCOME_NAMES``, the ``/vanet/rx`` outcome column): ok; below_sensitivity (path loss alone puts it
under the sensitivity); shadowed (buildings do); collided (the receiver was itself transmitting in that slot:
half duplex); damaged (same-slot interference).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from cosim.vanet.channel import Aether

OK, BELOW_SENSITIVITY, SHADOWED, COLLIDED, DAMAGED = 0, 1, 2, 3, 4
OUTCOME_NAMES = ("ok", "below_sensitivity", "shadowed", "collided", "damaged")


@dataclass
class LinkBatch:
    """Per-link results of one window, for links within the communication range (arrays of shape (L,))."""

    tx: np.ndarray  # int32 index into the transmissions
    rx: np.ndarray  # int32 index into the receivers
    distance_m: np.ndarray  # float32 antenna distance [m]
    power_dbm: np.ndarray  # float32 received power after shadowing [dBm] (-inf: line of sight blocked)
    outcome: np.ndarray  # uint8 OK / BELOW_SENSITIVITY / SHADOWED / COLLIDED / DAMAGED
    n_evaluated: int = 0  # links evaluated, including interference-only ones


@dataclass
class _Block:
    """Dense (transmission x receiver) matrices of one block of a window; every mask is (T, M) bool."""

    t: np.ndarray | None  # transmissions of the block (rows), None = all
    m: np.ndarray | None  # receivers of the block (columns, ascending), None = all
    d2: np.ndarray  # float32 squared distance [m^2]
    logged: np.ndarray  # reported: within the communication range, not the transmitter itself
    above: np.ndarray  # path loss alone leaves the power at or above the sensitivity
    reach: np.ndarray  # power after shadowing at or above the sensitivity
    collided: np.ndarray  # the receiver transmits in the same slot
    damaged: np.ndarray | None  # same-slot interference (None: no slot has two transmissions)
    ok: np.ndarray  # decoded
    p0: np.ndarray | None  # float32 power before shadowing [dBm], when computed for every pair
    loss: np.ndarray | None  # shadowing loss [dB] (None: ``blocked`` or no shadowing)
    blocked: np.ndarray | None  # line of sight blocked (line-of-sight fast path)
    sensed: np.ndarray | None = None  # (slots, M) bool: the receiver senses the slot busy (CS threshold)
    lg: np.ndarray | None = None  # (T,) the block-local slot of each row


class Links:
    """Outcomes of one window's transmissions, kept as dense blocks of (transmission x receiver) masks.

    Per-link arrays are made only for the links asked for: the decoded ones (slot maps, OBU tables), one
    receiver's (the log's default) or all reported ones (``batch``).
    """

    def __init__(self, aether: Aether, n_tx: int, n_rx: int, blocks: list[_Block], n_evaluated: int):
        self.aether = aether
        self.n_tx, self.n_rx = n_tx, n_rx
        self.blocks = blocks
        self.n_evaluated = n_evaluated

    @staticmethod
    def _global(b: _Block, tl: np.ndarray, ml: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (tl if b.t is None else b.t[tl]), (ml if b.m is None else b.m[ml])

    def decoded(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(transmission index, receiver index, distance [m] float32) of every decoded message."""
        ti, ri, d = [], [], []
        for b in self.blocks:
            flat = np.flatnonzero(b.ok)
            d.append(np.sqrt(b.d2.reshape(-1)[flat]))
            tl = flat // b.ok.shape[1]
            t, m = self._global(b, tl, flat - tl * b.ok.shape[1])
            ti.append(t)
            ri.append(m)
        if not self.blocks:
            e = np.zeros(0, dtype=np.intp)
            return e, e, np.zeros(0, dtype=np.float32)
        ti, ri, d = np.concatenate(ti), np.concatenate(ri), np.concatenate(d)
        if len(self.blocks) > 1:  # the same (tx, rx) order as a single block
            order = np.lexsort((ri, ti))
            ti, ri, d = ti[order], ri[order], d[order]
        return ti, ri, d

    def sensed_busy_us(self, air_us: np.ndarray) -> np.ndarray:
        """Per receiver (n_rx,), the time it senses the channel busy [us]: the longest air time of each slot
        whose energy reaches the carrier-sense threshold there (air_us (n_tx,) per transmission)."""
        busy = np.zeros(self.n_rx)
        air_us = np.asarray(air_us, dtype=np.float64)
        for b in self.blocks:
            rows = air_us if b.t is None else air_us[b.t]
            g_air = np.zeros(b.sensed.shape[0])
            np.maximum.at(g_air, b.lg, rows)
            val = g_air @ b.sensed
            if b.m is None:
                busy += val
            else:
                busy[b.m] = np.maximum(busy[b.m], val)  # a receiver lies in one block
        return busy

    def decoded_at(self, receivers: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``decoded()`` restricted to the sorted unique receiver indices ``receivers`` (a column gather)."""
        ti, ri, d = [], [], []
        for b in self.blocks:
            cols = np.asarray(receivers, dtype=np.intp) if b.m is None else np.intersect1d(b.m, receivers)
            pos = cols if b.m is None else np.searchsorted(b.m, cols)
            tl, cl = np.nonzero(b.ok[:, pos])
            ti.append(tl if b.t is None else b.t[tl])
            ri.append(cols[cl])
            d.append(np.sqrt(b.d2[tl, pos[cl]]))
        if not self.blocks:
            e = np.zeros(0, dtype=np.intp)
            return e, e, np.zeros(0, dtype=np.float32)
        return np.concatenate(ti), np.concatenate(ri), np.concatenate(d)

    def batch(self, receivers: np.ndarray | None = None) -> LinkBatch:
        """Every reported link (or those of the receiver indices ``receivers``), sorted by tx then rx."""
        parts = []
        for b in self.blocks:
            logged = b.logged
            cols = None
            if receivers is not None:
                want = np.asarray(receivers, dtype=np.intp)
                if want.size > 1:  # (np.unique costs more than the rest of a one-receiver batch)
                    want = np.unique(want)
                if b.m is None:
                    cols = want
                else:
                    pos = np.minimum(np.searchsorted(b.m, want), max(b.m.size - 1, 0))
                    cols = pos[(b.m.size > 0) & (b.m[pos] == want)] if b.m.size else pos[:0]
                logged = logged[:, cols]
            tl, cl = np.nonzero(logged)
            ml = cl if cols is None else cols[cl]
            parts.append((b, tl, ml))
        ti = [self._global(b, tl, ml)[0] for b, tl, ml in parts]
        ri = [self._global(b, tl, ml)[1] for b, tl, ml in parts]
        cols = [self._link_values(b, tl, ml) for b, tl, ml in parts]
        if not parts:
            e = np.zeros(0, dtype=np.int32)
            return LinkBatch(e, e, np.zeros(0, np.float32), np.zeros(0, np.float32), np.zeros(0, np.uint8))
        ti, ri = np.concatenate(ti), np.concatenate(ri)
        d, pw, outcome = (np.concatenate([c[k] for c in cols]) for k in range(3))
        if len(parts) > 1:
            order = np.lexsort((ri, ti))
            ti, ri, d, pw, outcome = ti[order], ri[order], d[order], pw[order], outcome[order]
        return LinkBatch(
            tx=ti.astype(np.int32),
            rx=ri.astype(np.int32),
            distance_m=d,
            power_dbm=pw,
            outcome=outcome,
            n_evaluated=self.n_evaluated,
        )

    def _link_values(self, b: _Block, tl: np.ndarray, ml: np.ndarray) -> tuple[np.ndarray, ...]:
        """(distance [m], power after shadowing [dBm], outcome) of the block's links (tl, ml)."""
        d2 = b.d2[tl, ml]
        if b.p0 is not None:
            p0 = b.p0[tl, ml]
        else:
            a = self.aether
            p0 = np.float32(a.p.tx_power_dbm) - a.path_loss.loss_db_from_d2(d2)
        if b.loss is not None:
            pw = (p0 - b.loss[tl, ml]).astype(np.float32)
        elif b.blocked is not None:
            pw = np.where(b.blocked[tl, ml], np.float32(-np.inf), p0)
        else:
            pw = p0
        reach = b.reach[tl, ml]
        damaged = b.damaged[tl, ml] if b.damaged is not None else np.zeros(tl.size, dtype=bool)
        outcome = np.where(damaged, DAMAGED, OK).astype(np.uint8)
        outcome[b.collided[tl, ml] & reach] = COLLIDED
        outcome[~reach] = SHADOWED
        outcome[~b.above[tl, ml]] = BELOW_SENSITIVITY
        return np.sqrt(d2), pw.astype(np.float32, copy=False), outcome

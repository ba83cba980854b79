"""The aether: who receives each transmission of a slot, and how well.

Which reading each default follows
----------------------------------
* Link budget: 5.89 GHz, 20 mW (13.0 dBm), sensitivity -89 dBm, noise -110 dBm (issue 5). Path loss is free
  space by default (Friis; 510.5 m range with these numbers). ``two_ray`` is the two-ray interference model of
  Sommer et al. (the one Veins ships: ground reflection with epsilon_r = 1.02, antennas at 1.5 m);
  ``log_distance`` is free space up to ``log_distance_ref_m`` and ``10 n log10(d / d0)`` beyond.
* Shadowing, ``los`` (the paper, §VI.E): a link is blocked when the straight 2-D line between the antennas
  touches any building footprint. The paper raised the sender 10 m so vehicles would not block; we keep
  only buildings, in 2-D, so that lift is moot. ``veins``: the Veins obstacle model, 9 dB per wall crossed
  plus 0.4 dB per metre inside a building (Sommer et al. 2011), both configurable. ``none``: range only.
* Same slot, ``paper``: a receiver reached (in range, not shadowed) by two or more transmitters of the same
  slot gets damaged messages from all of them ("overlapping interference area"). ``sinr``: a message is
  decoded when S / (N + sum of the other same-slot signals) >= ``capture_threshold_db`` (6 dB at 6 Mbit/s);
  interferers weaker than ``interference_floor_dbm`` (before shadowing) are ignored for speed.
* Outcomes (``OUTCOME_NAMES``): ok; below_sensitivity (path loss alone puts it under the sensitivity);
  shadowed (buildings do); collided (the receiver was itself transmitting in that slot: half duplex);
  damaged (same-slot interference). Only links within the communication range are reported.

Module layout: the building footprints and the shadowing methods (exact, polar) are in ``shadowing``; the
per-link results of a window (``Links``, ``LinkBatch``) and the outcome codes in ``links``; both are
re-exported here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import shapely

from cosim.vanet.links import (  # noqa: F401 (re-exported: the outcome codes and link results)
    BELOW_SENSITIVITY,
    COLLIDED,
    DAMAGED,
    OK,
    OUTCOME_NAMES,
    SHADOWED,
    LinkBatch,
    Links,
    _Block,
)
from cosim.vanet.mapstore import MapStore
from cosim.vanet.pathloss import (
    PATH_LOSS_MODELS,
    PathLoss,
    ShadowingField,
    default_shadowing,
    nlos_shadowing_sigma_db,
)
from cosim.vanet.receiver import ReceiverParams, capture
from cosim.vanet.shadowing import (  # noqa: F401 (re-exported)
    Buildings,
    ExactShadowing,
    NoShadowing,
    PolarShadowing,
    _Scratch,
    pseudo_angle,
    pseudo_angle_direction,
)

SPEED_OF_LIGHT_MPS = 299_792_458.0


def dbm_to_mw(dbm):
    return np.power(10.0, np.asarray(dbm, dtype=np.float64) / 10.0)


@dataclass(frozen=True)
class ChannelParams:
    """Radio link budget, path loss, shadowing and the receiver (``receiver``: cosim.vanet.receiver)."""

    frequency_hz: float = 5.89e9  # carrier [Hz] (ITS-G5 control channel, ETSI EN 302 663)
    tx_power_mw: float = 20.0  # transmit power [mW] (13 dBm)
    path_loss: Literal["free_space", "two_ray", "log_distance", "winner_b1", "3gpp_highway", "3gpp_urban"] = (
        "free_space"  # see cosim.vanet.pathloss
    )
    antenna_height_m: float = 1.5  # both antennas (two-ray, WINNER+ B1) [m]
    winner_height_offset_m: float = 1.0  # WINNER+ B1 effective height h - offset (D5.3); 0: h itself [m]
    winner_min_m: float = 10.0  # WINNER+ B1: shorter distances evaluated here (D5.3 validity: 10 m) [m]
    winner_free_space_floor: bool = False  # WINNER+ B1: never below free space (Gonzalez-Martin et al. 2019)
    ground_permittivity: float = 1.02  # relative permittivity epsilon_r of the ground, two-ray model
    log_distance_exponent: float = 2.5  # path-loss exponent n, log-distance model
    log_distance_ref_m: float = 1.0  # reference distance d0 [m]
    lognormal_sigma_db: float | None = None  # log-normal shadowing sigma [dB]; None: the model's (pathloss)
    lognormal_decorrelation_m: float | None = None  # its decorrelation distance [m]; None: the model's
    shadowing: Literal["none", "los", "veins"] = "los"  # buildings
    wall_db: float = 9.0  # Veins model: loss per wall crossed [dB]
    per_meter_db: float = 0.4  # Veins model: loss per metre inside a building [dB/m]
    shadow_method: Literal["polar", "exact"] = "polar"
    polar_lattice_m: float = 4.0  # transmitter lattice of the cached visibility maps [m]
    polar_bins: int = 1024  # directions per visibility map
    polar_cache_mb: float = 256.0  # flush the visibility cache above this size [MB]
    # the receiver (defaults and sources: cosim.vanet.receiver)
    interference: Literal["paper", "sinr"] = "sinr"  # same-slot rule: SINR capture, or the paper's overlap
    sensitivity_dbm: float = -89.0  # receiver sensitivity [dBm]
    bandwidth_hz: float = 10e6  # channel bandwidth [Hz]
    noise_figure_db: float = 9.0  # receiver noise figure [dB]
    noise_dbm: float | None = (
        None  # noise floor [dBm]; None: -174 dBm/Hz + 10 log10(bandwidth) + noise figure
    )
    cs_threshold_dbm: float = -85.0  # carrier sense / energy detection threshold (channel busy ratio) [dBm]
    capture_threshold_db: float = 6.0  # SINR rule: minimum SINR to decode [dB]
    interference_floor_dbm: float | None = (
        None  # SINR rule: weaker senders not summed [dBm]; None: noise - 20
    )

    def __post_init__(self) -> None:
        if not self.frequency_hz > 0 or not self.tx_power_mw > 0:
            raise ValueError("channel.frequency_hz and channel.tx_power_mw must be > 0")
        if self.path_loss not in PATH_LOSS_MODELS:
            raise ValueError(f"channel.path_loss must be one of {', '.join(PATH_LOSS_MODELS)}")
        if not self.antenna_height_m > 0 or not self.ground_permittivity >= 1.0:
            raise ValueError("channel: antenna_height_m must be > 0 and ground_permittivity >= 1")
        if self.path_loss == "winner_b1" and not self.antenna_height_m > self.winner_height_offset_m:
            raise ValueError("channel: WINNER+ B1 needs antenna_height_m > winner_height_offset_m")
        if self.winner_height_offset_m < 0 or not self.winner_min_m >= 1.0:
            raise ValueError("channel: winner_height_offset_m must be >= 0 and winner_min_m >= 1 m")
        if not self.log_distance_exponent > 0 or not self.log_distance_ref_m > 0:
            raise ValueError("channel: log_distance_exponent and log_distance_ref_m must be > 0")
        if self.lognormal_sigma_db is not None and not 0 <= self.lognormal_sigma_db <= 20:
            raise ValueError("channel.lognormal_sigma_db must be in [0, 20] dB (or null: the model's)")
        if self.lognormal_decorrelation_m is not None and not self.lognormal_decorrelation_m > 0:
            raise ValueError("channel.lognormal_decorrelation_m must be > 0 (or null: the model's)")
        if self.wall_db < 0 or self.per_meter_db < 0:
            raise ValueError("channel: wall_db and per_meter_db must be >= 0")
        if not self.polar_lattice_m > 0 or self.polar_bins < 8:
            raise ValueError("channel: polar_lattice_m must be > 0 and polar_bins >= 8")
        if not self.polar_cache_mb >= 16:
            raise ValueError("channel.polar_cache_mb must be >= 16")
        if self.capture_threshold_db < 0:
            raise ValueError("channel.capture_threshold_db must be >= 0 (one decoded message per slot)")
        if not self.bandwidth_hz > 0 or self.noise_figure_db < 0:
            raise ValueError("channel: bandwidth_hz must be > 0 and noise_figure_db >= 0")
        if self.tx_power_dbm <= self.sensitivity_dbm:
            raise ValueError("channel: tx power must exceed the sensitivity, or nothing is ever received")

    @property
    def receiver(self) -> ReceiverParams:
        return ReceiverParams(
            rule=self.interference,
            bandwidth_hz=self.bandwidth_hz,
            noise_figure_db=self.noise_figure_db,
            noise_dbm=self.noise_dbm,
            sensitivity_dbm=self.sensitivity_dbm,
            cs_threshold_dbm=self.cs_threshold_dbm,
            capture_threshold_db=self.capture_threshold_db,
            interference_floor_dbm=self.interference_floor_dbm,
        )

    @property
    def shadowing_sigma_db(self) -> float:
        """Log-normal shadowing sigma in use [dB] (LOS)."""
        return (
            default_shadowing(self.path_loss)[0]
            if self.lognormal_sigma_db is None
            else self.lognormal_sigma_db
        )

    @property
    def shadowing_decorrelation_m(self) -> float:
        d = self.lognormal_decorrelation_m
        return default_shadowing(self.path_loss)[1] if d is None else d

    @property
    def tx_power_dbm(self) -> float:
        return 10.0 * math.log10(self.tx_power_mw)

    @property
    def wavelength_m(self) -> float:
        return SPEED_OF_LIGHT_MPS / self.frequency_hz


# ------------------------------------------------------------------------------------------------------------
# the aether
# ------------------------------------------------------------------------------------------------------------
def _slot_sums(rows: np.ndarray, starts: np.ndarray, dtype) -> np.ndarray:
    """Sums of consecutive row runs (run i starts at row starts[i]) in row order, like bincount's; far
    faster than np.add.reduceat along axis 0 when most runs are a single row."""
    total = rows[starts].astype(dtype)
    size = np.diff(starts, append=len(rows))
    for j in range(1, int(size.max())):
        runs = np.flatnonzero(size > j)
        total[runs] += rows[starts[runs] + j]
    return total


class Aether:
    """Decides, for every transmission of a window, each receiver's outcome.

    Links are evaluated as dense (transmission x receiver) matrices: on a city map most stations are in
    range of each other, and broadcasting beats per-link gathers. Above ``max_cells`` pairs the receivers
    are split into grid cells of the link range, each with only the transmitters that can reach it.
    """

    max_cells = 4_000_000

    # log-normal shadowing is cut at this many sigma when sizing the ranges (a 3e-5 tail is left out)
    SHADOWING_TAIL_SIGMA = 4.0

    def __init__(
        self,
        params: ChannelParams,
        buildings: Sequence[shapely.Polygon] | Buildings,
        rng: np.random.Generator | None = None,
        map_store: Path | None = None,
    ):
        """``rng`` draws the log-normal shadowing field (only when its sigma > 0; None: a fixed seed 0);
        ``map_store``: the directory of the visibility maps kept between runs (cosim.vanet.mapstore; None:
        none); ``close`` adds this run's maps to it."""
        self.p = params
        self.rx = params.receiver
        self.buildings = buildings if isinstance(buildings, Buildings) else Buildings(buildings)
        self.path_loss = PathLoss(params)
        sigma = params.shadowing_sigma_db
        self.field = None
        if sigma > 0:
            rng = rng if rng is not None else np.random.default_rng(0)
            self.field = ShadowingField.draw(sigma, params.shadowing_decorrelation_m, rng)
        margin = self.SHADOWING_TAIL_SIGMA * sigma * (nlos_shadowing_sigma_db(params.path_loss) / 3.0 or 1.0)
        budget = params.tx_power_dbm - params.sensitivity_dbm + margin
        self.comm_range_m = self.path_loss.max_range_m(budget)
        floor = params.sensitivity_dbm
        if params.interference == "sinr":
            floor = min(floor, self.rx.floor_dbm)
        self.floor_dbm = floor
        self.link_range_m = max(
            self.path_loss.max_range_m(params.tx_power_dbm - floor + margin), self.comm_range_m
        )
        # models with their own NLOS formula use it for links that buildings block (``los`` shadowing)
        self._nlos = self.path_loss.has_nlos and params.shadowing == "los"
        # carrier sense from one sender alone: the distance test of the line-of-sight fast path
        self._cs_d2 = self.path_loss.max_range_m(params.tx_power_dbm - params.cs_threshold_dbm) ** 2
        if params.shadowing == "none" or len(self.buildings) == 0:
            self.shadow = NoShadowing()
        elif params.shadow_method == "exact":
            self.shadow = ExactShadowing(
                self.buildings, params.shadowing, params.wall_db, params.per_meter_db
            )
        else:
            max_loss = params.tx_power_dbm - floor - float(self.path_loss.loss_db(1.0))
            # line of sight only needs the outline of the dissolved footprints: shared walls never block first
            geom = self.buildings
            if params.shadowing == "los":
                geom = Buildings(list(shapely.get_parts(shapely.union_all(self.buildings.polygons))))
            self.shadow = PolarShadowing(
                geom,
                params.shadowing,
                self.link_range_m,
                params.polar_lattice_m,
                params.polar_bins,
                params.polar_cache_mb,
                params.wall_db,
                params.per_meter_db,
                max_loss,
            )
        self.map_store = None
        if map_store is not None and isinstance(self.shadow, PolarShadowing):
            self.map_store = MapStore(map_store, self.shadow)
            self.map_store.load()
        # links beyond the communication range only matter as interference, and two-ray has nulls inside
        self._general = (
            self.link_range_m > self.comm_range_m
            or params.path_loss == "two_ray"
            or self.field is not None
            or self._nlos
        )
        # paper rule with a 0 / inf shadowing loss and a monotone path loss: the power is needed only for
        # the links logged, and "above the sensitivity" is a distance test (see _above_sensitivity)
        self._fast = (
            not self._general
            and params.interference == "paper"
            and (isinstance(self.shadow, NoShadowing) or params.shadowing == "los")
            and self.comm_range_m > 2.0
        )
        # squared distances clearly inside / outside the range; the power is computed between them
        self._d2_band = (self.comm_range_m**2 * (1.0 - 1e-3), self.comm_range_m**2 * (1.0 + 1e-3))
        self._d2_threshold = None  # exact float32 threshold, found on first use (False: use the band)
        self._scratch = _Scratch()

    def close(self) -> None:
        """The end of the run: its visibility maps join the store (``map_store``)."""
        if self.map_store is not None:
            self.map_store.save()

    def evaluate(
        self,
        tx_xy: np.ndarray,
        tx_station: np.ndarray,
        tx_group: np.ndarray,
        rx_xy: np.ndarray,
        rx_station: np.ndarray,
    ) -> LinkBatch:
        """Outcomes of one window's transmissions, every reported link (see ``links``)."""
        return self.links(tx_xy, tx_station, tx_group, rx_xy, rx_station).batch()

    def links(
        self,
        tx_xy: np.ndarray,
        tx_station: np.ndarray,
        tx_group: np.ndarray,
        rx_xy: np.ndarray,
        rx_station: np.ndarray,
    ) -> Links:
        """Outcomes of one window's transmissions.

        tx_xy (T,2) [m], tx_station (T,) station ids, tx_group (T,) int: same value = same slot;
        rx_xy (M,2) [m], rx_station (M,) sorted unique station ids of all potential receivers (transmitters
        must be among them). A transmitter never receives itself; a receiver transmitting in the same group
        is half-duplex ("collided").
        """
        n_tx, n_rx = len(tx_xy), len(rx_xy)
        tx_rx = np.searchsorted(rx_station, tx_station)  # receiver index of each transmitter
        if n_tx and (np.any(tx_rx >= n_rx) or np.any(rx_station[np.minimum(tx_rx, n_rx - 1)] != tx_station)):
            raise ValueError("aether: every transmitting station must be among the receivers")
        if n_tx == 0 or n_rx == 0:
            return Links(self, n_tx, n_rx, [], 0)
        tx_xy = np.asarray(tx_xy, dtype=np.float64)
        # per-link arithmetic in float32: positions to ~1 mm up to 10 km from the origin, and 3-4x faster
        rx_x, rx_y = rx_xy[:, 0].astype(np.float32), rx_xy[:, 1].astype(np.float32)
        tx_group = np.asarray(tx_group)
        if np.all(tx_group[1:] >= tx_group[:-1]):  # the usual case (slots in order): no sort needed
            gi = np.zeros(n_tx, dtype=np.intp)
            np.cumsum(tx_group[1:] != tx_group[:-1], out=gi[1:])
        else:
            gi = np.unique(tx_group, return_inverse=True)[1].reshape(-1)
        blocks, n_eval = [], 0
        for t, m in self._plan(tx_xy, rx_xy, n_tx, n_rx):
            if t is not None and t.size == 0:
                continue
            if m is None:
                col = tx_rx if t is None else tx_rx[t]
            else:
                pos = np.minimum(np.searchsorted(m, tx_rx[t]), m.size - 1)
                col = np.where(m[pos] == tx_rx[t], pos, -1)
            sel = slice(None) if t is None else t
            cols = slice(None) if m is None else m
            b, n = self._block(tx_xy[sel], gi[sel], col, rx_x[cols], rx_y[cols])
            b.t, b.m = t, m
            blocks.append(b)
            n_eval += n
        return Links(self, n_tx, n_rx, blocks, n_eval)

    def _plan(self, tx_xy: np.ndarray, rx_xy: np.ndarray, n_tx: int, n_rx: int):
        """Blocks (transmissions, receivers) to evaluate densely; None = all."""
        if n_tx * n_rx <= self.max_cells:
            yield None, None
            return
        cell = max(self.link_range_m, 1.0)
        key_xy = np.floor(np.asarray(rx_xy, dtype=np.float64) / cell).astype(np.int64)
        _, inv = np.unique(key_xy, axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        order = np.argsort(inv, kind="stable")
        bounds = np.flatnonzero(np.r_[True, inv[order][1:] != inv[order][:-1], True])
        margin = self.link_range_m + 1.0  # float32 rounding of the exact test is far below 1 m
        for a, z in zip(bounds[:-1], bounds[1:], strict=True):
            m = np.sort(order[a:z])
            lo, hi = rx_xy[m].min(axis=0), rx_xy[m].max(axis=0)
            gap = np.maximum(np.maximum(lo - tx_xy, tx_xy - hi), 0.0)
            yield np.flatnonzero(np.hypot(gap[:, 0], gap[:, 1]) <= margin), m

    def _above_sensitivity(self, d2: np.ndarray, cand: np.ndarray) -> np.ndarray:
        """p0 >= sensitivity for candidate pairs, from the squared distance alone (the path loss is
        monotone): one comparison with the exact float32 threshold when the float32 power is monotone around
        it, else the power computed where the squared distance is within 0.1 % of the range's."""
        if self._d2_threshold is None:
            self._d2_threshold = self._exact_d2_threshold()
        if self._d2_threshold is not False:
            return d2 <= self._d2_threshold
        lo, hi = self._d2_band
        above = d2 <= np.float32(lo)
        band = np.flatnonzero(cand & ~above & (d2 <= np.float32(hi)))
        if band.size:
            above.reshape(-1)[band] = self._p0(d2.reshape(-1)[band]) >= self.p.sensitivity_dbm
        return above

    def _p0(self, d2: np.ndarray) -> np.ndarray:
        """Power before shadowing [dBm] (float32) from squared distances."""
        return np.float32(self.p.tx_power_dbm) - self.path_loss.loss_db_from_d2(d2)

    def _exact_d2_threshold(self):
        """The largest float32 squared distance whose float32 power reaches the sensitivity, checked on
        every float32 value of the 0.1 % band around the range (False: not monotone there)."""
        lo, hi = (np.float32(v) for v in self._d2_band)
        bits = np.arange(lo.view(np.int32), hi.view(np.int32) + 1, dtype=np.int32)
        d2 = bits.view(np.float32)  # every float32 in [lo, hi], ascending
        above = self._p0(d2) >= self.p.sensitivity_dbm
        k = int(np.count_nonzero(above))
        if not above[:k].all() or k == 0 or k == d2.size:
            return False
        return d2[k - 1]

    def _block(
        self, tx_xy: np.ndarray, gi: np.ndarray, col: np.ndarray, rx_x: np.ndarray, rx_y: np.ndarray
    ) -> tuple[_Block, int]:
        """Dense evaluation of transmissions tx_xy (T,2) with dense group ids gi (T,) at receivers (rx_x,
        rx_y) (M,) float32; col (T,) the receiver column of each transmitter (-1: not among them)."""
        p = self.p
        n_tx, n_rx = len(tx_xy), len(rx_x)
        tx32 = tx_xy.astype(np.float32)
        dx = np.subtract(rx_x[None, :], tx32[:, 0:1], out=self._scratch("dx", (n_tx, n_rx), np.float32))
        d2 = dx * dx
        dy = np.subtract(rx_y[None, :], tx32[:, 1:2], out=dx)
        d2 += np.multiply(dy, dy, out=dx)
        cand = d2 <= np.float32(self.link_range_m * self.link_range_m)
        own = (col >= 0).nonzero()[0]
        cand[own, col[own]] = False  # a transmitter never receives itself
        loss = blocked = p0 = None
        if self._general:
            p0 = np.float32(p.tx_power_dbm) - self.path_loss.loss_db_from_d2(d2)
            s_db = None
            if self.field is not None:  # log-normal shadowing: (X(tx) + X(rx)) / sqrt(2)
                x_tx = self.field.at(tx_xy)
                x_rx = self.field.at(np.stack([rx_x, rx_y], axis=1).astype(np.float64))
                s_db = self.field.link_db(x_tx[:, None], x_rx[None, :]).astype(np.float32)
                p0 = p0 + s_db
            relevant = p0 >= self.floor_dbm
            logged = cand & (np.sqrt(d2) <= self.comm_range_m)
            keep = cand & (relevant | logged)
            loss = np.full(d2.shape, np.inf, dtype=np.float32)
            need = np.flatnonzero(cand & relevant)
            loss.reshape(-1)[need] = self._sparse_loss(tx_xy, need, n_rx, rx_x, rx_y)
            if self._nlos:  # blocked line of sight: the model's NLOS formula (and NLOS shadowing) instead
                nl = need[np.isinf(loss.reshape(-1)[need])]
                if nl.size:
                    d = np.sqrt(d2.reshape(-1)[nl].astype(np.float64))
                    extra = self.path_loss.nlos_db(d) - self.path_loss.loss_db(d)
                    if s_db is not None:
                        extra -= s_db.reshape(-1)[nl] * (nlos_shadowing_sigma_db(p.path_loss) / 3.0 - 1.0)
                    loss.reshape(-1)[nl] = extra
            pw = p0 - loss
            above = p0 >= p.sensitivity_dbm
            reach = keep & (pw >= p.sensitivity_dbm)
        else:  # every candidate is within the communication range and above the floor
            logged = keep = cand
            if isinstance(self.shadow, PolarShadowing) and p.shadowing == "los":
                blocked = self.shadow.blocked_pairs(tx_xy, cand, rx_x, rx_y)
            elif not isinstance(self.shadow, NoShadowing):
                need = np.flatnonzero(cand)
                vals = self._sparse_loss(tx_xy, need, n_rx, rx_x, rx_y)
                loss = np.zeros(d2.shape, dtype=vals.dtype)
                loss.reshape(-1)[need] = vals
            if self._fast:
                above = self._above_sensitivity(d2, cand)
                reach = cand & above
                if blocked is None and loss is not None:
                    blocked, loss = np.isinf(loss), None
                if blocked is not None:
                    reach &= ~blocked
                pw = None
            else:
                p0 = np.float32(p.tx_power_dbm) - self.path_loss.loss_db_from_d2(d2)
                if blocked is not None:
                    pw = np.where(blocked, np.float32(-np.inf), p0)
                elif loss is not None:
                    pw = p0 - loss
                else:  # as p0 minus NoShadowing's float64 zeros
                    pw = p0.astype(np.float64)
                above = p0 >= p.sensitivity_dbm
                reach = cand & (pw >= p.sensitivity_dbm)
        # slots of the block: rows sorted by group (stable) for per-(slot, receiver) sums
        order = np.argsort(gi, kind="stable")
        gs = gi[order]
        change = np.empty(n_tx, dtype=bool)  # (np.r_ costs more than the rest of this together)
        np.not_equal(gs[1:], gs[:-1], out=change[1:])
        change[0] = True
        starts = change.nonzero()[0]
        change[0] = False
        lg = np.empty(n_tx, dtype=np.intp)
        lg[order] = np.cumsum(change)
        sorted_rows = bool(np.all(order == np.arange(n_tx)))
        # half duplex: the receiver transmits in the same slot
        sending = np.zeros((starts.size, n_rx), dtype=bool)
        sending[lg[own], col[own]] = True
        collided = sending[lg]
        # same-slot interference at each (slot, receiver)
        damaged = None
        if p.interference == "paper":
            if starts.size < n_tx:  # some slot carries two or more transmissions
                r = reach if sorted_rows else reach[order]
                multi = _slot_sums(r, starts, np.int32) >= 2
                damaged = reach & multi[lg]
        else:
            mw = np.power(10.0, np.where(np.isfinite(pw), pw, -300.0) / 10.0)
            mw = np.where(keep, mw, 0.0).astype(np.float64)  # bincount over the kept links, as before
            total = _slot_sums(mw if sorted_rows else mw[order], starts, np.float64)
            interf = np.maximum(total[lg] - mw, 0.0)
            damaged = reach & ~capture(mw, interf, self.rx)[1]
        ok = reach & above & ~collided
        if damaged is not None:
            ok &= ~damaged
        # carrier sense per (slot, receiver): the energy of the slot's senders at or above the CS threshold
        if pw is not None:
            if p.interference != "sinr":
                e = np.where(keep & np.isfinite(pw), np.power(10.0, pw.astype(np.float64) / 10.0), 0.0)
                total = _slot_sums(e if sorted_rows else e[order], starts, np.float64)
            sensed = total >= 10.0 ** (p.cs_threshold_dbm / 10.0)
        else:  # line-of-sight fast path: one sender at or above the threshold (no power computed)
            near = cand & (d2 <= np.float32(self._cs_d2))
            if blocked is not None:
                near &= ~blocked
            sensed = _slot_sums(near if sorted_rows else near[order], starts, np.int32) > 0
        sensed &= ~sending
        b = _Block(None, None, d2, logged, above, reach, collided, damaged, ok, p0, loss, blocked)
        b.sensed, b.lg = sensed, lg
        return b, int(np.count_nonzero(keep))

    def _sparse_loss(
        self, tx_xy: np.ndarray, flat: np.ndarray, n_rx: int, rx_x: np.ndarray, rx_y: np.ndarray
    ) -> np.ndarray:
        """Shadowing loss of the pairs at flat (T x M) positions, through the per-link shadowing API."""
        ti = flat // n_rx
        ri = flat - ti * n_rx
        return self.shadow.loss_db(tx_xy, ti, rx_x[ri], rx_y[ri])

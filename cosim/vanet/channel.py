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

Speed: the exact test (``shadow_method="exact"``) asks shapely about every link (~10-25 us per link on a
city map). The default ``polar`` method caches, for each cell of a ``polar_lattice_m`` lattice from which a
vehicle transmitted, a ray-cast visibility map in ``polar_bins`` directions: the distance of the first
building along each ray (``los``, cast against the dissolved footprints, whose shared walls can never be
the first hit) or the first wall crossings with their in/out sense (``veins``). A link then costs one table
lookup. The approximation is equivalent to moving the transmitter by at most half a lattice diagonal
(2.8 m at 4 m: the cell centre is used, moved 0.5 m across the nearest wall when it is inside a building
and the transmitter is not, or the other way round) and the receiver sideways by half a bin (bins are
uniform in a trigonometry-free pseudo-angle, 0.22-0.45 deg wide at 1024 bins: at most 2 m at 500 m). On
Helsinki road positions it agrees with the exact test on 99.5 % of in-range links. The maps depend only on
geometry, so the cache never changes results; it is flushed when it exceeds ``polar_cache_mb``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import shapely

from cosim.vanet.pathloss import (
    PATH_LOSS_MODELS,
    PathLoss,
    ShadowingField,
    default_shadowing,
    nlos_shadowing_sigma_db,
)
from cosim.vanet.receiver import ReceiverParams, capture

OK, BELOW_SENSITIVITY, SHADOWED, COLLIDED, DAMAGED = 0, 1, 2, 3, 4
OUTCOME_NAMES = ("ok", "below_sensitivity", "shadowed", "collided", "damaged")

SPEED_OF_LIGHT_MPS = 299_792_458.0


def dbm_to_mw(dbm):
    return np.power(10.0, np.asarray(dbm, dtype=np.float64) / 10.0)


def mw_to_dbm(mw):
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(np.asarray(mw, dtype=np.float64))


@dataclass(frozen=True)
class ChannelParams:
    """Radio link budget, path loss, shadowing and the receiver (``receiver``: cosim.vanet.receiver)."""

    frequency_hz: float = 5.89e9  # carrier [Hz] (ITS-G5 control channel, ETSI EN 302 663)
    tx_power_mw: float = 20.0  # transmit power [mW] (13 dBm)
    path_loss: Literal["free_space", "two_ray", "log_distance", "winner_b1", "3gpp_highway", "3gpp_urban"] = (
        "free_space"  # see cosim.vanet.pathloss
    )
    antenna_height_m: float = 1.5  # both antennas (two-ray, WINNER+ B1) [m]
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
        if self.path_loss == "winner_b1" and not self.antenna_height_m > 1.0:
            raise ValueError("channel: WINNER+ B1 needs antenna_height_m > 1 (effective height h - 1 m)")
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


def pseudo_angle(x: np.ndarray, y: np.ndarray, out=None, tmp=None, neg=None) -> np.ndarray:
    """A stand-in for the direction angle without trigonometry: p in [0, 4), strictly increasing
    counter-clockwise from -90 deg (p = 0: -y, 1: +x, 2: +y, 3: -x). Keeps the input dtype.

    out, tmp (float) and neg (bool), of the broadcast shape, are optional work arrays (out is returned)."""
    # in place, but the same operations in the same order as 1 + q + (x < 0) (2 - 2 q): bit-identical
    s = np.abs(x, out=out)
    t = np.abs(y, out=tmp)
    s += t
    s += x.dtype.type(1e-9)
    q = np.divide(y, s, out=s)
    b = np.multiply(q, -2.0, out=t)
    b += 2.0
    b *= np.less(x, 0, out=neg)
    q += 1.0
    q += b
    return q


class _Scratch:
    """Work arrays reused from call to call: a fresh multi-MB temporary costs more in page faults than
    the arithmetic done in it. ``scratch(name, shape, dtype)`` is valid until the next call with that name."""

    def __init__(self):
        self._arrays: dict[tuple[str, np.dtype], np.ndarray] = {}

    def __call__(self, name: str, shape: tuple[int, ...], dtype) -> np.ndarray:
        n = math.prod(shape)
        key = (name, np.dtype(dtype))
        a = self._arrays.get(key)
        if a is None or a.size < n:
            a = self._arrays[key] = np.empty(max(n, 16), dtype=dtype)
        return a[:n].reshape(shape)


def pseudo_angle_direction(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors (x, y) whose pseudo_angle is p."""
    p = np.asarray(p, dtype=np.float64)
    right = p < 2.0
    q = np.where(right, p - 1.0, 3.0 - p)
    x = np.where(right, 1.0, -1.0) * (1.0 - np.abs(q))
    norm = np.hypot(x, q)
    return x / norm, q / norm


# ------------------------------------------------------------------------------------------------------------
# buildings
# ------------------------------------------------------------------------------------------------------------
class Buildings:
    """Footprints prepared for shadowing: oriented polygons, an STRtree and flat wall-edge arrays.

    Rings are oriented so that the right-hand normal (ey, -ex) of every edge points out of the material
    (exterior counter-clockwise, holes clockwise).
    """

    def __init__(self, polygons: Sequence[shapely.Polygon]):
        parts: list[shapely.Polygon] = []
        stack = [g for g in polygons if g is not None and not g.is_empty]
        while stack:
            geom = stack.pop(0)
            if not geom.is_valid:
                geom = shapely.make_valid(geom)
            if isinstance(geom, shapely.Polygon):
                if geom.area > 0:
                    parts.append(geom)
            elif isinstance(geom, (shapely.MultiPolygon, shapely.GeometryCollection)):
                stack[:0] = list(shapely.get_parts(geom))
        # exterior counter-clockwise, holes clockwise
        parts = (
            list(shapely.orient_polygons(np.array(parts, dtype=object), exterior_cw=False)) if parts else []
        )
        self.polygons = np.array(parts, dtype=object)
        self.tree = shapely.STRtree(self.polygons)
        self.boundaries = shapely.boundary(self.polygons) if len(parts) else np.array([], dtype=object)
        for poly in parts:
            shapely.prepare(poly)
        x0, y0, x1, y1 = [], [], [], []
        for poly in parts:
            for ring in [poly.exterior, *poly.interiors]:
                c = np.asarray(ring.coords)
                x0.append(c[:-1, 0])
                y0.append(c[:-1, 1])
                x1.append(c[1:, 0])
                y1.append(c[1:, 1])
        cat = (lambda a: np.concatenate(a)) if x0 else (lambda a: np.zeros(0))
        self.ex0, self.ey0, self.ex1, self.ey1 = cat(x0), cat(y0), cat(x1), cat(y1)
        keep = (self.ex0 != self.ex1) | (self.ey0 != self.ey1)
        self.ex0, self.ey0, self.ex1, self.ey1 = (
            self.ex0[keep],
            self.ey0[keep],
            self.ex1[keep],
            self.ey1[keep],
        )
        self.edge_len = np.hypot(self.ex1 - self.ex0, self.ey1 - self.ey0)

    def __len__(self) -> int:
        return len(self.polygons)

    def containing_count(self, xy: np.ndarray) -> np.ndarray:
        """Number of footprints containing each point (n,2) -> (n,) int."""
        if len(self.polygons) == 0 or len(xy) == 0:
            return np.zeros(len(xy), dtype=np.int64)
        pts = shapely.points(xy)
        hit = self.tree.query(pts, predicate="within")[0]
        return np.bincount(hit, minlength=len(xy))


# ------------------------------------------------------------------------------------------------------------
# shadowing
# ------------------------------------------------------------------------------------------------------------
class ExactShadowing:
    """Shadowing loss from shapely on the exact link segments (reference implementation)."""

    def __init__(
        self, buildings: Buildings, model: Literal["los", "veins"], wall_db: float, per_meter_db: float
    ):
        self.b = buildings
        self.model = model
        self.wall_db = wall_db
        self.per_meter_db = per_meter_db

    def loss_db(
        self, tx_xy: np.ndarray, link_tx: np.ndarray, rx_x: np.ndarray, rx_y: np.ndarray
    ) -> np.ndarray:
        """tx_xy (T,2) transmitter positions [m]; link_tx (L,) index into tx_xy; rx_x, rx_y (L,) receiver
        positions [m] -> (L,) shadowing loss [dB] (inf: blocked)."""
        n = len(link_tx)
        loss = np.zeros(n)
        if n == 0 or len(self.b) == 0:
            return loss
        a = tx_xy[link_tx]
        segs = shapely.linestrings(np.stack([a, np.stack([rx_x, rx_y], axis=1)], axis=1))
        if self.model == "los":
            hit = self.b.tree.query(segs, predicate="intersects")[0]
            loss[np.unique(hit)] = np.inf
            return loss
        li, bi = self.b.tree.query(segs)
        if li.size == 0:
            return loss
        inside_m = shapely.length(shapely.intersection(segs[li], self.b.polygons[bi]))
        crossings = shapely.intersection(segs[li], self.b.boundaries[bi])
        # an empty result still counts as one (empty) part in shapely
        cuts = np.where(shapely.is_empty(crossings), 0, shapely.get_num_geometries(crossings))
        per_pair = self.wall_db * cuts + self.per_meter_db * inside_m
        return np.bincount(li, weights=per_pair, minlength=n)


class PolarShadowing:
    """Cached per-lattice-cell ray-cast visibility maps (see the module docstring for the approximation)."""

    def __init__(
        self,
        buildings: Buildings,
        model: Literal["los", "veins"],
        range_m: float,
        lattice_m: float,
        n_bins: int,
        cache_mb: float,
        wall_db: float,
        per_meter_db: float,
        max_loss_db: float,
    ):
        self.b = buildings
        self.model = model
        self.range_m = float(range_m)
        self.lattice_m = float(lattice_m)
        self.n_bins = int(n_bins)
        # directions are binned uniformly in the pseudo-angle p in [0, 4) (see pseudo_angle); bin b covers
        # p in [b w, (b + 1) w), w = 4 / n_bins, and is represented by the ray through its centre
        self.bin_w = 4.0 / n_bins
        self.ux, self.uy = pseudo_angle_direction((np.arange(n_bins) + 0.5) * self.bin_w)
        self.wall_db = wall_db
        self.per_meter_db = per_meter_db
        # crossings kept per ray: beyond K walls the loss exceeds any usable margin
        self.k = (
            1 if model == "los" else (min(64, math.ceil(max_loss_db / wall_db) + 1) if wall_db > 0 else 64)
        )
        row_bytes = n_bins * 4 if model == "los" else n_bins * (self.k * 2 + 1)
        self.max_rows = max(1024, int(cache_mb * 1e6 // (row_bytes + 24)))
        # map key -> pool row; lattice cell key (a map key without the inside bit) -> it touches a footprint
        self._row_of: dict[int, int] = {}
        self._cell_touched: dict[int, bool] = {}
        self._scratch = _Scratch()
        self.n_rows = 0
        self.builds = 0  # maps built so far (diagnostics)
        self.flushes = 0
        self._rows_cap = 0
        self._grow(min(self.max_rows, 4096))
        # edge buckets: for a cell of size C, the edges within range of some point of the cell
        self.cell_m = 64.0
        # (point, edge) pairs per vectorised cast: small enough for the expanded arrays to stay in cache
        self._chunk_pairs = 100_000 if model == "los" else 20_000
        self._bucket: dict[tuple[int, int], np.ndarray] = {}
        # per-edge terms of _cast: the edge vector and the squared reach (range + edge length)^2
        self._edge_x, self._edge_y = buildings.ex1 - buildings.ex0, buildings.ey1 - buildings.ey0
        near = self.range_m + buildings.edge_len
        self._near2 = near * near

    # -- pool ------------------------------------------------------------------------------------------------
    def _grow(self, rows: int) -> None:
        old = self._rows_cap
        b, k = self.n_bins, self.k

        def grown(name, shape, dtype, fill):
            arr = np.full(shape, fill, dtype=dtype)
            if old:
                arr[:old] = getattr(self, name)
            setattr(self, name, arr)

        grown("rep_xy", (rows, 2), np.float64, np.nan)
        grown("n0", rows, np.int8, 0)
        if self.model == "los":
            grown("depth2", (rows, b), np.float32, np.inf)  # squared distance to the first wall [m^2]
        else:
            # first K wall crossings per ray: distance [m], positive entering / negative leaving a building
            grown("cross_d", (rows, b, k), np.float16, np.inf)
            grown("saturated", (rows, b), np.bool_, False)
        self._rows_cap = rows

    def _flush(self) -> None:
        self._row_of = {}
        self.n_rows = 0
        self.flushes += 1

    def _edges_for_cell(self, cx: int, cy: int) -> np.ndarray:
        key = (cx, cy)
        hit = self._bucket.get(key)
        if hit is None:
            b, c = self.b, self.cell_m
            px, py = (cx + 0.5) * c, (cy + 0.5) * c
            # distance from the cell centre to each edge segment
            ex, ey = b.ex1 - b.ex0, b.ey1 - b.ey0
            t = np.clip(
                ((px - b.ex0) * ex + (py - b.ey0) * ey) / np.maximum(ex * ex + ey * ey, 1e-12), 0.0, 1.0
            )
            dist = np.hypot(b.ex0 + t * ex - px, b.ey0 + t * ey - py)
            ok = dist <= self.range_m + c * math.sqrt(0.5)
            if self.model == "los":
                # _cast keeps an edge for a point only when the point is on the edge's outer side and an end
                # of the edge lies within range + edge length: drop the edges for which no point of the cell
                # passes (both tests are linear / convex in the point, so the cell's corners and box bound
                # them; the 1 mm margin is far above rounding)
                x0, y0 = cx * c, cy * c
                xb, yb = np.where(ey > 0.0, x0 + c, x0), np.where(ex > 0.0, y0, y0 + c)
                ok &= -(b.ex0 - xb) * ey + (b.ey0 - yb) * ex > -1e-3 * b.edge_len
                lim = self.range_m + b.edge_len + 1e-3
                near = np.zeros(ok.shape, dtype=bool)
                for qx, qy in ((b.ex0, b.ey0), (b.ex1, b.ey1)):
                    gx = np.maximum(np.maximum(x0 - qx, qx - (x0 + c)), 0.0)
                    gy = np.maximum(np.maximum(y0 - qy, qy - (y0 + c)), 0.0)
                    near |= gx * gx + gy * gy <= lim * lim
                ok &= near
            hit = np.flatnonzero(ok)
            self._bucket[key] = hit
        return hit

    # -- map building ----------------------------------------------------------------------------------------
    def _representatives(self, keys_ij: np.ndarray, inside: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ray origins of lattice cells: the cell centre, moved 0.5 m across the nearest wall when it is
        inside a building and the transmitter is not (or the other way round)."""
        xy = (keys_ij.astype(np.float64) + 0.5) * self.lattice_m
        if len(self.b) == 0:
            return xy, np.zeros(len(xy), dtype=np.int64)
        n0 = self.b.containing_count(xy)
        wrong = np.flatnonzero((n0 > 0) != inside)
        if wrong.size:
            pts = shapely.points(xy[wrong])
            near = self.b.tree.query_nearest(pts, all_matches=False)[1]
            line = shapely.shortest_line(pts, self.b.boundaries[near])
            q = shapely.get_coordinates(line).reshape(-1, 2, 2)[:, 1, :]
            v = q - xy[wrong]
            norm = np.maximum(np.hypot(v[:, 0], v[:, 1]), 1e-9)
            xy[wrong] = q + 0.5 * v / norm[:, None]
            n0 = self.b.containing_count(xy)
        return xy, n0

    def _build(self, rows: np.ndarray, xy: np.ndarray, n0: np.ndarray) -> None:
        self.rep_xy[rows] = xy
        self.n0[rows] = np.minimum(n0, 127)
        if self.model == "los":
            self.depth2[rows] = np.inf
            self.depth2[rows[n0 > 0]] = 0.0
        else:
            self.cross_d[rows] = np.inf
            self.saturated[rows] = False
        if self.b.ex0.size == 0:
            return
        todo = (
            np.flatnonzero(n0 == 0) if self.model == "los" else np.arange(len(rows))
        )  # inside: sees nothing
        if todo.size == 0:
            return
        cells = np.floor(xy[todo] / self.cell_m).astype(np.int64).tolist()
        buckets = [self._edges_for_cell(cx, cy) for cx, cy in cells]
        # flat (point, edge) pairs, cast in chunks of ~1M pairs
        start = 0
        while start < todo.size:
            stop, size = start, 0
            while stop < todo.size and (size == 0 or size + buckets[stop].size <= self._chunk_pairs):
                size += buckets[stop].size
                stop += 1
            sub = todo[start:stop]
            lens = np.array([buckets[i].size for i in range(start, stop)])
            if size:
                ei = np.concatenate(buckets[start:stop])
                pi = np.repeat(np.arange(sub.size), lens)
                self._cast(rows[sub], xy[sub], pi, ei)
            start = stop

    def _cast(self, rows: np.ndarray, xy: np.ndarray, pi: np.ndarray, ei: np.ndarray) -> None:
        """Ray-cast the maps of points xy (P,2) into pool ``rows`` against edge ei of point pi (pairs)."""
        b = self.b
        R = self.range_m
        ax = b.ex0[ei] - xy[:, 0][pi]  # edge start relative to the point
        ay = b.ey0[ei] - xy[:, 1][pi]
        exv, eyv = self._edge_x[ei], self._edge_y[ei]
        bx, by = ax + exv, ay + eyv
        near = np.minimum(ax * ax + ay * ay, bx * bx + by * by) <= self._near2[ei]
        # the point sits on the material's outer side of the edge: a ray crossing it enters the building
        outer = (-ax * eyv + ay * exv) > 0.0
        cr = ax * by - ay * bx  # cross(a, b) > 0: b is counter-clockwise from a
        keep = near & (np.abs(cr) > 1e-12)
        if self.model == "los":
            keep &= outer
        k = np.flatnonzero(keep)
        if k.size == 0:
            return
        pi, axk, ayk, bxk, byk, crk = pi[k], ax[k], ay[k], bx[k], by[k], cr[k]
        exv, eyv = exv[k], eyv[k]
        sign = np.where(outer[k], 1, -1).astype(np.int8)
        p_a = pseudo_angle(axk, ayk)
        p_b = pseudo_angle(bxk, byk)
        ccw = crk > 0
        lo = np.where(ccw, p_a, p_b)
        span = np.mod(np.where(ccw, p_b - p_a, p_a - p_b), 4.0)
        b0 = np.ceil(lo / self.bin_w - 0.5).astype(np.int64)
        b1 = np.floor((lo + span) / self.bin_w - 0.5).astype(np.int64)
        cnt = np.maximum(b1 - b0 + 1, 0)
        total = int(cnt.sum())
        if total == 0:
            return
        # one (edge, bin) pair per bin an edge spans; per-edge values are repeated, not gathered, and the
        # numerator of the ray parameter is per edge (the same products as per pair: bit-identical)
        bins = np.arange(total)
        bins += np.repeat(b0 - (np.cumsum(cnt) - cnt), cnt)
        if self.n_bins & (self.n_bins - 1) == 0:  # bins >= 0: the same as % for a power of two, cheaper
            bins &= self.n_bins - 1
        else:
            bins %= self.n_bins
        exr, eyr = np.repeat(exv, cnt), np.repeat(eyv, cnt)
        denom = self.ux[bins] * eyr
        denom -= self.uy[bins] * exr
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.repeat(axk * eyv - ayk * exv, cnt) / denom
        ok = t > 0.0  # NaN and +-inf fail one of the two tests
        ok &= t <= R
        nb = self.n_bins
        flat = np.repeat(pi * nb, cnt)
        flat += bins
        if self.model == "los":
            # misses as inf rather than compressed away: the minimum per cell is the same, and cheaper
            depth = np.full(len(rows) * nb, np.inf, dtype=np.float64)
            t[~ok] = np.inf
            np.minimum.at(depth, flat, t)
            self.depth2[rows] = (depth * depth).reshape(len(rows), nb).astype(np.float32)
            return
        t, flat = t[ok], flat[ok]
        s = np.repeat(sign, cnt)[ok]
        order = np.lexsort((t, flat))
        flat, t, s = flat[order], t[order], s[order]
        start = np.flatnonzero(np.r_[True, flat[1:] != flat[:-1]])
        count = np.diff(np.r_[start, flat.size])
        rank = np.arange(flat.size) - np.repeat(start, count)
        k = self.k
        sel = rank < k
        d = np.full((len(rows) * nb, k), np.inf, dtype=np.float16)
        d[flat[sel], rank[sel]] = t[sel] * s[sel]
        sat = np.zeros(len(rows) * nb, dtype=bool)
        sat[flat[start][count > k]] = True
        self.cross_d[rows] = d.reshape(len(rows), nb, k)
        self.saturated[rows] = sat.reshape(len(rows), nb)

    def _inside(self, tx_xy: np.ndarray, ij: np.ndarray, cell_key: list[int]) -> np.ndarray:
        """Whether each point is inside a footprint; the point test only in lattice cells that touch one."""
        touched = [self._cell_touched.get(k) for k in cell_key]
        if None in touched:
            new = {}  # unknown cell -> its first point
            for i, (k, t) in enumerate(zip(cell_key, touched, strict=True)):
                if t is None:
                    new.setdefault(k, i)
            corner = ij[list(new.values())] * self.lattice_m
            boxes = shapely.box(*corner.T, *(corner + self.lattice_m).T)
            hit = set(self.b.tree.query(boxes, predicate="intersects")[0].tolist()) if len(self.b) else set()
            self._cell_touched.update((k, i in hit) for i, k in enumerate(new))
            touched = [self._cell_touched[k] for k in cell_key]
        inside = np.zeros(len(tx_xy), dtype=bool)
        test = [i for i, t in enumerate(touched) if t]
        if test:
            inside[test] = self.b.containing_count(tx_xy[test]) > 0
        return inside

    def rows_for(self, tx_xy: np.ndarray) -> np.ndarray:
        """Pool rows of the visibility maps for these transmitter positions (T,2), building missing maps.

        A map is keyed by the lattice cell and by whether the transmitter is inside a building footprint.
        A window has a few dozen transmitters: the keys are looked up in dicts, one by one.
        """
        tx_xy = np.asarray(tx_xy, dtype=np.float64)
        ij = np.floor(tx_xy / self.lattice_m).astype(np.int64)
        cell_key = (((ij[:, 0] + (1 << 30)) << 32) | ((ij[:, 1] + (1 << 30)) << 1)).tolist()
        inside = self._inside(tx_xy, ij, cell_key).tolist()
        keys = [k | i for k, i in zip(cell_key, inside, strict=True)]
        rows = [self._row_of.get(k, -1) for k in keys]
        if -1 in rows:
            first = {}  # new key -> first transmitter with it, by key (rows are handed out in key order)
            for i, (k, r) in enumerate(zip(keys, rows, strict=True)):
                if r < 0:
                    first.setdefault(k, i)
            new_keys = sorted(first)
            n_new = len(new_keys)
            if self.n_rows + n_new > self.max_rows:
                if len(set(keys)) > self.max_rows:
                    raise ValueError("channel.polar_cache_mb is too small for one window's transmitters")
                self._flush()
                return self.rows_for(tx_xy)
            if self.n_rows + n_new > self._rows_cap:
                self._grow(min(self.max_rows, max(2 * self._rows_cap, self.n_rows + n_new)))
            new_rows = np.arange(self.n_rows, self.n_rows + n_new)
            self.n_rows += n_new
            self._row_of.update(zip(new_keys, new_rows.tolist(), strict=True))
            xy, n0 = self._representatives(ij[[first[k] for k in new_keys]], (np.array(new_keys) & 1) == 1)
            self._build(new_rows, xy, n0)
            self.builds += n_new
            rows = [self._row_of[k] for k in keys]
        return np.array(rows, dtype=np.int64)

    def _lookup(
        self, rows: np.ndarray, dx: np.ndarray, dy: np.ndarray, scratch: _Scratch | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Squared distance and flat (row, bin) cell of receivers at (dx, dy) [m] (float32) from the ray
        origins of pool ``rows``; any shapes that broadcast: (L,) links or (T, 1) x (T, M). The results
        live in ``scratch`` when given (valid until its next use)."""
        shape = np.broadcast_shapes(dx.shape, dy.shape)
        buf = scratch or _Scratch()
        r2 = np.multiply(dx, dx, out=buf("r2", shape, np.float32))
        t = np.multiply(dy, dy, out=buf("t", shape, np.float32))
        r2 += t
        p = pseudo_angle(dx, dy, out=buf("p", shape, np.float32), tmp=t, neg=buf("neg", shape, np.bool_))
        p *= np.float32(1.0 / self.bin_w)
        bins = buf("bins", shape, np.intp)  # intp: take() converts any other index type first
        np.copyto(bins, p, casting="unsafe")
        np.minimum(bins, self.n_bins - 1, out=bins)
        bins += rows * self.n_bins
        return r2, bins

    def blocked_pairs(
        self, tx_xy: np.ndarray, mask: np.ndarray, rx_x: np.ndarray, rx_y: np.ndarray
    ) -> np.ndarray:
        """Line-of-sight model on the (transmitter, receiver) pairs of ``mask`` (T, M) bool: (T, M) bool,
        True = blocked (False outside the mask). Only the pairs asked for are looked up: on a city map the
        links in range are about a third of all pairs."""
        if self.model != "los":
            raise ValueError("blocked_pairs is the line-of-sight model only")
        n_rx = mask.shape[1]
        tx_rows = self.rows_for(tx_xy)
        rep = self.rep_xy[tx_rows].astype(np.float32)
        flat = np.flatnonzero(mask)
        per_row = mask.sum(axis=1)  # flat is row-major: per-row values by repeat, not gather
        ri = flat - np.repeat(np.arange(0, mask.size, n_rx), per_row)
        buf = self._scratch
        shape = flat.shape
        dx = np.subtract(rx_x.take(ri), np.repeat(rep[:, 0], per_row), out=buf("dx", shape, np.float32))
        dy = np.subtract(rx_y.take(ri), np.repeat(rep[:, 1], per_row), out=buf("dy", shape, np.float32))
        r2, cell = self._lookup(np.repeat(tx_rows, per_row), dx, dy, buf)
        depth = np.take(self.depth2.reshape(-1), cell, out=dx, mode="clip")  # cells are valid; no buffering
        blocked = np.zeros(mask.shape, dtype=bool)
        blocked.reshape(-1)[flat] = np.greater(r2, depth, out=buf("blocked", shape, np.bool_))
        return blocked

    def loss_db(
        self, tx_xy: np.ndarray, link_tx: np.ndarray, rx_x: np.ndarray, rx_y: np.ndarray
    ) -> np.ndarray:
        """Same contract as ExactShadowing.loss_db."""
        n = len(link_tx)
        if n == 0:
            return np.zeros(0)
        tx_rows = self.rows_for(tx_xy)
        rows = tx_rows[link_tx]
        rep = self.rep_xy[tx_rows].astype(np.float32)
        dx = rx_x.astype(np.float32, copy=False) - rep[:, 0][link_tx]
        dy = rx_y.astype(np.float32, copy=False) - rep[:, 1][link_tx]
        r2, cell = self._lookup(rows, dx, dy)
        if self.model == "los":
            return np.where(r2 > self.depth2.reshape(-1)[cell], np.float32(np.inf), np.float32(0.0))
        r = np.sqrt(r2)
        k = self.k
        v = self.cross_d.reshape(-1, k)[cell].astype(np.float32)  # (L, K)
        d, s = np.abs(v), np.sign(v)
        before = d < r[:, None]
        walls = before.sum(axis=1, dtype=np.float32)
        inside_now = self.n0[rows] + (before * s).sum(axis=1)
        inside_m = (np.where(before, -s, np.float32(0.0)) * np.where(before, d, np.float32(0.0))).sum(axis=1)
        inside_m += r * inside_now
        loss = np.float32(self.wall_db) * walls + np.float32(self.per_meter_db) * inside_m
        sat = self.saturated.reshape(-1)[cell] & (r > d[:, -1])
        return np.where(sat, np.float32(np.inf), loss)

    @property
    def nbytes(self) -> int:
        arrays = [self.rep_xy, self.n0]
        arrays += [self.depth2] if self.model == "los" else [self.cross_d, self.saturated]
        return int(sum(a.nbytes for a in arrays))


class NoShadowing:
    def loss_db(
        self, tx_xy: np.ndarray, link_tx: np.ndarray, rx_x: np.ndarray, rx_y: np.ndarray
    ) -> np.ndarray:
        return np.zeros(len(link_tx))


# ------------------------------------------------------------------------------------------------------------
# the aether
# ------------------------------------------------------------------------------------------------------------
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
    ):
        """``rng`` draws the log-normal shadowing field (only when its sigma > 0; None: a fixed seed 0)."""
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

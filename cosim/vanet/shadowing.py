"""Building footprints and the shadowing methods of the aether (``cosim.vanet.channel``).

* ``ExactShadowing``: shapely on the exact link segments (reference implementation);
* ``PolarShadowing``: cached per-lattice-cell ray-cast visibility maps (below);
* ``NoShadowing``: range only.

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

import hashlib
import math
import os
from functools import cached_property
from pathlib import Path
from typing import Literal

import numpy as np
import shapely

from cosim.buildings import Buildings  # noqa: F401 (re-exported: the footprints the methods shade with)


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
# shadowing
# ------------------------------------------------------------------------------------------------------------
def _cast_los_py(xy, pi, ei, ex0, ey0, edge_x, edge_y, near2, ux, uy, bin_w, n_bins, range_m, depth):
    """The line-of-sight cast of :meth:`PolarShadowing._cast`, one (point, edge) pair at a time: for each
    bin the edge spans (seen from the point, on the edge's outer side), the nearest ray parameter in
    (0, range] into ``depth`` (flat point * n_bins + bin, float64, inf = no wall). The same floating-point
    operations in the same order as the numpy version, so the same bits; compiled by numba (below)."""
    pow2 = n_bins & (n_bins - 1) == 0
    for j in range(pi.size):
        p = pi[j]
        e = ei[j]
        ax = ex0[e] - xy[p, 0]
        ay = ey0[e] - xy[p, 1]
        exv = edge_x[e]
        eyv = edge_y[e]
        bx = ax + exv
        by = ay + eyv
        if not min(ax * ax + ay * ay, bx * bx + by * by) <= near2[e]:
            continue
        if not (-ax * eyv + ay * exv) > 0.0:  # the point is on the material's outer side
            continue
        cr = ax * by - ay * bx
        if not abs(cr) > 1e-12:
            continue
        # pseudo_angle of a and b: the same operations as the array version
        s = abs(ax) + abs(ay) + 1e-9
        q = ay / s
        b = q * -2.0 + 2.0
        b = b * (1.0 if ax < 0 else 0.0)
        p_a = q + 1.0 + b
        s = abs(bx) + abs(by) + 1e-9
        q = by / s
        b = q * -2.0 + 2.0
        b = b * (1.0 if bx < 0 else 0.0)
        p_b = q + 1.0 + b
        if cr > 0:
            lo = p_a
            span = (p_b - p_a) % 4.0
        else:
            lo = p_b
            span = (p_a - p_b) % 4.0
        b0 = math.ceil(lo / bin_w - 0.5)
        b1 = math.floor((lo + span) / bin_w - 0.5)
        num = ax * eyv - ay * exv
        base = p * n_bins
        for bb in range(b0, b1 + 1):
            k = bb & (n_bins - 1) if pow2 else bb % n_bins
            t = num / (ux[k] * eyv - uy[k] * exv)
            if t > 0.0 and t <= range_m and t < depth[base + k]:
                depth[base + k] = t


_F32_EPS, _F32_M2, _F32_0, _F32_1, _F32_2 = (np.float32(v) for v in (1e-9, -2.0, 0.0, 1.0, 2.0))
_F32_INF = np.float32(np.inf)


def _los_loss_py(link_tx, tx_rows, rep_x, rep_y, rx_x, rx_y, depth2, inv_bin_w, n_bins, out):
    """:meth:`PolarShadowing.loss_db` of the line-of-sight model per link, in float32 like the numpy
    version (the same operations in the same order: the same bits): ``out[j]`` = inf when the receiver is
    farther from the transmitter's ray origin than the first wall in its direction bin, else 0."""
    for j in range(link_tx.size):
        i = link_tx[j]
        dx = rx_x[j] - rep_x[i]
        dy = rx_y[j] - rep_y[i]
        r2 = dx * dx + dy * dy
        s = abs(dx) + abs(dy) + _F32_EPS
        q = dy / s
        b = q * _F32_M2 + _F32_2
        b = b * (_F32_1 if dx < _F32_0 else _F32_0)
        p = (q + _F32_1 + b) * inv_bin_w
        k = min(int(p), n_bins - 1)
        out[j] = _F32_INF if r2 > depth2[tx_rows[i] * n_bins + k] else _F32_0


_KERNELS: list = []


def los_kernels() -> tuple:
    """(map cast, link lookup) compiled by numba on first use (cached on disk beside this module), or
    (None, None) without numba or with ``COSIM_NO_NUMBA`` set: then numpy does the same, to the bit.
    numba compiles without fastmath (no reassociation, no fused multiply-add), with numpy's division by
    zero (inf / nan, no exception)."""
    if not _KERNELS:
        try:
            if os.environ.get("COSIM_NO_NUMBA"):
                raise ImportError
            import numba
        except ImportError:
            _KERNELS.extend((None, None))
        else:
            jit = numba.njit(cache=True, error_model="numpy")
            _KERNELS.extend((jit(_cast_los_py), jit(_los_loss_py)))
    return _KERNELS[0], _KERNELS[1]


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
        self.builds = 0  # maps cast so far (diagnostics)
        self.flushes = 0
        # maps cast by earlier runs, taken on demand (cosim.vanet.mapstore.MapStore.fetch; None: none)
        self.source = None
        self.taken = 0  # maps taken from the source so far
        self.cast_keys: set[int] = set()  # keys of the maps this pool cast (what a store does not have)
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
        # the compiled line-of-sight cast and link lookup (None: numpy; set them to None to compare)
        self.kernel, self.loss_kernel = los_kernels() if model == "los" else (None, None)

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

    # -- maps kept between runs (cosim.vanet.mapstore) -------------------------------------------------------
    @property
    def map_fields(self) -> tuple[str, ...]:
        """The pool's arrays with a row per map: ray origin, inside count and the model's map."""
        return ("rep_xy", "n0", *(("depth2",) if self.model == "los" else ("cross_d", "saturated")))

    @cached_property
    def map_digest(self) -> str:
        """What the maps depend on: the footprints' edges, the model and its parameters, and this module's
        code (any change of it makes a new digest, so maps built by other code are never taken)."""
        h = hashlib.sha256(Path(__file__).read_bytes())
        h.update(repr((self.model, self.range_m, self.lattice_m, self.n_bins, self.k)).encode())
        for a in (self.b.ex0, self.b.ey0, self.b.ex1, self.b.ey1):
            h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
        return h.hexdigest()[:24]

    def map_arrays(self, keys=None) -> dict[str, np.ndarray]:
        """Maps in the pool, in key order: ``key`` (int64) and the pool's arrays of those rows; ``keys``:
        only those of them still in the pool (None: all)."""
        keys = self._row_of.keys() if keys is None else [k for k in keys if k in self._row_of]
        keys = np.sort(np.fromiter(keys, dtype=np.int64, count=len(keys)))
        rows = np.fromiter((self._row_of[k] for k in keys.tolist()), dtype=np.int64, count=len(keys))
        return {
            "key": keys,
            **{name: getattr(self, name)[rows] for name in self.map_fields},
        }

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
        if self.model == "los" and self.kernel is not None:
            nb = self.n_bins
            depth = np.full(len(rows) * nb, np.inf, dtype=np.float64)
            self.kernel(np.ascontiguousarray(xy, dtype=np.float64), pi.astype(np.int64, copy=False),
                        ei.astype(np.int64, copy=False), b.ex0, b.ey0, self._edge_x, self._edge_y, self._near2,
                        self.ux, self.uy, self.bin_w, nb, R, depth)  # fmt: skip
            self.depth2[rows] = (depth * depth).reshape(len(rows), nb).astype(np.float32)
            return
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
            cast = np.arange(n_new)
            if self.source is not None:  # maps an earlier run cast: the same bits, taken instead
                found, maps = self.source.fetch(new_keys)
                if found.size:
                    for name in self.map_fields:
                        getattr(self, name)[new_rows[found]] = maps[name]
                    self.taken += found.size
                    cast = np.setdiff1d(cast, found)
            if cast.size:
                cast_keys = np.array(new_keys)[cast]
                xy, n0 = self._representatives(
                    ij[[first[k] for k in cast_keys.tolist()]], (cast_keys & 1) == 1
                )
                self._build(new_rows[cast], xy, n0)
                self.builds += cast.size
                self.cast_keys.update(cast_keys.tolist())
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
        if self.model == "los" and self.loss_kernel is not None:
            rep = self.rep_xy[tx_rows].astype(np.float32)
            out = np.empty(n, dtype=np.float32)
            self.loss_kernel(np.asarray(link_tx, dtype=np.int64), tx_rows, np.ascontiguousarray(rep[:, 0]),
                             np.ascontiguousarray(rep[:, 1]), rx_x.astype(np.float32, copy=False),
                             rx_y.astype(np.float32, copy=False), self.depth2.reshape(-1),
                             np.float32(1.0 / self.bin_w), self.n_bins, out)  # fmt: skip
            return out
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

"""The compiled line-of-sight kernels (numba) give the same visibility maps and link losses as numpy, bit for
bit (the numpy versions stay the fallback without numba and the reference here)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from shapely import affinity

from cosim.vanet import shadowing
from cosim.vanet.shadowing import Buildings, PolarShadowing


def _footprints(seed: int = 7, n: int = 60) -> list:
    """Rotated boxes, triangles and an L-shaped block with a courtyard, scattered over 600 m x 600 m."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        x, y = rng.uniform(0, 600, 2)
        w, h = rng.uniform(5, 40, 2)
        shape = (
            shapely.box(x, y, x + w, y + h)
            if rng.random() < 0.7
            else shapely.Polygon([(x, y), (x + w, y), (x + 0.3 * w, y + h)])
        )
        out.append(affinity.rotate(shape, rng.uniform(0, 180), origin="centroid"))
    court = shapely.box(250, 250, 330, 330).difference(shapely.box(270, 270, 310, 310))
    out.append(court.union(shapely.box(330, 250, 380, 270)))
    return out


def _maps(po: PolarShadowing, tx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    rows = po.rows_for(tx)
    return po.depth2[rows].copy(), po.rep_xy[rows].copy()


@pytest.mark.parametrize("n_bins", [1024, 1000])  # a power of two (bit mask) and not (modulo)
def test_compiled_and_numpy_casts_give_identical_maps(n_bins):
    pytest.importorskip("numba")
    bl = Buildings(_footprints())
    rng = np.random.default_rng(1)
    tx = rng.uniform(-50, 650, (400, 2))  # inside and outside footprints, and beyond the map
    fast = PolarShadowing(bl, "los", 500.0, 4.0, n_bins, 64, 9.0, 0.4, 80.0)
    slow = PolarShadowing(bl, "los", 500.0, 4.0, n_bins, 64, 9.0, 0.4, 80.0)
    assert fast.kernel is not None and fast.loss_kernel is not None
    slow.kernel = slow.loss_kernel = None  # the numpy cast and lookup
    d_fast, xy_fast = _maps(fast, tx)
    d_slow, xy_slow = _maps(slow, tx)
    assert np.array_equal(xy_fast, xy_slow)
    assert d_fast.tobytes() == d_slow.tobytes()  # bit for bit, inf included
    assert np.isfinite(d_fast).any() and np.isinf(d_fast).any()  # walls seen, and open directions
    # and so every link decision
    rx = rng.uniform(-50, 650, (3000, 2))
    link_tx = rng.integers(0, len(tx), len(rx))
    a = fast.loss_db(tx, link_tx, rx[:, 0], rx[:, 1])
    b = slow.loss_db(tx, link_tx, rx[:, 0], rx[:, 1])
    assert a.tobytes() == b.tobytes()


def test_the_kernel_source_run_as_python_matches_numpy():
    """The kernel's source without numba (small case: plain Python is slow) against the numpy cast."""
    bl = Buildings(_footprints(n=12))
    po = PolarShadowing(bl, "los", 300.0, 4.0, 256, 16, 9.0, 0.4, 80.0)
    po.kernel = None
    tx = np.random.default_rng(2).uniform(0, 600, (12, 2))
    ref, _ = _maps(po, tx)
    py = PolarShadowing(bl, "los", 300.0, 4.0, 256, 16, 9.0, 0.4, 80.0)
    py.kernel = shadowing._cast_los_py
    got, _ = _maps(py, tx)
    assert got.tobytes() == ref.tobytes()
    rx = np.random.default_rng(3).uniform(0, 600, (500, 2))
    link_tx = np.arange(500) % len(tx)
    py.loss_kernel = shadowing._los_loss_py
    po.loss_kernel = None
    a = py.loss_db(tx, link_tx, rx[:, 0], rx[:, 1])
    assert a.tobytes() == po.loss_db(tx, link_tx, rx[:, 0], rx[:, 1]).tobytes()
    assert 0 < np.isinf(a).sum() < len(a)


def test_veins_model_keeps_the_numpy_cast():
    bl = Buildings(_footprints(n=10))
    po = PolarShadowing(bl, "veins", 300.0, 4.0, 256, 16, 9.0, 0.4, 80.0)
    po.rows_for(np.array([[100.0, 100.0]]))  # the kernel is line-of-sight only: veins casts with numpy
    assert po.builds == 1 and np.isfinite(po.cross_d[0]).any()


def test_without_numba_the_numpy_versions_run(monkeypatch):
    monkeypatch.setattr(shadowing, "_KERNELS", [])
    monkeypatch.setenv("COSIM_NO_NUMBA", "1")
    assert shadowing.los_kernels() == (None, None)
    po = PolarShadowing(Buildings(_footprints(n=5)), "los", 300.0, 4.0, 256, 16, 9.0, 0.4, 80.0)
    assert po.kernel is None and po.loss_kernel is None

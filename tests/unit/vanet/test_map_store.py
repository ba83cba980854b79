"""Visibility maps kept between runs (cosim.vanet.mapstore): a pool that takes its maps from the store answers
every link as a pool that casts them anew, casts none of the stored ones, reads only the maps it needs, and
a bad store is reported and replaced, never trusted."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from cosim.vanet import mapstore
from cosim.vanet.mapstore import MapStore, store_dir
from cosim.vanet.shadowing import Buildings, PolarShadowing
from tests.unit.vanet.test_shadowing_kernel import _footprints

RNG = np.random.default_rng(3)
TX = RNG.uniform(0, 600, (40, 2))  # transmitters over the footprints (some inside buildings)
RX = RNG.uniform(-50, 650, (300, 2))


def _pool(model: str = "los", bins: int = 1024) -> PolarShadowing:
    return PolarShadowing(Buildings(_footprints()), model, 600.0, 4.0, bins, 16, 9.0, 0.4, 80.0)


def _losses(po: PolarShadowing, tx: np.ndarray) -> np.ndarray:
    link_tx = np.repeat(np.arange(len(tx)), len(RX))
    r = np.tile(RX, (len(tx), 1)).astype(np.float32)
    return po.loss_db(tx, link_tx, r[:, 0], r[:, 1])


@pytest.mark.parametrize("model", ["los", "veins"])
def test_a_pool_from_the_store_casts_nothing_and_answers_the_same(tmp_path, model):
    built = _pool(model)
    fresh = _losses(built, TX)
    assert built.builds > 0
    MapStore(tmp_path, built).save()

    warm = _pool(model)
    store = MapStore(tmp_path, warm)
    assert store.load() == built.builds
    again = _losses(warm, TX)
    assert warm.builds == 0 and warm.taken == built.builds  # every map came from the store
    assert not warm.cast_keys
    assert np.array_equal(fresh, again)
    # and the maps themselves are the same bits as cast ones
    rows_a, rows_b = built.rows_for(TX), warm.rows_for(TX)
    for name in ("rep_xy", "n0", *built.map_fields):
        assert np.array_equal(getattr(built, name)[rows_a], getattr(warm, name)[rows_b], equal_nan=True)


def test_runs_merge_their_maps_and_new_transmitters_still_get_theirs(tmp_path):
    a, b = _pool(), _pool()
    _losses(a, TX[:20])
    _losses(b, TX[20:])
    MapStore(tmp_path, a).save()
    MapStore(tmp_path, b).save()  # re-reads the store under the lock: a's maps stay
    c = _pool()
    both = set(a.map_arrays()["key"].tolist()) | set(b.map_arrays()["key"].tolist())
    assert MapStore(tmp_path, c).load() == len(both)
    other = RNG.uniform(700, 900, (5, 2))  # cells no run has seen: cast as usual
    assert np.array_equal(_losses(c, np.vstack([TX, other])), _losses(_pool(), np.vstack([TX, other])))
    assert c.builds == len({tuple(v) for v in np.floor(other / 4.0).astype(int).tolist()})
    assert c.taken == len(both)


def test_a_run_takes_only_the_maps_it_needs_and_small_additions_are_not_written(tmp_path, monkeypatch):
    a = _pool()
    _losses(a, TX)
    MapStore(tmp_path, a).save()
    b = _pool()
    MapStore(tmp_path, b).load()
    _losses(b, TX[:3])
    assert b.taken == len({k for k in b.map_arrays()["key"].tolist()}) <= 3  # not the whole store
    c = _pool()
    MapStore(tmp_path, c).load()
    _losses(c, RNG.uniform(700, 900, (2, 2)))  # two new maps: not worth rewriting a store for ...
    monkeypatch.setattr(mapstore, "MIN_NEW_PER_MB", 1e6)
    before = MapStore(tmp_path, c).path.stat().st_mtime_ns
    MapStore(tmp_path, c).save()
    assert MapStore(tmp_path, c).path.stat().st_mtime_ns == before
    monkeypatch.setattr(mapstore, "MIN_NEW_PER_MB", 0.0)  # ... unless told so
    MapStore(tmp_path, c).save()
    assert MapStore(tmp_path, _pool()).load() == a.builds + c.builds


def test_other_parameters_make_another_store(tmp_path):
    a = _pool(bins=1024)
    _losses(a, TX)
    MapStore(tmp_path, a).save()
    b = _pool(bins=512)
    assert b.map_digest != a.map_digest
    assert MapStore(tmp_path, b).load() == 0
    assert MapStore(tmp_path, _pool("veins")).load() == 0


def test_a_broken_store_is_reported_and_replaced(tmp_path, capsys):
    a = _pool()
    store = MapStore(tmp_path, a)
    store.path.write_bytes(b"not a store at all")
    assert store.load() == 0
    assert "unreadable" in capsys.readouterr().err
    _losses(a, TX)
    store.save()
    assert MapStore(tmp_path, _pool()).load() == a.builds


def test_a_store_of_other_arrays_is_not_taken(tmp_path, capsys):
    a = _pool()
    store = MapStore(tmp_path, a)
    mapstore.write_maps(store.path, {"key": np.arange(3), "rep_xy": np.zeros((3, 2)), "n0": np.zeros(3, np.int8),
                                     "depth2": np.zeros((3, 16), np.float32)})  # fmt: skip
    assert store.load() == 0
    assert "does not hold maps of this pool" in capsys.readouterr().err


def test_a_truncated_store_is_not_taken(tmp_path, capsys):
    a = _pool()
    _losses(a, TX)
    store = MapStore(tmp_path, a)
    store.save()
    data = store.path.read_bytes()
    store.path.write_bytes(data[: len(data) // 2])
    assert MapStore(tmp_path, _pool()).load() == 0
    assert "truncated" in capsys.readouterr().err


def test_an_unwritable_store_leaves_the_run_going(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    a = _pool()
    _losses(a, TX[:3])
    MapStore(blocker / "visibility", a).save()  # a directory under a file: cannot be made
    assert "this run's maps are not kept" in capsys.readouterr().err


def test_the_store_is_capped_keeping_the_newest_maps(tmp_path, monkeypatch):
    a = _pool()
    _losses(a, TX[:20])
    MapStore(tmp_path, a).save()
    row_bytes = sum(v[:1].nbytes for v in a.map_arrays().values())
    monkeypatch.setattr(mapstore, "STORE_MAX_MB", 10 * row_bytes / 1e6)
    b = _pool()
    _losses(b, TX[20:])
    MapStore(tmp_path, b).save()
    keys = np.asarray(mapstore.read_maps(MapStore(tmp_path, b).path)["key"])
    assert len(keys) == 10 and set(keys.tolist()) <= set(b.map_arrays()["key"].tolist())


def test_the_directory_keeps_the_stores_used_last(tmp_path, monkeypatch):
    monkeypatch.setattr(mapstore, "STORE_MAX_FILES", 2)
    for bins in (256, 512, 1024):
        po = _pool(bins=bins)
        _losses(po, TX[:2])
        MapStore(tmp_path, po).save()
    assert len(list(tmp_path.glob("*.vis"))) == 2
    assert MapStore(tmp_path, _pool(bins=256)).load() == 0  # the oldest went


def test_a_killed_runs_temporary_file_is_neither_a_store_nor_kept(tmp_path):
    left = tmp_path / ".visibility-killed.vis"
    left.write_bytes(b"half a store")
    writing = tmp_path / ".visibility-now.vis"  # another run writing its store right now
    writing.write_bytes(b"")
    os.utime(left, (time.time() - 7200, time.time() - 7200))
    po = _pool()
    _losses(po, TX[:2])
    MapStore(tmp_path, po).save()
    assert not left.exists() and writing.exists()
    assert [p.name for p in tmp_path.glob("[!.]*.vis")] == [f"{po.map_digest}.vis"]


def test_the_store_directory_and_no_store_when_switched_off(tmp_path, monkeypatch):
    monkeypatch.delenv("COSIM_MAP_STORE_DIR", raising=False)
    assert store_dir(tmp_path) == tmp_path / "visibility"
    monkeypatch.setenv("COSIM_MAP_STORE_DIR", str(tmp_path / "elsewhere"))
    assert store_dir(tmp_path) == tmp_path / "elsewhere"
    monkeypatch.setenv("COSIM_NO_MAP_STORE", "1")
    assert store_dir(tmp_path) is None

"""Visibility maps kept between runs (issue 20).

``PolarShadowing`` casts a visibility map for each lattice cell a vehicle transmits from (~0.2 ms each; ~16,000
maps and 7 % of the CPU time of a participant of ``make experiment``). The maps depend only on the building
footprints, the shadowing model's parameters and the code that casts them (``PolarShadowing.map_digest``),
so a run may start with the maps an earlier run on the same town cast: the results are the same to the bit
(tests/integration/test_visibility_store_runs.py), only the casting is saved.

A store is one ``<digest>.npz`` per digest in the cache (``$COSIM_CACHE_DIR/visibility``, or
``$COSIM_MAP_STORE_DIR``; none with ``COSIM_NO_MAP_STORE`` set). A run reads it when its radio starts and, when it
has built maps, merges them in when it ends: under a file lock, re-read first (runs beside it may have
added theirs), written to a temporary file and renamed over the old one, so a reader never sees half a
store and no run's maps are lost to another's. A store holds at most STORE_MAX_MB (this run's new maps
first); the directory keeps the STORE_MAX_FILES stores used last. A store that cannot be read or written is
reported in one line on stderr and the run goes on without it.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np
from filelock import FileLock, Timeout

from cosim.vanet.shadowing import PolarShadowing

STORE_MAX_MB = 128.0  # ~30,000 line-of-sight maps of 1024 bins: a town's roads at a 4-m lattice
STORE_MAX_FILES = 6  # stores (towns, channel settings) kept in the directory; the ones used longest ago go
LOCK_TIMEOUT_S = 120.0  # another run merging its maps: wait this long, then leave the maps unsaved


def store_dir(cache_root: Path) -> Path | None:
    """The stores' directory: ``visibility`` in the cache, or ``$COSIM_MAP_STORE_DIR``; None when
    ``COSIM_NO_MAP_STORE`` is set."""
    if os.environ.get("COSIM_NO_MAP_STORE"):
        return None
    return Path(os.environ.get("COSIM_MAP_STORE_DIR") or Path(cache_root) / "visibility")


def _warn(msg: str) -> None:
    print(f"cosim: visibility maps: {msg}", file=sys.stderr, flush=True)


class MapStore:
    """The store of one ``PolarShadowing`` pool: ``load`` when the radio starts, ``save`` when it ends."""

    def __init__(self, root: Path, shadow: PolarShadowing):
        self.root = Path(root)
        self.shadow = shadow
        self.path = self.root / f"{shadow.map_digest}.npz"
        self.loaded = 0  # maps taken from the store

    def _read(self, like: dict[str, np.ndarray]) -> dict[str, np.ndarray] | None:
        """The store's maps (None: no store, or one whose arrays are not those of ``like``, the pool's
        ``map_arrays``: reported)."""
        try:
            with np.load(self.path, allow_pickle=False) as z:
                maps = {name: z[name] for name in z.files}
        except FileNotFoundError:
            return None
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            _warn(f"{self.path} is unreadable ({exc}); it is built anew")
            return None
        n = len(maps.get("key", ()))
        if (
            set(maps) != set(like)
            or n == 0
            or any(maps[k].dtype != v.dtype or maps[k].shape != (n, *v.shape[1:]) for k, v in like.items())
        ):
            _warn(f"{self.path} does not hold maps of this pool; it is built anew")
            return None
        return maps

    def load(self) -> int:
        """Put the stored maps into the pool; returns how many."""
        maps = self._read(self.shadow.map_arrays())
        if maps is None:
            return 0
        self.loaded = self.shadow.add_maps(maps)
        try:
            os.utime(self.path)  # used now: the directory keeps the stores used last
        except OSError:
            pass
        return self.loaded

    def save(self) -> None:
        """Merge the maps built in this run into the store (nothing to do when none was built)."""
        if self.shadow.builds == 0:
            return
        try:
            self.root.mkdir(parents=True, exist_ok=True)
            with FileLock(self.path.with_suffix(".lock"), timeout=LOCK_TIMEOUT_S):
                self._merge()
            self._evict()
        except Timeout:
            _warn(f"{self.path} stayed locked for {LOCK_TIMEOUT_S:g} s; this run's maps are not kept")
        except OSError as exc:
            _warn(f"cannot write {self.path} ({exc}); this run's maps are not kept")

    def _merge(self) -> None:
        mine = self.shadow.map_arrays()
        old = self._read(mine)
        if old is None:
            old = {k: v[:0] for k, v in mine.items()}
        new = ~np.isin(mine["key"], old["key"])
        if not new.any():
            return
        row_bytes = sum(v[:1].nbytes for v in mine.values())
        room = max(int(STORE_MAX_MB * 1e6 // row_bytes), 1)
        n_new = min(int(new.sum()), room)
        n_old = min(len(old["key"]), room - n_new)
        merged = {k: np.concatenate([mine[k][new][:n_new], old[k][:n_old]]) for k in mine}
        fd, tmp = tempfile.mkstemp(prefix=".visibility-", suffix=".npz", dir=self.root)
        try:
            with os.fdopen(fd, "wb") as f:
                np.savez(f, **merged)
            os.chmod(tmp, 0o644)  # as the cache's other files (mkstemp makes it private)
            os.replace(tmp, self.path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    def _evict(self) -> None:
        """Keep the STORE_MAX_FILES stores used last (a store in use by a run is read whole at its start), and
        remove temporary files a killed run left (an hour old: none is being written then)."""
        stores, now = [], time.time()
        for p in self.root.glob("*.npz"):
            try:
                used = p.stat().st_mtime
            except OSError:
                continue
            if not p.name.startswith("."):
                stores.append((used, p))
            elif now - used > 3600.0:
                p.unlink(missing_ok=True)
        for _, p in sorted(stores, reverse=True)[STORE_MAX_FILES:]:
            p.unlink(missing_ok=True)
            p.with_suffix(".lock").unlink(missing_ok=True)

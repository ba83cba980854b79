"""Visibility maps kept between runs (issue 20).

``PolarShadowing`` casts a visibility map for each lattice cell a vehicle transmits from (~0.2 ms each; ~16,000
maps and 7 % of the CPU time of a participant of ``make experiment``). The maps depend only on the building
footprints, the shadowing model's parameters and the code that casts them (``PolarShadowing.map_digest``),
so a run may take the maps an earlier run on the same town cast instead of casting them: the results are the
same to the bit (tests/integration/test_visibility_store_runs.py), only the casting is saved.

A store is one file per digest, ``<digest>.vis``, in the cache (``$COSIM_CACHE_DIR/visibility``, or
``$COSIM_MAP_STORE_DIR``; none with ``COSIM_NO_MAP_STORE`` set): a JSON header, then each array (keys, ray
origins, inside counts, the maps) as one block. A run maps the file into memory when its radio starts and
reads the keys only; a map is read when the run first needs it (``fetch``), so a short run on a town with a
large store reads little of it. When the run ends, the maps it cast are merged in if they are worth the
rewrite (at least MIN_NEW_PER_MB per MB of store: rewriting takes ~3.5 ms per MB, casting ~0.2 ms per map):
under a file lock, the store re-read first (runs beside it may have added theirs), written to a temporary
file and renamed over the old one, so a reader never sees half a store (a run that mapped the old file keeps
reading it) and no run's maps are lost to another's. A store holds at most STORE_MAX_MB (this run's maps
first); the directory keeps the STORE_MAX_FILES stores used last. A store that cannot be read or written is
reported in one line on stderr and the run goes on without it.
"""

from __future__ import annotations

import json
import mmap
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from filelock import FileLock, Timeout

from cosim.vanet.shadowing import PolarShadowing

STORE_MAX_MB = 128.0  # ~30,000 line-of-sight maps of 1024 bins: a town's roads at a 4-m lattice
STORE_MAX_FILES = 6  # stores (towns, channel settings) kept in the directory; the ones used longest ago go
MIN_NEW_PER_MB = 5.0  # a run's new maps are merged in when there are at least this many per MB of store
LOCK_TIMEOUT_S = 120.0  # another run merging its maps: wait this long, then leave the maps unsaved
MAGIC = b"COSIM-VISIBILITY-1\n"
HEADER_BYTES = 4096  # the JSON header, padded; the arrays follow, each at a multiple of 64 bytes


def store_dir(cache_root: Path) -> Path | None:
    """The stores' directory: ``visibility`` in the cache, or ``$COSIM_MAP_STORE_DIR``; None when
    ``COSIM_NO_MAP_STORE`` is set."""
    if os.environ.get("COSIM_NO_MAP_STORE"):
        return None
    return Path(os.environ.get("COSIM_MAP_STORE_DIR") or Path(cache_root) / "visibility")


def _warn(msg: str) -> None:
    print(f"cosim: visibility maps: {msg}", file=sys.stderr, flush=True)


def write_maps(path: Path, maps: dict[str, np.ndarray]) -> None:
    """``maps`` (arrays of equal length, ``key`` first) into ``path``: header, then the arrays."""
    fields, offset = [], HEADER_BYTES
    for name, a in maps.items():
        fields.append({"name": name, "dtype": a.dtype.str, "shape": list(a.shape[1:]), "offset": offset})
        offset += -(-a.nbytes // 64) * 64
    header = MAGIC + json.dumps({"n": len(maps["key"]), "fields": fields}).encode()
    if len(header) > HEADER_BYTES:
        raise ValueError("visibility store header too long")
    with open(path, "wb") as f:
        f.write(header.ljust(HEADER_BYTES, b" "))
        for field, a in zip(fields, maps.values(), strict=True):
            f.seek(field["offset"])
            f.write(np.ascontiguousarray(a).tobytes())
        f.truncate(offset)


def read_maps(path: Path) -> dict[str, np.ndarray]:
    """The arrays of a store, mapped into memory (read when indexed). Raises OSError / ValueError."""
    with open(path, "rb") as f:
        head = f.read(HEADER_BYTES)
        if not head.startswith(MAGIC):
            raise ValueError("not a visibility store")
        meta = json.loads(head[len(MAGIC) :])
        # plain arrays over one read-only mapping (np.memmap's subclass costs more per small read)
        buf = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
    n, maps = int(meta["n"]), {}
    for field in meta["fields"]:
        dtype, shape = np.dtype(field["dtype"]), (n, *field["shape"])
        count = int(np.prod(shape))
        if field["offset"] + dtype.itemsize * count > len(buf):
            raise ValueError("truncated")
        maps[field["name"]] = np.frombuffer(buf, dtype=dtype, count=count, offset=field["offset"]).reshape(
            shape
        )
    return maps


class MapStore:
    """The store of one ``PolarShadowing`` pool: ``load`` when the radio starts (the pool then takes its
    maps from ``fetch``), ``save`` when it ends."""

    def __init__(self, root: Path, shadow: PolarShadowing):
        self.root = Path(root)
        self.shadow = shadow
        self.path = self.root / f"{shadow.map_digest}.vis"
        self._maps: dict[str, np.ndarray] | None = None
        self._index: dict[int, int] = {}  # key -> its position in the store

    def _read(self) -> dict[str, np.ndarray] | None:
        """The store's arrays (None: no store, or one whose arrays are not those of the pool: reported)."""
        try:
            maps = read_maps(self.path)
        except FileNotFoundError:
            return None
        except (OSError, ValueError, KeyError, TypeError) as exc:
            _warn(f"{self.path} is unreadable ({exc}); it is built anew")
            return None
        like = self.shadow.map_arrays([])  # the dtypes and row shapes of the pool's arrays
        if set(maps) != set(like) or any(
            maps[k].dtype != v.dtype or maps[k].shape[1:] != v.shape[1:] for k, v in like.items()
        ):
            _warn(f"{self.path} does not hold maps of this pool; it is built anew")
            return None
        return maps

    def load(self) -> int:
        """Open the store and give the pool its maps on demand; returns how many it holds."""
        maps = self._read()
        if maps is None:
            return 0
        self._maps = maps
        self._index = {k: i for i, k in enumerate(np.asarray(maps["key"]).tolist())}
        self.shadow.source = self
        try:
            os.utime(self.path)  # used now: the directory keeps the stores used last
        except OSError:
            pass
        return len(self._index)

    def fetch(self, keys: list[int]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """The stored maps of ``keys``: (positions in ``keys`` found, their arrays in that order)."""
        at = [self._index.get(k, -1) for k in keys]
        found = np.flatnonzero(np.array(at) >= 0)
        if found.size == 0:
            return found, {}
        idx = np.array(at)[found]
        return found, {name: np.asarray(a[idx]) for name, a in self._maps.items() if name != "key"}

    def save(self) -> None:
        """Merge the maps this run cast into the store, when there are enough of them."""
        if not self.shadow.cast_keys:
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
        old = self._read()  # the store as it is now (another run may have replaced it since ``load``)
        have = set() if old is None else set(np.asarray(old["key"]).tolist())
        mine = self.shadow.map_arrays(k for k in self.shadow.cast_keys if k not in have)
        n_new, n_old = len(mine["key"]), len(have)
        row_bytes = sum(v[:1].nbytes for v in mine.values()) if n_new else 0
        if n_new == 0 or n_new < MIN_NEW_PER_MB * n_old * row_bytes / 1e6:
            return  # not worth rewriting the store for
        room = max(int(STORE_MAX_MB * 1e6 // row_bytes), 1)
        n_new = min(n_new, room)
        n_old = min(n_old, room - n_new)
        merged = {
            k: np.concatenate([v[:n_new], np.asarray(old[k][:n_old]) if old else v[:0]])
            for k, v in mine.items()
        }
        fd, tmp = tempfile.mkstemp(prefix=".visibility-", suffix=".vis", dir=self.root)
        os.close(fd)
        try:
            write_maps(Path(tmp), merged)
            os.chmod(tmp, 0o644)  # as the cache's other files (mkstemp makes it private)
            os.replace(tmp, self.path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    def _evict(self) -> None:
        """Keep the STORE_MAX_FILES stores used last, and remove temporary files a killed run left (an hour
        old: none is being written then)."""
        stores, now = [], time.time()
        for p in self.root.glob("*.vis"):
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

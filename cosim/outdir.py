"""Where the commands write: every ``--out`` is checked here before anything is built or written.

* ``check_dir`` / ``check_file``: a path that cannot be an output (a file where a directory is meant, a
  path under a file, no write permission) is a :class:`CosimError` naming the path and the fix.
* ``RunDir``: the directory of a run (or an experiment) while it is written. It is locked (``filelock``: an
  OS lock on ``.cosim.lock`` inside it, gone when the run ends), so a second run on the same ``--out`` stops
  with one line instead of interleaving its log with the first; a directory that already holds a run is
  replaced only with ``force``, and then emptied first, so no plot of the old run remains beside the new
  one. A directory it created is removed again when the command fails with a user error.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from filelock import FileLock, Timeout

from cosim.errors import CosimError

LOCK_NAME = ".cosim.lock"
# a directory holding one of these (or a folder with a run.mcap) holds a run or an experiment
RUN_MARKERS = ("run.mcap", "summary.json")


def _nearest_existing(path: Path) -> Path:
    path = path.absolute()
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def _check_parents(path: Path, option: str) -> None:
    """The nearest existing folder of ``path`` is a directory we may create entries in."""
    base = _nearest_existing(path.parent if path.exists() else path)
    if not base.is_dir():
        raise CosimError(f"{option} {path} lies under {base}, which is a file, not a directory: "
                         f"give a path whose parent folders are directories")  # fmt: skip
    if not os.access(base, os.W_OK | os.X_OK):
        raise CosimError(f"{option} {path}: no permission to write in {base}: give a writable location")


def check_dir(path: str | Path, option: str = "--out") -> Path:
    """``path`` can be (or become) an output directory we may write into; nothing is created."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise CosimError(f"{option} {path} is a file, not a directory: remove it or give another directory")
    _check_parents(path, option)
    if path.is_dir() and not os.access(path, os.W_OK | os.X_OK):
        raise CosimError(f"{option} {path}: no permission to write in it: give a writable directory")
    return path


def check_file(path: str | Path, option: str = "--out") -> Path:
    """``path`` can be (or become) an output file; nothing is created."""
    path = Path(path)
    if path.is_dir():
        raise CosimError(f"{option} {path} is a directory: give a file name")
    _check_parents(path, option)
    if path.exists() and not os.access(path, os.W_OK):
        raise CosimError(f"{option} {path}: no permission to overwrite it: give a writable file")
    return path


def holds_run(path: Path) -> bool:
    """Whether the directory ``path`` holds the outputs of a run or an experiment."""
    if not path.is_dir():
        return False
    if any((path / m).exists() for m in RUN_MARKERS):
        return True
    return any((child / "run.mcap").exists() for child in path.iterdir() if child.is_dir())


class RunDir:
    """``with RunDir(out, force=...):`` around everything that writes a run into ``out`` (see module doc)."""

    def __init__(self, path: str | Path, *, force: bool = False, keep_existing: bool = False,
                 option: str = "--out"):  # fmt: skip
        """``keep_existing``: earlier outputs are not a conflict (a sweep resumes in its folder)."""
        self.path = Path(path)
        self.force = force
        self.keep_existing = keep_existing
        self.option = option
        self._lock: FileLock | None = None
        self._created = False

    def __enter__(self) -> Path:
        check_dir(self.path, self.option)
        self._created = not self.path.exists()
        self.path.mkdir(parents=True, exist_ok=True)
        self._lock = FileLock(self.path / LOCK_NAME)
        try:
            self._lock.acquire(timeout=0)
        except Timeout:
            self._lock = None
            raise CosimError(f"{self.option} {self.path} is being written by another cosim run right now: wait "
                             f"for it to end or give another {self.option}") from None  # fmt: skip
        try:
            if not self.keep_existing and holds_run(self.path):
                if not self.force:
                    raise CosimError(f"{self.option} {self.path} already holds a run: add --force to replace it "
                                     f"(its old outputs are removed) or give another {self.option}")  # fmt: skip
                self._clear()
        except BaseException:
            self._release()
            raise
        return self.path

    def _clear(self) -> None:
        for entry in self.path.iterdir():
            if entry.name == LOCK_NAME:
                continue
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry)
            else:
                entry.unlink()

    def _release(self) -> None:
        if self._lock is not None:
            # unlinked while still held, so nothing is left behind; a contender that opened it meanwhile sees
            # the inode gone once it gets the lock and starts over (filelock checks that)
            (self.path / LOCK_NAME).unlink(missing_ok=True)
            self._lock.release()
            self._lock = None

    def __exit__(self, exc_type, exc, tb) -> None:
        self._release()
        if self._created and exc_type is not None and issubclass(exc_type, CosimError):
            shutil.rmtree(self.path, ignore_errors=True)  # a user error: leave nothing half-written

"""One MCAP file per run: zstd chunks, JSON messages with JSON-schema channels.

The JSON encoding, chunking and compression run in a child process by default (``background``): the
simulation process only pickles each step's messages into a pipe, so logging costs the lockstep loop little (a
thread would not help: libsumo keeps the GIL while SUMO steps). Messages keep their order (one pipe, one
writer), so the file is as deterministic as before; ``write_deferred`` moves the building of a large
payload (per-vehicle columns) to the writer too.

Chunking follows the content only, never the wall clock, so the same run gives the same bytes: a chunk is
closed when its uncompressed size reaches ``chunk_size`` or when a message is ``flush_every_s`` of
*simulated* time past the chunk's start, whichever comes first. Crash safety: each closed chunk is handed
to the OS at once, so a killed run loses at most the last ``flush_every_s`` simulated seconds;
``cosim.log.read`` reads such a file up to the last complete chunk. Ctrl-C (or SIGTERM) ends the run
through ``close()``, which writes the summary; the writer ignores both itself and, if the simulation
process is killed, writes what reached it and closes the file.
"""

from __future__ import annotations

import json
import math
import pickle
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

from mcap.writer import CompressionType, Writer

from cosim.childproc import send, start_child
from cosim.log import schemas

TOPIC_SCHEMAS = {
    "/ego/state": schemas.EGO_STATE,
    "/traffic/vehicles": schemas.TRAFFIC_VEHICLES,
    "/traffic/lights": schemas.TRAFFIC_LIGHTS,
    "/events": schemas.EVENT,
    "/scene": schemas.SCENE_UPDATE,
}


def _clean(value):
    """JSON has no NaN/inf: write them as null so every reader (Foxglove too) accepts the file."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, list):
        return [_clean(v) for v in value]
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    return value


def encode(message: dict) -> bytes:
    """A message's JSON payload: compact separators, NaN/inf as null."""
    try:
        return json.dumps(message, separators=(",", ":"), allow_nan=False).encode()
    except ValueError:  # a NaN/inf somewhere: the rare slow path
        return json.dumps(_clean(message), separators=(",", ":"), allow_nan=False).encode()


ZSTD_LEVEL = 9  # chunks compress ~10 % smaller than at zstd's default 3, at ~1 % of the writer's time


class _Zstd:
    """Stands in for the ``zstandard`` module in ``mcap.writer``, which compresses every chunk with
    ``zstandard.compress(data)`` at the default level and has no option for another."""

    _compressor = None

    @classmethod
    def compress(cls, data: bytes) -> bytes:
        if cls._compressor is None:
            import zstandard

            cls._compressor = zstandard.ZstdCompressor(level=ZSTD_LEVEL)
        return cls._compressor.compress(data)


class _File:
    """The MCAP file itself: encodes, chunks (zstd) and flushes. Lives where the bytes are written."""

    def __init__(self, path: Path, chunk_size: int, flush_every_s: float):
        import mcap.writer

        mcap.writer.zstandard = _Zstd  # every MCAP file this process writes: the same bytes for the same run
        self._fh = open(path, "wb")  # noqa: SIM115 - closed in close()
        self._writer = Writer(self._fh, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library="cosim")
        self._channels: dict[str, int] = {}
        self._flush_every_ns = round(flush_every_s * 1e9)
        self._chunk_end_ns: int | None = None  # the open chunk is closed at the first message from here on
        self.count = 0

    def channel(self, topic: str, schema: dict | None = None) -> int:
        if topic not in self._channels:
            schema = schema or TOPIC_SCHEMAS.get(topic) or schemas.GENERIC
            sid = self._writer.register_schema(schema["title"], "jsonschema", json.dumps(schema).encode())
            self._channels[topic] = self._writer.register_channel(topic, "json", sid)
        return self._channels[topic]

    def write(self, topic: str, ns: int, message, build: Callable | None = None, args: tuple = ()) -> None:
        if build is not None:
            message = build(*args)
        data = message if isinstance(message, bytes) else encode(message)
        if self._chunk_end_ns is None:
            self._chunk_end_ns = ns + self._flush_every_ns
        elif ns >= self._chunk_end_ns:  # by simulated time, so the chunk boundaries are the same every run
            self._writer.flush()  # close the chunk and hand it to the OS: a killed run keeps it
            self._chunk_end_ns = ns + self._flush_every_ns
        self._writer.add_message(
            self.channel(topic), log_time=ns, data=data, publish_time=ns, sequence=self.count
        )
        self.count += 1

    def metadata(self, name: str, data: dict[str, str]) -> None:
        self._writer.add_metadata(name, data)

    def close(self) -> None:
        self._writer.finish()
        self._fh.flush()
        self._fh.close()


def _serve(path: str, chunk_size: int, flush_every_s: float) -> None:
    """The writer process: apply the lists of (method, args) records from stdin (one per step,
    ``McapLog.end_step``) to the file until end of input."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the run decides when the log ends
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # ... also when a service manager stops every process
    out = _File(Path(path), chunk_size, flush_every_s)
    stdin = sys.stdin.buffer
    try:
        while True:
            try:
                records = pickle.load(stdin)
            except (EOFError, pickle.UnpicklingError):  # closed, or the simulation process is gone (maybe in
                break  # the middle of a record): finish the file with what came complete
            for method, args in records:
                getattr(out, method)(*args)
    finally:
        out.close()


class McapLog:
    def __init__(self, path: str | Path, *, chunk_size: int = 1024 * 1024, flush_every_s: float = 5.0,
                 background: bool = True):  # fmt: skip
        """``background`` writes from a child process (see the module doc); else in this process.
        ``flush_every_s``: a chunk spans at most this much simulated time (crash-safe flushes)."""
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.closed = False
        self.count = 0
        self.kept: dict[str, list[dict | bytes]] = {}
        self._proc: subprocess.Popen | None = None
        self._file: _File | None = None
        self._batch: list[tuple[str, tuple]] = []  # records for the writer, sent as one (end_step)
        if background:
            self._proc = start_child(f"from cosim.log.writer import _serve; _serve({str(self.path)!r}, {chunk_size}, "
                                     f"{flush_every_s!r})", replies=False)  # fmt: skip
        else:
            self._file = _File(self.path, chunk_size, flush_every_s)

    @property
    def writer_pid(self) -> int | None:
        """Process id of the background writer (None when writing in this process)."""
        return self._proc.pid if self._proc is not None else None

    def _call(self, method: str, *args) -> None:
        if self._file is not None:
            getattr(self._file, method)(*args)
            return
        self._batch.append((method, args))
        if len(self._batch) >= self.BATCH_MAX:
            self.end_step()

    BATCH_MAX = 256  # records held before they go to the writer even without end_step

    def end_step(self) -> None:
        """Send the records of the step to the writer as one pickle (one per message costs the simulation
        ~10 us each in pickling and signal masking). They are pickled only now: a message written this step
        must not change before (``write_deferred``'s args never)."""
        if not self._batch:
            return
        batch, self._batch = self._batch, []
        try:
            send(self._proc.stdin, batch, flush=False)
        except (BrokenPipeError, OSError):
            raise RuntimeError(f"the log writer of {self.path} stopped (its error is above)") from None

    def channel(self, topic: str, schema: dict | None = None) -> None:
        """Register ``topic`` now (with its own ``schema``; default: the topic's known one or a generic)."""
        self._call("channel", topic, schema)

    def keep(self, topics: list[str]) -> dict[str, list[dict | bytes]]:
        """Also keep the messages of ``topics`` in memory (``kept``), for the run's own post-processing:
        ``cosim.log.Log.of_messages`` turns them into the columns ``read`` would give, without decoding the
        whole file again."""
        for topic in topics:
            self.kept.setdefault(topic, [])
        return self.kept

    def write(self, topic: str, t_s: float, message: dict | bytes) -> None:
        """Append one message (a dict, or its JSON as ``encode`` gives it); log time = simulated time (so the
        file is deterministic)."""
        self._call("write", topic, round(t_s * 1e9), message)
        self.count += 1
        if topic in self.kept:
            self.kept[topic].append(message)

    def write_deferred(self, topic: str, t_s: float, build: Callable, *args) -> None:
        """Append the message ``build(*args)`` (a dict or JSON bytes), built by the writer: ``build`` must be a
        module-level function and ``args`` picklable and not changed afterwards (pass copies)."""
        self._call("write", topic, round(t_s * 1e9), None, build, args)
        self.count += 1
        if topic in self.kept:
            self.kept[topic].append(build(*args))

    def metadata(self, name: str, data: dict[str, str]) -> None:
        self._call("metadata", name, {k: str(v) for k, v in data.items()})

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        if self._file is not None:
            self._file.close()
            return
        try:
            self.end_step()
        except RuntimeError:
            pass  # the writer is gone: its exit status below says so
        try:
            self._proc.stdin.close()  # end of input: the writer finishes the file
        except (BrokenPipeError, OSError):
            pass
        if self._proc.wait() != 0:
            raise RuntimeError(
                f"the log writer of {self.path} failed (exit {self._proc.returncode}; error above)"
            )

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

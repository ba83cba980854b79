"""Read a cosim MCAP log into per-topic columns (numpy arrays).

Messages whose fields are lists of equal length (per-vehicle columns) are exploded into one row per item,
with the message's scalar fields repeated. A file cut short by a crash is read up to its last complete
chunk (``truncated`` says so); a damaged chunk elsewhere (CRC mismatch, bad zstd data) is a CosimError.
"""

from __future__ import annotations

import json
import struct
from collections import defaultdict
from collections.abc import Callable, Collection
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mcap.exceptions import McapError
from mcap.records import Channel, Chunk, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, StreamReader, breakup_chunk

from cosim.errors import CosimError


@dataclass
class Log:
    path: Path
    topics: dict[str, dict[str, np.ndarray]]
    counts: dict[str, int]
    metadata: dict[str, dict[str, str]]
    start_ns: int | None
    end_ns: int | None
    truncated: bool = False
    raw: dict[str, list[bytes]] = field(default_factory=dict)

    def __getitem__(self, topic: str) -> dict[str, np.ndarray]:
        return self.topics[topic]

    @classmethod
    def of_messages(cls, path: str | Path, messages: dict[str, list[dict | bytes]]) -> Log:
        """The topics of messages kept while they were written (``McapLog.keep``), as ``read`` would give
        them from the file (tests/integration/test_experiment.py checks that for the experiment's topics)."""
        decoded = {
            t: [json.loads(m) if isinstance(m, bytes) else m for m in ms] for t, ms in messages.items()
        }
        return cls(Path(path), {t: _columns(ms) for t, ms in decoded.items() if ms},
                   {t: len(ms) for t, ms in messages.items()}, {}, None, None)  # fmt: skip

    @property
    def duration_s(self) -> float:
        return 0.0 if self.start_ns is None else (self.end_ns - self.start_ns) / 1e9


def iter_messages(path: str | Path):
    """Yield (topic, log_time_ns, data bytes) and metadata records; stops quietly at a truncated tail.

    Returns via StopIteration value whether the file was truncated."""
    path = Path(path)
    channels: dict[int, Channel] = {}
    with path.open("rb") as fh:
        if fh.read(8) != b"\x89MCAP0\r\n":
            raise CosimError(f"{path} is not an MCAP file")
        fh.seek(0)
        try:
            for record in StreamReader(fh, skip_magic=False, emit_chunks=True).records:
                if isinstance(record, Chunk):
                    try:
                        inner = breakup_chunk(record, validate_crc=True)
                    except Exception as exc:  # a chunk read whole but damaged: not a crash's cut-off tail
                        raise _corrupt(path, record, exc) from None
                else:
                    inner = [record]
                for r in inner:
                    if isinstance(r, Channel):
                        channels[r.id] = r
                    elif isinstance(r, Message):
                        yield channels[r.channel_id].topic, r.log_time, r.data
                    elif isinstance(r, Metadata):
                        yield "#metadata", r.name, r.metadata
                    elif isinstance(r, Schema):
                        pass
        except (McapError, EOFError, ValueError, KeyError, struct.error):  # cut short by a crash
            return True
    return False


def _corrupt(path: Path, chunk: Chunk, exc: Exception) -> CosimError:
    what = "CRC mismatch" if isinstance(exc, CRCValidationError) else f"cannot decompress: {exc}"
    return CosimError(
        f"{path} is damaged: the chunk of messages at {chunk.message_start_time / 1e9:.1f}-"
        f"{chunk.message_end_time / 1e9:.1f} s is corrupt ({what}); re-run to get a good log or restore a copy"
    )


def _decode(path: Path, topic: str, t_ns: int, data: bytes):
    try:
        return json.loads(data)
    except ValueError:
        raise CosimError(f"{path} is damaged: a {topic} message at {t_ns / 1e9:.1f} s is not valid JSON; "
                         f"re-run to get a good log or restore a copy") from None  # fmt: skip


def _columns(messages: list[dict]) -> dict[str, np.ndarray]:
    cols: dict[str, list] = defaultdict(list)
    keys: list[str] = []
    for msg in messages:
        for k in msg:
            if k not in cols:
                keys.append(k)
                cols[k]  # noqa: B018 - create in order
    for msg in messages:
        lists = {k: v for k, v in msg.items() if isinstance(v, list)}
        n = len(next(iter(lists.values()))) if lists else 1
        if lists and any(len(v) != n for v in lists.values()):
            lists = {}  # not a column message: keep the lists as objects
            n = 1
        for k in keys:
            v = msg.get(k)
            if k in lists:
                cols[k].extend(v)
            else:
                cols[k].extend([v] * n)
    out = {}
    for k, v in cols.items():
        types = set(map(type, v))  # (bool is its own type: flags stay objects)
        if types <= _NUMERIC_TYPES and types != {type(None)} and types:
            out[k] = np.asarray([np.nan if x is None else x for x in v] if type(None) in types else v)
        else:
            out[k] = np.asarray(v, dtype=object)
    return out


_NUMERIC_TYPES = {int, float, type(None)}


def read(
    path: str | Path, topics: Collection[str] | Callable[[str], bool] | None = None, keep_raw: bool = False
) -> Log:
    """Per-topic columns of a cosim MCAP log; ``topics`` (a collection of names, or a predicate on a name)
    limits what is decoded."""
    path = Path(path)
    if not path.is_file():
        raise CosimError(f"log file {path} does not exist")
    decoded: dict[str, list[dict]] = defaultdict(list)
    raw: dict[str, list[bytes]] = defaultdict(list)
    counts: dict[str, int] = defaultdict(int)
    metadata: dict[str, dict[str, str]] = {}
    start = end = None
    wanted = topics if callable(topics) else (lambda t: True) if topics is None else topics.__contains__
    gen = iter_messages(path)
    truncated = False
    while True:
        try:
            topic, t, data = next(gen)
        except StopIteration as stop:
            truncated = bool(stop.value)
            break
        if topic == "#metadata":
            metadata[t] = dict(data)
            continue
        counts[topic] += 1
        start = t if start is None else min(start, t)
        end = t if end is None else max(end, t)
        if wanted(topic):
            decoded[topic].append(_decode(path, topic, t, data))
            if keep_raw:
                raw[topic].append(bytes(data))
    return Log(path, {k: _columns(v) for k, v in decoded.items()}, dict(counts), metadata, start, end, truncated,
               dict(raw))  # fmt: skip

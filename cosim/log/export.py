"""``cosim log export``: one topic of a run's MCAP log as CSV or JSON lines that standard tools read.

- ``json``: JSON lines, one message per line, exactly as logged (``jq``, ``pandas.read_json(lines=True)``);
  the right format for nested messages (``/scene``, ``/map``, ``/adas/events``).
- ``csv``: one row per item (column messages such as ``/traffic/vehicles`` or ``/vanet/rx`` are exploded,
  as ``cosim.log.read`` does), a header row; an object in a cell becomes dotted columns (``/adas/events``:
  ``events.system``, ``events.kind`` ...), a list that is not a column stays one cell as its JSON text
  (``/scene``'s entities); null is an empty cell, booleans ``true`` / ``false``.

Never Python repr. The file is written next to its final name and moved into place when complete.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TextIO

from cosim.errors import CosimError

FORMATS = ("csv", "json")


def _messages(path: Path, topic: str) -> Iterator[bytes]:
    from cosim.log.reader import iter_messages

    for t, _, data in iter_messages(path):
        if t == topic:
            yield bytes(data)


def _topics(path: Path) -> list[str]:
    from cosim.log.reader import iter_messages

    return sorted({t for t, _, _ in iter_messages(path) if t != "#metadata"})


def _flat(prefix: str, value, out: dict) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            _flat(f"{prefix}.{k}", v, out)
    else:
        out[prefix] = value


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "" if not math.isfinite(value) else repr(value)
    if isinstance(value, (list, tuple)):
        return json.dumps(value, separators=(",", ":"), allow_nan=False)
    if isinstance(value, str):
        return value
    return str(value)


def _rows(message: dict) -> list[dict]:
    """A message's rows, as ``cosim.log.read`` explodes them: lists of equal length are columns (one row
    per item, the scalar fields repeated); otherwise the message is one row and a list stays a cell."""
    lists = {k: v for k, v in message.items() if isinstance(v, list)}
    n = len(next(iter(lists.values()))) if lists else 1
    if not lists or any(len(v) != n for v in lists.values()):
        return [message]
    return [{k: (v[i] if k in lists else v) for k, v in message.items()} for i in range(n)]


def write_csv(path: Path, topic: str, out: TextIO) -> int:
    """Rows of ``topic`` as CSV; returns the number of rows."""
    rows = []
    header: dict[str, None] = {}
    for data in _messages(path, topic):
        for item in _rows(json.loads(data)):
            row: dict = {}
            for k, v in item.items():
                _flat(k, v, row)
            header.update(dict.fromkeys(row))
            rows.append(row)
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow([_cell(row.get(k)) for k in header])
    return len(rows)


def write_json_lines(path: Path, topic: str, out: TextIO) -> int:
    """Messages of ``topic`` as JSON lines; returns the number of messages."""
    n = 0
    for data in _messages(path, topic):
        out.write(data.decode())
        out.write("\n")
        n += 1
    return n


def export_topic(path: str | Path, topic: str, out: str | Path | None = None, fmt: str = "csv") -> int:
    """Write ``topic`` of the log at ``path`` to ``out`` (stdout if None) as ``fmt`` (csv | json)."""
    path = Path(path)
    if fmt not in FORMATS:
        raise CosimError(f"unknown export format {fmt!r} (formats: {', '.join(FORMATS)})")
    if not path.is_file():
        raise CosimError(f"log file {path} does not exist")
    topics = _topics(path)
    if topic not in topics:
        raise CosimError(f"{path} has no topic {topic} (topics: {', '.join(topics)})")
    write = write_csv if fmt == "csv" else write_json_lines
    if out is None:
        return write(path, topic, sys.stdout)
    out = Path(out)
    buf = io.StringIO()
    n = write(path, topic, buf)
    tmp = out.with_name(f".{out.name}.part")
    try:
        tmp.write_text(buf.getvalue(), newline="")
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    return n

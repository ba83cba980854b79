"""One MCAP file per run: zstd chunks, JSON messages with JSON-schema channels.

Crash safety: chunks are small and the writer is flushed (chunk closed, bytes handed to the OS) every
``flush_every_s`` of wall time, so a killed process loses at most that much; ``cosim.log.read`` reads such
a file up to the last complete chunk. Ctrl-C ends the run through ``close()``, which writes the summary.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

from mcap.writer import CompressionType, Writer

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


class McapLog:
    def __init__(self, path: str | Path, *, chunk_size: int = 256 * 1024, flush_every_s: float = 2.0):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fh = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        self._writer = Writer(self._fh, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library="cosim")
        self._channels: dict[str, int] = {}
        self._flush_every_s = flush_every_s
        self._last_flush = time.monotonic()
        self.closed = False
        self.count = 0

    def channel(self, topic: str, schema: dict | None = None) -> int:
        if topic not in self._channels:
            schema = schema or TOPIC_SCHEMAS.get(topic) or schemas.GENERIC
            sid = self._writer.register_schema(schema["title"], "jsonschema", json.dumps(schema).encode())
            self._channels[topic] = self._writer.register_channel(topic, "json", sid)
        return self._channels[topic]

    def write(self, topic: str, t_s: float, message: dict) -> None:
        """Append one message; log time = simulated time (so the file is deterministic)."""
        ns = round(t_s * 1e9)
        try:
            data = json.dumps(message, separators=(",", ":"), allow_nan=False).encode()
        except ValueError:  # a NaN/inf somewhere: the rare slow path
            data = json.dumps(_clean(message), separators=(",", ":"), allow_nan=False).encode()
        self._writer.add_message(
            self.channel(topic), log_time=ns, data=data, publish_time=ns, sequence=self.count
        )
        self.count += 1
        now = time.monotonic()
        if now - self._last_flush > self._flush_every_s:
            self._last_flush = now
            self._writer.flush()

    def metadata(self, name: str, data: dict[str, str]) -> None:
        self._writer.add_metadata(name, {k: str(v) for k, v in data.items()})

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self._writer.finish()
            self._fh.flush()
            self._fh.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

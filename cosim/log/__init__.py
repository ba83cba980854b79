"""MCAP logging: one file per run, readable by Foxglove and by ``cosim.log.read``."""

from cosim.log.reader import Log, read
from cosim.log.writer import McapLog

__all__ = ["Log", "McapLog", "read"]

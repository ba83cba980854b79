"""The VANET phase: every vehicle a station, one lockstep step of CAMs over SOTDMA through the aether.

Ports: the run's VANET parameters, the shared building footprints, its own random stream; ``step`` reads
the snapshot only.
"""

from __future__ import annotations

import numpy as np

from cosim.buildings import Buildings
from cosim.log.columns import json_columns
from cosim.vanet import VanetLayer, VanetParams, VanetStepResult
from cosim.world import World

_DECIMALS = {
    "distance_m": 2,
    "rx_power_dbm": 2,
    "t_s": 4,
    "gen_t_s": 4,
    "busy_ratio": 4,
    "airtime_ratio": 4,
    "cbr_mean": 4,
    "cbr_p95": 4,
    "cbr_ego": 4,
}


class VanetPhase:
    def __init__(self, params: VanetParams, buildings: Buildings, rng: np.random.Generator, *, log: bool):
        """``log``: build the step's log messages (``/vanet/*``)."""
        self.layer = VanetLayer(params, buildings, rng)
        self.log = log

    def step(self, world: World, step_s: float) -> tuple[VanetStepResult, dict[str, object]]:
        """One radio step on the snapshot: the layer's result and the log messages, by topic."""
        res = self.layer.step(world, world.step, step_s)
        topics: dict[str, object] = {}
        if self.log:
            for topic, cols in res.columns().items():
                n = len(next(iter(cols.values()))) if cols else 0
                if n:
                    topics[topic] = json_columns(cols, _DECIMALS)
        return res, topics

    def ego_obu(self, world: World):
        """The ego's OBU (what it has heard), or None."""
        return self.layer.obu_view(world)

    def vehicle_of_station(self, world: World, station: int | None) -> str:
        """The vehicle id behind a station id (for the log; system B itself never uses it)."""
        if station is None:
            return ""
        ids = self.layer.station_id
        hits = np.flatnonzero(ids[: world.capacity] == station)
        return next((world.ids[h] for h in hits if world.valid[h]), "") or ""

    def close(self) -> None:
        pass

"""The VANET phase: every vehicle a station, one lockstep step of CAMs over SOTDMA through the aether.

Ports: the run's VANET parameters, the shared building footprints, its own random stream; ``step`` reads
the snapshot only. A run drives it as ``begin`` (after which the ego's OBU view of the step is readable) and
``finish`` (the step's result and log messages); ``cosim.phases.vanet_process.VanetProcess`` does the same
with the layer in a second process, which finishes the step while this one goes on.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

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


def _logged_tx(tx: dict[str, np.ndarray], rx: dict[str, np.ndarray], mode: str) -> dict[str, np.ndarray]:
    """The rows of ``tx`` that ``vanet.tx_log`` logs: "rx" keeps the transmissions with a reception row
    this step (a row of /vanet/rx refers to a transmission of the same step: same sender, frame, slot and
    CAM generation time), "none" none."""
    if mode == "none" or not len(tx["sender_slot"]):
        return {k: v[:0] for k, v in tx.items()}

    def keys(cols):
        return np.stack([cols["sender_slot"].astype(np.int64), cols["frame"].astype(np.int64),
                         cols["slot"].astype(np.int64), np.round(cols["gen_t_s"] * 1e3).astype(np.int64)], 1)  # fmt: skip

    if not len(rx["sender_slot"]):
        return {k: v[:0] for k, v in tx.items()}
    a, b = keys(tx), keys(rx)
    view = np.dtype((np.void, a.dtype.itemsize * a.shape[1]))
    keep = np.isin(np.ascontiguousarray(a).view(view).ravel(), np.ascontiguousarray(b).view(view).ravel())
    return {k: v[keep] for k, v in tx.items()}


class VanetPhase:
    def __init__(self, params: VanetParams, buildings: Buildings, rng: np.random.Generator, *, log: bool,
                 map_store: Path | None = None):  # fmt: skip
        """``log``: build the step's log messages (``/vanet/*``); ``map_store``: see ``VanetLayer``."""
        self.layer = VanetLayer(params, buildings, rng, map_store)
        self.log = log
        self.tx_log = params.tx_log
        self._done: tuple[VanetStepResult, dict[str, object]] | None = None

    def begin(self, world: World, step_s: float) -> None:
        """Run the step on the snapshot (its result waits for ``finish``)."""
        self._done = self.step(world, step_s)

    def finish(self) -> tuple[VanetStepResult, dict[str, object]]:
        """The result and the log messages of the step ``begin`` ran."""
        done, self._done = self._done, None
        return done

    def step(self, world: World, step_s: float, on_view: Callable[[], None] | None = None
             ) -> tuple[VanetStepResult, dict[str, object]]:  # fmt: skip
        """One radio step on the snapshot: the layer's result and the log messages, by topic (``on_view``:
        see ``VanetLayer.step``)."""
        res = self.layer.step(world, world.step, step_s, on_view)
        topics: dict[str, object] = {}
        if self.log:
            columns = res.columns()
            if self.tx_log != "all":
                columns["/vanet/tx"] = _logged_tx(columns["/vanet/tx"], columns["/vanet/rx"], self.tx_log)
            for topic, cols in columns.items():
                n = len(next(iter(cols.values()))) if cols else 0
                if n:
                    topics[topic] = json_columns(cols, _DECIMALS)
        return res, topics

    def ego_obu(self, world: World):
        """The ego's OBU (what it has heard), or None."""
        return self.layer.obu_view(world)

    def vehicle_of_station(self, world: World, station: int | None) -> str:
        return vehicle_of_station(world, self.layer.station_id, station)

    def close(self) -> None:
        self.layer.close()


def vehicle_of_station(world: World, station_ids: np.ndarray, station: int | None) -> str:
    """The vehicle id behind a station id (for the log; system B itself never uses it)."""
    if station is None:
        return ""
    hits = np.flatnonzero(station_ids[: world.capacity] == station)
    return next((world.ids[h] for h in hits if world.valid[h]), "") or ""

"""Lockstep VANET layer: ETSI CAMs over SOTDMA through a shadowing radio channel, and the on-board unit.

Pure numpy + shapely; no simulator handle. Entry point: ``VanetLayer(params, buildings, rng).step(world,
step_index, dt_s)``. Metrics and the report work on logged columns (``metrics``, ``report``).
"""

from cosim.vanet.cam import CamParams
from cosim.vanet.channel import OUTCOME_NAMES, ChannelParams
from cosim.vanet.layer import VanetLayer, VanetParams, VanetStepResult
from cosim.vanet.obu import (
    LeaderCriteria,
    Neighbour,
    NeighbourTable,
    ObuParams,
    ObuView,
    OwnState,
    ReceivedCam,
)
from cosim.vanet.sotdma import SotdmaParams

__all__ = [
    "OUTCOME_NAMES",
    "CamParams",
    "ChannelParams",
    "LeaderCriteria",
    "Neighbour",
    "NeighbourTable",
    "ObuParams",
    "ObuView",
    "OwnState",
    "ReceivedCam",
    "SotdmaParams",
    "VanetLayer",
    "VanetParams",
    "VanetStepResult",
]

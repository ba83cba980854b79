"""The ego car (user-controlled vehicle) simulated in MuJoCo.

Pure parts (parameters, state, powertrain) import without MuJoCo; ``EgoCar`` and the model builders
(``build_mjcf``, ``compile_model``) load MuJoCo on first use. This package and nothing else imports mujoco
for vehicle physics. Poses are in MuJoCo convention (car centre, yaw ccw from +x); ``cosim.frames``
converts to SUMO's front bumper and compass angle (``EgoState.to_sumo``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from cosim.ego_mujoco.params import (
    BrakeParams,
    CarParams,
    Obstacle,
    PowertrainParams,
    StaticBox,
    StaticMesh,
    TyreParams,
)
from cosim.ego_mujoco.state import EgoState

if TYPE_CHECKING:
    from cosim.ego_mujoco.car import build_mjcf, compile_model
    from cosim.ego_mujoco.physics import EgoCar

__all__ = [
    "BrakeParams",
    "CarParams",
    "EgoCar",
    "EgoState",
    "Obstacle",
    "PowertrainParams",
    "StaticBox",
    "StaticMesh",
    "TyreParams",
    "build_mjcf",
    "compile_model",
]

_LAZY = {
    "EgoCar": "cosim.ego_mujoco.physics",
    "build_mjcf": "cosim.ego_mujoco.car",
    "compile_model": "cosim.ego_mujoco.car",
}


def __getattr__(name: str) -> Any:  # PEP 562: import MuJoCo only when the simulator is needed
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(module), name)

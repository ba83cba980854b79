"""Driver-assistance systems: A = rear-mounted stereo distance warning, B = V2V time-gap warning.

Both are pure (no simulator handle), stateful per run (``update`` once per step), and record their
display transitions as ``AdasEvent`` for the log.
"""

from cosim.adas.common import AdasEvent, VehicleState, along_heading_gap_m, time_gap_s
from cosim.adas.config import AdasConfig, System
from cosim.adas.rear_stereo import RearStereoWarning, RearWarningOutput, RearWarningParams, StereoCameraParams
from cosim.adas.v2v_timegap import (
    CamData,
    TimeGapOutput,
    TimeGapParams,
    V2VTimeGapWarning,
    ground_truth_gap_m,
    ground_truth_time_gap,
)

__all__ = [
    "AdasConfig",
    "AdasEvent",
    "CamData",
    "RearStereoWarning",
    "RearWarningOutput",
    "RearWarningParams",
    "StereoCameraParams",
    "System",
    "TimeGapOutput",
    "TimeGapParams",
    "V2VTimeGapWarning",
    "VehicleState",
    "along_heading_gap_m",
    "ground_truth_gap_m",
    "ground_truth_time_gap",
    "time_gap_s",
]

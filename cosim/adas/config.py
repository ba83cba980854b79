"""The assistance systems' run config (``adas:`` in a run config): which one the driver sees, and both
systems' parameters."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from cosim.adas.rear_stereo import RearWarningParams
from cosim.adas.v2v_timegap import TimeGapParams
from cosim.vanet.obu import LeaderCriteria

System = Literal["none", "A", "B"]


@dataclass(frozen=True)
class AdasConfig:
    system: System = "none"  # what the driver sees when no experiment protocol decides
    rear: RearWarningParams = field(default_factory=RearWarningParams)  # system A
    v2v: TimeGapParams = field(default_factory=TimeGapParams)  # system B
    # how system B's OBU picks the vehicle to show the gap to: the paper's criteria a-d and g; e (it
    # accelerates less) and f (gap below 2 s) decide a warning, not who the leader is
    leader_criteria: LeaderCriteria = field(
        default_factory=lambda: LeaderCriteria(accel_smaller=False, time_gap=False)
    )
    leader_search_m: float = 150.0  # ground-truth leader search distance [m]

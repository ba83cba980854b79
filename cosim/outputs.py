"""What one step of the phases produced: a frozen, typed record (``Simulation.outputs`` after ``step()``).

The log phase and the 3D view read its fields; nothing is passed between phases by string keys.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class StepOutputs:
    # the VANET phase's cosim.vanet.VanetStepResult (None: radio off)
    vanet: Any = None
    # cosim.phases.adas's record of the step (the /adas/state message; None: no ego this step)
    adas: dict | None = None
    # what the driver is shown: Percept kwargs (sys_a_lit | sys_b_gap_s, sys_b_level); empty: nothing
    adas_displays: dict = field(default_factory=dict)
    # the ego controller's additions to /ego/state (pedals, steering, its percept)
    ego_log: dict = field(default_factory=dict)
    # messages the phases log this step, topic -> message, in the order they were produced
    log: dict[str, Any] = field(default_factory=dict)


class StepBuffer:
    """The outputs of the step being run, filled phase by phase and frozen before the log phase."""

    def __init__(self) -> None:
        self.vanet = None
        self.adas: dict | None = None
        self.adas_displays: dict = {}
        self.ego_log: dict = {}
        self.log: dict[str, Any] = {}

    def freeze(self) -> StepOutputs:
        return StepOutputs(self.vanet, self.adas, self.adas_displays, self.ego_log, self.log)

"""ETSI reactive Decentralized Congestion Control (transmit rate control), off by default.

ETSI TS 102 687 V1.2.1 (2018-04), Annex A, Table A.2 ("reactive approach", T_on <= 500 us: a CAM of up to
~300 B at 6 Mbit/s lasts ~450 us): each station maps the channel busy ratio it measured (CBR, per
``cbr_period_ms`` = 100 ms, §5.2) onto a state, and the state onto the minimum gap T_off between two of its
packets:

    state        CBR                T_off [ms]
    Relaxed      < 0.30             50
    Active 1     [0.30, 0.40)       100
    Active 2     [0.40, 0.50)       200
    Active 3     [0.50, 0.65)       250
    Restrictive  >= 0.65            1000

Transitions are gradual, one state per CBR evaluation (TS 102 687 V1.2.1 §A.2: "state changes shall only
be made to adjacent states"), as vanetza's ``GradualStateMachine`` implements it. A MAC that supports DCC
(``mac_80211p``, ``mac_cv2x``) hands a CAM to the air no earlier than T_off after the station's previous
transmission; the CAM waits (and a newer CAM replaces it, as in the layer).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DccParams:
    enabled: bool = False  # reactive DCC is off by default (TS 102 687 is optional for CAM studies)
    cbr_limits: tuple[float, ...] = (0.30, 0.40, 0.50, 0.65)  # lower CBR limit of states 1.. (Table A.2)
    t_off_ms: tuple[int, ...] = (50, 100, 200, 250, 1000)  # T_off per state (Table A.2) [ms]

    def __post_init__(self) -> None:
        if len(self.t_off_ms) != len(self.cbr_limits) + 1:
            raise ValueError("dcc: t_off_ms needs one entry more than cbr_limits")
        if list(self.cbr_limits) != sorted(self.cbr_limits) or not all(0 < c < 1 for c in self.cbr_limits):
            raise ValueError("dcc.cbr_limits must be ascending within (0, 1)")
        if any(t < 0 for t in self.t_off_ms):
            raise ValueError("dcc.t_off_ms must be >= 0")


class ReactiveDcc:
    """Per-station DCC state (arrays indexed by station key)."""

    def __init__(self, params: DccParams, capacity: int = 0):
        self.p = params
        self.capacity = 0
        self.state = np.zeros(0, dtype=np.int8)
        self.last_tx_us = np.zeros(0, dtype=np.int64)
        self._t_off_us = np.asarray(params.t_off_ms, dtype=np.int64) * 1000
        self.ensure_capacity(capacity)

    def ensure_capacity(self, capacity: int) -> None:
        if capacity <= self.capacity:
            return
        state = np.zeros(capacity, dtype=np.int8)
        last = np.full(capacity, np.iinfo(np.int64).min // 4, dtype=np.int64)
        state[: self.capacity] = self.state
        last[: self.capacity] = self.last_tx_us
        self.state, self.last_tx_us, self.capacity = state, last, capacity

    def start(self, stations: np.ndarray) -> None:
        self.state[stations] = 0
        self.last_tx_us[stations] = np.iinfo(np.int64).min // 4

    def earliest_us(self, stations: np.ndarray) -> np.ndarray:
        """Earliest time each station may transmit again [us] (no limit when DCC is off)."""
        if not self.p.enabled:
            return np.full(np.size(stations), np.iinfo(np.int64).min // 4, dtype=np.int64)
        return self.last_tx_us[stations] + self._t_off_us[self.state[stations]]

    def sent(self, stations: np.ndarray, t_us: np.ndarray) -> None:
        self.last_tx_us[stations] = t_us

    def update(self, stations: np.ndarray, cbr: np.ndarray) -> None:
        """One CBR evaluation per station: move at most one state towards the state of this CBR."""
        if not self.p.enabled or np.size(stations) == 0:
            return
        target = np.searchsorted(np.asarray(self.p.cbr_limits), np.asarray(cbr), side="right")
        cur = self.state[stations].astype(np.int64)
        self.state[stations] = (cur + np.sign(target - cur)).astype(np.int8)

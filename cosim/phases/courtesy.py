"""A priority car lets the participant in after a long wait at a yield line (limited priority).

At a give-way or stop line onto a busy road, a driver who has waited long is let in: a driver on the
priority road slows and stops short of the junction. Troutbeck & Kako ("Limited priority merge at
unsignalized intersections", Transp. Res. A 33 (1999)) observed and modelled it; SUMO's own cars get in
the same way by their impatience (``cosim.phases.impatience``: with time, a queue head accepts gaps that
make priority traffic brake). The participant's gap acceptance (``cosim.driver.gap_acceptance``) falls
only to the follow-up headway, and a stream that never leaves one held the lead and the ego at Monaco
-166149542#0 for 30 s together and the ego 30-50 s more alone (experiment, every participant's route):
the priority cars that turned in meanwhile came between the lead and the ego.

After ``COURTESY_AFTER_S`` first in line (the lead with the ego queued behind it, or the ego alone), the
nearest priority car approaching within ``COURTESY_LOOK_M`` that can still stop comfortably short of the
conflict (``COURTESY_DECEL_MPS2``) is asked to: its speed is capped so that it stops ``STOP_SHORT_M``
before it (at its line when that spot is inside the junction; a car already in one is not asked), and held
there until the ego is through the junction, its rear past the junction's end on its path (both of the pair
go through), or ``COURTESY_HOLD_S`` at most. Standing, it is no foe
(``cosim.phases.ego.priority_gap_s``); other priority traffic still is. Each ask is a ``courtesy_yield``
event. The wait and the ask are assumptions of this simulator (no measured rate): ``COURTESY_AFTER_S``
lies between a typical wait for a gap (HCM 2010: 10-25 s of control delay for LOS B-C at a two-way stop)
and the lead's ``YIELD_TOGETHER_S``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

from cosim.world import EGO_ID, LEAD_ID, SumoEvent, World

COURTESY_AFTER_S = 20.0  # first in line this long at a yield line, the waiting driver is let in [s]
COURTESY_LOOK_M = 80.0  # the priority car asked is at most this far from the conflict [m]
COURTESY_DECEL_MPS2 = 2.5  # ... and can stop short of it braking at this (a comfortable stop) [m/s^2]
STOP_SHORT_M = 6.0  # it stops this far before the conflict [m] ...
# ... or, when that is inside the junction, this far before its line: standing in a wide junction it was in
# the way of the other priority movements, which the participant then waited for (graphhopper's Beatty,
# US-95 at 140889506, seed 2: asked 26 m before the conflict, it stood on its internal lane, a car behind it
# in the junction was the participant's foe, and all three waited 28 s, until COURTESY_HOLD_S let it go)
LINE_SPARE_M = 0.5
# it stands until the ego is past the line, at most this long: let go after 15 s, while crossing traffic
# from the other side still held the lead, the car came between the lead and the ego itself (Monaco seed 2)
COURTESY_HOLD_S = 30.0
MOVING_MPS = 1.0  # a priority car slower than this is queued, not approaching


class CourtesyBridge(Protocol):
    """What the courtesy asks SUMO and tells it (``cosim.sumo_bridge.SumoBridge`` provides it)."""

    def yield_foes(self, vid: str, lookahead_m: float) -> list[tuple[str, float, float, float, bool]]: ...

    def junction_ahead(self, vid: str) -> tuple[float, float] | None: ...

    def cap_speed(self, vid: str, speed_mps: float | None) -> None: ...


class CourtesyYield:
    """The priority car stopping for the participant (at most one at a time). Ports: SUMO's operations
    (``bridge``), the step length and ``emit`` for its events; ``ask`` picks the car, ``hold`` runs each step
    (given the ego's front on its path), ``car`` is the one standing for them."""

    def __init__(self, *, bridge: CourtesyBridge, step_s: float, emit: Callable[[SumoEvent], None]):
        self.bridge = bridge
        self.step_s = step_s
        self.emit = emit
        self.car: str | None = None
        self._to_stop_m = 0.0  # how far the car may still drive before it stands [m]
        self._since = 0.0
        self._line_s = 0.0  # the yield line on the ego's path [m]
        self._clear_s = 0.0  # ... and where the path leaves that junction [m]
        self._asked_at: set[tuple[str, float]] = set()  # (who, line) asked once each

    def ask(self, w: World, vid: str, line_dist_m: float, line_s_m: float, junction: str,
            clear_s_m: float | None = None) -> None:  # fmt: skip
        """``vid`` has waited first in line ``line_dist_m`` before the line at ``line_s_m`` on the ego's path
        (``junction``, which the path leaves at ``clear_s_m``; default: the line): ask the nearest priority
        car that can still stop comfortably to stop short."""
        key = (vid, round(line_s_m))
        if self.car is not None or key in self._asked_at:
            return
        best = None
        for foe, _, foe_dist, _, held_back in self.bridge.yield_foes(vid, line_dist_m + 5.0):
            slot = w.slot_of.get(foe)
            if slot is None or held_back or foe_dist > COURTESY_LOOK_M or foe in (EGO_ID, LEAD_ID):
                continue
            v = float(w.speed_mps[slot])
            if v < MOVING_MPS:
                continue  # queued: it goes first
            ahead = self.bridge.junction_ahead(foe)
            if ahead is None:
                continue  # already in a junction: it goes first
            room = _short_of_the_junction(foe_dist - STOP_SHORT_M, ahead)
            if room < v * v / (2.0 * COURTESY_DECEL_MPS2):
                continue  # too near to stop comfortably: it goes first
            if best is None or foe_dist < best[1]:
                best = (foe, foe_dist, room)
        if best is None:
            return
        self._asked_at.add(key)
        self.car, self._since, self._line_s = best[0], w.t_s, line_s_m
        self._clear_s = line_s_m if clear_s_m is None else max(line_s_m, clear_s_m)
        self._to_stop_m = best[2]
        self.emit(SumoEvent("courtesy_yield", self.car, f"stops for the {vid} at {junction}", best[1]))
        self.hold(w, None)

    def hold(self, w: World, ego_front_s_m: float | None, ego_length_m: float = 0.0) -> None:
        """Keep the car stopping short of the conflict; let it go once the ego (front at ``ego_front_s_m``,
        ``ego_length_m`` long) is through the junction, after COURTESY_HOLD_S, or when it has left the
        simulation. Let go as soon as the ego's front passed the line, the car pulled out into the ego turning
        left in the junction behind the lead (Krems 327615515, make experiment P3 system_B, with the one-way
        merge spread)."""
        if self.car is None:
            return
        slot = w.slot_of.get(self.car)
        passed = ego_front_s_m is not None and ego_front_s_m - ego_length_m > self._clear_s
        if slot is None or passed or w.t_s - self._since >= COURTESY_HOLD_S:
            if slot is not None:
                self.bridge.cap_speed(self.car, None)
            self.car = None
            return
        self._to_stop_m = max(0.0, self._to_stop_m - float(w.speed_mps[slot]) * self.step_s)
        ahead = self.bridge.junction_ahead(self.car)  # asked a junction upstream, it has come to the next one
        if ahead is not None:
            self._to_stop_m = max(0.0, _short_of_the_junction(self._to_stop_m, ahead))
        self.bridge.cap_speed(self.car, math.sqrt(2.0 * COURTESY_DECEL_MPS2 * self._to_stop_m))


def _short_of_the_junction(to_stop_m: float, ahead: tuple[float, float]) -> float:
    """Where a car stops: ``to_stop_m`` ahead, or at its line when that spot is in the junction ahead of it
    (``ahead``: metres to its line, metres through the junction)."""
    line_m, passage_m = ahead
    return line_m - LINE_SPARE_M if line_m - LINE_SPARE_M < to_stop_m < line_m + passage_m else to_stop_m

"""The route the ego and the lead vehicle follow, extended while they drive so that it never runs out.

The scenario fixes the start of the route (the paper's predefined path, ``demand.ego_route_length_m``).
Whenever less than ``EXTEND_AHEAD_M`` of it is left ahead of the ego, another A* leg to a random
destination is appended (SUMO's router at run time, the same no-hairpin rules as the predefined route:
``cosim.scenario.demand.RouteChainer``), and the lead's route in SUMO gets the same edges. A run of any
duration on any map, small ones included, therefore always has road ahead.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np

from cosim.scenario.demand import RouteChainer
from cosim.world import LEAD_ID, SumoEvent, World

EXTEND_AHEAD_M = 2000.0  # another leg is appended when less than this is left ahead of the ego [m]
RETRY_S = 10.0  # after a batch without a usable leg, the next try waits this long [s]


class RouteBridge(Protocol):
    """What the route extension asks SUMO (``cosim.sumo_bridge.SumoBridge`` provides it)."""

    def find_route(self, origin: str, destination: str) -> list[str]: ...

    def extend_route(self, vid: str, edges: list[str]) -> bool: ...


class EgoRoute:
    """Ports: the route's edge list (extended in place: the ego's controller and the lead share it), its
    random stream (``cosim.seeds`` "route"), the drivable edges (a callable: computed only when a leg is
    needed), SUMO's router and the lead's route in SUMO (``bridge``), the snapshot (``world``: the time and
    whether the lead is in), whether there is a lead, and ``emit`` for its events of the step.

    The ego's controller calls ``step`` (``extend_if_short``) with what is left of the route ahead of it."""

    def __init__(self, edges: list[str], *, rng: np.random.Generator, drivable_edges: Callable[[], list],
                 bridge: RouteBridge, world: World, emit: Callable[[SumoEvent], None], lead: bool):  # fmt: skip
        self.edges = edges  # shared with the ego's controller and the lead
        self.rng = rng
        self._drivable_edges = drivable_edges
        self.bridge = bridge
        self.world = world
        self.emit = emit
        self.lead = lead
        self._chainer: RouteChainer | None = None
        self._lead_pending: list[str] = []  # appended edges SUMO has not taken for the lead yet
        self._next_try_s = 0.0
        self.extensions = 0

    @property
    def chainer(self) -> RouteChainer:
        if self._chainer is None:  # the network's drivable part, once per run and only when needed
            self._chainer = RouteChainer(self._drivable_edges())
        return self._chainer

    def step(self, ahead_m: float) -> bool:
        """Append a leg when less than ``EXTEND_AHEAD_M`` is left ahead of the ego; True when it did."""
        if self._lead_pending:
            self._give_lead_pending()
        t = self.world.t_s
        if ahead_m >= EXTEND_AHEAD_M or t < self._next_try_s:
            return False
        n = len(self.edges)
        added = self.chainer.extend(self.edges, self.rng, self._legs)
        if not added:
            self._next_try_s = t + RETRY_S
            self.emit(SumoEvent("route_not_extended", "ego", f"{ahead_m:.0f} m left", ahead_m))
            return False
        self.extensions += 1
        new = self.edges[n:]
        self.emit(SumoEvent("route_extended", "ego", f"+{len(new)} edges to {new[-1]}", added))
        if self.lead:
            self._lead_pending += new
            self._give_lead_pending()
        return True

    extend_if_short = step  # the name the ego's controller (cosim.phases.ego) calls it by

    def _legs(self, pairs: list[tuple[str, str]]) -> dict[tuple[str, str], list[str]]:
        legs = {}
        for origin, dest in pairs:
            edges = self.bridge.find_route(origin, dest)
            if edges:
                legs[(origin, dest)] = edges
        return legs

    def _give_lead_pending(self) -> None:
        if LEAD_ID not in self.world.slot_of:
            return
        if self.bridge.extend_route(LEAD_ID, self._lead_pending):
            self._lead_pending = []

    def close(self) -> None:
        pass

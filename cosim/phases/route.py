"""The route the ego and the lead vehicle follow, extended while they drive so that it never runs out.

The scenario fixes the start of the route (the paper's predefined path, ``demand.ego_route_length_m``).
Whenever less than ``EXTEND_AHEAD_M`` of it is left ahead of the ego, another A* leg to a random
destination is appended (SUMO's router at run time, the same no-hairpin rules as the predefined route:
``cosim.scenario.demand.RouteChainer``), and the lead's route in SUMO gets the same edges. A run of any
duration on any map, small ones included, therefore always has road ahead.
"""

from __future__ import annotations

from cosim.scenario.demand import RouteChainer
from cosim.seeds import stream
from cosim.world import LEAD_ID, SumoEvent

EXTEND_AHEAD_M = 2000.0  # another leg is appended when less than this is left ahead of the ego [m]
RETRY_S = 10.0  # after a batch without a usable leg, the next try waits this long [s]


class EgoRoute:
    def __init__(self, sim):
        self.sim = sim
        self.edges: list[str] = sim.ego_route  # shared with the ego's controller and the lead
        self.rng = stream(sim.config.seed, "route")
        self._chainer: RouteChainer | None = None
        self._lead_pending: list[str] = []  # appended edges SUMO has not taken for the lead yet
        self._next_try_s = 0.0
        self.extensions = 0

    @property
    def chainer(self) -> RouteChainer:
        if self._chainer is None:  # the network's drivable part, once per run and only when needed
            self._chainer = RouteChainer(self.sim.drivable_edges)
        return self._chainer

    def extend_if_short(self, ahead_m: float) -> bool:
        """Append a leg when less than ``EXTEND_AHEAD_M`` is left ahead of the ego; True when it did."""
        if self._lead_pending:
            self._give_lead_pending()
        t = self.sim.world.t_s
        if ahead_m >= EXTEND_AHEAD_M or t < self._next_try_s:
            return False
        n = len(self.edges)
        added = self.chainer.extend(self.edges, self.rng, self._legs)
        if not added:
            self._next_try_s = t + RETRY_S
            self.sim.events.append(SumoEvent("route_not_extended", "ego", f"{ahead_m:.0f} m left", ahead_m))
            return False
        self.extensions += 1
        new = self.edges[n:]
        self.sim.events.append(SumoEvent("route_extended", "ego", f"+{len(new)} edges to {new[-1]}", added))
        if self.sim.lead is not None:
            self._lead_pending += new
            self._give_lead_pending()
        return True

    def _legs(self, pairs: list[tuple[str, str]]) -> dict[tuple[str, str], list[str]]:
        bridge = self.sim.bridge
        legs = {}
        for origin, dest in pairs:
            edges = bridge.find_route(origin, dest)
            if edges:
                legs[(origin, dest)] = edges
        return legs

    def _give_lead_pending(self) -> None:
        if LEAD_ID not in self.sim.world.slot_of:
            return
        if self.sim.bridge.extend_route(LEAD_ID, self._lead_pending):
            self._lead_pending = []

"""The route the ego and the lead vehicle follow, extended while they drive so that it never runs out.

The scenario fixes the start of the route (the paper's predefined path, ``demand.ego_route_length_m``).
Whenever less than ``EXTEND_AHEAD_M`` of it is left ahead of the ego, another A* leg to a random
destination is appended (SUMO's router at run time, the same no-hairpin rules as the predefined route:
``cosim.scenario.demand.RouteChainer``), and the lead's route in SUMO gets the same edges. A run of any
duration on any map, small ones included, therefore always has road ahead.

The lead also drives it like a driver who sees a jam ahead: every ``REPLAN_EVERY_S`` it looks for a stalled
queue on the route within ``JAM_LOOK_M`` (a queue whose front car has waited longer than a red light lasts),
and where SUMO's router finds a way round it that is expected to save ``REPLAN_GAIN_S``, the route takes
it: the ego's path, the ego's twin and the lead in SUMO all get the new edges (event ``route_replanned``).
Without it the pair joined whatever queue SUMO's own traffic built on their way and stood in it for minutes
(Krems, seed 1, 300 s: the ego drove 547 m; with four ways round, 1218 m).
Standing in the queue before the stalled edge itself, the pair leaves from the lane it is in, and the cars
ahead of it there that were to join the same queue turn off first (event ``jam_diverted``). A queue that
forms behind the lead it cannot go round.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np

from cosim.scenario.demand import RouteChainer
from cosim.world import EGO_ID, LEAD_ID, SumoEvent, World

EXTEND_AHEAD_M = 2000.0  # another leg is appended when less than this is left ahead of the ego [m]
RETRY_S = 10.0  # after a batch without a usable leg, the next try waits this long [s]

REPLAN_EVERY_S = 5.0  # the lead looks for a stalled queue ahead this often [s]
JAM_LOOK_M = 600.0  # ... this far ahead of it [m]
# a queue is stalled when the front car of every lane onward has waited this long within SUMO's waiting-time
# memory (100 s; creeping does not restart it) with at least STALL_MIN_HALTING cars halting: longer than
# the reds on the benchmark maps (45-57 s), so a queue at a light that clears each cycle is not one
STALL_WAIT_S = 60.0
STALL_MIN_HALTING = 2
# ... and a queue the pair stands in is stalled only when its front has come less than this far over
# STALL_WAIT_S: the front car of a queue that drains slowly at a give-way line has waited a minute in it too
# (Krems, make experiment P1, 335 s: the pair left a queue it crept through, 80 m in 55 s) [m]
STALL_PROGRESS_M = 7.5
# the route's cost of a stalled queue: each car in it is costed this much, less than a saturated merge
# takes (a minor street merging into 1800 veh/h: HCM 2010 potential capacity ~70 veh/h, eq. 19-32 with
# critical gap 6.9 s and follow-up time 3.3 s, one car in ~50 s; 60-75 s measured at Monaco 25193333), so
# the pair leaves its route only where the way round clearly saves time
STALL_HEADWAY_S = 30.0
REPLAN_GAIN_S = 30.0  # a way round is taken when it is expected to save this much [s]
COMMIT_M = 100.0  # the route is left at the end of the lead's edge only with this much of it left (room
#                   to change lanes for the new turn), otherwise at the end of the next edge [m]
REJOIN_M = 300.0  # the way round joins the route again this far past the last stalled queue [m]
JAM_HOLD_S = 300.0  # SUMO's router holds the stalled queue's cost for routes entering it this soon [s]
LEAD_WITHIN_EDGES = 64  # the lead's edge is looked for this many route edges ahead of the ego's
# a way round may not pass a junction twice within this many edges of it: a loop round the block back through
# a junction the route passes again makes the twin's mapping onto the route ambiguous there
# (``cosim.phases.ego``, ``REPASS_MARGIN_M``: SUMO then maps it freely, onto any lane nearby)
LOOP_CONTEXT_EDGES = 3


class RouteBridge(Protocol):
    """What the route extension asks SUMO (``cosim.sumo_bridge.SumoBridge`` provides it)."""

    def find_route(self, origin: str, destination: str) -> list[str]: ...

    def extend_route(self, vid: str, edges: list[str]) -> bool: ...

    def replace_route(self, vid: str, edges: list[str]) -> bool: ...

    def route_edge_left(self, vid: str) -> tuple[str, float]: ...

    def queue_heads(self, edge: str, next_edge: str) -> list[tuple[int, float]]: ...

    def weigh_edges(self, travel_time_s: dict[str, float], hold_s: float) -> None: ...

    def lane_queue(self, vid: str) -> tuple[int, float]: ...

    def queue_ahead(self, vid: str) -> list[tuple[str, str | None]]: ...

    def lane_leads_to(self, vid: str, edge: str) -> bool: ...

    def divert(self, vid: str, keep_off: set[str], min_ahead_m: float, continue_m: float = 300.0,
               from_its_lane: bool = False) -> str | None: ...  # fmt: skip


class EgoRoute:
    """Ports: the route's edge list (extended in place: the ego's controller and the lead share it), its
    random stream (``cosim.seeds`` "route"), the drivable edges (a callable: computed only when a leg is
    needed), SUMO's router and the lead's route in SUMO (``bridge``), the snapshot (``world``: the time and
    whether the lead is in), whether there is a lead, and ``emit`` for its events of the step.

    The ego's controller calls ``step`` (``update``) with what is left of the route ahead of it, the route
    index of the edge it is on and the metres left on that edge."""

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
        self._next_replan_s = REPLAN_EVERY_S
        # stalled queues seen: edge -> (the route's cost of it [s], until when [s]); SUMO's router holds the
        # same costs (weigh_edges), so a way round is judged as the router chose it, not against a queue
        # forgotten since (the pair went round one queue, met another, and turned back into the first)
        self._queued: dict[str, tuple[float, float]] = {}
        self.extensions = 0
        self.replans = 0
        self._front_track: list[tuple[float, float]] = []  # (time [s], the pair's front along the route [m])

    @property
    def chainer(self) -> RouteChainer:
        if self._chainer is None:  # the network's drivable part, once per run and only when needed
            self._chainer = RouteChainer(self._drivable_edges())
        return self._chainer

    def step(self, ahead_m: float, ego_index: int = 0, ego_edge_left_m: float = 0.0) -> int | None:
        """Take a way round a stalled queue ahead, then append a leg when less than ``EXTEND_AHEAD_M`` is
        left ahead of the ego. Returns the first route index whose edge changed (None: the route is as it
        was)."""
        if self._lead_pending:
            self._give_lead_pending()
        changed = self._replan(ego_index, ego_edge_left_m)
        n = len(self.edges)
        if self._extend(ahead_m):
            changed = n if changed is None else changed
        return changed

    update = step  # the name the ego's controller (cosim.phases.ego) calls it by

    def _extend(self, ahead_m: float) -> bool:
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

    def _front_of_the_pair(self, ego_index: int, ego_edge_left_m: float) -> tuple[str, int, float] | None:
        """(the vehicle at the front of the pair, the route index of its edge, metres left on it): the lead
        when there is one, else the ego; None while the lead is not in or off the route."""
        if not self.lead:
            return EGO_ID, ego_index, ego_edge_left_m
        if LEAD_ID not in self.world.slot_of:
            return None
        edge, left = self.bridge.route_edge_left(LEAD_ID)
        for i in range(ego_index, min(len(self.edges), ego_index + LEAD_WITHIN_EDGES)):
            if self.edges[i] == edge:
                return LEAD_ID, i, left
        return None

    def _replan(self, ego_index: int, ego_edge_left_m: float) -> int | None:
        """A way round the stalled queues within JAM_LOOK_M ahead, when it saves REPLAN_GAIN_S; returns the
        first route index whose edge changed."""
        t = self.world.t_s
        if t < self._next_replan_s:
            return None
        self._next_replan_s = t + REPLAN_EVERY_S
        where = self._front_of_the_pair(ego_index, ego_edge_left_m)
        if where is None:
            return None
        vid, i, left = where
        edges, chainer = self.edges, self.chainer
        d = i if left >= COMMIT_M else i + 1  # the route is left at the end of edges[d]
        stalled: dict[int, float] = {}  # route index -> cost of its queue [s]
        ahead = left
        for j in range(i + 1, len(edges) - 1):
            if ahead > JAM_LOOK_M:
                break
            heads = self.bridge.queue_heads(edges[j], edges[j + 1])
            if heads and all(n >= STALL_MIN_HALTING and wait >= STALL_WAIT_S for n, wait in heads):
                stalled[j] = min(n for n, _ in heads) * STALL_HEADWAY_S
            ahead += chainer.length.get(edges[j], 0.0)
        # too near the end of its edge to change lanes, the front of the pair stands in a queue that does not
        # move, on the next edge or in its own lane (whose turn may lead onto a stalled lane of a road that
        # flows on another: Krems -24980485#0, seed 6, a left turn onto the stalled one of two lanes): the
        # way round leaves from the lane it is on, and the cars ahead of it in that lane that were to take
        # the same turn are let out first (``_clear_the_way``)
        standing = self._standing_still(t, i, left)
        if d == i + 1 and standing and self._held_by_the_same_turn(vid, edges[d]):
            n, wait = self.bridge.lane_queue(vid)
            if n >= STALL_MIN_HALTING and wait >= STALL_WAIT_S:
                stalled[d] = max(stalled.get(d, 0.0), n * STALL_HEADWAY_S)
        escape = d == i + 1 and d in stalled
        if escape:
            d = i
        stalled = {j: cost for j, cost in stalled.items() if j > d}
        self._queued = {e: q for e, q in self._queued.items() if q[1] > t}
        if not stalled:
            return None
        r, past = max(stalled) + 1, 0.0
        while r < len(edges) - 1 and past + chainer.length.get(edges[r], 0.0) < REJOIN_M:
            past += chainer.length.get(edges[r], 0.0)
            r += 1
        seen = {edges[j]: cost for j, cost in stalled.items()}
        self._queued.update({e: (cost, t + JAM_HOLD_S) for e, cost in seen.items()})
        self.bridge.weigh_edges({e: chainer.free_s.get(e, 0.0) + c for e, c in seen.items()}, JAM_HOLD_S)

        def cost(leg: list[str]) -> float:
            return sum(chainer.free_s.get(e, 0.0) + self._queued.get(e, (0.0,))[0] for e in leg[1:])

        leg = self.bridge.find_route(edges[d], edges[r])
        old = edges[d : r + 1]
        if len(leg) < 2 or leg[0] != edges[d] or leg[-1] != edges[r] or leg == old or chainer.turns_back(leg):
            return None
        if escape and not self.bridge.lane_leads_to(vid, leg[1]):
            return None
        before, after = cost(old), cost(leg)
        if after + REPLAN_GAIN_S > before:
            return None
        route = [*edges[:d], *leg, *edges[r + 1 :]]
        c = LOOP_CONTEXT_EDGES
        # a loop back through a junction passed, unless the route already looped there (round a block at its
        # end: Krems seed 6, every way round a gridlock was refused for the old route's own loop)
        looped_before = self._repassed(edges[max(0, d - c) : r + 1 + c])
        if self._repassed(route[max(0, d - c) : d + len(leg) + c]) - looped_before:
            return None
        if vid == LEAD_ID and not self.bridge.replace_route(LEAD_ID, route[i:]):
            return None
        if escape:
            self._clear_the_way(vid, edges[i + 1])
        edges[:] = route  # in place: shared with the ego's controller
        self._lead_pending = []
        self.replans += 1
        self.emit(SumoEvent("route_replanned", vid, f"round a stalled queue on {', '.join(seen)}: "
                            f"{before:.0f} s -> {after:.0f} s", before - after))  # fmt: skip
        return d + 1

    def _standing_still(self, t: float, i: int, left: float) -> bool:
        """Whether the front of the pair (on route edge ``i``, ``left`` metres before its end) has come less
        than STALL_PROGRESS_M along the route over the last STALL_WAIT_S (tracked at every look)."""
        s = sum(self.chainer.length.get(e, 0.0) for e in self.edges[: i + 1]) - left
        track = self._front_track
        track.append((t, s))
        while len(track) > 1 and track[1][0] <= t - STALL_WAIT_S:
            track.pop(0)  # the oldest kept is the last one at least STALL_WAIT_S back
        return track[0][0] <= t - STALL_WAIT_S and s - track[0][1] < STALL_PROGRESS_M

    def _held_by_the_same_turn(self, vid: str, next_edge: str) -> bool:
        """Whether another car heads the queue ``vid`` stands in and is bound for ``next_edge`` too. The front
        of the pair waiting at the head itself (for the ego, for a gap) is no stalled queue: taking it for
        one, the lead changed its turn three times in 10 s at a Helsinki light (experiment P1, 135-145 s)."""
        ahead = self.bridge.queue_ahead(vid)
        return bool(ahead) and ahead[0][1] == next_edge

    def _repassed(self, edges: list[str]) -> set[str]:
        """The junctions ``edges`` lead into more than once."""
        junctions = [self.chainer.to_node.get(e, e) for e in edges]
        return {j for j in junctions if junctions.count(j) > 1}

    def _clear_the_way(self, vid: str, stalled_edge: str) -> None:
        """The cars ahead of ``vid`` in its lane that were to join the stalled queue on ``stalled_edge`` turn
        off, right or straight, from the lane they stand in (``cut_in_diverted``'s way out), as drivers do
        who see the road they were to take blocked: each held the pair behind it for as long as the queue
        stood (Krems -24980485#0, seed 6: 160 s behind one car waiting to turn left into a gridlock)."""
        for car, next_edge in self.bridge.queue_ahead(vid):
            if next_edge != stalled_edge:
                continue
            out = self.bridge.divert(car, {stalled_edge}, 0.0, from_its_lane=True)
            if out is not None:
                self.emit(
                    SumoEvent("jam_diverted", car, f"turns onto {out}: {stalled_edge} ahead is stalled")
                )

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

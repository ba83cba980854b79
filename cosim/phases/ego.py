"""The ego in the loop: what its driver perceives, how MuJoCo moves it, and its write-back into SUMO.

Its entries in the schedule (``cosim.sim``, ARCHITECTURE.md phase order): in ``sumo`` the ego's pose, speed
and acceleration in the snapshot become the physics' (``own_state``); ``driver`` builds the Percept from the
snapshot and SUMO's view of the ego (next light, right of way) and asks the driver (``step``); ``ego``
integrates the car for one SUMO step (``integrate``); ``writeback`` places the ego in SUMO (moveToXY +
speed) for the next step (``write_back``).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable, Collection
from typing import Protocol

import numpy as np

from cosim import frames
from cosim.driver import Controls, Percept, make_driver
from cosim.driver.gap_acceptance import FOE_RADIUS_M, arrival_time_s, movement_of
from cosim.driver.route import LaneChange, RoutePath
from cosim.ego_mujoco.params import CarParams
from cosim.ego_mujoco.state import EgoState
from cosim.phases.courtesy import COURTESY_AFTER_S, CourtesyYield
from cosim.runconfig import EgoConfig
from cosim.world import EGO_ID, LEAD_ID, SumoEvent, World

PREVIEW_BEHIND_M = 5.0
PREVIEW_AHEAD_M = 160.0
TLS_NEAR_M = 150.0  # a light nearer than this is looked up every step, farther ones once a second
TLS_REFRESH_S = 1.0
YIELD_LOOK_M = 80.0  # the gap at a junction where the ego must yield is judged from this close on [m]
# a priority vehicle that has stood this long behind another car or at a closed link is waiting itself
# (queued, yielding, blocked): a driver who sees it stand goes, as SUMO's junction model (which counts
# approaching foes only) does. One first in line at an open link is not: a queue released by its green
# light has stood for a whole red (an ego turning left at a permissive green hit such a right-turner)
FOE_WAITING_S = 3.0
# SUMO is given the ego's route this far ahead, renewed at half of it: enough for its next light (read
# within 300 m) and right of way. It matches every pose against each edge of the route it holds (the ones
# passed too, which it keeps), so the whole route ahead would cost up to 0.3 ms a step.
SUMO_ROUTE_AHEAD_M = 800.0
ON_PATH_M = 2.0  # the ego's centre this close to its path's centre line is certainly on the road [m]
# ... and this close it is still on the road its route takes, so SUMO maps the twin onto that route: a
# driver cutting a corner or drifting within a lane width of the path has not left it (Munich seed 1:
# 2.1 m off the path in a right turn, the twin mapped freely onto the crossing road hit scv98 there)
ON_ROUTE_M = 3.5
# ... except within this of a junction the route passes a second time (``_in_junction_passed_before``) [m]
REPASS_MARGIN_M = 5.0
# ... and where the path passes within this of a stretch of itself driven before (at least REPASS_BACK_M of
# road earlier), such as a bridge over its own earlier road: keepRoute=1 matches the pose onto the nearest
# edge of the route SUMO holds, which keeps the edges driven. Moscow (graphhopper's extract) seed 2: under
# -19032712, driven 4 edges earlier, the twin was put onto it for one step, into scv830 driving there (a
# collision of the ego); the free mapping with the path's lane as hint keeps it on its own road [m]
REPASS_RADIUS_M = 5.0
REPASS_BACK_M = 60.0
# ... and for this far after SUMO put the twin, mapped on its route, onto a road the route passed before:
# keepRoute=1 searches the route's passed edges too (SUMO keeps them in the route it holds, whatever it is
# given), and where such a road runs under or beside the ego's (Krems 38571954 over -51713752#0, seven edges
# earlier) the twin went into the queue standing there every other step (3 SUMO collisions) [m]
FREE_MAPPING_M = 100.0
NEXT_LEADERS_SEEN = 3  # vehicles on the path the percept keeps, nearest first: the leader and those beyond it
LEAD_BESIDE_M = 5.0  # the lead's rear this close to the path's centre line is ahead of the ego, in its lane or the next [m]
LEAD_AT_ROADSIDE_M = 12.0  # ... and standing at the roadside, beside up to three lanes [m]
# ... and on a SUMO edge the path takes there, in any lane: the lanes of a wide junction's passage fan out
# (Berlin's Grosser Stern: two lanes of one roundabout entry 6.5 m apart), and the ego passed the lead there [m]
LEAD_SAME_EDGE_M = 12.0
ROADSIDE_KEEP_BACK_M = 6.0  # the participant stops this much farther back from the lead at the roadside [m]
PATH_HALF_WIDTH_M = (
    1.0  # a vehicle whose rear is this close to the path's centre line (+ half its width) is ahead
)
# Crossing traffic: a vehicle in a junction (committed: SUMO let it in, maybe because the ego twin stood
# when it decided) or standing across the ego's way, whose way crosses the route within CROSS_LOOK_M ahead,
# predicted at constant velocity over CROSS_TIMES_S. A driver lets it through unless the ego is through first.
CROSS_LOOK_M = 40.0
CROSS_TIMES_S = np.arange(0.0, 3.01, 0.5)
CROSS_MIN_SIN = math.sin(math.radians(30.0))  # nearer the route's direction: a leader or a merging car
EGO_PULL_AWAY_MPS2 = 1.5  # the ego's arrival at the crossing is estimated accelerating at this
CROSS_MARGIN_S = 1.0  # the ego goes first only if its rear is past the crossing this long before the car
# ... and only where the ways cross in or by a junction of the route: elsewhere one passes over the other
# (Krems: the trunk 38571954 runs over -51713752#0, whose queue the driver took for crossing traffic and
# stood for on the bridge, the lead 40 m ahead; a body still in the junction it left lies within this)
CROSS_JUNCTION_REACH_M = 10.0
# Lane changes on the path (RoutePath.lane_changes): the driver moves over only into a gap in the lanes it
# enters. The gap is judged for when the front bumper reaches the point where the car begins to enter the
# next lane (LaneChange.enter_s), predicted at constant speeds from MERGE_LOOK_M before it; the ego
# accelerating at EGO_PULL_AWAY_MPS2. Vehicles within MERGE_NEAR_M of the ego are looked at.
MERGE_LOOK_M = 60.0
MERGE_NEAR_M = MERGE_LOOK_M + 60.0
# The car it moves in front of must be left SUMO's secure gap (MSCFModel::getSecureGap, Krauss: its speed
# times its reaction time tau plus the difference of the two braking distances at its deceleration) and its
# minGap; a car ahead must be MERGE_FRONT_GAP_M clear of the ego's front. A driver held MERGE_PATIENCE_S
# accepts what SUMO's cars can still absorb (tau of half a second, braking at their emergency deceleration),
# as SUMO's lane-change impatience does, instead of waiting for ever beside a dense stream.
MERGE_MIN_GAP_M, MERGE_FRONT_GAP_M = 2.5, 2.0
MERGE_TAU_S, MERGE_DECEL_MPS2 = 1.0, 4.5  # SUMO's defaults for passenger cars (vType tau, decel)
MERGE_PATIENCE_S, MERGE_IMPATIENT_TAU_S, MERGE_IMPATIENT_DECEL_MPS2 = 10.0, 0.5, 9.0  # emergencyDecel 9
# A car ahead in the new lane driving at least MERGE_STREAM_MPS (a moving stream, not a queue that crawls
# and may stop again) is judged where it will be when the ego gets there, the ego's own secure gap behind
# it, and is the ego's leader until it has moved over (``_fall_behind``). Judged where it is, such a car
# stayed "in the way" of a change put off 20 m at a time while the ego drove beside it at its speed
# (Monaco 166009792#2, experiment P2 baseline: 150 m in the other lane, two cars came between)
MERGE_STREAM_MPS = 5.0
MERGE_LATE_DECEL_MPS2 = 4.5  # stopping short would need harder braking than this: the change goes on
# No gap, the change near (or too fast to stop short of it): it is put off by MERGE_PUT_OFF_M along the lane
# the ego is in, as a driver stays in lane until a gap comes (a stream passing, a queue alongside), as long
# as the edge leaves room. (Slowing first to let the cars pass, putting it off only when still held up below
# 2 m/s, was tried: in the experiment the lead drove away more often and two ego collisions came back.)
MERGE_PUT_OFF_WITHIN_M, MERGE_PUT_OFF_M = 15.0, 20.0
# Held MERGE_LET_IN_AFTER_S (a stream passing, a queue alongside closes every gap), the ego is let in, as a
# driver lets in a car that has been blinking a while: the nearest car behind it in the new lane that can
# slow to its speed MERGE_MIN_GAP_M behind its rear (braking at MERGE_LET_IN_DECEL_MPS2) drives slower than
# the ego (SUMO: speed capped every step; 0 while the ego stands) until the ego has begun to move over, for
# MERGE_LET_IN_S at most; then another may be asked. Not while a car ahead holds the ego standing short of
# where it would move over: the gap would open beside that car (Munich seed 1). (SUMO's gap control, TraCI
# openGap, asked before, widens a car's gap to its own leader, which in a moving queue passes the ego as
# well: the gap never opened beside it, Munich seed 2, Helsinki seed 3.)
MERGE_LET_IN_AFTER_S, MERGE_LET_IN_DECEL_MPS2, MERGE_LET_IN_S = 5.0, 3.0, 10.0
# ... at once when the lead is ahead in the lane it moves into: the gap behind the lead is the participant's
# place, and every car of the stream that passes the waiting ego fills it (Helsinki 194850767#2, Monaco
# 166009792#2, experiment: after 4-7 s of waiting a passing car came between, lead as leader 0.23-0.72)
MERGE_LET_IN_BEHIND_LEAD_S = 0.0
# ... and drops back at this much below the ego's speed: matching it, it kept a bumper gap of 2.5 m, short of
# the secure gap the ego leaves a follower at speed (its tau), and the ego never moved over
MERGE_LET_IN_DROP_BACK_MPS = 1.5
STOPPED_FOR_MPS = 0.5  # a car that stops for the ego (or the lead) stands below this speed [m/s]
FIRST_AT_LINE_M = 10.0  # standing this close to a yield line with no car before it, the ego waits first [m]


# SUMO link states of the route's connections: 's' stop sign, 'w' all-way stop, 'm' minor road (give-way
# sign, an unsigned minor road, a roundabout entry), '=' priority to the right (right_before_left)
_SIGN_OF_STATE = {"s": "stop", "w": "stop", "m": "give_way", "=": "give_way"}
_TLS = {"g": "g", "G": "g", "y": "y", "Y": "y", "u": "y", "r": "r", "R": "r", "s": "r"}
# a green without priority ('g': a permissive left turn across oncoming traffic) is a yield line as well
_TLS_YIELD = "g"


class FoesBridge(Protocol):
    """SUMO's right of way at the next junctions (``cosim.sumo_bridge.SumoBridge`` provides it)."""

    def yield_foes(self, vid: str, lookahead_m: float) -> list[tuple[str, float, float, float, bool]]: ...


class EgoBridge(FoesBridge, Protocol):
    """What the ego's phase asks SUMO and writes into it (``cosim.sumo_bridge.SumoBridge`` provides it)."""

    def next_tls(self, vid: str) -> tuple[str, int, float, str] | None: ...

    def edges_left(self, vid: str) -> int: ...

    def route_edge_left(self, vid: str) -> tuple[str, float]: ...

    def set_ego_route(self, edges: list[str]) -> SumoEvent | None: ...

    def cap_speed(self, vid: str, speed_mps: float | None) -> None: ...

    def write_ego(self, x_m: float, y_m: float, heading_deg: float, speed_mps: float, *, edge_hint: str = "",
                  lane_hint: int = -1, verify_on_road: bool = True, on_route: bool = False) -> SumoEvent | None: ...  # fmt: skip


class EgoPhysics(Protocol):
    """The car the driver drives (``cosim.ego_mujoco.EgoCar``; a unit test may give a kinematic one)."""

    params: CarParams

    def reset(self, x_m: float, y_m: float, yaw_rad: float, speed_mps: float = 0.0) -> None: ...

    def step(self, throttle: float, brake: float, steer: float, duration_s: float) -> EgoState: ...

    def state(self) -> EgoState: ...


class RouteExtension(Protocol):
    """The route as it is extended and re-planned (``cosim.phases.route.EgoRoute``): given what is left
    ahead of the ego, the route index of its edge and the metres left on that edge, returns the first route
    index whose edge changed (None: unchanged)."""

    def update(self, ahead_m: float, ego_index: int, ego_edge_left_m: float) -> int | None: ...


def priority_gap_s(world: World, bridge: FoesBridge, vid: str, line_dist_m: float,
                   stopping_for: Collection[str | None] = ()) -> float:  # fmt: skip
    """Time until the first vehicle ``vid`` must yield to at its next junction reaches the conflict [s]
    (SUMO's right of way; inf: none within FOE_RADIUS_M). ``stopping_for``: cars that stop for ``vid`` (one
    letting the ego into its lane, ``EgoController._merge``; one letting the pair in, ``CourtesyYield``), no
    foes once they stand: counted, the car letting the ego in held it at a give-way line while it stood
    there for the ego (Monaco 1712696757, experiment P2 system_A: 54 s, and five cars came between the lead
    and the ego)."""
    w = world
    gap = math.inf
    for foe, _, foe_dist, standing_s, held_back in bridge.yield_foes(vid, line_dist_m + 5.0):
        slot = w.slot_of.get(foe)
        if slot is None or foe_dist > FOE_RADIUS_M or (standing_s >= FOE_WAITING_S and held_back):
            continue
        if foe in stopping_for and w.speed_mps[slot] < STOPPED_FOR_MPS:
            continue
        gap = min(gap, arrival_time_s(foe_dist, float(w.speed_mps[slot])))
    return gap


def pull_away_arrival(v: float, v_top: float, dist_m: float) -> tuple[float, float]:
    """(time [s], speed [m/s]) of the ego ``dist_m`` on, speeding up from ``v`` at EGO_PULL_AWAY_MPS2 to at
    most ``v_top``."""
    a = EGO_PULL_AWAY_MPS2
    speeding_up_m = (v_top * v_top - v * v) / (2.0 * a)
    if dist_m <= speeding_up_m:
        v_end = math.sqrt(v * v + 2.0 * a * dist_m)
        return (v_end - v) / a, v_end
    return (v_top - v) / a + (dist_m - speeding_up_m) / v_top, v_top


def _next_leader(on_path, kw: dict) -> dict:
    """The nearest vehicle on the path beyond the percept's leader (``on_path``: (id, gap, speed) nearest
    first), for the driver's multi-anticipation; {} when there is none."""
    if not kw.get("leader_present"):
        return {}
    beyond = [
        (gap, speed) for vid, gap, speed in on_path if vid != kw["leader_id"] and gap > kw["leader_gap_m"]
    ]
    return {"next_leader_gap_m": beyond[0][0], "next_leader_speed_mps": beyond[0][1]} if beyond else {}


class EgoController:
    """Owns the car and the driver; plugs into the sumo / driver / ego / writeback phases.

    Ports: its config (the driver and the car's steering geometry), the car (``car``: MuJoCo's
    ``EgoCar`` in a run), the driver's random stream (``cosim.seeds`` "driver" + ``driver_seed``), the
    route's edge list (shared with ``cosim.phases.route``, which extends it in place) and ``path_of``, which
    turns edges and lane-change delays into route geometry (``RoutePath.from_network`` on the read-only
    network view), the route extension (None: the route is fixed), SUMO's operations for the ego
    (``bridge``), the step length and ``emit`` for its events of the step. Each entry point is given the snapshot; ``step`` also the assistance
    systems' displays (Percept kwargs). ``write_back`` returns the ego's additions to /ego/state."""

    def __init__(self, config: EgoConfig, *, car: EgoPhysics, rng: np.random.Generator, route: list[str],
                 path_of: Callable[[list[str], dict[int, float]], RoutePath], extension: RouteExtension | None,
                 bridge: EgoBridge, step_s: float, emit: Callable[[SumoEvent], None]):  # fmt: skip
        self.car = car
        self.route = route
        self._path_of = path_of
        self.extension = extension
        self.bridge = bridge
        self.step_s = step_s
        self.emit = emit
        self._change_delays: dict[int, float] = {}  # route index -> lane change put off by [m] (RoutePath)
        self._new_lane: LaneChange | None = None  # the lane change the ego is making (into its new lane)
        self.path = path_of(route, self._change_delays)
        p = config.car
        self.driver = make_driver(config.driver, rng, math.radians(p.max_steer_deg), p.wheelbase_m)
        self.origin: tuple[float, float] | None = None
        self.s_front_m: float | None = None  # the front bumper's arc position on the route path [m]
        self.controls = Controls()
        self.started = False
        self.percept: Percept | None = None
        self._last_tls = None
        self._tls_cache = None  # (SUMO's next light, arc position and step when read)
        self._on_sumo_route = True  # SUMO holds the planned route ahead of the ego ...
        self._sumo_route_end: int | None = None  # ... up to this route index (exclusive); None: all of it
        self._mapped_on_route = False  # the last pose was mapped onto SUMO's route (keepRoute=1) ...
        self._free_mapping_until_s = -math.inf  # ... and is mapped freely up to this arc position
        self._route_renewed = False  # the route changed within what SUMO holds: SUMO must get it again
        self._repassed: list[tuple[float, float]] = []  # arc spans of junctions the route passes again ...
        self._repassed_for = None  # ... on this path
        self._near_self: list[tuple[float, float]] = []  # arc spans where the path passes near itself ...
        self._near_self_for = None  # ... on this path
        # waiting for a gap: (route index of the lane change's edge, since [s])
        self._merge_held: tuple[int, float] | None = None
        # the car letting the ego in: (its id, since [s], route index of the lane change's edge)
        self._let_in: tuple[str, float, int] | None = None
        self.courtesy = CourtesyYield(bridge=bridge, step_s=step_s, emit=emit)  # shared with the lead
        # set by the lead's phase while the lead stands at the roadside to let cars pass (``LeadVehicle``)
        self.lead_at_roadside = False
        self._first_at_line: tuple[str, float] | None = None  # (junction, since [s]) the ego waits first

    def _start(self, w, slot: int) -> None:
        cx, cy, yaw = frames.sumo_to_mujoco(
            w.x_m[slot], w.y_m[slot], w.heading_deg[slot], self.car.params.length_m
        )
        self.origin = (float(cx), float(cy))
        self.car.reset(0.0, 0.0, float(yaw), float(w.speed_mps[slot]))
        self.started = True

    def own_state(self, w: World) -> None:
        """The ego is MuJoCo's: its pose, speed and acceleration in the snapshot come from the physics, not
        from SUMO's twin. The twin's pose is where moveToXY put it, snapped onto the new lane's centre line
        as soon as a lane change begins (``write_back``): read back, the ego jumped 3-6 m sideways in one
        step (Munich seed 2, four times in 300 s), in the log, in its CAMs and in the distance systems
        measure. Its edge and lane stay SUMO's: the lane the twin holds in SUMO's traffic."""
        slot = w.slot_of.get(EGO_ID)
        if slot is not None and self.started:
            st = self.car.state()
            w.x_m[slot], w.y_m[slot], w.heading_deg[slot] = st.to_sumo(self.origin)
            w.speed_mps[slot] = st.speed_mps
            w.accel_mps2[slot] = st.accel_mps2

    def step(self, w: World, displays: dict) -> None:
        """The driver phase: the Percept from the snapshot, SUMO's view of the ego and the assistance
        systems' ``displays``, and the driver's controls for the step."""
        slot = w.slot_of.get(EGO_ID)
        if slot is None:
            return
        if not self.started:
            self._start(w, slot)
        st = self.car.state()
        cx, cy = st.x_m + self.origin[0], st.y_m + self.origin[1]
        s_c, _ = self.path.project(cx, cy)
        s_front = s_c + 0.5 * self.car.params.length_m
        self.s_front_m = s_front
        if self.extension is not None:
            k = self.path.edge_index(s_front)
            left = max(0.0, self.path.edge_lanes[k][1] - s_front) if k < len(self.path.edge_lanes) else 0.0
            changed = self.extension.update(self.path.length_m - s_front, k, left)
            if changed is not None:
                self._route_changed(changed)
        limit, next_limit, next_dist = self.path.speed_limit(s_front)
        self._on_sumo_route = self._keep_sumo_route(w, slot, s_front)
        if self._mapped_on_route and self._on_a_passed_edge(w, slot, s_front):
            self._free_mapping_until_s = s_front + FREE_MAPPING_M
        kw, on_path = self._leader_on_path(w, slot, cx, cy, s_front)
        kw.update(self._lead_one_lane_over(w, s_front, kw))
        # SUMO has the ego's twin in the new lane from the moment it begins to enter it (write_back): the cars
        # there see it and stay behind (mapped to the nearest lane, the twin would jump over only half way)
        self._new_lane, upcoming = self.path.lane_changes_around(s_front)
        self._keep_letting_in(w, s_front)
        if self._new_lane is not None or (
            upcoming is not None and upcoming.enter_s - s_front <= MERGE_LOOK_M
        ):
            live, _ = w.live()
            near = live[(np.hypot(w.x_m[live] - cx, w.y_m[live] - cy) < MERGE_NEAR_M) & (live != slot)]
            if self._new_lane is not None:
                kw.update(self._leader_in_new_lane(w, near, self._new_lane, s_front, kw))
            if upcoming is not None:
                kw.update(self._merge(w, near, upcoming, s_front, kw))
        kw.update(_next_leader(on_path, kw))
        tls = self._next_tls(w, s_front)
        self._check_red_light(tls)
        if tls and tls[2] < 300.0 and _TLS.get(tls[3]):
            kw.update(tls_state=_TLS[tls[3]], tls_dist_m=max(0.0, tls[2]), tls_id=f"{tls[0]}:{tls[1]}")
        self.courtesy.hold(w, s_front, self.car.params.length_m)
        kw.update(self._yield_line(w, s_front, tls))
        self._ask_courtesy(w, s_front, st.speed_mps, kw)
        adas = displays
        self.percept = Percept(
            t_s=w.t_s, speed_mps=st.speed_mps, x_m=cx, y_m=cy, yaw_rad=st.yaw_rad, accel_mps2=st.accel_mps2,
            yaw_rate_rps=st.yaw_rate_rps, path_xy_m=self.path.window(s_c - PREVIEW_BEHIND_M, s_c + PREVIEW_AHEAD_M),
            speed_limit_mps=limit, next_speed_limit_mps=next_limit, next_speed_limit_dist_m=next_dist,
            route_end_dist_m=max(0.0, self.path.length_m - s_front), **kw, **adas,
        )  # fmt: skip
        self.controls = self.driver.act(self.percept, self.step_s)

    def _keep_sumo_route(self, w: World, slot: int, s_front: float) -> bool:
        """Whether SUMO holds the ego's planned route ahead of it; gives SUMO the next stretch of it when the
        held one runs short or SUMO has replaced it.

        Off its path the ego's pose may be mapped onto any lane (the driver may leave its route), and SUMO
        then replaces the route with the one edge it mapped to. Left so, the twin would carry that one-edge
        route for the rest of the run: SUMO's next light and right of way for the ego, and its foes' view
        of where the ego goes, would all end at the next junction."""
        route = self.route
        k = self.path.edge_index(s_front)
        end = self._sumo_route_end
        # SUMO's route index may be one edge behind the path's: the pose written last step (moveToXY) takes
        # effect only at the next one, so the front bumper can enter the next edge here a step earlier
        expected = (len(route) if end is None else end) - k
        held = self.bridge.edges_left(EGO_ID) in (expected, expected + 1)
        if (
            held
            and not self._route_renewed
            and end is not None
            and (end == len(route) or self.path.limit_s[end] - s_front > 0.5 * SUMO_ROUTE_AHEAD_M)
        ):
            return True
        road = w.edge_of(slot)
        start = k if road == route[k] else self._start_in_junction(road, k)
        if start is None:
            return held  # in a junction, or off the route: SUMO's route cannot start here
        end = self.path.edge_index(s_front + SUMO_ROUTE_AHEAD_M) + 1
        ev = self.bridge.set_ego_route(route[start:end])
        if ev:
            self.emit(ev)
            return False
        self._sumo_route_end = end
        self._route_renewed = False
        self._tls_cache = None
        return True

    def _start_in_junction(self, road: str, k: int) -> int | None:
        """Where SUMO's route starts while the twin is in a junction (the edge it has just left: the path's
        edge ``k`` or, with the front bumper already past the junction, the one before), when the route
        changed ahead and SUMO must get it there (the twin may stand in a junction's queue for minutes);
        None otherwise."""
        if not road.startswith(":") or not self._route_renewed:  # SUMO's internal edges start with ':'
            return None
        current = self.bridge.route_edge_left(EGO_ID)[0]
        return next((i for i in (k, k - 1) if i >= 0 and self.route[i] == current), None)

    def _next_tls(self, w: World, s_front: float):
        """SUMO's next light on the ego's way (a costly lookup): every step when it is near, otherwise once
        a second, its distance carried forward with the ego's progress in between."""
        cached = self._tls_cache
        if cached is not None:
            tls, s_read, step = cached
            moved = s_front - s_read
            if tls and tls[2] - moved > TLS_NEAR_M and (w.step - step) * self.step_s < TLS_REFRESH_S:
                return (tls[0], tls[1], tls[2] - moved, tls[3])
        tls = self.bridge.next_tls(EGO_ID)
        self._tls_cache = (tls, s_front, w.step)
        return tls

    def _check_red_light(self, tls) -> None:
        """The ego crossed a stop line at red: the light it was about to reach is gone while it was red."""
        last = self._last_tls
        self._last_tls = tls
        if last and last[2] < 5.0 and _TLS.get(last[3]) == "r" and (not tls or tls[:2] != last[:2]):
            self.emit(SumoEvent("red_light_violation", EGO_ID, f"{last[0]} link {last[1]}", last[2]))

    def _leader_on_path(self, w, ego_slot: int, cx: float, cy: float, s_front: float) -> tuple[dict, list]:
        """The nearest vehicle whose rear is on the ego's own path ahead: what a driver sees in front of
        them, whichever SUMO lane it is on (a car the ego is about to change lanes behind, one in a bend);
        with the percept's fields, (id, gap, speed) of the nearest NEXT_LEADERS_SEEN such vehicles. A car
        merging into the ego's way at a shallow angle is ahead from where its middle or front is on the
        path, before its rear is: crawling in 2.5 m ahead of the ego, its rear still off the path and too
        shallow to cross it, scv662 was neither leader nor crossing car, and the ego drove into its side
        (Monaco 25177449, experiment P2)."""
        live, _ = w.live()
        near = live[np.hypot(w.x_m[live] - cx, w.y_m[live] - cy) < PREVIEW_AHEAD_M + 10.0]
        idx = near[near != ego_slot]
        if idx.size == 0:
            return {}, []
        n = idx.size
        heading = np.radians(w.heading_deg[idx])  # World.heading_unit, for these vehicles only
        hx, hy = np.sin(heading), np.cos(heading)
        length = w.length_m[idx]
        xs = np.concatenate([w.x_m[idx] - hx * length, w.x_m[idx] - 0.5 * hx * length, w.x_m[idx]])
        ys = np.concatenate([w.y_m[idx] - hy * length, w.y_m[idx] - 0.5 * hy * length, w.y_m[idx]])
        half = PATH_HALF_WIDTH_M + 0.5 * (w.width_m[idx].sum() / n)  # = .mean(), without its overhead
        rows, s_at = self.path.vehicles_on_path(xs, ys, s_front - 2.0, s_front + PREVIEW_AHEAD_M, half)
        kw = self._crossing(w, idx, heading, cx, cy, s_front, half)
        veh = rows % n
        if rows.size and (rows >= n).any():  # middle or front on the path: only cars heading its way
            ux, uy = self.path.direction_at(s_at)
            along = (ux * hx[veh] + uy * hy[veh] > 0.0) & (
                np.abs(ux * hy[veh] - uy * hx[veh]) < CROSS_MIN_SIN
            )
            keep = (rows < n) | along
            veh, s_at = veh[keep], s_at[keep]
        if veh.size:  # only vehicles SUMO has on a road of the route there (RoutePath.on_its_roads)
            keep = self.path.on_its_roads(w.edges_of(idx[veh]), s_at)
            veh, s_at = veh[keep], s_at[keep]
        if veh.size == 0:
            return kw, []
        s_rear = np.full(n, np.inf)  # per vehicle, the nearest of its points on the path
        np.minimum.at(s_rear, veh, s_at)
        order = np.argsort(s_rear, kind="stable")[:NEXT_LEADERS_SEEN]
        seen = [(w.ids[int(idx[k])], max(0.0, float(s_rear[k] - s_front)), float(w.speed_mps[idx[k]]))
                for k in order.tolist() if math.isfinite(s_rear[k])]  # fmt: skip
        vid, gap, speed = seen[0]
        return {**kw, "leader_present": True, "leader_id": vid, "leader_gap_m": gap,
                "leader_speed_mps": speed}, seen  # fmt: skip

    def _lead_one_lane_over(self, w: World, s_front: float, seen: dict) -> dict:
        """The lead car ahead of the ego one lane over is the participant's leader: they follow the lead,
        not their lane, so they keep behind it and leave it room to move over (Helsinki seed 1: the lead,
        blocked from changing into the ego's lane, was passed by the ego closing up in that lane; it was
        the ego's leader 3 % of the run). At the roadside, letting cars pass, SUMO shows it beside the road's
        rightmost lane (6.4 m off a two-lane road's left lane): the participant stops behind it, whichever
        lane they are in, and lets it back in. Farther off, up to LEAD_SAME_EDGE_M, the lead is still ahead
        when SUMO has it on an edge the path takes there (another lane of a wide junction's passage)."""
        slot = w.slot_of.get(LEAD_ID)
        if slot is None:
            return {}
        heading = math.radians(float(w.heading_deg[slot]))
        length = float(w.length_m[slot])
        rear_x = np.array([w.x_m[slot] - math.sin(heading) * length])
        rear_y = np.array([w.y_m[slot] - math.cos(heading) * length])
        rows, s_rear = self.path.vehicles_on_path(
            rear_x, rear_y, s_front, s_front + PREVIEW_AHEAD_M,
            LEAD_AT_ROADSIDE_M if self.lead_at_roadside else LEAD_BESIDE_M,
        )  # fmt: skip
        if rows.size == 0:
            if self.lead_at_roadside:  # searched as wide already
                return {}
            rows, s_rear = self.path.vehicles_on_path(
                rear_x, rear_y, s_front, s_front + PREVIEW_AHEAD_M, LEAD_SAME_EDGE_M
            )
            code = int(w.edge_code[slot])
            if not rows.size or code < 0:
                return {}
            s = float(s_rear[0])  # a point off to the side projects up to a lane width along from its place
            if w.edge_names[code] not in self.path.edges_between(s - LEAD_SAME_EDGE_M, s + LEAD_SAME_EDGE_M):
                return {}
        gap = float(s_rear[0]) - s_front
        if self.lead_at_roadside:  # stop short of it: room for it to pull out in front (SUMO needs that)
            gap = max(0.0, gap - ROADSIDE_KEEP_BACK_M)
        if seen.get("leader_present") and seen["leader_gap_m"] <= gap:
            return {}
        return {"leader_present": True, "leader_id": LEAD_ID, "leader_gap_m": gap,
                "leader_speed_mps": float(w.speed_mps[slot])}  # fmt: skip

    def _crossing(self, w, idx: np.ndarray, heading: np.ndarray, cx: float, cy: float, s_front: float,
                  half: float) -> dict:  # fmt: skip
        """Where the nearest vehicle crossing the route ahead will be in the ego's way (``crossing_dist_m``;
        see CROSS_LOOK_M). Vehicles approaching a junction are left to its right of way: only those inside
        one (or standing across the route) are committed to their way."""
        keep = np.hypot(w.x_m[idx] - cx, w.y_m[idx] - cy) < CROSS_LOOK_M + 30.0
        if not keep.any():
            return {}
        idx, heading = idx[keep], heading[keep]
        hx, hy = np.sin(heading), np.cos(heading)
        speed, length = w.speed_mps[idx], w.length_m[idx]
        codes = w.edge_code[idx]
        in_junction = np.array([c >= 0 and w.edge_names[c].startswith(":") for c in codes.tolist()], bool)
        # front and middle of each vehicle (SUMO's position is the front bumper) at each predicted time; a
        # vehicle outside a junction only as it is now
        times = np.where(in_junction[:, None], CROSS_TIMES_S[None, :], 0.0)  # (V, T)
        ahead = speed[:, None] * times
        xs = np.stack([w.x_m[idx, None] + hx[:, None] * (ahead - f * length[:, None]) for f in (0.0, 0.5)], 2)
        ys = np.stack([w.y_m[idx, None] + hy[:, None] * (ahead - f * length[:, None]) for f in (0.0, 0.5)], 2)
        rows, s_hit = self.path.vehicles_on_path(
            xs.ravel(), ys.ravel(), s_front, s_front + CROSS_LOOK_M, half
        )
        if rows.size == 0:
            return {}
        veh, t_at = rows // xs[0].size, times.ravel()[rows // 2]
        ux, uy = self.path.direction_at(s_hit)
        crossing = np.abs(ux * hy[veh] - uy * hx[veh]) >= CROSS_MIN_SIN
        crossing &= self.path.near_junction(s_hit, CROSS_JUNCTION_REACH_M)
        if not crossing.any():
            return {}
        veh, t_at, s_hit = veh[crossing], t_at[crossing], s_hit[crossing]
        # the ego's front reaches the crossing (accelerating from its speed) and its rear leaves it
        v = max(self.car.state().speed_mps, 0.0)
        d = s_hit - s_front
        t_ego = (np.sqrt(v * v + 2.0 * EGO_PULL_AWAY_MPS2 * d) - v) / EGO_PULL_AWAY_MPS2
        through = t_ego + (self.car.params.length_m + 2.0 * half) / max(v, 1.0)
        # the crossing vehicle is first in the ego's way at its earliest predicted time on the route
        in_way = np.full(len(idx), np.inf)
        np.minimum.at(in_way, veh, t_at)
        yield_to = through + CROSS_MARGIN_S > in_way[veh]
        if not yield_to.any():
            return {}
        return {"crossing_dist_m": max(0.0, float(d[yield_to].min()) - 0.5 * float(w.width_m[idx].max()))}

    def _watched(self, w: World, near: np.ndarray, change: LaneChange, feeders: bool):
        """(slot, lane id, position from the edge's start [m]) of the vehicles ``near`` the ego in the lanes
        a lane change enters (and, with ``feeders``, in the lanes leading into them)."""
        for slot in near.tolist():
            code = int(w.edge_code[slot])
            if code < 0:
                continue
            lane = f"{w.edge_names[code]}_{w.lane_index[slot]}"
            if lane in change.enters or (feeders and lane in change.feeders):
                yield slot, lane, change.position(lane, float(w.x_m[slot]), float(w.y_m[slot]))

    def _leader_in_new_lane(self, w: World, near: np.ndarray, change: LaneChange, s_front: float,
                            seen: dict) -> dict:  # fmt: skip
        """While the ego moves over, the nearest car ahead in the lane it moves into is its leader too,
        though the path (half in the old lane) passes it more than a lane's half width away."""
        front = s_front - change.s_start + change.delay_m
        best = (seen["leader_gap_m"], None) if seen.get("leader_present") else (math.inf, None)
        for slot, _, p in self._watched(w, near, change, feeders=False):
            gap = p - w.length_m[slot] - front
            if -0.5 <= gap < best[0]:
                best = (max(0.0, float(gap)), slot)
        if best[1] is None:
            return {}
        slot = best[1]
        return {"leader_present": True, "leader_id": w.ids[slot], "leader_gap_m": best[0],
                "leader_speed_mps": float(w.speed_mps[slot])}  # fmt: skip

    def _merge(self, w: World, near: np.ndarray, change: LaneChange, s_front: float, seen: dict) -> dict:
        """Whether the next lane change on the path (``change``) has a gap (see MERGE_LOOK_M). Without one
        the driver puts the change off along the lane it is in (MERGE_PUT_OFF_M at a time, as the edge
        allows) or, at the edge's end, waits short of it (``merge_dist_m``: its front at the point where it
        would begin to enter the next lane); held long enough, it is let in. ``seen``: its leader so far."""
        enter_s = change.enter_s
        if enter_s - s_front > MERGE_LOOK_M:
            return {}
        v = max(self.car.state().speed_mps, 0.0)
        d = enter_s - s_front
        blocked, behind, ahead = self._no_gap(w, near, s_front, change, enter_s, v)
        if not blocked:
            return {}
        kw = self._fall_behind(w, ahead, seen)
        held = self._merge_held
        lead_ahead = held is not None and self._lead_in_new_lane(w, near, change, s_front)
        patience_s = MERGE_LET_IN_BEHIND_LEAD_S if lead_ahead else MERGE_LET_IN_AFTER_S
        if (
            held is not None
            and held[0] == change.edge_index
            # a car nearer than the one letting the ego in (come in from a lane leading in) is asked instead
            and (self._let_in is None or self._let_in[0] != behind)
            and behind is not None
            and w.t_s - held[1] >= patience_s
            # not standing behind a car short of the point where it would move over (Munich seed 1)
            and not (v < 0.5 and seen.get("leader_present") and seen["leader_gap_m"] < d + MERGE_FRONT_GAP_M)
        ):
            if self._let_in is not None:
                self.bridge.cap_speed(self._let_in[0], None)
            self.bridge.cap_speed(behind, max(v - MERGE_LET_IN_DROP_BACK_MPS, 0.0))
            self._let_in = (behind, w.t_s, change.edge_index)
            self.emit(SumoEvent("merge_let_in", behind, f"lets the ego into {change.to_lane_id}"))
        late = v * v > 2.0 * MERGE_LATE_DECEL_MPS2 * max(d - 1.0, 0.1)  # stopping short would be too hard
        if (d < MERGE_PUT_OFF_WITHIN_M or late) and change.delay_m < change.max_delay_m:
            self._change_delays[change.edge_index] = change.delay_m + MERGE_PUT_OFF_M
            self._rebuild_path()
            return kw
        if late:
            return kw  # committed
        if held is None or held[0] != change.edge_index:
            self._merge_held = (change.edge_index, w.t_s)
        return {**kw, "merge_dist_m": d}

    @staticmethod
    def _fall_behind(w: World, ahead: tuple[int, float] | None, seen: dict) -> dict:
        """A car ahead in the lane the ego must move into, in its way there, is its leader (when nearer than
        the one it has): the driver drops back to slot in behind it. Putting the change off 20 m at a time,
        the ego drove beside such a car at its speed and never moved over (Monaco 166009792#2, experiment P2
        baseline: 150 m in the other lane while two cars stayed between the lead and the ego)."""
        if ahead is None or (seen.get("leader_present") and seen["leader_gap_m"] <= ahead[1]):
            return {}
        slot, gap = ahead
        return {"leader_present": True, "leader_id": w.ids[slot], "leader_gap_m": gap,
                "leader_speed_mps": float(w.speed_mps[slot])}  # fmt: skip

    def _lead_in_new_lane(self, w: World, near: np.ndarray, change: LaneChange, s_front: float) -> bool:
        """Whether the lead car is ahead of the ego's front in the lanes ``change`` enters."""
        front_now = s_front - change.s_start + change.delay_m  # the ego's front, from the edge's start
        return any(w.ids[slot] == LEAD_ID and p - w.length_m[slot] > front_now
                   for slot, _lane, p in self._watched(w, near, change, feeders=False))  # fmt: skip

    def _keep_letting_in(self, w: World, s_front: float) -> None:
        """The car letting the ego in drives MERGE_LET_IN_DROP_BACK_MPS slower than the ego; it is let go once
        the ego has begun to move over (it follows the ego then), after MERGE_LET_IN_S, or when it has left
        the simulation."""
        if self._let_in is None:
            return
        vid, since, edge_index = self._let_in
        moving_over = self._new_lane is not None and self._new_lane.edge_index == edge_index
        if vid not in w.slot_of:
            self._let_in = None
        elif moving_over or self.path.edge_index(s_front) > edge_index or w.t_s - since >= MERGE_LET_IN_S:
            self.bridge.cap_speed(vid, None)
            self._let_in = None
        else:
            self.bridge.cap_speed(vid, max(self.car.state().speed_mps - MERGE_LET_IN_DROP_BACK_MPS, 0.0))

    def _no_gap(self, w: World, near: np.ndarray, s_front: float, change: LaneChange, enter_s: float,
                v: float) -> tuple[bool, str | None, tuple[int, float] | None]:  # fmt: skip
        """Whether a vehicle in (or coming into) the lanes ``change`` enters leaves the ego no gap when its
        front reaches ``enter_s``; the nearest car on those lanes, or still on a lane leading into them,
        that can still slow to the ego's speed MERGE_MIN_GAP_M behind its rear (the one to let it in; a car
        still coming in passed the ego waiting near the edge's start, Helsinki 194850767#2), or the one already
        letting it in while it is behind the ego; and (slot, bumper gap now [m]) of the nearest car of a moving
        stream in the way that is ahead of the ego's front already (the one to fall behind)."""
        held = self._merge_held
        impatient = held is not None and held[0] == change.edge_index and w.t_s - held[1] >= MERGE_PATIENCE_S
        tau = MERGE_IMPATIENT_TAU_S if impatient else MERGE_TAU_S
        decel = MERGE_IMPATIENT_DECEL_MPS2 if impatient else MERGE_DECEL_MPS2
        t_e, v_e = pull_away_arrival(v, max(v, self.path.speed_limit(s_front)[0]), enter_s - s_front)
        front = enter_s - change.s_start + change.delay_m  # the ego's front then, from the edge's start
        rear = front - self.car.params.length_m
        rear_now = rear - (enter_s - s_front)
        front_now = front - (enter_s - s_front)
        blocked, behind, behind_p, ahead = False, None, -math.inf, None
        for slot, _lane, p in self._watched(w, near, change, feeders=True):
            vf = float(w.speed_mps[slot])
            faster = max(0.0, vf - v)  # it gains this on the ego until it has slowed to the ego's speed
            matched_p = p + faster * self.step_s + faster * faster / (2.0 * MERGE_LET_IN_DECEL_MPS2)
            letting_in = self._let_in is not None and w.ids[slot] == self._let_in[0]
            if (
                behind_p < p
                and w.ids[slot] != LEAD_ID
                and (
                    (letting_in and p <= rear_now)  # still behind: it stays the one (slowed, it is slower)
                    or (
                        matched_p <= rear_now - MERGE_MIN_GAP_M
                        and vf + 0.5 >= v  # a slower car falls behind anyway (the ego drives past a queue)
                    )
                )
            ):
                behind, behind_p = w.ids[slot], p
            if p - w.length_m[slot] >= front + MERGE_FRONT_GAP_M:
                continue  # clear ahead already (a car crawling in a queue may stop again: not as predicted)
            v_in = min(v_e, max(v, vf))  # behind a car, the ego speeds up no faster than it drives
            ego_secure = MERGE_MIN_GAP_M + v_in * tau + max(0.0, v_in * v_in - vf * vf) / (2.0 * decel)
            if vf >= MERGE_STREAM_MPS and p + vf * t_e - w.length_m[slot] >= front + ego_secure:
                continue  # a moving car ahead: far enough ahead when the ego gets there
            secure = MERGE_MIN_GAP_M + vf * tau + max(0.0, vf * vf - v_e * v_e) / (2.0 * decel)
            if p + vf * t_e <= rear - secure:
                continue  # far enough behind when the ego gets there
            blocked = True
            gap_now = p - w.length_m[slot] - front_now
            if vf >= MERGE_STREAM_MPS and gap_now > 0.0 and (ahead is None or gap_now < ahead[1]):
                ahead = (slot, float(gap_now))
        return blocked, behind, ahead

    def _yield_line(self, w: World, s_front: float, tls) -> dict:
        """The next line where the ego must yield (a stop or give-way sign, a minor road, priority to the
        right, a roundabout entry; a green without priority at a light) and, near it, the gap in the
        priority traffic: when the first vehicle the ego must let pass reaches the conflict [s] (paper IV.B:
        vehicles approaching within 200 m count)."""
        lines = self.path.stop_lines
        kw: dict = {}
        # the lines more than 1 m behind are skipped (they are sorted by arc position)
        for i in range(bisect.bisect_left(self.path.stop_s, s_front - 1.0), len(lines)):
            line = lines[i]
            if line.s_m - s_front > 300.0:
                break
            kind = _SIGN_OF_STATE.get(line.state)
            permissive = False
            if kind is None and tls and tls[3] == _TLS_YIELD and abs(tls[2] - (line.s_m - s_front)) < 5.0:
                kind, permissive = "yield", True
            if kind:
                dist = max(0.0, line.s_m - s_front)
                kw.update(sign_kind=kind, sign_dist_m=dist, sign_id=line.junction,
                          junction_movement=movement_of(line.direction, line.into_roundabout, permissive))  # fmt: skip
                if dist <= YIELD_LOOK_M:
                    stopping_for = (self._let_in[0] if self._let_in is not None else None, self.courtesy.car)
                    kw["junction_gap_s"] = priority_gap_s(w, self.bridge, EGO_ID, dist, stopping_for)
                break
        return kw

    def _ask_courtesy(self, w: World, s_front: float, speed_mps: float, kw: dict) -> None:
        """The ego standing first in line at a yield line (no car between it and the line) for
        COURTESY_AFTER_S is let in (``CourtesyYield``)."""
        dist = kw.get("sign_dist_m")
        first = (
            dist is not None
            and dist <= FIRST_AT_LINE_M
            and speed_mps < STOPPED_FOR_MPS
            and not (kw.get("leader_present") and kw["leader_gap_m"] < dist)
        )
        if not first:
            self._first_at_line = None
            return
        if self._first_at_line is None or self._first_at_line[0] != kw["sign_id"]:
            self._first_at_line = (kw["sign_id"], w.t_s)
        elif w.t_s - self._first_at_line[1] >= COURTESY_AFTER_S:
            line_s = s_front + dist
            self.courtesy.ask(w, EGO_ID, dist, line_s, kw["sign_id"], self.path.junction_end(line_s))

    def _route_changed(self, first: int) -> None:
        """The route's edges from index ``first`` on are new (extended, or a way round a stalled queue):
        what was planned for the old ones goes, SUMO gets the new stretch, the path is built again."""
        self._change_delays = {i: m for i, m in self._change_delays.items() if i < first}
        if self._merge_held is not None and self._merge_held[0] >= first:
            self._merge_held = None
        if self._let_in is not None and self._let_in[2] >= first:
            self._let_in = None
        if self._sumo_route_end is None or self._sumo_route_end > first:
            self._route_renewed = True  # SUMO holds edges that are no longer the route: give it the new ones
        self._rebuild_path()

    def _rebuild_path(self) -> None:
        """The route was extended or a lane change put off: the path again from the whole route, the
        projection kept."""
        last_s = self.path._last_s
        self.path = self._path_of(self.route, self._change_delays)
        self.path._last_s = last_s
        self._tls_cache = None

    def integrate(self) -> None:
        """The ego phase: the car over one SUMO step under the driver's controls."""
        if not self.started:
            return
        c = self.controls
        self.car.step(c.throttle, c.brake, c.steer, self.step_s)

    def write_back(self, w: World) -> dict:
        """The writeback phase: the car's pose and speed into SUMO for the next step; returns the ego's
        additions to /ego/state (empty before the ego has started)."""
        if not self.started:
            return {}
        st = self.car.state()
        x, y, angle = st.to_sumo(self.origin)
        p = self.percept
        slot = w.slot_of.get(EGO_ID)
        # on its own path and mapped to a lane by SUMO: no need to search the network for the road
        mapped = p is not None and slot is not None and w.edge_code[slot] >= 0
        suspicious = not mapped or abs(p.lateral_error_m) > ON_PATH_M
        # in a junction passed before, the free mapping once the twin is inside it; while SUMO still has it on
        # the road into it, the on-route mapping takes the route's next internal lane (SUMO searches the
        # upcoming edges first), where the free one may take another that starts at the same point
        twin_inside = mapped and w.edge_names[w.edge_code[slot]].startswith(":")
        on_route = (self._on_sumo_route and mapped and abs(p.lateral_error_m) <= ON_ROUTE_M
                    and self.s_front_m > self._free_mapping_until_s
                    and not (twin_inside and self._in_junction_passed_before(self.s_front_m))
                    and not self._over_an_earlier_pass(self.s_front_m))  # fmt: skip
        self._mapped_on_route = on_route
        if on_route and self._new_lane is not None:  # SUMO maps the twin onto the nearest lane: that one
            x, y = self._new_lane.onto_new_lane(x, y)
        edge_hint, lane_hint = "", -1  # none
        if not on_route and self.s_front_m is not None:
            # SUMO maps the pose onto the nearest lane; where a junction's internal lanes start together (a
            # lane that turns and one that goes straight) either is nearest: the path's own breaks the tie
            # (Krems cluster_206089614_71582005, passed twice: the twin took the lane to 24980491#2 and SUMO
            # held a route off the ego's for 2 s)
            lane = self.path.lane_at(self.s_front_m + max(st.speed_mps, 0.0) * self.step_s)  # where it is now
            if lane is not None:
                edge_hint, lane_hint = lane
        ev = self.bridge.write_ego(x, y, angle, st.speed_mps, edge_hint=edge_hint, lane_hint=lane_hint,
                                   verify_on_road=suspicious, on_route=on_route)  # fmt: skip
        if ev:
            self.emit(ev)
        return {
            "throttle": round(self.controls.throttle, 4), "brake": round(self.controls.brake, 4),
            "steer": round(self.controls.steer, 4), "physics_speed_mps": round(st.speed_mps, 4),
            "path_offset_m": round(p.lateral_error_m, 4) if p else None,
            "leader_id": p.leader_id if p else None,
            "leader_gap_m": round(p.leader_gap_m, 3) if p and p.leader_present else None,
            "tls_state": p.tls_state if p else None,
            "sign": p.sign_kind if p else None,
            "sign_dist_m": round(p.sign_dist_m, 2) if p and p.sign_kind else None,
            # the driver judged the junction ahead not passable: gap too short (or blocked)
            "junction_conflict": bool(getattr(getattr(self.driver, "debug", None), "yielding", False)),
            "junction_gap_s": round(p.junction_gap_s, 2) if p and math.isfinite(p.junction_gap_s) else None,
            "driver_mode": getattr(getattr(self.driver, "debug", None), "mode", ""),
        }  # fmt: skip

    def _on_a_passed_edge(self, w: World, slot: int, s_front: float) -> bool:
        """Whether SUMO has the twin on an edge the route passed before the one the ego is on (or has just
        left: SUMO may be a step behind), see FREE_MAPPING_M."""
        road = w.edge_of(slot)
        k = self.path.edge_index(s_front)
        if not road or road.startswith(":") or road in self.route[max(0, k - 1) : k + 1]:
            return False
        return road in self.route[: max(0, k - 1)]

    def _in_junction_passed_before(self, s_front: float | None) -> bool:
        """Whether the ego's front is in (or within REPASS_MARGIN_M of) a junction its route has passed
        before. There SUMO's on-route mapping (keepRoute=1) also matches the pose onto the internal lanes of
        the earlier pass, since the route SUMO holds keeps the edges driven (and a replaced route keeps them
        too): Krems 71582001, make experiment P3, the twin was put onto the earlier left turn's
        :71582001_24_0, 1.33 m away, instead of its own lane 0.13 m away, flipped between the two every
        step, and SUMO moved scv677 from the parallel lane onto the ego. The free mapping (keepRoute=2)
        takes the nearest lane in the pose's heading: its own."""
        if s_front is None:
            return False
        path = self.path
        if self._repassed_for is not path:
            seen: set[str] = set()
            spans = []
            ends = [a for a, _b, _e, _l in path.edge_lanes[1:]]  # where the path is on the next edge
            for stop in path.stop_lines:
                if stop.junction in seen and 0 <= stop.edge_index < len(ends):
                    spans.append((stop.s_m - REPASS_MARGIN_M, ends[stop.edge_index] + REPASS_MARGIN_M))
                seen.add(stop.junction)
            self._repassed, self._repassed_for = spans, path
        return any(a <= s_front <= b for a, b in self._repassed)

    def _over_an_earlier_pass(self, s_front: float | None) -> bool:
        """Whether the ego's front is within REPASS_MARGIN_M of where its path passes near a stretch of
        itself driven before (see REPASS_RADIUS_M)."""
        if s_front is None:
            return False
        if self._near_self_for is not self.path:
            spans = self.path.passes_near_itself(REPASS_RADIUS_M, REPASS_BACK_M)
            self._near_self = [(a - REPASS_MARGIN_M, b + REPASS_MARGIN_M) for a, b in spans]
            self._near_self_for = self.path
        return any(a <= s_front <= b for a, b in self._near_self)

    def close(self) -> None:
        pass

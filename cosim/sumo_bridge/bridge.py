"""The only place that talks to a running SUMO: start/close, read the snapshot, write the ego back.

The backend handle is private (``_sumo``): the phases call named operations (``remove_vehicle``,
``add_scv``, ``find_route``, ``extend_route``, ``leader`` ...); the network files are read by
``cosim.sumo_bridge.network`` and a plain-SUMO check run is ``cosim.sumo_bridge.plain``.

The backend is chosen in one place (``_backend``): libsumo in-process by default, TraCI over TCP with
``sumo-gui`` for watching a run; both expose the same API, so the rest of the code path is identical.
Reading uses plain libsumo getters (measured faster than subscriptions and context queries in libsumo:
see bench/bench_core.py).
"""

from __future__ import annotations

import heapq
import math
from itertools import chain

import numpy as np
import shapely

from cosim.driver.gap_acceptance import FOE_RADIUS_M
from cosim.errors import CosimError
from cosim.sumo_bridge.tools import binary
from cosim.world import (  # noqa: F401 (the ids and SumoEvent are re-exported for old imports)
    EGO_ID,
    EGO_VTYPE,
    LEAD_ID,
    LEAD_VTYPE,
    SCV_VTYPE,
    SumoEvent,
    World,
)

# the lead drives a little below the limit, as a leader who wants to be followed does (an SCV's speed
# factor is drawn from 0.8-1.2: a fast one would leave the participant behind at every stretch)
LEAD_SPEED_FACTOR = 0.95
HELD_BACK_GAP_M = 10.0  # a standing car this close behind another is queued, not about to go [m]
OFF_ROAD_STEPS = 5  # the ego is off the road after this many consecutive steps without a lane
# lanes of one road differ in length (curves, lanes that begin or end), so a light's distance falls a little
# faster or slower than the odometer runs: next_tls asks again this long before the light is in reach [m]
TLS_BEYOND_SLACK_M = 10.0
MATCH_THRESHOLD_M = 5.0  # an ego pose farther than this from every lane's centre line is off the road [m]
# A car at rest in MuJoCo still creeps by ~1e-5 m. A pose a hair behind the last one makes SUMO measure the
# move along the route the long way round: a phantom speed, and a collision with the car ahead it stands
# behind. At rest the ego's SUMO twin therefore keeps its pose until it moves by more than this [m].
STANDSTILL_JITTER_M = 0.01
STANDSTILL_SPEED_MPS = 0.05
# SUMO's default max-gap of an actuated light: a green is extended while vehicles cross its detectors at most
# this far apart (sumo.dlr.de/docs/Simulation/Traffic_Lights.html, "Actuated Traffic Lights") [s]
ACTUATED_MAX_GAP_S = 3.0
PARKED_FOR_GOOD_S = 86400.0  # a roadside stop lasts until ``rejoin`` ends it [s]
STOP_PARKING = 1  # TraCI's stop flag for parking: off the lane, beside it
# SUMO's position of a vehicle that is off the network for a moment: re-inserted after a roadside stop
# (libsumo's INVALID_DOUBLE_VALUE, -2^30) [m]
INVALID_POSITION = -1.0e9
# SUMO reports a collision again every step the two bodies overlap, and where one car overlaps two it names
# the pairs in turn (Krems, make experiment P1: ego/scv181 and ego/scv188 every other step, 30 events in
# 3 s): a pair reported within this many steps is the same collision, reported once
COLLISION_MEMORY_STEPS = 10
PULL_OVER_PAST_JUNCTION_M = 10.0  # a roadside stop on the next edge is at least this far into it [m]
MAX_INTERNAL_CHAIN = 8  # internal lanes one way through a junction is split into, at most (netconvert: 2)


def _phase_span(phase) -> tuple[float, float, str]:
    """(shortest, longest) duration [s] and state of a light's phase: its minDur and maxDur when they bound
    the duration (an actuated phase), its duration twice otherwise (a fixed one: libsumo gives them -1 or the
    duration)."""
    d, lo, hi = float(phase.duration), float(phase.minDur), float(phase.maxDur)
    return (lo, hi, phase.state) if 0.0 <= lo <= d <= hi < math.inf else (d, d, phase.state)


def _allows_cars(allowed: list[str] | tuple[str, ...]) -> bool:
    return not allowed or "passenger" in allowed  # SUMO lists nothing when every class is allowed


def _backend(use_traci: bool):
    if use_traci:
        import traci

        return traci
    import libsumo

    return libsumo


def _footprint(
    x_m: float, y_m: float, heading_deg: float, length_m: float, width_m: float
) -> shapely.Polygon:
    """A vehicle's body: the rectangle behind its front bumper's centre (x, y), SUMO heading (0 = north)."""
    ux, uy = math.sin(math.radians(heading_deg)), math.cos(math.radians(heading_deg))
    half_x, half_y = uy * 0.5 * width_m, -ux * 0.5 * width_m  # to its right
    rear_x, rear_y = x_m - ux * length_m, y_m - uy * length_m
    return shapely.Polygon([(x_m + half_x, y_m + half_y), (x_m - half_x, y_m - half_y),
                            (rear_x - half_x, rear_y - half_y), (rear_x + half_x, rear_y + half_y)])  # fmt: skip


class _LaneTable(dict):
    """SUMO lane id -> row of (edge code, lane index); a lane seen for the first time is split and its edge
    interned in ``world`` (``__missing__``), so the per-step lookup is one C-level dict access per vehicle.
    Row 0 is the empty lane id of a vehicle off the network (-1, -1)."""

    def __init__(self):
        super().__init__({"": 0})
        self.world: World | None = None
        self._edge, self._index = [-1], [-1]
        self._arrays: tuple[np.ndarray, np.ndarray] | None = None

    def __missing__(self, lane: str) -> int:
        edge, _, idx = lane.rpartition("_")
        row = self[lane] = len(self._edge)
        self._edge.append(self.world.intern_edge(edge))
        self._index.append(int(idx) if idx.isdigit() else -1)
        self._arrays = None
        return row

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(edge code, lane index) by row."""
        if self._arrays is None:
            self._arrays = (np.array(self._edge, np.int32), np.array(self._index, np.int16))
        return self._arrays


def collision_onset(seen: dict[tuple[str, str], int], pair: tuple[str, str], step: int) -> bool:
    """Whether SUMO's report of ``pair`` at ``step`` starts a collision (see COLLISION_MEMORY_STEPS);
    records it in ``seen``."""
    last = seen.get(pair)
    seen[pair] = step
    return last is None or step - last > COLLISION_MEMORY_STEPS


def forget_collisions(seen: dict[tuple[str, str], int], step: int) -> None:
    """Drop the pairs of ``seen`` not reported for COLLISION_MEMORY_STEPS."""
    for pair in [p for p, last in seen.items() if step - last > COLLISION_MEMORY_STEPS]:
        del seen[pair]


class SumoBridge:
    def __init__(self, sumocfg, *, seed: int, step_s: float, gui: bool = False, traci: bool = False,
                 extra_args: tuple[str, ...] = ()):  # fmt: skip
        """``gui`` watches the run in sumo-gui (over TraCI); ``traci`` uses TCP without a GUI (benchmarks)."""
        self.gui = gui
        self._sumo = _backend(gui or traci)
        cmd = [binary("sumo-gui" if gui else "sumo"), "-c", str(sumocfg), "--seed", str(seed),
               "--step-length", f"{step_s:g}", "--no-warnings", "true", "--no-step-log", "true",
               # collision detection is the scenario's (its sumocfg), so bare SUMO on it pays the same
               "--additional-files", str(sumocfg.parent / "signs.add.xml"),  # buildings are cosim's, not SUMO's
               *extra_args]  # fmt: skip
        if gui:
            cmd += ["--start", "true", "--quit-on-end", "true"]
        try:
            self._sumo.start(cmd)
        except Exception as exc:  # libsumo raises a bare error; the message log has the detail
            raise CosimError(f"SUMO could not start the scenario {sumocfg}: {exc}") from None
        self.step_s = step_s
        self.open = True
        self._lanes = _LaneTable()
        self._tls_ids: list[str] | None = None
        self._getters = self._fast_getters()
        self.ego_id: str | None = None
        self.ego_on_road = True
        self._unmapped_steps = 0
        self._pose_off_road = False
        self._ego_pose: tuple[float, float, float] | None = None  # last pose written to SUMO
        self._collision_seen: dict[tuple[str, str], int] = {}  # pair -> step SUMO last reported it
        self._removed: list[str] = []  # removed by cosim this step
        self._tls_logics: dict[tuple[str, str], list[tuple[float, float, str]] | None] = {}
        self._tls_max_gaps: dict[str, float] = {}
        # vehicle -> (its route changes, next_tls' reach, odometer [m] before which its next light lies beyond)
        self._tls_beyond: dict[str, tuple[int, float, float]] = {}
        self._route_changes: dict[str, int] = {}  # vehicle -> routes given to it (any teleport counts too)
        # light -> (link index -> its lane's detector distance before the stop line [m], (detector, links of
        # its lane) per detector); None: no detectors of its own (not gap-actuated)
        self._tls_detectors: dict[str, tuple[dict[int, float], list[tuple[str, list[int]]]] | None] = {}
        self._incoming: dict[str, list[tuple[str, str, float]]] | None = None  # lane -> lanes into it
        self._lc_mode_before: dict[str, int] = {}  # vehicle -> its lane-change mode while keep_lane forces

    def close(self) -> None:
        if self.open:
            self.open = False
            self._sumo.close()

    # -- stepping --------------------------------------------------------------------------------------------
    def step(self, world: World) -> list[SumoEvent]:
        """Advance SUMO one step and refresh ``world`` in place; returns the step's traffic events."""
        self.advance()
        return self.read(world)

    def advance(self) -> None:
        """SUMO computes one step (``read`` brings it into the snapshot)."""
        self._sumo.simulationStep()

    def read(self, world: World) -> list[SumoEvent]:
        """Refresh ``world`` in place from the step SUMO computed last; returns the step's traffic events."""
        sumo = self._sumo
        sim = sumo.simulation
        world.step += 1
        world.t_s = sim.getTime()
        for vid in sim.getArrivedIDList():
            world.remove(vid)
        for vid in self._removed:  # SUMO does not list vehicles removed by TraCI as arrived
            world.remove(vid)
        self._removed.clear()
        veh = sumo.vehicle
        for vid in sim.getDepartedIDList():
            slot = world.add(vid, is_ego=(vid == self.ego_id))
            world.length_m[slot] = veh.getLength(vid)
            world.width_m[slot] = veh.getWidth(vid)
        events = [SumoEvent("teleport", v, self._where(world, v)) for v in sim.getStartingTeleportIDList()]
        for e in events:
            self._route_changes[e.vehicle] = self._route_changes.get(e.vehicle, 0) + 1
        for c in sim.getCollisions():
            if collision_onset(self._collision_seen, (c.collider, c.victim), world.step):
                detail = f"with {c.victim} ({c.type}) on {c.lane}"
                kind = "collision" if self._bodies_touch(c.collider, c.victim) else "ego_twin_overlap"
                events.append(SumoEvent(kind, c.collider, detail, c.colliderSpeed))
        if self._collision_seen:
            forget_collisions(self._collision_seen, world.step)
        self._read(world)
        ego = world.slot_of.get(self.ego_id) if self.ego_id else None
        if ego is not None:  # keepRoute=2 places an ego that left the road off-lane (empty lane id)
            mapped = world.edge_code[ego] >= 0 and not self._pose_off_road
            self._unmapped_steps = 0 if mapped else self._unmapped_steps + 1
            # a single unmapped step happens where lanes meet at a junction; off-road means staying off
            on_road = self._unmapped_steps < OFF_ROAD_STEPS
            if on_road != self.ego_on_road:
                self.ego_on_road = on_road
                events.append(SumoEvent("ego_on_road" if on_road else "ego_off_road", self.ego_id))
        return events

    @staticmethod
    def _where(world: World, vid: str) -> str:
        """Where the snapshot (the step before) last had ``vid``: the lane a teleport took it from."""
        slot = world.slot_of.get(vid)
        if slot is None or world.edge_code[slot] < 0:
            return ""
        return f"from {world.edge_names[world.edge_code[slot]]}_{world.lane_index[slot]}"

    def _bodies_touch(self, collider: str, victim: str) -> bool:
        """Whether the two bodies SUMO found overlapping do: for the ego, its car (the pose written for this
        step), not its twin. The twin sits on a lane SUMO matched the pose to, which may be the neighbouring
        internal lane of a junction 1.5 m from the car (Monaco seed 2: on a car waiting at its line, 2.7 m
        from the car itself); such an overlap is the twin's alone."""
        if self.ego_id not in (collider, victim) or self._ego_pose is None or self._pose_off_road:
            return True
        other = victim if collider == self.ego_id else collider
        veh = self._sumo.vehicle
        x, y = veh.getPosition(other)
        ego = _footprint(*self._ego_pose, veh.getLength(self.ego_id), veh.getWidth(self.ego_id))
        return ego.intersects(
            _footprint(x, y, veh.getAngle(other), veh.getLength(other), veh.getWidth(other))
        )

    def _read(self, world: World) -> None:
        """All vehicles' pose, speed, acceleration and lane with one pass of plain getters per quantity.

        ``map`` over the getters and one numpy assignment per field keep the per-vehicle Python overhead
        small; lane position, lateral offset and signals are read for the ego only (nothing else uses them).
        """
        slots, ids = world.live()
        n = len(ids)
        if not n:
            return
        get = self._getters
        xy = np.fromiter(chain.from_iterable(map(get["position"], ids)), np.float64, 2 * n)
        x, y = xy[0::2], xy[1::2]
        fresh = world.depart_step[slots] == world.step
        off = x <= INVALID_POSITION
        if off.any():  # off the network for a moment (leaving a roadside stop): it keeps its last pose
            x[off], y[off] = world.x_m[slots[off]], world.y_m[slots[off]]
        # a car whose position did not change at all stands: its speed is 0 and its lane the same (SUMO
        # moves a car by its speed times the step), so speed and lane are read for the moving ones only
        moved = fresh | (x != world.x_m[slots]) | (y != world.y_m[slots]) | world.is_ego[slots]
        world.x_m[slots] = x
        world.y_m[slots] = y
        heading = np.fromiter(map(get["angle"], ids), np.float64, n)
        world.heading_deg[slots] = np.where(off, world.heading_deg[slots], heading)
        if moved.all():
            mslots, mids = slots, ids
        else:
            mslots = slots[moved]
            mids = [ids[i] for i in np.flatnonzero(moved).tolist()]
        speed = np.zeros(n)
        speed[moved] = np.fromiter(map(get["speed"], mids), np.float64, len(mids))
        # SUMO's acceleration is the speed change over the step: derived here instead of one more getter
        # per vehicle (a vehicle that departed this step has no previous speed: 0)
        world.accel_mps2[slots] = np.where(fresh, 0.0, (speed - world.speed_mps[slots]) / self.step_s)
        world.speed_mps[slots] = speed
        lanes = self._lanes
        lanes.world = world
        rows = np.fromiter(map(lanes.__getitem__, map(get["lane"], mids)), np.intp, len(mids))
        edge_code, lane_index = lanes.arrays()
        world.edge_code[mslots] = edge_code[rows]
        world.lane_index[mslots] = lane_index[rows]
        ego = world.slot_of.get(self.ego_id) if self.ego_id else None
        if ego is not None:
            veh = self._sumo.vehicle
            world.lane_pos_m[ego] = veh.getLanePosition(self.ego_id)
            world.lateral_offset_m[ego] = veh.getLateralLanePosition(self.ego_id)
            world.signals[ego] = veh.getSignals(self.ego_id)

    def _fast_getters(self) -> dict:
        """Getters called for every vehicle (or light) each step; with libsumo its compiled functions
        directly, skipping the Python wrapper around each (a fifth of the read time at 1000 vehicles).
        TraCI keeps its own methods."""
        names = {"position": ("vehicle", "getPosition"), "angle": ("vehicle", "getAngle"),
                 "speed": ("vehicle", "getSpeed"), "lane": ("vehicle", "getLaneID"),
                 "tls_state": ("trafficlight", "getRedYellowGreenState")}  # fmt: skip
        native = getattr(self._sumo, "_libsumo", None)
        return {
            k: getattr(native, f"{d}_{m}", None) or getattr(getattr(self._sumo, d), m)
            for k, (d, m) in names.items()
        }

    def traffic_lights(self) -> tuple[list[str], list[str]]:
        """(ids, states) of every traffic light, sorted by id (the set of lights never changes in a run)."""
        if self._tls_ids is None:
            self._tls_ids = sorted(self._sumo.trafficlight.getIDList())
        return list(self._tls_ids), list(map(self._getters["tls_state"], self._tls_ids))

    # -- ego -------------------------------------------------------------------------------------------------
    def remove_vehicle(self, vid: str) -> None:
        """Take a vehicle (or a pending insertion) out of SUMO; it leaves the world at the next step."""
        self._sumo.vehicle.remove(vid)
        self._removed.append(vid)

    def pending_on(self, edges: list[str]) -> list[str]:
        """Vehicles waiting to be inserted whose route starts on one of ``edges``."""
        veh, wanted = self._sumo.vehicle, set(edges)
        return [v for v in self._sumo.simulation.getPendingVehicles() if veh.getRoute(v)[0] in wanted]

    def add_vehicle(self, vid: str, route: list[str], *, depart: float | str = "now", type_id: str | None = None,
                    depart_speed: str = "0", color=None) -> None:  # fmt: skip
        rid = f"route_{vid}"
        self._sumo.route.add(rid, route)
        self._sumo.vehicle.add(vid, rid, typeID=type_id or "DEFAULT_VEHTYPE", depart=str(depart),
                               departLane="best", departSpeed=depart_speed)  # fmt: skip
        if color is not None:
            self._sumo.vehicle.setColor(vid, color)

    def add_scv(self, vid: str, route_id: str, depart_pos_m: float) -> None:
        """Insert an SCV (``SCV_VTYPE``) on the scenario's route ``route_id``, from standstill at
        ``depart_pos_m`` along its first edge's best lane (``cosim.phases.traffic``)."""
        self._sumo.vehicle.add(vid, route_id, typeID=SCV_VTYPE, depart="now", departLane="best",
                               departPos=f"{depart_pos_m:.1f}", departSpeed="0")  # fmt: skip

    def place_on_route(self, vid: str, route: list[str], front_m: float, *, type_id: str, color=None) -> None:
        """Add a vehicle on ``route`` with its front bumper ``front_m`` along it and place it there at the next
        step, whatever SUMO's insertion queue holds (moveToXY inserts a vehicle that has not departed yet;
        a plain insertion waits behind every pending vehicle of its edge)."""
        self.add_vehicle(vid, route, depart="now", type_id=type_id, color=color)
        lane = self._sumo.lane
        for edge in route:
            lanes = [f"{edge}_{i}" for i in range(self._sumo.edge.getLaneNumber(edge))]
            lane_id = next((ln for ln in lanes if _allows_cars(lane.getAllowed(ln))), lanes[0])
            length = lane.getLength(lane_id)
            if front_m <= length or edge == route[-1]:
                break
            front_m -= length
        pos = min(max(front_m, 0.1), length - 0.1)
        x, y = self._sumo.simulation.convert2D(edge, pos, int(lane_id.rpartition("_")[2]))
        self._sumo.vehicle.moveToXY(vid, edge, int(lane_id.rpartition("_")[2]), x, y, keepRoute=1)

    def add_lead(self, route: list[str], front_m: float) -> None:
        """The lead vehicle of the following task, placed on ``route`` (see ``place_on_route``)."""
        vtype = self._sumo.vehicletype
        if LEAD_VTYPE not in vtype.getIDList():
            vtype.copy("DEFAULT_VEHTYPE", LEAD_VTYPE)
            vtype.setSpeedFactor(LEAD_VTYPE, LEAD_SPEED_FACTOR)
            vtype.setSpeedDeviation(LEAD_VTYPE, 0.0)
        self.place_on_route(LEAD_ID, route, front_m, type_id=LEAD_VTYPE, color=(40, 120, 255, 255))

    def add_ego(self, route: list[str], *, depart: float | str = "now", controlled: bool, length_m: float,
                width_m: float, front_m: float | None = None) -> None:  # fmt: skip
        """Insert the ego with the car's dimensions; with ``front_m`` placed on its route at the next step
        (``place_on_route``), else queued for insertion at ``depart``. When MuJoCo drives it
        (``controlled``), SUMO must not move it by itself."""
        self.ego_id = EGO_ID
        vtype = self._sumo.vehicletype
        if EGO_VTYPE not in vtype.getIDList():  # a scenario from elsewhere: SUMO's default car
            vtype.copy("DEFAULT_VEHTYPE", EGO_VTYPE)
        vtype.setLength(EGO_VTYPE, length_m)
        vtype.setWidth(EGO_VTYPE, width_m)
        color = (255, 40, 40, 255)
        if front_m is None:
            self.add_vehicle(EGO_ID, route, depart=depart, type_id=EGO_VTYPE, color=color)
        else:
            self.place_on_route(EGO_ID, route, front_m, type_id=EGO_VTYPE, color=color)
        if controlled:
            veh = self._sumo.vehicle
            veh.setSpeedMode(EGO_ID, 0)  # no SUMO safety checks: the physics decides
            veh.setLaneChangeMode(EGO_ID, 0)

    def write_ego(self, x_m: float, y_m: float, heading_deg: float, speed_mps: float, edge_hint: str = "",
                  lane_hint: int = -1, verify_on_road: bool = True, on_route: bool = False) -> SumoEvent | None:  # fmt: skip
        """Place the ego (front-bumper pose) for the next SUMO step and tell followers its speed.

        ``on_route``: the caller knows the ego is on the route SUMO holds for it, so the pose is mapped onto
        that route only (keepRoute=1), never onto another road it passes close to (the opposite lane in a
        tight bend, a crossing lane inside a junction). Otherwise keepRoute=2 lets SUMO map it onto any lane
        (the driver may leave the route). A pose farther than ``matchThreshold`` from every lane puts the
        ego off-road, which ``step`` reports as an event.
        ``verify_on_road`` looks that up first (a search over all lanes, ~5 ms): the caller skips it while
        the ego is plainly on its path.
        """
        veh, sim = self._sumo.vehicle, self._sumo.simulation
        last = self._ego_pose
        if (last is not None and speed_mps < STANDSTILL_SPEED_MPS
                and math.hypot(x_m - last[0], y_m - last[1]) < STANDSTILL_JITTER_M):  # fmt: skip
            x_m, y_m, heading_deg = last
        self._ego_pose = (x_m, y_m, heading_deg)
        try:
            if verify_on_road or self._pose_off_road:
                # far from every lane: keep the SUMO twin where it last was on the road (SUMO is not meant
                # to carry a vehicle off the network for long) and let step() report the ego as off-road
                edge, pos, lane = sim.convertRoad(x_m, y_m, False, "passenger")
                rx, ry = sim.convert2D(edge, pos, lane)
                self._pose_off_road = math.hypot(rx - x_m, ry - y_m) > MATCH_THRESHOLD_M
                if self._pose_off_road:
                    return None
            try:
                veh.moveToXY(EGO_ID, edge_hint, lane_hint, x_m, y_m, heading_deg, keepRoute=1 if on_route else 2,
                             matchThreshold=MATCH_THRESHOLD_M)  # fmt: skip
            except Exception:  # libsumo.TraCIException: no lane of the route that near; any lane will do
                if not on_route:
                    raise
                veh.moveToXY(EGO_ID, edge_hint, lane_hint, x_m, y_m, heading_deg, keepRoute=2,
                             matchThreshold=MATCH_THRESHOLD_M)  # fmt: skip
            veh.setPreviousSpeed(EGO_ID, max(0.0, speed_mps))
        except Exception as exc:  # libsumo.TraCIException: the pose could not be used at all
            return SumoEvent("ego_write_failed", EGO_ID, str(exc).splitlines()[0][:200])
        return None

    def _set_route(self, vid: str, edges: list[str]) -> str | None:
        """SUMO's setRoute for ``vid``; the first line of SUMO's refusal, or None when it took the route."""
        try:
            self._sumo.vehicle.setRoute(vid, edges)
        except Exception as exc:  # libsumo.TraCIException
            return str(exc).splitlines()[0][:200]
        self._route_changes[vid] = self._route_changes.get(vid, 0) + 1
        return None

    def set_ego_route(self, edges: list[str]) -> SumoEvent | None:
        """Replace the ego's route in SUMO; ``edges[0]`` must be the edge it is on."""
        refused = self._set_route(EGO_ID, edges)
        return None if refused is None else SumoEvent("ego_route_rejected", EGO_ID, refused)

    def extend_route(self, vid: str, edges: list[str]) -> bool:
        """Append ``edges`` to the route SUMO holds for ``vid`` (which must end where they start); False
        when SUMO refused (e.g. while the vehicle is being inserted): the caller tries again later."""
        veh = self._sumo.vehicle
        try:
            held = veh.getRoute(vid)[veh.getRouteIndex(vid) :]
        except Exception:  # libsumo.TraCIException: not in the network yet
            return False
        return self._set_route(vid, [*held, *edges]) is None

    def replace_route(self, vid: str, edges: list[str]) -> bool:
        """Give ``vid`` the route ``edges`` (``edges[0]`` its current route edge); False when SUMO refused."""
        return self._set_route(vid, edges) is None

    def route_edge_left(self, vid: str) -> tuple[str, float]:
        """(the edge of its route ``vid`` is on or has just left for a junction, metres left on it: 0 in the
        junction)."""
        veh = self._sumo.vehicle
        edge = veh.getRoute(vid)[max(veh.getRouteIndex(vid), 0)]
        if veh.getRoadID(vid) != edge:
            return edge, 0.0
        lane = veh.getLaneID(vid) or f"{edge}_0"  # at the roadside (``pull_over``) it has no lane
        return edge, self._sumo.lane.getLength(lane) - veh.getLanePosition(vid)

    def queue_heads(self, edge: str, next_edge: str) -> list[tuple[int, float]]:
        """Per lane of ``edge`` with a connection onto ``next_edge``: (vehicles halting on it, the time its
        front vehicle has waited within SUMO's waiting-time memory [s]: creeping does not restart it)."""
        lane_api = self._sumo.lane
        out = []
        for i in range(self._sumo.edge.getLaneNumber(edge)):
            lane = f"{edge}_{i}"
            if not self._lane_leads_onto(lane, next_edge):
                continue
            ids = lane_api.getLastStepVehicleIDs(lane)  # back to front
            wait = self._sumo.vehicle.getAccumulatedWaitingTime(ids[-1]) if ids else 0.0
            out.append((lane_api.getLastStepHaltingNumber(lane), wait))
        return out

    def lane_queue(self, vid: str) -> tuple[int, float]:
        """(vehicles halting on the lane ``vid`` is on, the time its front vehicle has waited within SUMO's
        waiting-time memory [s], 0 while a red or yellow light at the lane's end holds it); (0, 0) in a
        junction or at the roadside."""
        veh = self._sumo.vehicle
        lane = veh.getLaneID(vid)
        if not lane or lane.startswith(":"):
            return 0, 0.0
        ids = self._sumo.lane.getLastStepVehicleIDs(lane)  # back to front
        halting, front = self._sumo.lane.getLastStepHaltingNumber(lane), ids[-1]
        lights = veh.getNextTLS(front)  # (id, link index, distance [m], state), nearest first
        to_end = self._sumo.lane.getLength(lane) - veh.getLanePosition(front)
        if lights and lights[0][2] <= to_end + 1.0 and lights[0][3] in "rRyYu":
            return halting, 0.0
        return halting, veh.getAccumulatedWaitingTime(front)

    def queue_ahead(self, vid: str) -> list[tuple[str, str | None]]:
        """The vehicles ahead of ``vid`` on its lane, front first, each with the next edge of its route (None
        at its route's end); [] in a junction or at the roadside."""
        veh = self._sumo.vehicle
        lane = veh.getLaneID(vid)
        if not lane or lane.startswith(":"):
            return []
        ids = self._sumo.lane.getLastStepVehicleIDs(lane)  # back to front
        ahead = ids[ids.index(vid) + 1 :] if vid in ids else ()
        out = []
        for car in reversed(ahead):
            route, i = veh.getRoute(car), veh.getRouteIndex(car)
            out.append((car, route[i + 1] if 0 <= i < len(route) - 1 else None))
        return out

    def lane_leads_to(self, vid: str, edge: str) -> bool:
        """Whether the lane ``vid`` is on has a connection onto ``edge`` (it can go there without a lane
        change)."""
        lane = self._sumo.vehicle.getLaneID(vid)
        return bool(lane) and self._lane_leads_onto(lane, edge)

    def _lane_leads_onto(self, lane: str, edge: str) -> bool:
        """Whether ``lane`` has a connection onto ``edge``."""
        return any(link[0].rsplit("_", 1)[0] == edge for link in self._sumo.lane.getLinks(lane))

    def weigh_edges(self, travel_time_s: dict[str, float], hold_s: float) -> None:
        """SUMO's router (``find_route``) takes these travel times for routes entering the edges within the
        next ``hold_s`` seconds (global edge weights; SCVs' rerouting devices keep their own)."""
        t = self._sumo.simulation.getTime()
        for edge, tt in travel_time_s.items():
            self._sumo.edge.adaptTraveltime(edge, tt, t, t + hold_s)

    def divert(
        self, vid: str, keep_off: set[str], min_ahead_m: float, continue_m: float = 300.0,
        from_its_lane: bool = False,
    ) -> str | None:  # fmt: skip
        """Send ``vid`` off the edges ``keep_off`` at the first junction at least ``min_ahead_m`` ahead where
        one of its lanes leads right or straight onto another road (never a left turn: waiting in the junction
        for a gap in the oncoming traffic, the car held up the participant behind it, 7 s on Monaco
        166009792#2; never a U-turn), then on along that road for about
        ``continue_m`` (straight on where it can, still off ``keep_off``). With ``from_its_lane`` the way
        out at the end of its own edge must leave from the lane it is on (a car standing in a queue cannot
        change lanes). Returns the edge it turns onto, or None when it already leaves ``keep_off`` within
        that stretch or no junction offers a way out."""
        veh, lane_api = self._sumo.vehicle, self._sumo.lane
        try:
            route, i = list(veh.getRoute(vid)), veh.getRouteIndex(vid)
            lane, pos = veh.getLaneID(vid), veh.getLanePosition(vid)
        except Exception:  # libsumo.TraCIException: gone meanwhile
            return None
        if i < 0 or not lane or lane.startswith(":"):
            return None
        ahead = lane_api.getLength(lane) - pos
        for k in range(i, len(route)):
            if k + 1 < len(route) and route[k + 1] not in keep_off:
                return None  # its own route leaves ``keep_off`` at this junction
            if k > i:
                ahead += lane_api.getLength(f"{route[k]}_0")
            if ahead < min_ahead_m:
                continue
            lanes = [int(lane.rsplit("_", 1)[1])] if from_its_lane and k == i else None
            out = self._exits(route[k], keep_off | {route[k]}, prefer="rs", only="rs", lanes=lanes)
            if not out:
                continue
            new = [*route[i : k + 1], out[0]]
            while sum(lane_api.getLength(f"{e}_0") for e in new[k - i + 1 :]) < continue_m:
                more = self._exits(new[-1], keep_off | set(new), prefer="s")
                if not more:
                    break
                new.append(more[0])
            return out[0] if self._set_route(vid, new) is None else None
        return None

    def _exits(self, edge: str, avoid: set[str], prefer: str = "rls", only: str = "rls",
               lanes: list[int] | None = None) -> list[str]:  # fmt: skip
        """Edges a passenger car can reach from ``edge`` (from its ``lanes``, default all) at its end junction
        in the directions ``only``, outside ``avoid``, no U-turns, ordered by the directions in ``prefer``
        (r right, l left, s straight)."""
        found: dict[str, int] = {}
        for n in lanes if lanes is not None else range(self._sumo.edge.getLaneNumber(edge)):
            # link tuples: (toLane, hasPrio, isOpen, hasFoe, via, state, direction, length)
            for link in self._sumo.lane.getLinks(f"{edge}_{n}"):
                to, direction = link[0].rsplit("_", 1)[0], link[6].lower()
                if to in avoid or direction[0] not in only or to.startswith(":"):
                    continue
                allowed = self._sumo.lane.getAllowed(link[0])
                if allowed and "passenger" not in allowed:
                    continue
                rank = prefer.find(direction[0]) if direction[0] in prefer else len(prefer)
                found[to] = min(found.get(to, rank), rank)
        return sorted(found, key=lambda e: (found[e], e))

    def route_ahead(self, vid: str, within_m: float = math.inf) -> list[str]:
        """The edges of the route SUMO holds for ``vid`` from the one it is on to the end, or to the first
        that begins ``within_m`` or more ahead of the start of the one it is on."""
        veh, lane_api = self._sumo.vehicle, self._sumo.lane
        route = veh.getRoute(vid)[max(veh.getRouteIndex(vid), 0) :]
        out, ahead = [], 0.0
        for edge in route:
            if ahead >= within_m:
                break
            out.append(edge)
            if within_m < math.inf:
                ahead += lane_api.getLength(f"{edge}_0")
        return out

    def edges_left(self, vid: str) -> int:
        """Edges of the route SUMO holds for ``vid`` from the one it is on (or has just left) to the end."""
        veh = self._sumo.vehicle
        return len(veh.getRoute(vid)) - veh.getRouteIndex(vid)

    def cap_speed(self, vid: str, speed_mps: float | None) -> None:
        """Limit a SUMO-driven vehicle's speed (its car following and right of way still apply); None gives
        it back to SUMO's own driving."""
        self._sumo.vehicle.setSpeed(vid, -1.0 if speed_mps is None else max(0.0, speed_mps))

    def set_impatience(self, vid: str, impatience: float) -> None:
        """The vehicle's impatience at junctions until it drives off (SUMO then clears it)."""
        self._sumo.vehicle.setImpatience(vid, impatience)

    def time_to_impatience_s(self) -> float:
        """The run's ``--time-to-impatience`` [s] (the scenario's sumocfg sets it)."""
        return float(self._sumo.simulation.getOption("time-to-impatience"))

    def lane_end(self, edge_id: str, lane_index: int) -> tuple[float, float]:
        """Where a lane ends (its stop line at a junction) [m]."""
        x, y = self._sumo.lane.getShape(f"{edge_id}_{lane_index}")[-1][:2]
        return float(x), float(y)

    def lane_speed_limit(self, vid: str) -> float:
        """The speed the vehicle may drive on its lane (limit x its speed factor) [m/s]."""
        return self._sumo.vehicle.getAllowedSpeed(vid)

    def tls_green_left_s(self, tls_id: str, link_index: int) -> tuple[float, float]:
        """(earliest, latest) time from now [s] at which the light's link stops being green (G or g),
        following its programme: (0, 0) when it is not green now, inf when it never changes. A fixed
        programme gives one time. A gap-actuated green ends between its minDur and maxDur: SUMO extends it
        while vehicles cross the lane's detector at most ``max-gap`` apart (``tls_max_gap_s``), and
        ``getNextSwitch`` is only its next check (Krems 71582001: 0-4 s ahead throughout a 50-s green)."""
        tl = self._sumo.trafficlight
        logic = self._tls_logic(tls_id, tl.getProgram(tls_id))
        if logic is None:
            return math.inf, math.inf
        phase = tl.getPhase(tls_id)
        if logic[phase][2][link_index] not in "Gg":
            return 0.0, 0.0
        spent = tl.getSpentDuration(tls_id)
        min_s, max_s, _ = logic[phase]
        earliest = max(tl.getNextSwitch(tls_id) - self._sumo.simulation.getTime(), min_s - spent, 0.0)
        latest = max(earliest, max_s - spent)
        for k in range(1, len(logic)):
            min_s, max_s, state = logic[(phase + k) % len(logic)]
            if state[link_index] not in "Gg":
                return earliest, latest
            earliest, latest = earliest + min_s, latest + max_s
        return math.inf, math.inf

    def tls_max_gap_s(self, tls_id: str) -> float:
        """The longest time gap between vehicles at a detector that still extends the light's actuated green
        [s] (its ``max-gap`` parameter; SUMO's default 3.0 s, Simulation/Traffic_Lights, "Actuated Traffic
        Lights")."""
        if tls_id not in self._tls_max_gaps:  # asked every step near a light; a programme's parameter
            value = self._sumo.trafficlight.getParameter(tls_id, "max-gap")
            self._tls_max_gaps[tls_id] = float(value) if value else ACTUATED_MAX_GAP_S
        return self._tls_max_gaps[tls_id]

    def tls_detection(self, tls_id: str, link_index: int) -> tuple[float, float] | None:
        """(how far before the stop line the detector of the link's lane lies [m], time since a detector of
        one of the light's lanes whose links are all green now last saw a vehicle [s], 0 while one is on it)
        for a gap-actuated light: at each check SUMO extends the green while that time is below ``max-gap``
        (Simulation/Traffic_Lights, "Actuated Traffic Lights"; MSActuatedTrafficLightLogic::init uses a lane's
        detector for a phase only when all the lane's links are green in it). None for a light without
        detectors of its own, or a lane whose detector SUMO placed on the lane before it."""
        if tls_id not in self._tls_detectors:
            self._tls_detectors[tls_id] = self._find_tls_detectors(tls_id)
        found = self._tls_detectors[tls_id]
        if found is None or link_index not in found[0]:
            return None
        ahead_of_line, detectors = found
        state = self._sumo.trafficlight.getRedYellowGreenState(tls_id)
        loop = self._sumo.inductionloop
        since = min(
            (loop.getTimeSinceDetection(d) for d, links in detectors if all(state[k] in "Gg" for k in links)),
            default=math.inf,
        )
        return ahead_of_line[link_index], since

    def _find_tls_detectors(self, tls_id: str) -> tuple[dict[int, float], list[tuple[str, list[int]]]] | None:
        """The detectors SUMO built for the light's programme (ids ``<light>_<programme>_D<edge>.<lane>``,
        MSActuatedTrafficLightLogic::init) on the lanes it controls, by link; None when it has none."""
        links_of: dict[str, list[int]] = {}
        for k, links in enumerate(self._sumo.trafficlight.getControlledLinks(tls_id)):
            if links:
                links_of.setdefault(links[0][0], []).append(k)
        loop = self._sumo.inductionloop
        prefix = f"{tls_id}_{self._sumo.trafficlight.getProgram(tls_id)}_D"
        ahead_of_line: dict[int, float] = {}
        detectors = []
        for d in loop.getIDList():
            lane = loop.getLaneID(d) if d.startswith(prefix) else None
            if lane not in links_of:
                continue
            detectors.append((d, links_of[lane]))
            for k in links_of[lane]:
                ahead_of_line[k] = self._sumo.lane.getLength(lane) - loop.getPosition(d)
        return (ahead_of_line, detectors) if detectors else None

    def _tls_logic(self, tls_id: str, program: str) -> list[tuple[float, float, str]] | None:
        """(shortest [s], longest [s], state) of each phase of the programme: minDur and maxDur for an
        actuated phase, the duration twice for a fixed one."""
        key = (tls_id, program)
        if key not in self._tls_logics:
            logic = next((lg for lg in self._sumo.trafficlight.getAllProgramLogics(tls_id) if lg.programID == program),
                         None)  # fmt: skip
            self._tls_logics[key] = [_phase_span(p) for p in logic.phases] if logic else None
        return self._tls_logics[key]

    def min_gap(self, vid: str) -> float:
        """SUMO's getLeader distance excludes the follower's minGap; add this for the bumper gap [m]."""
        return self._sumo.vehicle.getMinGap(vid)

    def leader(self, vid: str, distance_m: float = 200.0) -> tuple[str, float] | None:
        """(id, gap [m]) of the vehicle ahead of ``vid`` within ``distance_m`` (None also when ``vid`` has
        left the simulation since the snapshot was read)."""
        try:
            res = self._sumo.vehicle.getLeader(vid, distance_m)
        except Exception:  # libsumo.TraCIException: gone meanwhile
            return None
        return (res[0], res[1]) if res and res[0] else None

    def follower(self, vid: str, distance_m: float) -> tuple[str, float] | None:
        """(id, bumper gap [m]) of the vehicle following ``vid`` in its lane within ``distance_m``."""
        res = self._sumo.vehicle.getFollower(vid, distance_m)
        return (res[0], res[1] + self._sumo.vehicle.getMinGap(res[0])) if res and res[0] else None

    def find_route(self, origin: str, destination: str) -> list[str]:
        """SUMO's fastest route (the run's routing algorithm: A*) from edge to edge; [] when there is none."""
        try:
            return list(self._sumo.simulation.findRoute(origin, destination, vType="DEFAULT_VEHTYPE").edges)
        except Exception:  # libsumo.TraCIException: unknown or unreachable edge
            return []

    def vehicle_ids(self) -> list[str]:
        return list(self._sumo.vehicle.getIDList())

    def yield_foes(self, vid: str, lookahead_m: float) -> list[tuple[str, float, float, float, bool]]:
        """(foe id, the ego's distance to the conflict, the foe's [m], how long the foe has been standing [s],
        whether something holds the foe back: a car right ahead of it or a closed link) for the vehicles
        ``vid`` must yield to at the junctions within ``lookahead_m`` on its route (SUMO's right of way)."""
        veh = self._sumo.vehicle
        foes = veh.getJunctionFoes(vid, lookahead_m)
        # tuples: (foeId, egoDist, foeDist, egoExitDist, foeExitDist, egoLane, foeLane, egoResponse, foeResponse)
        found = {f[0]: (f[1], f[2]) for f in foes if f[7]}
        for foe, dists in self._approaching_foes(vid, lookahead_m).items():
            found.setdefault(foe, dists)
        out = []
        for foe, (ego_dist, foe_dist) in found.items():
            standing = veh.getWaitingTime(foe)
            out.append((foe, ego_dist, foe_dist, standing, standing > 0 and self._held_back(foe)))
        return out

    def junction_ahead(self, vid: str) -> tuple[float, float] | None:
        """(metres from ``vid`` to the end of its lane, the length of its way through the junction there) for a
        vehicle on a normal lane; None inside a junction or with no link ahead."""
        veh, lane_api = self._sumo.vehicle, self._sumo.lane
        lane = veh.getLaneID(vid)
        if not lane or lane.startswith(":"):
            return None
        links = veh.getNextLinks(vid)  # (lane, hasPrio, isOpen, hasFoe, via, state, direction, length)
        if not links:
            return None
        passage, via = 0.0, links[0][4]
        for _ in range(MAX_INTERNAL_CHAIN):  # a junction's way may be split by internal junctions
            if not via:
                break
            passage += lane_api.getLength(via)
            onward = lane_api.getLinks(via)
            via = onward[0][4] if onward else ""
        return lane_api.getLength(lane) - veh.getLanePosition(vid), passage

    def _approaching_foes(self, vid: str, lookahead_m: float) -> dict[str, tuple[float, float]]:
        """foe id -> (``vid``'s distance to its stop line, the foe's distance to that junction) [m] for the
        vehicles within FOE_RADIUS_M on the lanes with right of way over ``vid``'s next connection, or on
        the lanes leading into them with a route through them (whether SUMO lists them yet or not).

        Priority vehicles within FOE_RADIUS_M of the junction count (paper IV.B); SUMO's getJunctionFoes lists
        only those that have announced their approach to a foe link (about a braking distance plus the lane
        they are on): a car 60 m away at 10 m/s, one lane upstream, was not there, and the lead pulled out 6 s
        before it (Krems 268939011, seed 2)."""
        veh, lane_api = self._sumo.vehicle, self._sumo.lane
        lane = veh.getLaneID(vid)
        if not lane or lane.startswith(":"):
            return {}
        ego_dist = lane_api.getLength(lane) - veh.getLanePosition(vid)
        links = veh.getNextLinks(vid)  # (lane, hasPrio, isOpen, hasFoe, via, state, direction, length)
        if ego_dist > lookahead_m or not links or links[0][1]:
            return {}
        # the connection leaves from the lane the vehicle must be in (not always the one it is in yet)
        from_lanes = [up for up, via, _ in self._lanes_into(links[0][0]) if via == links[0][4]]
        if not from_lanes:
            return {}
        out: dict[str, tuple[float, float]] = {}
        # upstream, nearest first: (its end's distance to the junction, lane, the foe lane's edge)
        todo = [(0.0, foe_lane, "") for foe_lane in sorted(set(lane_api.getFoes(from_lanes[0], links[0][0])))]
        seen_lanes = set()
        while todo:
            end_dist, here, via_edge = heapq.heappop(todo)
            if here.startswith(":") or here in seen_lanes or end_dist > FOE_RADIUS_M:
                continue
            seen_lanes.add(here)
            length = lane_api.getLength(here)
            on_way = via_edge or here.rsplit("_", 1)[0]  # the foe lane's edge
            lanes = [(here, end_dist + length)]
            for up, via, via_length in self._lanes_into(here):
                heapq.heappush(todo, (end_dist + length + via_length, up, on_way))
                if via:  # the upstream junction's internal lane, between the two
                    lanes.append((via, end_dist + length + via_length))
            for lane_id, lane_end in lanes:
                for foe in lane_api.getLastStepVehicleIDs(lane_id):
                    dist = lane_end - veh.getLanePosition(foe)
                    if dist > FOE_RADIUS_M or foe == vid or foe in out:
                        continue
                    i = max(veh.getRouteIndex(foe), 0)
                    on_foe_lane = not via_edge and lane_id == here
                    if on_foe_lane or on_way in veh.getRoute(foe)[i : i + 6]:  # upstream: on its way there
                        out[foe] = (ego_dist, dist)
        return out

    def _lanes_into(self, lane: str) -> list[tuple[str, str, float]]:
        """(lane, the junction's internal lane between, its length) for the lanes with a connection into
        ``lane`` (the network's reverse links, read from SUMO once)."""
        if self._incoming is None:
            lane_api, incoming = self._sumo.lane, {}
            for here in lane_api.getIDList():
                if here.startswith(":"):
                    continue
                # links: (toLane, hasPrio, isOpen, hasFoe, via, state, direction, length)
                for link in lane_api.getLinks(here):
                    incoming.setdefault(link[0], []).append((here, link[4], float(link[7])))
            self._incoming = incoming
        return self._incoming.get(lane, [])

    def _held_back(self, vid: str) -> bool:
        """A standing vehicle that cannot go now: a car within HELD_BACK_GAP_M ahead of it, or its next link
        closed (red, or yielding itself). One standing first in line at an open link may start any moment."""
        veh = self._sumo.vehicle
        ahead = veh.getLeader(vid, HELD_BACK_GAP_M)
        if ahead and ahead[0]:
            return True
        links = veh.getNextLinks(vid)  # (lane, hasPrio, isOpen, hasFoe, via, state, direction, length)
        return bool(links) and not links[0][2]

    def keep_lane(self, vid: str, lane_index: int, duration_s: float, force: bool = False) -> None:
        """Have SUMO move the vehicle to, and hold it in, lane ``lane_index`` of its edge for ``duration_s``.
        Its lane-change model waits for a safe gap, unless ``force``: then it only avoids an immediate
        collision (laneChangeMode bits 8-9 = 1 instead of the default 2, kept until a call without force)."""
        veh = self._sumo.vehicle
        if force and vid not in self._lc_mode_before:
            self._lc_mode_before[vid] = veh.getLaneChangeMode(vid)
            veh.setLaneChangeMode(vid, self._lc_mode_before[vid] & ~(3 << 8) | (1 << 8))
        elif not force and vid in self._lc_mode_before:
            veh.setLaneChangeMode(vid, self._lc_mode_before.pop(vid))
        veh.changeLane(vid, lane_index, duration_s)

    def pull_over(
        self, vid: str, ahead_m: float, clear_of_end_m: float, max_lanes: int | None = None
    ) -> str | None:
        """Park ``vid`` at the roadside at least ``ahead_m`` ahead: an on-road parking stop, which takes it off
        the lane once it stands there, so the cars behind it drive past. The spot is on its lane, or when
        that ends too soon, early on the next edge of its route (its rightmost lane for cars); never within
        ``clear_of_end_m`` of a lane's end (a junction's line), nor on an edge of more than ``max_lanes``
        lanes. Returns the lane, or None in a junction, when neither has room or SUMO refuses. It stays there
        until ``rejoin``."""
        veh, lane_api = self._sumo.vehicle, self._sumo.lane
        lane = veh.getLaneID(vid)
        if not lane or lane.startswith(":"):
            return None
        pos = veh.getLanePosition(vid) + ahead_m
        left = lane_api.getLength(lane) - veh.getLanePosition(vid)
        if pos > lane_api.getLength(lane) - clear_of_end_m:
            route, i = veh.getRoute(vid), veh.getRouteIndex(vid)
            if i + 1 >= len(route):
                return None
            edge = route[i + 1]
            lanes = [f"{edge}_{k}" for k in range(self._sumo.edge.getLaneNumber(edge))]
            lane = next((ln for ln in lanes if _allows_cars(lane_api.getAllowed(ln))), lanes[0])
            pos = max(ahead_m - left, PULL_OVER_PAST_JUNCTION_M)
            if pos > lane_api.getLength(lane) - clear_of_end_m:
                return None
        edge, _, index = lane.rpartition("_")
        if max_lanes is not None and self._sumo.edge.getLaneNumber(edge) > max_lanes:
            return None
        try:
            veh.setStop(
                vid, edge, pos=pos, laneIndex=int(index), duration=PARKED_FOR_GOOD_S, flags=STOP_PARKING
            )
        except Exception:  # libsumo.TraCIException: e.g. too close to stop in time
            return None
        return lane

    def parked(self, vid: str) -> bool:
        """Whether ``vid`` stands at the roadside (``pull_over``), off its lane."""
        return bool(self._sumo.vehicle.isStoppedParking(vid))

    def rejoin(self, vid: str) -> None:
        """End ``vid``'s roadside stop: SUMO puts it back on its lane as soon as that is safe for the cars
        approaching there."""
        self._sumo.vehicle.resume(vid)

    def follower_beside(self, vid: str, left: bool) -> tuple[str, float, float] | None:
        """(id, gap [m], speed [m/s]) of the nearest vehicle behind ``vid`` in the lane to its left (right)."""
        veh = self._sumo.vehicle
        return self._nearest((veh.getLeftFollowers if left else veh.getRightFollowers)(vid))

    def leader_beside(self, vid: str, left: bool) -> tuple[str, float, float] | None:
        """(id, gap [m], speed [m/s]) of the nearest vehicle ahead of ``vid`` in the lane to its left (right);
        the gap from ``vid``'s front to its rear less ``vid``'s minGap, as SUMO gives it (< 0: beside)."""
        veh = self._sumo.vehicle
        return self._nearest((veh.getLeftLeaders if left else veh.getRightLeaders)(vid))

    def _nearest(self, found) -> tuple[str, float, float] | None:
        """(id, gap, speed) of the nearest of SUMO's (id, gap) neighbours, None when there are none."""
        if not found:
            return None
        nid, gap = min(found, key=lambda f: f[1])
        return nid, gap, self._sumo.vehicle.getSpeed(nid)

    def next_link(self, vid: str, within_m: float = math.inf) -> tuple[str, float, str] | None:
        """(SUMO link state, distance to it [m], direction) of the link at the end of the vehicle's lane; None
        inside a junction, at the end of its route or farther than ``within_m`` (then SUMO is not asked for
        the links: ``getNextLinks`` costs more than the rest of the lead's step)."""
        veh = self._sumo.vehicle
        lane = veh.getLaneID(vid)
        if not lane or lane.startswith(":"):
            return None
        dist = self._sumo.lane.getLength(lane) - veh.getLanePosition(vid)
        if dist > within_m:
            return None
        links = veh.getNextLinks(vid)
        if not links:
            return None
        # (approachedLane, hasPrio, isOpen, hasFoe, approachedInternal, state, direction, length)
        first = links[0]
        return first[5], dist, first[6]

    def next_tls(self, vid: str, within_m: float = math.inf) -> tuple[str, int, float, str] | None:
        """(tls id, link index, distance to the stop line [m], state char) of the next light, if there is one
        within ``within_m``.

        SUMO's getNextTLS walks the whole route the vehicle holds (the lead's reaches 15 km ahead in the
        experiment: 0.36 ms a call, ten times the ego's). With a finite ``within_m`` SUMO is not asked again
        while the light it gave last is still farther than that by TLS_BEYOND_SLACK_M, by the vehicle's
        odometer, on the same route: the answer would be None.
        """
        veh = self._sumo.vehicle
        changes = self._route_changes.get(vid, 0)
        beyond = self._tls_beyond.get(vid)
        if beyond is not None and beyond[:2] == (changes, within_m) and veh.getDistance(vid) < beyond[2]:
            return None
        nxt = veh.getNextTLS(vid)
        first = tuple(nxt[0]) if nxt else None
        if first is not None and first[2] <= within_m:
            self._tls_beyond.pop(vid, None)
            return first
        if within_m < math.inf:
            reach = (first[2] if first is not None else math.inf) - within_m - TLS_BEYOND_SLACK_M
            self._tls_beyond[vid] = (changes, within_m, veh.getDistance(vid) + reach)
        return None

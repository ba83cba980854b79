"""The ego's phase with fake ports: a World, a fake bridge for what the ego asks SUMO and writes into it, a
kinematic bicycle in place of the MuJoCo car, route geometry from hand-made polylines and a list for its
events (no SUMO, no MuJoCo). The scripted driver is the real one (pure Python)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.driver.gap_acceptance import arrival_time_s
from cosim.driver.route import LaneChange, RoutePath, StopLine
from cosim.ego_mujoco.params import CarParams
from cosim.ego_mujoco.state import EgoState
from cosim.phases.courtesy import COURTESY_AFTER_S
from cosim.phases.ego import EgoController
from cosim.runconfig import EgoConfig
from cosim.seeds import stream
from cosim.world import EGO_ID, LEAD_ID, SumoEvent, World

EDGE_M = 200.0  # every fake edge: 200 m due north
STEP_S = 0.1
ON_PATH = 0.5  # the driver keeps the kinematic car this close to the straight centre line [m]


class KinematicCar:
    """The physics port without MuJoCo: a kinematic bicycle, throttle up to 3 m/s^2, brake up to 8 m/s^2."""

    def __init__(self, params: CarParams):
        self.params = params
        self.x = self.y = self.yaw = self.v = self.a = self.t = self.steer = 0.0
        self.resets: list[tuple] = []

    def reset(self, x_m, y_m, yaw_rad, speed_mps=0.0):
        self.resets.append((x_m, y_m, yaw_rad, speed_mps))
        self.x, self.y, self.yaw, self.v, self.a, self.t = x_m, y_m, yaw_rad, speed_mps, 0.0, 0.0

    def step(self, throttle, brake, steer, duration_s):
        self.a = 3.0 * throttle - 8.0 * brake
        self.v = max(0.0, self.v + self.a * duration_s)
        self.steer = steer
        self.yaw += self.v / self.params.wheelbase_m * math.tan(steer) * duration_s
        self.x += self.v * math.cos(self.yaw) * duration_s
        self.y += self.v * math.sin(self.yaw) * duration_s
        self.t += duration_s
        return self.state()

    def state(self):
        return EgoState(t_s=self.t, x_m=self.x, y_m=self.y, z_m=0.3, yaw_rad=self.yaw, pitch_rad=0.0, roll_rad=0.0,
                        speed_mps=self.v, lateral_speed_mps=0.0, accel_mps2=self.a, lateral_accel_mps2=0.0,
                        yaw_rate_rps=self.v / self.params.wheelbase_m * math.tan(self.steer), steer_rad=self.steer,
                        wheel_speed_radps=np.zeros(4), wheel_load_n=np.full(4, 3500.0),
                        in_contact=np.ones(4, bool), gear=1, engine_rpm=900.0, length_m=self.params.length_m)  # fmt: skip


class FakeBridge:
    """What the ego asks SUMO, answered from fields the test sets; what it writes, recorded."""

    def __init__(self):
        self.tls = None  # (id, link, dist, state)
        self.foes: list[tuple[str, float, float, float, bool]] = []
        self.held: int | None = None  # edges SUMO holds ahead; None: what the ego gave it
        self.current_edge = ""  # the edge of its route SUMO has the twin on (or has just left)
        self.given: list[list[str]] = []
        self.reject_route = False
        self.writes: list[dict] = []
        self.caps: dict[str, float] = {}  # vehicles held at a speed (cap_speed), by id
        self.let_in: list[str] = []  # vehicles asked to let the ego in, in order

    def next_tls(self, vid):
        assert vid == EGO_ID
        return self.tls

    def yield_foes(self, vid, lookahead_m):
        return self.foes

    def junction_ahead(self, vid):  # every priority car far from its line: a spot short of the conflict
        return (1000.0, 10.0)

    def edges_left(self, vid):
        return self.held if self.held is not None else len(self.given[-1]) if self.given else 0

    def route_edge_left(self, vid):
        return self.current_edge, 0.0

    def set_ego_route(self, edges):
        if self.reject_route:
            return SumoEvent("ego_route_rejected", EGO_ID, "no")
        self.given.append(list(edges))
        self.held = None
        return None

    def cap_speed(self, vid, speed_mps):
        if speed_mps is None:
            self.caps.pop(vid)
        else:
            if vid not in self.caps:
                self.let_in.append(vid)
            self.caps[vid] = speed_mps

    def write_ego(self, x_m, y_m, heading_deg, speed_mps, *, edge_hint="", lane_hint=-1, verify_on_road=True,
                  on_route=False):  # fmt: skip
        self.writes.append(dict(x=x_m, y=y_m, heading=heading_deg, speed=speed_mps, verify=verify_on_road,
                                on_route=on_route))  # fmt: skip
        return None


def _path(edges, stop_lines=()):
    n = len(edges)
    return RoutePath([(0.0, 0.0), (0.0, n * EDGE_M)], stop_lines, [(k * EDGE_M, 13.89) for k in range(n)])


class Drive:
    """The ego's phase and its ports; ``step`` runs its four schedule entries and plays SUMO's part (the
    written pose becomes the snapshot's)."""

    def __init__(self, stop_lines=(), extension=None, edges=("a", "b", "c")):
        self.cfg = EgoConfig()
        self.world = World(capacity=8)
        self.bridge = FakeBridge()
        self.events: list[SumoEvent] = []
        self.route = list(edges)
        self.paths: list[list[str]] = []
        self.car = KinematicCar(self.cfg.car)

        def path_of(edges, delays):
            self.paths.append(list(edges))
            return _path(edges, stop_lines)

        self.ego = EgoController(self.cfg, car=self.car, rng=stream(1, "driver", 0), route=self.route,
                                 path_of=path_of, extension=extension, bridge=self.bridge, step_s=STEP_S,
                                 emit=self.events.append)  # fmt: skip
        self.logs: list[dict] = []

    def place(self, front_m: float = 6.0) -> int:
        w = self.world
        slot = w.add(EGO_ID, is_ego=True)
        w.x_m[slot], w.y_m[slot], w.heading_deg[slot] = 0.0, front_m, 0.0
        w.length_m[slot], w.width_m[slot] = self.cfg.car.length_m, self.cfg.car.width_m
        w.edge_code[slot] = w.intern_edge("a")
        return slot

    def step(self, displays=None) -> None:
        w = self.world
        w.step += 1
        w.t_s = round(w.step * STEP_S, 6)
        self.ego.own_state(w)
        self.ego.step(w, displays or {})
        self.ego.integrate()
        self.logs.append(self.ego.write_back(w))
        slot = w.slot_of.get(EGO_ID)
        if slot is not None and self.bridge.writes:
            last = self.bridge.writes[-1]
            w.x_m[slot], w.y_m[slot], w.heading_deg[slot] = last["x"], last["y"], last["heading"]
            w.edge_code[slot] = w.intern_edge(self.route[min(int(last["y"] // EDGE_M), len(self.route) - 1)])


def test_the_driver_drives_the_car_along_its_path_and_the_pose_goes_back_to_sumo():
    d = Drive()
    d.step()  # no ego in the snapshot yet: nothing is done
    assert d.bridge.writes == [] and d.logs == [{}] and d.ego.percept is None and not d.ego.started
    slot = d.place()
    for _ in range(150):  # 15 s
        d.step()
    w = d.world
    assert d.ego.started and len(d.car.resets) == 1
    assert d.car.resets[0][2] == pytest.approx(math.pi / 2)  # facing north, MuJoCo's yaw
    d.ego.own_state(w)  # the sumo phase of the next step: the snapshot's speed and acceleration are the car's
    assert w.speed_mps[slot] == d.car.v > 5.0 and w.accel_mps2[slot] == d.car.a
    ys = [p["y"] for p in d.bridge.writes]
    assert ys[-1] > 60.0 and all(b >= a - 1e-6 for a, b in zip(ys, ys[1:], strict=False))
    assert (
        max(abs(p["x"]) for p in d.bridge.writes) < ON_PATH
        and max(abs((p["heading"] + 180.0) % 360.0 - 180.0) for p in d.bridge.writes) < 2.0
    )
    # on its path and on a lane: mapped onto the route SUMO holds, without a search of the network
    assert d.bridge.writes[-1]["on_route"] and not d.bridge.writes[-1]["verify"]
    assert d.bridge.given == [["a", "b", "c"]]  # SUMO got the route ahead once (800 m: all of it)
    log = d.logs[-1]
    assert log["physics_speed_mps"] == pytest.approx(round(d.car.v, 4)) and log["driver_mode"]
    assert abs(log["path_offset_m"]) < ON_PATH and log["tls_state"] is None and log["leader_id"] is None
    assert d.ego.percept.speed_limit_mps == pytest.approx(13.89)
    assert d.events == []
    d.ego.close()


def test_the_assistance_displays_reach_the_percept_and_a_leader_on_the_path_is_seen():
    d = Drive()
    d.place()
    w = d.world
    car = w.add("scv1")
    w.x_m[car], w.y_m[car], w.heading_deg[car], w.length_m[car], w.width_m[car] = 0.0, 40.0, 0.0, 4.5, 1.8
    w.speed_mps[car] = 7.0
    d.step({"sys_b_gap_s": 1.3, "sys_b_level": "advisory"})
    p = d.ego.percept
    assert p.sys_b_gap_s == 1.3 and p.sys_b_level == "advisory"
    assert p.leader_id == "scv1" and p.leader_gap_m == pytest.approx(40.0 - 4.5 - 6.0, abs=0.2)
    assert p.leader_speed_mps == 7.0 and d.logs[-1]["leader_id"] == "scv1"


def test_crossing_a_red_stop_line_is_an_event():
    d = Drive()
    d.place()
    d.bridge.tls = ("J", 2, 3.0, "r")
    d.step()
    assert d.ego.percept.tls_state == "r" and d.ego.percept.tls_id == "J:2" and d.logs[-1]["tls_state"] == "r"
    d.bridge.tls = None  # the light is behind the ego
    d.step()
    assert [(e.kind, e.vehicle, e.detail) for e in d.events] == [("red_light_violation", EGO_ID, "J link 2")]


def test_at_a_give_way_line_the_gap_comes_from_sumos_right_of_way():
    line = StopLine(60.0, "J7", "m", (0.0, 60.0), "s", False, 0)
    d = Drive(stop_lines=[line])
    d.place()
    foe = d.world.add("foe")
    d.world.speed_mps[foe] = 10.0
    d.bridge.foes = [("foe", 54.0, 50.0, 0.0, False), ("far", 54.0, 50.0, 0.0, False)]  # "far" is not in
    d.step()
    p = d.ego.percept
    assert p.sign_kind == "give_way" and p.sign_id == "J7" and p.sign_dist_m == pytest.approx(54.0, abs=0.1)
    assert p.junction_gap_s == pytest.approx(arrival_time_s(50.0, 10.0))
    d.bridge.foes = [("foe", 54.0, 50.0, 10.0, True)]  # standing behind another car: it waits itself
    d.step()
    assert d.ego.percept.junction_gap_s == math.inf


def test_a_car_standing_to_let_the_ego_in_is_no_foe_at_its_give_way_line():
    """Monaco 1712696757 (experiment P2): the ego, waiting at a give-way line with a lane change just beyond
    it, had a priority car stop to let it in; counted as a foe that might go any moment, it held the ego
    54 s while it stood for the ego, and five cars came between the lead and the ego."""
    line = StopLine(60.0, "J7", "m", (0.0, 60.0), "s", False, 0)
    d = Drive(stop_lines=[line])
    d.place()
    foe = d.world.add("x")
    d.bridge.foes = [("x", 54.0, 8.0, 5.0, False)]  # first in line at an open link: it may go any moment
    d.step()
    assert d.ego.percept.junction_gap_s == pytest.approx(arrival_time_s(8.0, 0.0))
    d.ego._let_in = ("x", d.world.t_s, 1)  # it stands for the ego
    d.step()
    assert d.ego.percept.junction_gap_s == math.inf
    d.world.speed_mps[foe] = 3.0  # it drives on: a foe again
    d.step()
    assert d.ego.percept.junction_gap_s == pytest.approx(arrival_time_s(8.0, 3.0))


def test_standing_first_at_a_give_way_line_long_enough_the_ego_is_let_in():
    """A stream that never leaves the critical gap: after COURTESY_AFTER_S first in line, a priority car
    that can stop comfortably is asked to (CourtesyYield); standing, it is no foe and the ego goes."""
    line = StopLine(60.0, "J7", "m", (0.0, 60.0), "s", False, 0)
    d = Drive(stop_lines=[line])
    d.place(40.0)
    c = d.world.add("c")
    d.world.speed_mps[c] = 12.0
    d.bridge.foes = [("c", 10.0, 50.0, 0.0, False)]  # always 4 s away: below every critical gap
    for _ in range(int(COURTESY_AFTER_S / STEP_S)):
        d.step()
    assert d.car.v < 0.1 and 60.0 - (40.0 + d.car.y) < 1.0  # at the line, waiting
    assert d.events == []
    for _ in range(int(12.0 / STEP_S)):  # it took the ego about 7 s to get there
        d.step()
    assert [(e.kind, e.vehicle) for e in d.events] == [("courtesy_yield", "c")]
    assert d.ego.courtesy.car == "c" and d.bridge.caps["c"] < 12.0
    d.world.speed_mps[c] = 0.0  # it stands short of the junction
    d.step()
    assert d.ego.percept.junction_gap_s == math.inf


def test_an_extended_route_rebuilds_the_path_and_sumo_gets_the_new_stretch():
    class Extension:
        def __init__(self, route):
            self.route, self.asked = route, []

        def update(self, ahead_m, ego_index, ego_edge_left_m):
            self.asked.append(ahead_m)
            if len(self.asked) == 2:
                self.route += ["d", "e", "f", "g"]  # in place: the list is shared
                return 3  # the first new route index
            return None

    d = Drive(extension=None)
    ext = Extension(d.route)
    d.ego.extension = ext
    d.place()
    d.step()
    assert d.paths == [["a", "b", "c"]] and ext.asked[0] == pytest.approx(3 * EDGE_M - 6.0, abs=0.1)
    d.step()
    assert d.paths[-1] == ["a", "b", "c", "d", "e", "f", "g"] and d.ego.path.length_m == 7 * EDGE_M
    assert d.bridge.given == [["a", "b", "c"]]  # SUMO's stretch is renewed only when it runs short ...
    d.bridge.held = 1  # ... or SUMO replaced it: then it ends 800 m ahead, not with the whole route
    d.step()
    assert d.bridge.given[-1] == ["a", "b", "c", "d", "e"]


class Replan:
    """The route's extension as the ego's controller sees it: at its second call the edges from ``first`` on
    become ``tail`` (a way round a stalled queue)."""

    def __init__(self, route: list[str], first: int, tail: list[str]):
        self.route, self.first, self.tail, self.calls = route, first, tail, 0

    def update(self, ahead_m, ego_index, ego_edge_left_m):
        self.calls += 1
        if self.calls == 2:
            self.route[self.first :] = self.tail  # in place: the list is shared
            return self.first
        return None


def test_a_route_replanned_inside_the_stretch_sumo_holds_is_given_to_sumo_at_once():
    d = Drive(extension=None)
    d.ego.extension = Replan(d.route, 1, ["x", "y"])  # a way round from the end of "a" on
    d.place()
    d.step()
    assert d.bridge.given == [["a", "b", "c"]]
    d.step()
    assert d.paths[-1] == ["a", "x", "y"] and d.bridge.given[-1] == ["a", "x", "y"]


def test_a_route_replanned_while_the_twin_stands_in_a_junction_is_given_from_the_edge_it_left():
    d = Drive(extension=None)
    d.ego.extension = Replan(d.route, 2, ["x"])
    slot = d.place()
    d.step()
    assert d.bridge.given == [["a", "b", "c"]]
    d.world.edge_code[slot] = d.world.intern_edge(":J_0")  # the twin stands in the junction after "a"
    d.bridge.current_edge = "b"  # SUMO's route is not at the path's edge: nothing is given
    d.step()
    assert d.bridge.given == [["a", "b", "c"]]
    d.world.edge_code[slot] = d.world.intern_edge(":J_0")
    d.bridge.current_edge = "a"
    d.step()
    assert d.bridge.given[-1] == ["a", "b", "x"]


def test_a_route_sumo_replaced_is_given_again_and_a_refusal_is_an_event():
    d = Drive()
    d.place()
    d.step()
    assert d.bridge.given == [["a", "b", "c"]] and d.bridge.writes[-1]["on_route"]
    d.bridge.held = 1  # SUMO mapped the pose onto one edge and dropped the rest
    d.step()
    assert d.bridge.given == [["a", "b", "c"], ["a", "b", "c"]]
    d.bridge.held, d.bridge.reject_route = 1, True
    d.step()
    assert [e.kind for e in d.events] == ["ego_route_rejected"]
    assert not d.bridge.writes[-1]["on_route"]  # SUMO may map the pose onto any lane meanwhile


def _crosser(d: Drive, y_m: float, x_m: float, heading_deg: float, speed_mps: float, edge: str) -> int:
    w = d.world
    car = w.add("x1")
    w.x_m[car], w.y_m[car], w.heading_deg[car], w.speed_mps[car] = x_m, y_m, heading_deg, speed_mps
    w.length_m[car], w.width_m[car], w.edge_code[car] = 4.5, 1.8, w.intern_edge(edge)
    return car


def test_a_car_crossing_in_the_junction_ahead_is_let_through():
    """Westbound across the route 30 m ahead, inside the junction (SUMO let it in): the ego, pulling away,
    would be there with it, so the driver stops short of its way; the same car still on its own road is left
    to the junction's right of way, and one the ego is through before is no reason to stop."""
    d = Drive()
    d.place()
    _crosser(d, 36.0, 12.0, 270.0, 5.0, ":J_0")  # front 12 m east of the route, 2.4 s from it
    d.step()
    p = d.ego.percept
    assert p.crossing_dist_m == pytest.approx(36.0 - 6.0 - 0.9, abs=0.5)

    d = Drive()
    d.place()
    _crosser(d, 36.0, 12.0, 270.0, 5.0, "side")  # approaching on its road, not yet committed
    d.step()
    assert d.ego.percept.crossing_dist_m == math.inf

    d = Drive()
    d.place()
    d.car.v = 13.0  # at 13 m/s the ego is through in ~2.8 s ...
    _crosser(d, 36.0, 40.0, 270.0, 5.0, ":J_0")  # ... before this one gets there (~7.6 s)
    d.step()
    assert d.ego.percept.crossing_dist_m == math.inf

    d = Drive()
    d.place()
    _crosser(d, 36.0, 0.0, 0.0, 5.0, ":J_0")  # along the route: a leader, not a crossing car
    d.step()
    assert d.ego.percept.crossing_dist_m == math.inf and d.ego.percept.leader_id == "x1"


def test_a_car_on_a_road_passing_under_the_route_is_no_crossing_car():
    """Krems: the trunk 38571954 runs over -51713752#0, and the driver stood on the bridge for the queue
    below. Ways cross only in or by a junction of the route (here 40-45 m along it)."""
    edges = [(0.0, 40.0, "a", 0), (45.0, 150.0, "b", 0), (155.0, 300.0, "c", 0)]
    path = RoutePath([(0.0, 0.0), (0.0, 300.0)], (), [(0.0, 13.89)], edges)
    assert path.near_junction(np.array([20.0, 31.0, 42.0, 54.0, 56.0, 148.0]), 10.0).tolist() == [
        False, True, True, True, False, True,
    ]  # fmt: skip
    for y_m, edge, stops in ((25.0, "below", False), (42.0, "x", True)):
        d = Drive()
        d.ego.path = path
        d.place()
        _crosser(d, y_m, -1.0, 270.0, 0.0, edge)  # standing across the route (front 1 m west of it)
        d.step()
        assert (d.ego.percept.crossing_dist_m < math.inf) == stops, (y_m, d.ego.percept.crossing_dist_m)


def test_a_car_on_a_road_drawn_over_the_route_is_no_leader_and_the_ego_drives_past_it():
    """Krems, An der Schuett: a one-way slip road mapped 1 m beside the route up to the junction where it
    merges as the minor road. Its queue stood on the route as drawn; the participant stood 160 s behind it,
    and the queue waited for the participant. SUMO's own cars see only cars on their own lanes and in the
    junctions ahead, and so does the driver: a car on an edge or junction of the route there (20 m) is a
    leader; one on an edge the route takes farther on is on another stretch of road (a bridge, a loop)."""
    edges = [(0.0, 195.0, "a", 0), (205.0, 400.0, "b", 0), (410.0, 600.0, "c", 0)]
    vias = [(195.0, 205.0, ":J_0_0"), (400.0, 410.0, ":K_3_0")]
    limits = [(a, 13.89) for a, _, _, _ in edges]  # one per edge: the route index of an arc position
    path = RoutePath([(0.0, 0.0), (0.0, 600.0)], (), limits, edges, via_lanes=vias)
    for edge, leader in (
        ("slip", False),
        ("a", True),
        ("b", False),
        (":J_0", False),
        (":K_3", False),
        ("", True),
    ):
        d = Drive()
        d.ego.path = path
        d.place()
        _crosser(d, 40.0, 0.5, 0.0, 0.0, edge)  # standing on the route 34 m ahead, heading along it
        d.step()
        assert (d.ego.percept.leader_id == "x1") == leader, edge
    assert path.on_its_roads([":J_0", ":K_3", "c", "b"], np.array([185.0, 405.0, 300.0, 300.0])).tolist() == [
        True, True, False, True,
    ]  # fmt: skip
    d = Drive()
    d.ego.path = path
    d.place()
    _crosser(d, 40.0, 0.5, 0.0, 0.0, "slip")
    for _ in range(100):  # 10 s
        d.step()
    assert 6.0 + d.car.y > 60.0 and d.car.v > 5.0  # past the queue on the road drawn beside


def test_the_ego_stops_short_of_a_car_standing_across_its_way_and_goes_once_it_has_gone():
    d = Drive()
    d.place()
    _crosser(d, 40.0, -1.0, 270.0, 0.0, ":J_0")  # stands across the route (front 1 m west of it)
    for _ in range(200):  # 20 s
        d.step()
    front = 6.0 + d.car.y  # the car starts with its front at y = 6 m
    assert d.car.v < 0.1 and 40.0 - 0.9 - 3.0 < front < 40.0 - 0.9, front
    assert d.logs[-1]["driver_mode"] == "crossing"
    d.world.remove("x1")
    for _ in range(100):
        d.step()
    assert d.car.v > 3.0


# the merge tests' path: straight north, with one lane change on edge b (route index 1, from y = 200 m): 3.2 m
# west into lane b_1 over 30 m, put off as far as the driver asks (at most 150 m); a_1 and the junction's
# :J_1_0 lead into b_1
_CHANGE_LATEST_M = 150.0


def _path_with_change(edges, delays) -> RoutePath:
    delay = min(delays.get(1, 0.0), _CHANGE_LATEST_M)
    change = LaneChange(200.0 + delay, 230.0 + delay, 1, 1, delay, _CHANGE_LATEST_M,
                        {"b_1": np.array([(-3.2, 200.0), (-3.2, 400.0)])}, {"a_1": (-3.2, 200.0), ":J_1_0": (-3.2, 200.0)}, "b_1")  # fmt: skip
    return RoutePath([(0.0, 0.0), (0.0, 3 * EDGE_M)], (), [(k * EDGE_M, 13.89) for k in range(3)],
                     lane_changes=[change])  # fmt: skip


def _merging(d: Drive, front_m: float, speed_mps: float) -> None:
    slot = d.place(front_m)
    d.world.speed_mps[slot] = speed_mps
    d.ego._path_of = _path_with_change
    d.ego.path = _path_with_change(d.route, {})


def _in_target_lane(d: Drive, vid: str, front_m: float, speed_mps: float) -> int:
    w = d.world
    slot = w.slot_of.get(vid)
    if slot is None:
        slot = w.add(vid)
        w.length_m[slot], w.width_m[slot], w.heading_deg[slot] = 4.5, 1.8, 0.0
    edge = "a" if front_m < 190.0 else ":J_1" if front_m < 200.0 else "b"
    w.x_m[slot], w.y_m[slot], w.speed_mps[slot] = -3.2, front_m, speed_mps
    w.edge_code[slot], w.lane_index[slot] = w.intern_edge(edge), 0 if edge == ":J_1" else 1
    return slot


def _entering(d: Drive) -> bool:
    """The ego's front is between where it begins to enter lane b_1 and the end of the lane change."""
    change, front = d.ego.path.lane_changes[0], 150.0 + d.car.y
    return change.s_start + 0.2 * (change.s_end - change.s_start) <= front <= change.s_end


def test_the_ego_lets_a_car_beside_it_in_the_lane_it_moves_into_go_first():
    """Side by side at 10 m/s, both 50 m before the lane change: driving on blind, the ego would move over
    onto the car (Monaco, Helsinki: SUMO saw a collision). The driver stays in its lane a little longer,
    lets the car pass and then moves in behind it with room to spare."""
    d = Drive()
    _merging(d, 150.0, 10.0)
    other = 148.0
    rear_gaps = []
    for _ in range(200):  # 20 s
        _in_target_lane(d, "x1", other, 10.0)
        d.step()
        other += 10.0 * STEP_S
        if _entering(d):
            rear_gaps.append(other - 4.5 - (150.0 + d.car.y))
    assert d.ego._change_delays or "merge" in {log["driver_mode"] for log in d.logs}
    assert rear_gaps and min(rear_gaps) > 2.0, min(rear_gaps, default=None)
    assert d.car.v > 5.0  # on its way again


def test_gaps_that_are_enough_are_taken_without_waiting():
    """A car far behind in the lane the ego moves into, or one well ahead of it: no reason to wait."""
    for front_m, speed_mps in ((60.0, 10.0), (300.0, 0.0)):
        d = Drive()
        _merging(d, 150.0, 10.0)
        _in_target_lane(d, "x1", front_m, speed_mps)
        for _ in range(80):
            d.step()
        assert "merge" not in {log["driver_mode"] for log in d.logs} and not d.ego._change_delays
        assert 150.0 + d.car.y > 230.0


def test_the_ego_drives_on_past_a_car_standing_where_it_would_move_over_and_changes_in_front_of_it():
    d = Drive()
    _merging(d, 150.0, 10.0)
    _in_target_lane(d, "x1", 209.0, 0.0)  # stands where the ego would move over
    for _ in range(150):
        d.step()
        if _entering(d):
            assert 150.0 + d.car.y - 4.6 > 209.0 + 2.5  # its rear well clear of the standing car's front
    assert d.ego._change_delays[1] > 0.0 and 150.0 + d.car.y > d.ego.path.lane_changes[0].s_end


def test_a_queue_along_the_whole_lane_holds_the_ego_at_the_last_point_until_it_moves_on():
    d = Drive()
    _merging(d, 150.0, 10.0)
    for k, front_m in enumerate(np.arange(205.0, 400.0, 7.0)):  # standing bumper to bumper (2.5 m apart)
        _in_target_lane(d, f"q{k}", float(front_m), 0.0)
    for _ in range(400):  # 40 s: along the queue, then past the driver's patience, still no room
        d.step()
    front = 150.0 + d.car.y
    last_entry = 200.0 + _CHANGE_LATEST_M + 0.2 * 30.0
    assert d.car.v < 0.1 and last_entry - 5.0 < front < last_entry, front
    assert d.logs[-1]["driver_mode"] == "merge"
    # the car that would follow the ego (its front the nearest behind the ego's rear) was asked to stop for
    # it
    follower = max((k for k, f in enumerate(np.arange(205.0, 400.0, 7.0)) if f <= front - 4.6 - 2.5))
    assert d.bridge.let_in and set(d.bridge.let_in) == {f"q{follower}"}
    assert [e.kind for e in d.events] == ["merge_let_in"] * len(d.bridge.let_in)
    for k in range(len(np.arange(205.0, 400.0, 7.0))):
        d.world.remove(f"q{k}")
    for _ in range(100):
        d.step()
    assert 150.0 + d.car.y > 200.0 + _CHANGE_LATEST_M + 30.0


def test_held_short_of_the_last_point_by_a_car_ahead_the_ego_asks_no_one_to_stop():
    """Munich seed 1: the ego stood behind the lead 15 m short of its last point; the car 'behind where its
    rear would be' at that point stood ahead of the lead in the queue, and holding it blocked the lane."""
    d = Drive()
    _merging(d, 150.0, 10.0)
    for k, front_m in enumerate(np.arange(205.0, 400.0, 7.0)):
        _in_target_lane(d, f"q{k}", float(front_m), 0.0)
    last_entry = 200.0 + _CHANGE_LATEST_M + 0.2 * 30.0
    w = d.world
    slot = w.add("ahead")
    w.length_m[slot], w.width_m[slot], w.heading_deg[slot] = 4.5, 1.8, 0.0
    w.x_m[slot], w.y_m[slot], w.edge_code[slot], w.lane_index[slot] = (
        0.0,
        last_entry - 12.0,
        w.intern_edge("b"),
        0,
    )
    for _ in range(400):
        d.step()
    assert d.car.v < 0.1 and 150.0 + d.car.y < last_entry - 14.0
    assert d.bridge.let_in == [] and d.events == []


def _stream_on(d: Drive, fronts: dict[str, float], speed_mps: float) -> None:
    """SUMO's part for a stream in the lane the ego moves into: each car at ``speed_mps`` or the speed it is
    capped at, never closer than 2.5 m to the car ahead (no braking limits); gone at the road's end."""
    for vid in sorted(fronts, key=fronts.get, reverse=True):
        if vid not in d.world.slot_of:
            continue
        ahead = [f for v, f in fronts.items() if f > fronts[vid] and v in d.world.slot_of]
        v = min(speed_mps, d.bridge.caps.get(vid, speed_mps))
        front = min(fronts[vid] + v * STEP_S, min(ahead, default=1e9) - 4.5 - 2.5)
        fronts[vid] = front
        if front > 560.0:
            d.world.remove(vid)
        else:
            _in_target_lane(d, vid, front, v)


def _drive_until_it_moves_over(d: Drive, fronts: dict[str, float], speed_mps: float) -> None:
    """Steps with the stream moving (``_stream_on``) until the ego begins to enter the new lane (40 s at most)."""
    for _ in range(400):
        d.step()
        _stream_on(d, fronts, speed_mps)
        if _entering(d):
            break
    assert _entering(d), "the ego never moved over"


def test_a_stream_passing_in_the_new_lane_lets_the_ego_in_when_it_has_waited():
    """Monaco seed 1: a stream at 12 m/s, 16 m apart, overtakes the ego in the lane it moves into; no gap is
    secure, and five cars came between the lead and the ego. Held MERGE_PATIENCE_S, the ego is let in: the
    nearest car behind it that can slow to its speed drives no faster than it until it has moved over."""
    d = Drive()
    _merging(d, 150.0, 8.0)
    fronts = {f"s{k}": float(f) for k, f in enumerate(np.arange(-200.0, 300.0, 16.0))}
    for vid, front in fronts.items():
        _in_target_lane(d, vid, front, 12.0)
    _drive_until_it_moves_over(d, fronts, 12.0)
    assert [e.kind for e in d.events] == ["merge_let_in"]
    held = d.events[0].vehicle
    assert fronts[held] <= 150.0 + d.car.y - 4.6 - 2.0  # behind the ego's rear
    d.step()
    _stream_on(d, fronts, 12.0)
    assert held not in d.bridge.caps


def test_a_crawling_queue_in_the_new_lane_lets_the_ego_in_when_it_has_waited():
    """Munich seed 2, Helsinki seed 3: a queue crawling at 2 m/s, 2.5 m bumper to bumper, along the lane the
    ego must move into; no gap in it is secure, even for an impatient driver. Waiting at the last point, the
    ego is let in: the nearest car that can still stop short of its rear stops (SUMO: held at speed 0), the
    cars ahead of it drive on, and the ego moves over; then that car drives on behind it."""
    d = Drive()
    _merging(d, 150.0, 10.0)
    fronts = {f"q{k}": float(f) for k, f in enumerate(np.arange(120.0, 420.0, 7.0))}
    for vid, front in fronts.items():
        _in_target_lane(d, vid, front, 2.0)
    first_wait = None
    for _ in range(600):
        d.step()
        _stream_on(d, fronts, 2.0)
        if first_wait is None and d.logs[-1].get("driver_mode") == "merge" and d.car.v < 0.1:
            first_wait = d.world.t_s
        if _entering(d):
            break
    assert first_wait is not None, "the queue never held the ego"
    assert _entering(d), "the ego never moved over"
    waited = d.world.t_s - first_wait
    assert waited < 20.0, waited
    assert [e.kind for e in d.events] == ["merge_let_in"] and d.bridge.let_in == [d.events[0].vehicle]
    held = d.events[0].vehicle
    rear = 150.0 + d.car.y - 4.6
    assert fronts[held] <= rear - 2.0  # it stopped behind the ego
    d.step()
    assert held not in d.bridge.caps  # moving over, the ego lets the car go on (it follows the ego now)


def test_behind_the_lead_in_the_new_lane_the_ego_is_let_in_at_once_and_no_stream_car_comes_between():
    """Helsinki 194850767#2, Monaco 166009792#2 (experiment): the lead drives ahead in the lane the ego must
    move into, a faster stream behind it. Waiting the usual MERGE_LET_IN_AFTER_S, stream cars passed the
    waiting ego into the gap behind the lead; that gap is the participant's, so the nearest stream car is
    asked at once and the ego moves in right behind the lead. A stranger's car ahead there does not count:
    the ego waits as long as before."""
    waits = {}
    for ahead in ("lead", "scv1"):
        d = Drive()
        _merging(d, 150.0, 8.0)
        fronts = {f"s{k}": float(f) for k, f in enumerate(np.arange(-200.0, 140.0, 16.0))}
        for vid, front in fronts.items():
            _in_target_lane(d, vid, front, 12.0)
        fronts[ahead] = 215.0
        d.bridge.caps[ahead] = 8.0  # it drives at the ego's speed (not a let-in: set directly)
        _in_target_lane(d, ahead, 215.0, 8.0)
        for _ in range(400):
            d.step()
            _stream_on(d, fronts, 12.0)
            if _entering(d) or d.events:
                break
        assert [e.kind for e in d.events] == ["merge_let_in"]
        waits[ahead] = d.world.t_s - d.ego._merge_held[1]
        if ahead == "lead":
            _drive_until_it_moves_over(d, fronts, 12.0)
            front = 150.0 + d.car.y
            assert not [v for v, f in fronts.items() if v != "lead" and front < f < fronts["lead"]]
    assert waits["lead"] <= 0.2 and waits["scv1"] >= 5.0, waits


@pytest.mark.parametrize("speed_mps", [6.0, 7.0, 8.0, 10.0])
def test_beside_a_car_ahead_in_the_new_lane_at_its_speed_the_ego_drops_back_and_moves_in_behind_it(speed_mps):
    """Monaco 166009792#2 (experiment P2): a car that had come in ahead of the ego in the lane it must move
    into drove at the ego's speed, 8 m ahead of its front, the lead farther on. Judged where it was, that car
    stayed in the way of a change put off 20 m at a time, and the ego drove 150 m beside it (here: it never
    moved over at 7 m/s, and at 6 m/s only at its last point, in front of the car). It is judged where it
    will be, and the ego follows it until it has moved over: it drops back and moves in behind it."""
    d = Drive()
    _merging(d, 150.0, speed_mps)
    fronts = {"x1": 150.0 + 8.0 + 4.5, LEAD_ID: 150.0 + 8.0 + 4.5 + 30.0}
    for vid, front in fronts.items():
        _in_target_lane(d, vid, front, speed_mps)
    leaders = set()
    for _ in range(300):
        d.step()
        _stream_on(d, fronts, speed_mps)
        leaders.add(d.ego.percept.leader_id)
        if _entering(d):
            break
    assert _entering(d), "the ego never moved over"
    front = 150.0 + d.car.y
    assert front < 200.0 + 40.0, front  # within 40 m of where the change begins (150 m of room)
    assert fronts["x1"] - 4.5 - front > 2.5  # behind the car, with room
    assert "x1" in leaders and d.events == []  # it fell behind that car; nobody was asked to stop


def test_a_car_nearer_than_the_one_letting_the_ego_in_is_asked_instead():
    """Monaco 166009792#2 (experiment P2): the car asked to let the ego in was still behind it when another
    came in between from a lane leading in; waiting for the first one's ask to run out, that car passed the
    ego into the gap behind the lead. The nearest car behind the ego is the one asked: the first is let go."""
    d = Drive()
    _merging(d, 150.0, 8.0)
    _in_target_lane(d, "s1", 100.0, 6.5)  # asked before, slowed below the ego's speed
    d.bridge.caps["s1"] = 6.5
    d.ego._let_in = ("s1", 8.0, 1)  # asked 2 s ago
    d.ego._merge_held = (1, 4.0)
    d.world.step = 99  # held 6 s already (patient still: judging gaps with SUMO's defaults)
    d.step()
    assert d.bridge.caps == {"s1": 6.5} and d.events == []  # nobody nearer: s1 keeps letting the ego in
    _in_target_lane(d, "s0", 138.0, 11.0)  # in between, faster: it would pass the ego
    d.step()
    assert "s1" not in d.bridge.caps and "s0" in d.bridge.caps
    assert [(e.kind, e.vehicle) for e in d.events] == [("merge_let_in", "s0")]


def test_moving_over_the_ego_follows_the_car_ahead_in_the_lane_it_moves_into():
    """Half way across, the path still passes a slow car ahead in the new lane more than a half lane width
    away (Monaco: the ego ran into one crawling in a queue): it is the ego's leader all the same."""
    d = Drive()
    _merging(d, 210.0, 3.0)  # its front past where it begins to enter lane b_1 (206 m)
    d.world.edge_code[d.world.slot_of[EGO_ID]] = d.world.intern_edge("b")
    _in_target_lane(d, "x1", 222.0, 1.0)  # rear at 217.5 m
    d.step()
    p = d.ego.percept
    assert p.leader_id == "x1" and p.leader_gap_m == pytest.approx(7.5, abs=0.5) and p.leader_speed_mps == 1.0
    # SUMO is given the ego's pose on the new lane: it maps its twin onto that lane already
    assert d.bridge.writes[-1]["x"] == pytest.approx(-3.2) and d.bridge.writes[-1]["on_route"]
    d = Drive()
    _merging(d, 150.0, 3.0)  # still in its own lane, far from the change: a car in the other lane is not
    _in_target_lane(d, "x1", 222.0, 1.0)
    d.step()
    assert not d.ego.percept.leader_present


def _standing_one_lane_over(d: Drive, vid: str, y_m: float) -> int:
    w = d.world
    car = w.add(vid)
    w.x_m[car], w.y_m[car], w.heading_deg[car], w.speed_mps[car] = 3.2, y_m, 0.0, 0.0
    w.length_m[car], w.width_m[car], w.edge_code[car] = 4.5, 1.8, w.intern_edge("a")
    return car


def test_the_participant_keeps_behind_the_lead_standing_one_lane_over_and_drives_past_other_cars():
    """The lead, blocked from moving into the ego's lane, stands one lane over 60 m ahead: the participant
    follows the lead, not the lane, so it stops behind it (leaving it room to move over) instead of passing
    it. A stranger's car standing there is passed."""
    for vid in ("lead", "scv1"):
        d = Drive()
        d.place()
        _standing_one_lane_over(d, vid, 60.0)
        for _ in range(300):  # 30 s
            d.step()
        front = d.car.y + 0.5 * d.cfg.car.length_m
        if vid == "lead":
            assert d.ego.percept.leader_id == "lead" and d.car.v < 0.1
            assert 60.0 - 4.5 - 8.0 < front < 60.0 - 4.5  # behind the lead's rear, close up
        else:
            assert d.ego.percept.leader_id is None and front > 100.0


@pytest.mark.parametrize("at_roadside", [False, True])
def test_the_participant_stops_behind_the_lead_standing_at_the_roadside_two_lanes_over(at_roadside):
    """Letting cars pass, the lead stands at the roadside, which SUMO shows beside the road's rightmost lane:
    6.4 m off the ego's path in the left lane of two. The participant stops behind it (it gets back in
    ahead of them); the same car there, not letting cars pass, is beside the road, not ahead."""
    d = Drive()
    d.place()
    car = _standing_one_lane_over(d, "lead", 60.0)
    d.world.x_m[car] = 6.4
    d.ego.lead_at_roadside = at_roadside
    for _ in range(300):  # 30 s
        d.step()
    front = d.car.y + 0.5 * d.cfg.car.length_m
    if at_roadside:
        assert (
            d.ego.percept.leader_id == "lead" and d.car.v < 0.1 and front < 60.0 - 4.5 - 5.0
        )  # room to pull out
    else:
        assert front > 100.0


def _path_with_edges(edges, delays) -> RoutePath:
    """The plain fake path, with the edges it takes recorded (a junction's internal edge :J_1 from 190 m)."""
    spans = [(0.0, 190.0, "a", 0), (200.0, 400.0, "b", 0), (400.0, 600.0, "c", 0)]
    return RoutePath([(0.0, 0.0), (0.0, 3 * EDGE_M)], (), [(k * EDGE_M, 13.89) for k in range(3)],
                     edge_lanes=spans, via_lanes=[(190.0, 200.0, ":J_1_0")])  # fmt: skip


@pytest.mark.parametrize("edge, ahead", [(":J_1", True), ("b", True), ("x", False)])
def test_the_lead_two_lanes_over_on_the_edge_the_path_takes_is_the_participants_leader(edge, ahead):
    """Berlin's Grosser Stern: two lanes of one roundabout entry fan out to 6.5 m apart, and the ego, in the
    one the path takes, drove past the lead in the other. The lead that far off (7.5 m) is ahead when SUMO
    has it on an edge the path takes there, the junction's passage or the road after it; on another road
    (a parallel street, ``x``) it is not."""
    d = Drive()
    d.place(170.0)
    d.ego._path_of = _path_with_edges
    d.ego.path = _path_with_edges(d.route, {})
    car = _standing_one_lane_over(d, "lead", 200.0)
    d.world.x_m[car], d.world.edge_code[car] = 7.5, d.world.intern_edge(edge)
    d.step()
    p = d.ego.percept
    if ahead:
        assert p.leader_id == "lead" and p.leader_gap_m == pytest.approx(200.0 - 4.5 - 170.0, abs=1.0)
    else:
        assert p.leader_id is None


def test_the_participant_stops_for_a_car_merging_in_at_a_shallow_angle_before_its_rear_is_in_the_way():
    """Monaco 25177449 (experiment P2): scv662 crawled into the ego's way 2.5 m ahead of it at a shallow
    angle, its rear still off the path and too shallow to cross it; the ego, seeing neither a leader nor a
    crossing car, drove into its side. Its middle on the path makes it the car ahead."""
    d = Drive()
    d.place()
    w = d.world
    car = w.add("scv662")
    # heading 25 degrees west of north into the path (x = 0); front 0.4 m off it, rear 2.5 m off it
    w.x_m[car], w.y_m[car], w.heading_deg[car], w.speed_mps[car] = 0.4, 40.0, 335.0, 0.0
    w.length_m[car], w.width_m[car], w.edge_code[car] = 5.0, 1.8, w.intern_edge("a")
    for _ in range(300):  # 30 s
        d.step()
    front = d.car.y + 0.5 * d.cfg.car.length_m
    assert d.ego.percept.leader_id == "scv662" and d.car.v < 0.1
    assert front < 40.0 - 0.5 * 5.0 * math.cos(math.radians(25.0))  # short of its middle, no contact


def test_a_cut_corner_keeps_the_twin_on_its_route_and_only_leaving_the_road_lets_sumo_map_it_freely():
    """Up to ON_ROUTE_M off the path's centre line (a right turn cut 2.1 m wide) SUMO maps the twin onto
    the route it holds; farther off, onto any lane (the driver may have left the route)."""
    from cosim.phases.ego import ON_ROUTE_M

    d = Drive()
    d.place()
    d.step()
    for offset, on_route in ((2.1, True), (ON_ROUTE_M + 0.5, False)):
        d.car.x = -offset  # the path runs due north along x = 0
        d.step()
        assert abs(d.ego.percept.lateral_error_m) == pytest.approx(offset, abs=0.3)
        assert d.bridge.writes[-1]["on_route"] is on_route and d.bridge.writes[-1]["verify"]


def test_sumo_maps_the_twin_freely_in_a_junction_the_route_passes_a_second_time():
    """SUMO's on-route mapping also matches the pose onto movements of the route's earlier passes (its
    route keeps the edges driven): in a junction passed before, the twin is mapped freely (Krems 71582001)."""
    d = Drive()
    stop = dict(state="M", xy=(0.0, 0.0))
    d.ego.path = RoutePath(
        [(0.0, 0.0), (0.0, 800.0)],
        [StopLine(200.0, "J", edge_index=0, **stop), StopLine(400.0, "K", edge_index=1, **stop),
         StopLine(600.0, "J", edge_index=2, **stop)],
        edge_lanes=[(0.0, 200.0, "a", 0), (212.0, 400.0, "b", 0), (412.0, 600.0, "c", 0), (612.0, 800.0, "d", 0)],
    )  # fmt: skip
    passed_before = d.ego._in_junction_passed_before
    assert not any(passed_before(s) for s in (190.0, 205.0, 300.0, 405.0, 500.0))  # first passes
    assert all(passed_before(s) for s in (596.0, 600.0, 606.0, 616.0))  # J again, and 5 m either side
    assert not passed_before(700.0) and not passed_before(None)


def test_a_twin_mapped_onto_an_edge_passed_before_is_mapped_freely_for_a_while():
    """keepRoute=1 searches the edges SUMO's route has passed too: Krems 38571954 runs over -51713752#0,
    seven edges earlier, and the twin flipped into the queue below every other step. Once SUMO puts the
    twin there, the pose is mapped freely (keepRoute=2) for the next FREE_MAPPING_M."""
    from cosim.phases.ego import FREE_MAPPING_M

    d = Drive(edges=("a", "b", "c", "d"))
    slot = d.place()
    while d.world.edge_names[d.world.edge_code[slot]] != "c":
        d.step()
    assert d.bridge.writes[-1]["on_route"]
    d.world.edge_code[slot] = d.world.intern_edge("a")  # SUMO matched the pose to the road passed before
    d.step()
    mis_mapped_at = d.ego.s_front_m
    assert not d.bridge.writes[-1]["on_route"]
    while d.ego.s_front_m < mis_mapped_at + FREE_MAPPING_M - 5.0:
        d.step()
        assert not d.bridge.writes[-1]["on_route"]
    while d.ego.s_front_m < mis_mapped_at + FREE_MAPPING_M + 5.0:
        d.step()
    assert d.bridge.writes[-1]["on_route"]

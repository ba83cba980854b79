"""The ego's route as geometry: one lane centre-line polyline with arc lengths, its stop lines and speed
limits, built from the network once per route (and again when the route is extended).

Pure geometry on numpy arrays: ``RoutePath.from_network`` reads the lanes and connections through a
sumolib-like network object; everything else works on the polylines alone (unit tests build one from a
hand-made centre line).
"""

from __future__ import annotations

import bisect
import itertools
import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

LANE_CHANGE_LENGTH_M = 30.0  # the path changes to the lane of the next connection over this length [m]
# a lane change put off (``change_delays``) still ends this far before the edge's end [m]
LANE_CHANGE_END_MARGIN_M = 5.0
# the car's side reaches the next lane a fifth of the way across it: (3.2 m lane - 1.8 m car) / 2 / 3.2 m = 0.22
LANE_CHANGE_ENTER_FRACTION = 0.2
BOX_SEGMENTS = 8  # vehicles_on_path pre-selects points by the bounding boxes of runs of this many segments
# a vehicle seen on the path counts when SUMO has it on an edge or junction of the path this near: a car's
# length and a junction's width from where its points project [m]
ROAD_REACH_M = 20.0
PROJECT_BEHIND_M, PROJECT_AHEAD_M = 20.0, 50.0  # the ego moves < 5 m a step: the path is searched this near


@dataclass(frozen=True)
class StopLine:
    s_m: float  # arc position of the stop line on the route path [m]
    junction: str
    state: str  # SUMO link state of the route's connection ('M','m','s','w','=', ...)
    xy: tuple[float, float]  # junction centre
    direction: str = "s"  # SUMO's direction of the route's connection: s, l, r, t, L, R (partly left/right)
    into_roundabout: bool = False  # the connection enters a roundabout
    edge_index: int = -1  # index in the route of the edge that ends at this line


@dataclass(frozen=True, eq=False)
class LaneChange:
    """Where the path moves over to another lane of an edge, and the lanes whose traffic it moves in front
    of: the edge's lanes it enters (their centre lines) and the lanes leading into those (where they join)."""

    s_start: float  # the path leaves the lane it entered the edge on here [m]
    s_end: float  # ... and is on the new lane's centre line here [m]
    lanes_crossed: int
    edge_index: int  # the edge's index in the route
    delay_m: float  # how far along the edge the change starts (0: at its start; see change_delays)
    max_delay_m: float  # how far it could start at the latest
    enters: dict[str, np.ndarray]  # SUMO lane id -> centre line (N, 2) of a lane of the edge it moves into
    feeders: dict[str, tuple[float, float]]  # SUMO lane id leading into one of those -> where that one starts
    to_lane_id: str  # the lane it moves into (one of ``enters``)

    @property
    def enter_s(self) -> float:
        """Where on the path the front is as the car begins to enter the next lane."""
        return self.s_start + LANE_CHANGE_ENTER_FRACTION / self.lanes_crossed * (self.s_end - self.s_start)

    def position(self, lane_id: str, x: float, y: float) -> float:
        """A vehicle's front (x, y) on a watched lane, as metres from the edge's start along its lanes:
        negative on a lane leading into them (the straight distance to the edge: never more than the way)."""
        start = self.feeders.get(lane_id)
        if start is not None:
            return -math.dist(start, (x, y))
        return _closest_on(self.enters[lane_id], x, y)[2]

    def onto_new_lane(self, x: float, y: float) -> tuple[float, float]:
        """The point of the new lane's centre line nearest to (x, y)."""
        return _closest_on(self.enters[self.to_lane_id], x, y)[:2]


def _closest_on(line: np.ndarray, x: float, y: float) -> tuple[float, float, float]:
    """(x, y, arc position) of the point of the polyline ``line`` (N, 2) nearest to (x, y)."""
    a, d = line[:-1], np.diff(line, axis=0)
    seg2 = np.maximum((d**2).sum(axis=1), 1e-12)
    t = np.clip(((x - a[:, 0]) * d[:, 0] + (y - a[:, 1]) * d[:, 1]) / seg2, 0.0, 1.0)
    pts = a + t[:, None] * d
    k = int(((pts - (x, y)) ** 2).sum(axis=1).argmin())
    return float(pts[k, 0]), float(pts[k, 1]), float(np.sqrt(seg2[:k]).sum() + t[k] * math.sqrt(seg2[k]))


class RoutePath:
    """The route as one lane centre-line polyline with arc lengths, its stop lines and speed limits."""

    def __init__(
        self,
        xy,
        stop_lines: list[StopLine] = (),
        limits: list[tuple[float, float]] = ((0.0, 13.89),),
        edge_lanes: list[tuple[float, float, str, int]] = (),
        lane_changes: list[LaneChange] = (),
        via_lanes: list[tuple[float, float, str]] = (),
    ):
        """``xy``: (N, 2) centre-line points; ``limits``: (arc position where it starts, speed [m/s]);
        ``edge_lanes``: per edge of the route, in order, (arc positions where the path is on it, edge id,
        index of the lane it takes there, where it leaves the edge); ``lane_changes``: where it moves to
        another lane, by arc position; ``via_lanes``: the junctions' internal lanes it drives through, (arc
        positions where it is on one, lane id)."""
        self.edge_lanes = list(edge_lanes)
        self.via_lanes = list(via_lanes)
        self._via_start = [a for a, _, _ in self.via_lanes]
        self.lane_changes = list(lane_changes)
        self.lane_change_s = [c.s_start for c in self.lane_changes]
        xy = np.asarray(xy, dtype=np.float64)
        keep = np.concatenate([[True], np.hypot(*np.diff(xy, axis=0).T) > 1e-3])
        self.xy = xy[keep]
        self.s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(self.xy, axis=0).T))])
        self.length_m = float(self.s[-1])
        self.stop_lines = list(stop_lines)
        self.stop_s = [stop.s_m for stop in self.stop_lines]  # arc positions, non-decreasing
        self.limit_s = np.asarray([a for a, _ in limits], dtype=np.float64)
        self.limit_v = np.asarray([b for _, b in limits], dtype=np.float64)
        self._last_s = 0.0  # arc position of the last projection

    @classmethod
    def from_network(cls, net, route: list[str], change_delays: dict[int, float] | None = None) -> RoutePath:
        """The path along ``route`` (edge ids) in ``net`` (a sumolib network read with internal lanes): on
        each edge the lane that has the connection to the next edge, through the junction's internal lane.

        A lane change starts at the start of its edge, or ``change_delays[route index]`` metres further on
        the lane the path arrived by (the driver found no gap earlier), at the latest so that it ends
        LANE_CHANGE_END_MARGIN_M before the edge's end."""
        change_delays = change_delays or {}
        line = _Polyline()
        stop_lines: list[StopLine] = []
        limits: list[tuple[float, float]] = []  # (s where it starts, speed)
        roundabout_edges = {e for r in net.getRoundabouts() for e in r.getEdges()}
        entry_lane = None
        came_by: set[str] = set()  # the path's lanes into the edge it is on (its own, never a foe's)
        edge_lanes: list[tuple[float, float, str, int]] = []
        via_lanes: list[tuple[float, float, str]] = []
        lane_changes: list[LaneChange] = []
        plan = _LanePlan(net, route)
        for i, eid in enumerate(route):
            edge = net.getEdge(eid)
            nxt = net.getEdge(route[i + 1]) if i + 1 < len(route) else None
            here = entry_lane.getIndex() if entry_lane is not None else 0
            lane, conn = plan.choose(i, here, first=entry_lane is None)
            lane = lane or entry_lane or edge.getLane(0)
            conns = [conn] if conn is not None else []
            shape = [tuple(p[:2]) for p in lane.getShape()]
            edge_start = line.length
            changes = entry_lane is not None and entry_lane is not lane and bool(line.pts)
            if changes:  # change lanes early on the edge, or as far on as the driver had to put it off
                length = min(LANE_CHANGE_LENGTH_M, 0.5 * lane.getLength())
                latest = max(
                    0.0, min(lane.getLength(), entry_lane.getLength()) - length - LANE_CHANGE_END_MARGIN_M
                )
                delay = min(change_delays.get(i, 0.0), latest)
                if delay > 0.0:
                    line.extend(_head([tuple(p[:2]) for p in entry_lane.getShape()], delay))
                shape = _trim_start(shape, delay + length)
                diagonal = math.dist(line.pts[-1], shape[0])
            s0 = line.extend(shape)
            if changes:
                enters, feeders, to_lane = _watched_lanes(
                    net, edge, entry_lane.getIndex(), lane.getIndex(), came_by
                )
                lane_changes.append(LaneChange(s0, s0 + diagonal, abs(lane.getIndex() - entry_lane.getIndex()), i,
                                               delay, latest, enters, feeders, to_lane))  # fmt: skip
            limits.append((edge_start, lane.getSpeed()))
            edge_lanes.append((edge_start, line.length, eid, lane.getIndex()))
            if conns:
                c = conns[0]
                node = edge.getToNode()
                into_roundabout = nxt.getID() in roundabout_edges and eid not in roundabout_edges
                stop_lines.append(StopLine(line.length, node.getID(), c.getState(), tuple(node.getCoord()[:2]),
                                           c.getDirection(), into_roundabout, i))  # fmt: skip
                came_by = {lane.getID()}
                for via in _via_chain(net, c):
                    via_start = line.length
                    line.extend([tuple(p[:2]) for p in via.getShape()])
                    via_lanes.append((via_start, line.length, via.getID()))
                    came_by.add(via.getID())
                entry_lane = c.getToLane()
        return cls(line.pts, stop_lines, limits, edge_lanes, lane_changes, via_lanes)

    def lane_on(self, edge_id: str, near_s: float) -> int | None:
        """The lane the path takes on ``edge_id`` where it passes that edge nearest to arc position ``near_s``
        (a route may pass an edge twice, in different lanes); None when the route does not take it."""
        spans = [
            (max(a - near_s, near_s - b, 0.0), lane) for a, b, eid, lane in self.edge_lanes if eid == edge_id
        ]
        return min(spans)[1] if spans else None

    def project(self, x: float, y: float, near_s: float | None = None) -> tuple[float, float]:
        """(arc position [m], signed lateral offset, left positive [m]) of a point; searches near the last hit
        (or near ``near_s``, for a second point tracked on the same path, which then is not remembered).

        The search is bounded by arc length around the last hit: a route that comes back past the same
        place later must not capture the projection (the driver would steer for the later pass)."""
        around = self._last_s if near_s is None else near_s
        lo = max(0, int(self.s.searchsorted(around - PROJECT_BEHIND_M)) - 1)
        hi = min(len(self.xy) - 1, max(lo + 1, int(self.s.searchsorted(around + PROJECT_AHEAD_M))))
        s, offset, at_window_end = self._nearest(lo, hi, x, y)
        if at_window_end and abs(offset) > 20.0 and hi - lo < len(self.xy) - 1:  # lost: search everywhere
            s, offset, _ = self._nearest(0, len(self.xy) - 1, x, y)
        if near_s is None:
            self._last_s = s
        return s, offset

    @cached_property
    def _segments(self) -> tuple[np.ndarray, ...]:
        """Per segment (point i to i + 1): start x, start y, direction x, direction y, squared length (at
        least 1e-12) and length; constants of the route, computed once for every projection."""
        a, d = self.xy[:-1], np.diff(self.xy, axis=0)
        seg2 = np.maximum((d**2).sum(axis=1), 1e-12)
        return a[:, 0].copy(), a[:, 1].copy(), d[:, 0].copy(), d[:, 1].copy(), seg2, np.sqrt(seg2)

    def _nearest(self, lo: int, hi: int, x: float, y: float) -> tuple[float, float, bool]:
        """Projection onto the segments from point ``lo`` to point ``hi``; also whether it fell on the
        first or last of them."""
        ax, ay, dx, dy, seg2, seg_len = (v[lo:hi] for v in self._segments)
        t = np.minimum(np.maximum(((x - ax) * dx + (y - ay) * dy) / seg2, 0.0), 1.0)
        dist2 = (ax + t * dx - x) ** 2 + (ay + t * dy - y) ** 2
        k = int(dist2.argmin())
        cross = dx[k] * (y - ay[k]) - dy[k] * (x - ax[k])
        s = float(self.s[lo + k] + t[k] * seg_len[k])
        return s, math.copysign(math.sqrt(dist2[k]), cross), k in (0, len(dist2) - 1)

    def lane_at(self, s: float) -> tuple[str, int] | None:
        """(edge id, lane index) of the lane the path is on at arc position ``s``: a junction's internal lane
        inside one, else the route edge's lane; None off the path's recorded lanes."""
        k = bisect.bisect_right(self._via_start, s) - 1
        if k >= 0 and s <= self.via_lanes[k][1]:
            edge, _, index = self.via_lanes[k][2].rpartition("_")
            return edge, int(index)
        for a, b, eid, lane in self.edge_lanes:
            if a <= s <= b:
                return eid, lane
        return None

    def edges_between(self, s_from: float, s_to: float) -> set[str]:
        """The ids of the edges the path is on between two arc positions, junctions' internal edges included."""
        spans = [(a, b, eid) for a, b, eid, _ in self.edge_lanes]
        spans += [(a, b, lane.rpartition("_")[0]) for a, b, lane in self.via_lanes]
        return {eid for a, b, eid in spans if a <= s_to and b >= s_from}

    def on_its_roads(self, edges: list[str], s: np.ndarray, reach_m: float = ROAD_REACH_M) -> np.ndarray:
        """Whether vehicles that SUMO has on ``edges`` (edge ids, "" unknown) and that lie on the path at arc
        positions ``s`` are on a road the path takes there: an edge of it, or a junction it passes, within
        ``reach_m``. A road drawn on top of the route is not (a one-way slip road mapped 1 m beside Krems'
        An der Schuett up to the junction where it merges: its queue, waiting to merge, stood on the ego's
        path and the participant stood behind it 160 s; a road on a bridge over the route). SUMO's own cars
        see only cars on their lanes and on the junctions ahead; an unknown edge counts as on the road, and
        so does everything for a path built without its edges."""
        s = np.asarray(s, dtype=np.float64)
        if not self.edge_lanes:
            return np.ones(s.shape, dtype=bool)
        spans = self._road_spans
        out = np.zeros(s.shape, dtype=bool)
        for k, (edge, at) in enumerate(zip(edges, s.tolist(), strict=True)):
            key = _junction_of(edge) if edge.startswith(":") else edge
            found = spans.get(key)
            out[k] = not edge or (
                found is not None and bool(((found[0] <= at + reach_m) & (found[1] >= at - reach_m)).any())
            )
        return out

    @cached_property
    def _road_spans(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Arc spans (begin, end) where the path is on each of its edges and in each junction it passes
        (keyed ":" + junction id)."""
        spans: dict[str, list[tuple[float, float]]] = {}
        for a, b, eid, _ in self.edge_lanes:
            spans.setdefault(eid, []).append((a, b))
        for a, b, lane in self.via_lanes:
            spans.setdefault(_junction_of(lane.rpartition("_")[0]), []).append((a, b))
        return {k: (np.array([a for a, _ in v]), np.array([b for _, b in v])) for k, v in spans.items()}

    def passes_near_itself(
        self, radius_m: float, min_back_m: float, step_m: float = 1.0
    ) -> list[tuple[float, float]]:
        """Arc spans where the path comes within ``radius_m`` (in the plane) of a stretch of itself at least
        ``min_back_m`` of road earlier: a junction passed twice, a bridge over its own earlier road."""
        import shapely

        s = np.arange(0.0, self.length_m, step_m)
        if s.size < 2:
            return []
        pts = shapely.points(np.interp(s, self.s, self.xy[:, 0]), np.interp(s, self.s, self.xy[:, 1]))
        i, j = shapely.STRtree(pts).query(pts, predicate="dwithin", distance=radius_m)
        near = np.zeros(s.size, bool)
        near[i[s[i] - s[j] >= min_back_m]] = True
        edges = np.flatnonzero(np.diff(np.concatenate([[0], near.astype(np.int8), [0]])))
        return [(float(s[a]), float(s[b - 1])) for a, b in zip(edges[::2], edges[1::2], strict=True)]

    def edge_index(self, s: float) -> int:
        """Index in the route of the edge at arc position ``s`` (the edge just left while in a junction)."""
        return max(0, int(self.limit_s.searchsorted(s, side="right")) - 1)

    def window(self, s_from: float, s_to: float) -> np.ndarray:
        """The path from arc position ``s_from`` to ``s_to``: both ends interpolated, the points between."""
        s_from, s_to = max(0.0, s_from), min(self.length_m, s_to)
        first = int(self.s.searchsorted(s_from, side="right"))  # the points strictly inside
        inner = self.xy[first : max(first, int(self.s.searchsorted(s_to, side="left")))]
        out = np.empty((len(inner) + 2, 2))
        out[1:-1] = inner
        out[0, 0], out[-1, 0] = np.interp([s_from, s_to], self.s, self.xy[:, 0]).tolist()
        out[0, 1], out[-1, 1] = np.interp([s_from, s_to], self.s, self.xy[:, 1]).tolist()
        return out

    @cached_property
    def _boxes(self) -> tuple[np.ndarray, ...]:
        """x min, y min, x max, y max of each run of BOX_SEGMENTS segments (run k: segments from k *
        BOX_SEGMENTS on), for a first cheap test of which points can be near the path."""
        x, y = self.xy[:, 0], self.xy[:, 1]
        starts = np.arange(0, len(self.xy) - 1, BOX_SEGMENTS)
        return (
            np.minimum.reduceat(np.minimum(x[:-1], x[1:]), starts),
            np.minimum.reduceat(np.minimum(y[:-1], y[1:]), starts),
            np.maximum.reduceat(np.maximum(x[:-1], x[1:]), starts),
            np.maximum.reduceat(np.maximum(y[:-1], y[1:]), starts),
        )

    def vehicles_on_path(self, xs: np.ndarray, ys: np.ndarray, s_from: float, s_to: float,
                         half_width_m: float) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """Arc positions of points lying on the path between ``s_from`` and ``s_to`` (within
        ``half_width_m`` of its centre line); returns (index into xs, arc position) of those points."""
        lo = max(0, int(self.s.searchsorted(s_from)) - 1)
        hi = min(len(self.s) - 1, int(self.s.searchsorted(s_to)) + 1)
        if hi <= lo or len(xs) == 0:
            return np.zeros(0, dtype=int), np.zeros(0)
        # Only points inside the bounding box of some run of segments (1 m spare for rounding) can lie on
        # the path: the others are dropped before the (points x segments) search, which treats every
        # point on its own.
        c0, c1 = lo // BOX_SEGMENTS, (hi - 1) // BOX_SEGMENTS + 1
        pad = half_width_m + 1.0
        x0, y0, x1, y1 = (b[c0:c1] for b in self._boxes)
        px, py = xs[:, None], ys[:, None]
        inside = (px >= x0 - pad) & (px <= x1 + pad) & (py >= y0 - pad) & (py <= y1 + pad)
        rows = np.flatnonzero(inside.any(axis=1))
        if rows.size == 0:
            return rows, np.zeros(0)
        ax, ay, dx, dy, seg2, seg_len = (v[lo:hi] for v in self._segments)
        px, py = xs[rows, None], ys[rows, None]
        t = np.minimum(np.maximum(((px - ax) * dx + (py - ay) * dy) / seg2, 0.0), 1.0)
        dist2 = (ax + t * dx - px) ** 2 + (ay + t * dy - py) ** 2
        k = dist2.argmin(axis=1)
        near = np.arange(len(rows))
        s_at = self.s[lo + k] + t[near, k] * seg_len[k]
        on = (dist2[near, k] <= half_width_m**2) & (s_at >= s_from) & (s_at <= s_to)
        return rows[on], s_at[on]

    def junction_end(self, line_s: float, tolerance_m: float = 3.0) -> float:
        """Arc position where the path leaves the junction whose line lies at ``line_s`` (the first junction
        beginning at most ``tolerance_m`` before it); ``line_s`` when the path passes none there."""
        begin, end = self._junction_spans
        k = int(begin.searchsorted(line_s - tolerance_m))
        return float(end[k]) if k < len(begin) and begin[k] <= line_s + tolerance_m else line_s

    def near_junction(self, s: np.ndarray, reach_m: float) -> np.ndarray:
        """Whether arc positions ``s`` lie within ``reach_m`` of a junction the path passes (between one
        edge's end and the next one's start); all True for a path built without its edges."""
        s = np.asarray(s, dtype=np.float64)
        if len(self.edge_lanes) < 2:
            return np.ones(s.shape, dtype=bool)
        begin, end = self._junction_spans
        k = begin.searchsorted(s + reach_m, side="right") - 1  # the last junction that begins before
        return (k >= 0) & (s - reach_m <= end[np.maximum(k, 0)])

    @cached_property
    def _junction_spans(self) -> tuple[np.ndarray, np.ndarray]:
        """(begin, end) arc positions of the junctions the path passes, in order: from one edge's end to the
        next edge's start."""
        begin = np.array([b for _, b, _, _ in self.edge_lanes[:-1]], dtype=np.float64)
        end = np.array([a for a, _, _, _ in self.edge_lanes[1:]], dtype=np.float64)
        return begin, end

    def direction_at(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit vectors (x, y) of the path's direction at arc positions ``s``."""
        ax, ay, dx, dy, seg2, seg_len = self._segments
        k = np.clip(self.s.searchsorted(s, side="right") - 1, 0, len(seg_len) - 1)
        return dx[k] / seg_len[k], dy[k] / seg_len[k]

    def lane_changes_around(self, s_front: float) -> tuple[LaneChange | None, LaneChange | None]:
        """(the lane change the car is making, its front between where it begins to enter the new lane and
        the change's end; the next one it has not begun to enter) for its front at ``s_front``."""
        current = None
        first = bisect.bisect_left(self.lane_change_s, s_front - LANE_CHANGE_LENGTH_M - 1.0)  # may be on it
        for c in self.lane_changes[first:]:
            enter = c.enter_s
            if enter > s_front:
                return current, c
            if current is None and s_front <= c.s_end:
                current = c
        return current, None

    def speed_limit(self, s: float) -> tuple[float, float | None, float]:
        """(limit here, next different limit or None, distance to it)."""
        i = max(0, int(self.limit_s.searchsorted(s, side="right")) - 1)
        j = self._next_limit_change[i]
        if j is None:
            return float(self.limit_v[i]), None, math.inf
        return float(self.limit_v[i]), float(self.limit_v[j]), float(self.limit_s[j] - s)

    @cached_property
    def _next_limit_change(self) -> list[int | None]:
        """For each limit, the index of the next one that differs from it by more than 0.1 m/s (or None)."""
        v = self.limit_v
        return [
            next((j for j in range(i + 1, len(v)) if abs(v[j] - v[i]) > 0.1), None) for i in range(len(v))
        ]


# A lane change costs 1 plus this many metres over the length of the edge it is made on: the path changes
# lanes where the road is long (early, one lane at a time) rather than on a short edge right before a turn,
# where it would cross several lanes within a few metres, blind to the cars in them (Munich 209452710#0:
# three lanes in 25 m in front of a car at 16 m/s)
LANE_CHANGE_COST_M = 100.0
# ... and every edge at least this long is long enough: a lane change takes 4.6 s on average (Toledo &
# Zohar 2007, Transp. Res. Rec. 1999: 71-78), 64 m at 50 km/h. Among edges that long the path changes on the
# first: deferred to a longer edge after a junction, it left the pair queued at a light in the lane it was
# to leave, while the cars of the lane it needed passed them and came between (Helsinki 25523727#0 ->
# 194850767#2, experiment P1 system_A: the lead was the ego's leader 56 % of the phase)
CHANGE_ROOM_M = 65.0


def _via_chain(net, conn) -> list:
    """The internal lanes a connection drives through: one, or several where a junction splits it at an
    internal junction (a left turn's waiting point), each leading to the next: without the later ones the
    path would cut the turn's curve with a straight line."""
    lanes, via = [], conn.getViaLaneID()
    while via and len(lanes) < 8:
        lane = net.getLane(via)
        lanes.append(lane)
        via = next((o.getViaLaneID() for o in lane.getOutgoing() if o.getToLane() is conn.getToLane()), None)
    return lanes


def _watched_lanes(net, edge, arriving: int, leaving: int, came_by: set[str]):
    """For a lane change on ``edge`` from lane index ``arriving`` to ``leaving``: the lanes it moves into
    (id -> centre line), those leading into them from the edges entering the junction before it, through its
    internal lanes, except the lanes ``came_by`` the path itself (id -> where the lane they lead into starts),
    and the id of the lane it ends in."""
    step = 1 if leaving > arriving else -1
    entered = [edge.getLane(i) for i in range(arriving + step, leaving + step, step)]
    enters = {lane.getID(): np.asarray(lane.getShape(), dtype=np.float64)[:, :2] for lane in entered}
    feeders: dict[str, tuple[float, float]] = {}
    for incoming in edge.getFromNode().getIncoming():
        for c in incoming.getOutgoing().get(edge, []):
            to = c.getToLane()
            if to.getID() in enters:
                start = tuple(to.getShape()[0][:2])
                for lane in (c.getFromLane(), *_via_chain(net, c)):
                    if lane.getID() not in came_by:
                        feeders.setdefault(lane.getID(), start)
    return enters, feeders, entered[-1].getID()


def _junction_of(internal_edge: str) -> str:
    """The key of the junction an internal edge (":<junction id>_<index>") lies in: ":" + junction id."""
    return internal_edge.rpartition("_")[0]


def _for_cars(lane) -> bool:
    return lane.allows("passenger")


def _change_cost(lanes: int, edge_length_m: float) -> float:
    return lanes * (1.0 + LANE_CHANGE_COST_M / min(max(edge_length_m, 1.0), CHANGE_ROOM_M))


class _LanePlan:
    """Which lane the path takes on each edge of a route and the connection it leaves by: the fewest and
    cheapest lane changes (``_change_cost``) to the end, planned backwards from the last edge like SUMO's
    best lanes."""

    def __init__(self, net, route: list[str]):
        self.edges = [net.getEdge(e) for e in route]
        n = len(route)
        # best[i][lane index] = (cost to the end leaving edge i from that lane, its connection)
        self.best: list[dict[int, tuple[float, object]]] = [{} for _ in range(n)]
        for i in range(n - 1, -1, -1):
            edge = self.edges[i]
            if i == n - 1:
                self.best[i] = {lane.getIndex(): (0.0, None) for lane in edge.getLanes() if _for_cars(lane)}
                continue
            nxt = self.edges[i + 1]
            length = nxt.getLength()
            after = self.best[i + 1]
            for c in edge.getOutgoing().get(nxt, []):
                if not (_for_cars(c.getFromLane()) and _for_cars(c.getToLane())):
                    continue
                b = c.getToLane().getIndex()
                onward = min(
                    (_change_cost(abs(b - a), length) + cost for a, (cost, _) in after.items()),
                    default=math.inf,
                )
                a = c.getFromLane().getIndex()
                if onward < self.best[i].get(a, (math.inf, None))[0]:
                    self.best[i][a] = (onward, c)

    def choose(self, i: int, arriving: int, first: bool):
        """(lane, connection out) on edge ``i`` for a path arriving on lane index ``arriving`` (the first
        edge: where the ego starts, the rightmost cheapest lane)."""
        edge, options = self.edges[i], self.best[i]
        if not options:
            return None, None
        length = edge.getLength()

        def total(a: int) -> tuple[float, int]:
            change = 0.0 if first else _change_cost(abs(a - arriving), length)
            # as cheap either way: change here rather than on a later edge (CHANGE_ROOM_M)
            return (round(change + options[a][0], 9), -abs(a - arriving) if not first else a)

        a = min(options, key=total)
        return edge.getLane(a), options[a][1]


def _length(pts) -> float:
    return float(sum(math.dist(a, b) for a, b in itertools.pairwise(pts)))


class _Polyline:
    """Points appended shape by shape, with the running length (the route can have thousands)."""

    def __init__(self):
        self.pts: list[tuple[float, float]] = []
        self.length = 0.0

    def extend(self, shape: list) -> float:
        """Append ``shape``; returns the length before it (the limit of a lane starts at its joint)."""
        s0 = self.length
        gap = math.dist(self.pts[-1], shape[0]) if self.pts and shape else 0.0
        self.pts.extend(shape)
        self.length = s0 + gap + _length(shape)
        return s0


def _split(shape: list, dist: float) -> tuple[list, list]:
    """A polyline cut ``dist`` metres along it: (the part before, the part after), both with the cut point
    (the whole line and its last point when it is shorter)."""
    acc = 0.0
    for i in range(1, len(shape)):
        seg = math.dist(shape[i - 1], shape[i])
        if acc + seg >= dist:
            f = (dist - acc) / seg if seg else 0.0
            p = (shape[i - 1][0] + f * (shape[i][0] - shape[i - 1][0]),
                 shape[i - 1][1] + f * (shape[i][1] - shape[i - 1][1]))  # fmt: skip
            return [*shape[:i], p], [p, *shape[i:]]
        acc += seg
    return list(shape), shape[-1:]


def _head(shape: list, dist: float) -> list:
    return _split(shape, dist)[0]


def _trim_start(shape: list, dist: float) -> list:
    return _split(shape, dist)[1]

"""A hand-built stand-in for the sumolib network objects cosim reads (nodes, edges, lanes, connections,
traffic lights), for unit tests of code that walks a network without building one with netconvert.
Only the getters cosim calls exist; their names are sumolib's."""

# ruff: noqa: N802 (sumolib's method names)

from __future__ import annotations

import numpy as np


class Node:
    """A junction of ``type`` (SUMO's junction types); edges add themselves to its incoming / outgoing."""

    def __init__(self, nid: str, xy: tuple[float, float] = (0.0, 0.0), type: str = "traffic_light"):
        self.nid, self.xy, self.type, self.incoming, self.outgoing = nid, xy, type, [], []

    def getID(self):
        return self.nid

    def getCoord(self):
        return self.xy

    def getType(self):
        return self.type

    def getIncoming(self):
        return self.incoming

    def getOutgoing(self):
        return self.outgoing


class Lane:
    """Lane ``index`` of ``edge`` (set by Edge), along ``shape``, with its outgoing connections; ``lid``
    names an internal lane (a connection's via)."""

    def __init__(self, index: int = 0, shape=((0.0, 0.0), (1.0, 0.0)), conns=(), lid: str = ""):
        self.index, self.shape, self.conns, self.edge, self.lid = index, list(shape), list(conns), None, lid

    def getIndex(self):
        return self.index

    def getID(self):
        return self.lid or f"{self.edge.eid}_{self.index}"

    def getShape(self):
        return self.shape

    def getLength(self):
        return float(np.hypot(*np.subtract(self.shape[-1], self.shape[0])))

    def getSpeed(self):
        return 13.89

    def getWidth(self):
        return 3.2

    def allows(self, vclass):
        return True

    def getOutgoing(self):
        return self.conns

    def getEdge(self):
        return self.edge


class Conn:
    def __init__(self, from_lane=None, to_lane=None, *, direction: str = "s", link: int = -1, state: str = "M",
                 via: Lane | None = None):  # fmt: skip
        self.from_lane, self.to_lane, self.direction, self.link, self.state, self.via = (
            from_lane, to_lane, direction, link, state, via)  # fmt: skip

    def getFromLane(self):
        return self.from_lane

    def getToLane(self):
        return self.to_lane

    def getDirection(self):
        return self.direction

    def getTLLinkIndex(self):
        return self.link

    def getState(self):
        return self.state

    def getViaLaneID(self):
        return self.via.lid if self.via is not None else None


class Edge:
    """An edge from ``from_node`` (default: a priority junction of its own) to ``node`` with ``lanes``;
    ``out`` maps a next edge to the connections into it."""

    def __init__(self, eid: str, lanes: list[Lane], node: Node, *, from_node: Node | None = None,
                 length_m: float = 100.0, speed_mps: float = 13.89):  # fmt: skip
        self.eid, self.lanes, self.node, self.out, self.length_m = eid, lanes, node, {}, length_m
        self.speed_mps = speed_mps
        self.into: dict = {}  # the edges feeding this one and their connections, as sumolib's getIncoming
        self.params: dict[str, str] = {}  # OSM's tags netconvert keeps (e.g. turn:lanes)
        self.from_node = from_node if from_node is not None else Node(f"from_{eid}", type="priority")
        node.incoming.append(self)
        self.from_node.outgoing.append(self)
        for lane in lanes:
            lane.edge = self

    @classmethod
    def straight(cls, eid: str, x0: float, x1: float, n_lanes: int) -> Edge:
        """An eastbound edge from x0 to x1, lane 0 on y = 0 and each further lane 3.2 m to the south."""
        lanes = [Lane(i, [(x0, -3.2 * i), (x1, -3.2 * i)]) for i in range(n_lanes)]
        return cls(eid, lanes, Node(f"n{eid}", (x1, 0.0)), length_m=abs(x1 - x0))

    def connect(self, to_edge: Edge, lane_pairs: list[tuple[int, int]]) -> None:
        """Connections from this edge's lanes into ``to_edge``'s, as (from lane, to lane) index pairs."""
        conns = [Conn(self.lanes[a], to_edge.lanes[b]) for a, b in lane_pairs]
        self.out[to_edge] = conns
        to_edge.into[self] = conns
        for c in conns:
            c.from_lane.conns.append(c)

    def getID(self):
        return self.eid

    def getFunction(self):
        return ""

    def getSpeed(self):
        return self.speed_mps

    def getOutgoing(self):
        return self.out

    def getIncoming(self):
        return self.into

    def getToNode(self):
        return self.node

    def getFromNode(self):
        return self.from_node

    def allows(self, vclass):
        return True

    def getLength(self):
        return self.length_m

    def getLane(self, i):
        return self.lanes[i]

    def getLanes(self):
        return self.lanes

    def getLaneNumber(self):
        return len(self.lanes)

    def getParams(self):
        return self.params


class _Phase:
    def __init__(self, state: str, duration: float = 30.0):
        self.state, self.duration, self.minDur, self.maxDur = state, duration, -1, -1


class _Program:
    def __init__(self, states: list[str]):
        self.phases = [_Phase(s) for s in states]

    def getPhases(self):
        return self.phases


class TrafficLight:
    """Light ``tid`` over the connections of ``lanes`` (their link indices), one programme of ``states``."""

    def __init__(self, tid: str, lanes: list[Lane], states: list[str]):
        self.tid, self.lanes, self.states = tid, lanes, states

    def getID(self):
        return self.tid

    def getConnections(self):
        return [(lane, c.getToLane(), c.getTLLinkIndex()) for lane in self.lanes for c in lane.getOutgoing()]

    def getPrograms(self):
        return {"0": _Program(self.states)}


class Net:
    def __init__(self, edges=(), traffic_lights=(), internal_lanes=()):
        self.edges = {e.eid: e for e in edges}
        self.traffic_lights = list(traffic_lights)
        self.internal = {lane.lid: lane for lane in internal_lanes}
        self.lefthand = False  # as cosim.sumo_bridge.network.read_network sets it

    def getLane(self, lid):
        return self.internal[lid]

    def getEdge(self, eid):
        return self.edges[eid]

    def getNodes(self):
        nodes = {}
        for e in self.edges.values():
            nodes.setdefault(e.from_node.nid, e.from_node)
            nodes.setdefault(e.node.nid, e.node)
        return list(nodes.values())

    def getEdges(self):
        return list(self.edges.values())

    def getRoundabouts(self):
        return []

    def getTrafficLights(self):
        return self.traffic_lights

"""Which signalised junctions get one green per approach (cosim.scenario.network.tls_layout_patches)."""

from __future__ import annotations

from dataclasses import dataclass

from cosim.scenario.network import tls_layout_patches


@dataclass
class Conn:
    direction: str
    link: int

    def getDirection(self):  # noqa: N802 (sumolib's names)
        return self.direction

    def getTLLinkIndex(self):  # noqa: N802
        return self.link


@dataclass(frozen=True)
class Node:
    id: str

    def getID(self):  # noqa: N802
        return self.id

    def getCoord(self):  # noqa: N802
        return (1.0, 2.0)


class Lane:
    def __init__(self, node, conns):
        self.node, self.conns = node, conns

    def getOutgoing(self):  # noqa: N802
        return self.conns

    def getEdge(self):  # noqa: N802
        return self

    def getToNode(self):  # noqa: N802
        return self.node


class Phase:
    def __init__(self, state):
        self.state = state


class Program:
    def __init__(self, states):
        self.phases = [Phase(s) for s in states]

    def getPhases(self):  # noqa: N802
        return self.phases


class Tls:
    def __init__(self, tid, lanes, states):
        self.tid, self.lanes, self.states = tid, lanes, states

    def getID(self):  # noqa: N802
        return self.tid

    def getConnections(self):  # noqa: N802
        return [(lane, None, c.getTLLinkIndex()) for lane in self.lanes for c in lane.getOutgoing()]

    def getPrograms(self):  # noqa: N802
        return {"0": Program(self.states)}


class Net:
    def __init__(self, *tls):
        self.tls = tls

    def getTrafficLights(self):  # noqa: N802
        return list(self.tls)


J = Node("j")


def test_a_permissive_left_sharing_its_lane_gets_one_green_per_approach():
    shared = Lane(J, [Conn("s", 0), Conn("l", 1)])
    (patch,) = tls_layout_patches(Net(Tls("j", [shared], ["Gg", "yy", "rr"])))
    assert 'id="j"' in patch and 'tl="j_incoming"' in patch and 'tlLayout="incoming"' in patch


def test_a_left_turn_with_its_own_lane_keeps_the_plan():
    through, left = Lane(J, [Conn("s", 0), Conn("r", 1)]), Lane(J, [Conn("l", 2)])
    assert tls_layout_patches(Net(Tls("j", [through, left], ["GGg", "rrG", "rrr"]))) == []


def test_a_protected_left_on_a_shared_lane_keeps_the_plan():
    shared = Lane(J, [Conn("s", 0), Conn("l", 1)])
    assert tls_layout_patches(Net(Tls("j", [shared], ["GG", "yy", "rr"]))) == []


def test_a_light_over_several_junctions_keeps_its_plan():
    a, b = Lane(J, [Conn("s", 0), Conn("l", 1)]), Lane(Node("k"), [Conn("s", 2)])
    assert tls_layout_patches(Net(Tls("joined", [a, b], ["GgG", "rrr"]))) == []

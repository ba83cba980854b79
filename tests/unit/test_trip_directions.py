"""Which road is the other direction of a street (cosim.scenario.demand.opposite_edges): a trip may leave
its origin street, or reach its destination street, on either."""

from __future__ import annotations

from fake_net import Edge, Lane, Node

from cosim.scenario.demand import CARRIAGEWAY_GAP_M, opposite_edges


def road(eid: str, a: Node, b: Node) -> Edge:
    return Edge(eid, [Lane(0, [a.getCoord(), b.getCoord()])], b, from_node=a)


def test_the_other_direction_is_the_same_junctions_the_other_way_or_the_other_carriageway_beside_it():
    a, b = Node("a", (0.0, 0.0)), Node("b", (200.0, 0.0))
    # a divided road: eastbound on y = 0, westbound 20 m north between junctions of its own
    c, d = Node("c", (200.0, 20.0)), Node("d", (0.0, 20.0))
    # a street crossing further east, and a parallel one-way street 100 m north heading west
    e, f = Node("e", (300.0, -100.0)), Node("f", (300.0, 100.0))
    g, h = Node("g", (200.0, 100.0)), Node("h", (0.0, 100.0))
    two_way = [road("ab", a, b), road("ba", b, a)]
    divided = [road("east", a, b), road("west", c, d)]
    others = [road("ef", e, f), road("gh", g, h)]
    assert opposite_edges(two_way) == {"ab": "ba", "ba": "ab"}
    assert opposite_edges(divided + others) == {"east": "west", "west": "east"}
    # no other direction: a crossing street, or a parallel one further away than a median
    assert 20.0 < CARRIAGEWAY_GAP_M < 100.0
    assert opposite_edges([road("east", a, b), *others]) == {}

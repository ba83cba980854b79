"""Which junctions the pipeline joins into one crossing where netconvert's own join left them apart
(cosim.scenario.network.junction_joins)."""

from __future__ import annotations

from fake_net import Edge, Lane, Net, Node

from cosim.scenario.network import junction_joins


def _link(eid: str, a: Node, b: Node, length_m: float) -> Edge:
    return Edge(eid, [Lane(0, [a.getCoord(), b.getCoord()])], b, from_node=a, length_m=length_m)


def test_junctions_whose_centres_lie_within_a_metre_are_one_crossing():
    """map-bug432.osm: two priority junctions 0.49 m apart, which netconvert left apart because their
    cluster had a long edge, are joined; two 1.75 m apart (Aberdeen) and two lights 0.2 m apart by road
    but 5 m apart by centre stay as the rules say (lights: by road; others: by centre)."""
    a, b = Node("a", (0.0, 0.0), "priority"), Node("b", (0.49, 0.0), "priority")
    c, d = Node("c", (50.0, 0.0), "priority"), Node("d", (51.75, 0.0), "priority")
    e, f = Node("e", (100.0, 0.0), "traffic_light"), Node("f", (105.0, 0.0), "traffic_light")
    g = Node("g", (200.0, 0.0), "priority")
    edges = [_link("ab", a, b, 0.2), _link("ba", b, a, 0.2), _link("cd", c, d, 0.2), _link("ef", e, f, 0.2),
             _link("bg", b, g, 0.5)]  # fmt: skip
    assert junction_joins(Net(edges)) == [["a", "b"], ["e", "f"]]


def test_a_road_of_a_metre_or_more_keeps_its_junctions_apart():
    a, b = Node("a", (0.0, 0.0), "priority"), Node("b", (0.5, 0.0), "priority")
    assert junction_joins(Net([_link("ab", a, b, 1.0)])) == []

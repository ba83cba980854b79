"""Which signalised junctions get one green per approach (cosim.scenario.network.tls_layout_patches)."""

from __future__ import annotations

from fake_net import Conn, Edge, Lane, Net, Node, TrafficLight

from cosim.scenario.network import tls_layout_patches


def approach(node: Node, *conns: tuple[str, int], **edge) -> Lane:
    """A lane into ``node`` whose connections are (direction, link index of the light)."""
    lane = Lane(conns=[Conn(direction=d, link=i) for d, i in conns])
    Edge("in", [lane], node, **edge)
    return lane


J = Node("j", (1.0, 2.0))


def test_a_permissive_left_sharing_its_lane_gets_one_green_per_approach():
    shared = approach(J, ("s", 0), ("l", 1))
    (patch,) = tls_layout_patches(Net(traffic_lights=[TrafficLight("j", [shared], ["Gg", "yy", "rr"])]))
    assert 'id="j"' in patch and 'tl="j_incoming"' in patch and 'tlLayout="incoming"' in patch


def test_a_left_turn_with_its_own_lane_keeps_the_plan():
    through, left = approach(J, ("s", 0), ("r", 1)), approach(J, ("l", 2))
    assert (
        tls_layout_patches(Net(traffic_lights=[TrafficLight("j", [through, left], ["GGg", "rrG", "rrr"])]))
        == []
    )


def test_a_protected_left_on_a_shared_lane_keeps_the_plan():
    shared = approach(J, ("s", 0), ("l", 1))
    assert tls_layout_patches(Net(traffic_lights=[TrafficLight("j", [shared], ["GG", "yy", "rr"])])) == []


def test_a_light_over_several_junctions_keeps_its_plan():
    a, b = approach(J, ("s", 0), ("l", 1)), approach(Node("k"), ("s", 2))
    assert tls_layout_patches(Net(traffic_lights=[TrafficLight("joined", [a, b], ["GgG", "rrr"])])) == []


def test_a_light_a_short_road_away_from_another_keeps_its_plan():
    """One green per approach would starve the short road between two lights (Helsinki 30259739#0)."""
    j = Node("j2")
    shared = approach(j, ("s", 0), ("l", 1), from_node=Node("other_light"), length_m=30.0)
    assert tls_layout_patches(Net(traffic_lights=[TrafficLight("j2", [shared], ["Gg", "yy", "rr"])])) == []
    far = Node("j3")
    shared = approach(far, ("s", 0), ("l", 1), from_node=Node("other_light"), length_m=200.0)
    assert (
        len(tls_layout_patches(Net(traffic_lights=[TrafficLight("j3", [shared], ["Gg", "yy", "rr"])]))) == 1
    )

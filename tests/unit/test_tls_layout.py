"""Which signal phases get one green per approach (cosim.scenario.network: split_permissive_phases,
split_signal_plans)."""

from __future__ import annotations

from fake_net import Conn, Edge, Lane, Net, Node, TrafficLight

from cosim.scenario.network import SignalPhase, split_permissive_phases, split_signal_plans


def approach(node: Node, *conns: tuple[str, int], **edge) -> Lane:
    """A lane into ``node`` whose connections are (direction, link index of the light)."""
    lane = Lane(conns=[Conn(direction=d, link=i) for d, i in conns])
    Edge("in", [lane], node, **edge)
    return lane


J = Node("j", (1.0, 2.0))


def phases(*states: str) -> list[SignalPhase]:
    """Green phases of 24 s (gap-actuated, 5-50 s), yellow ones of 3 s."""
    return [SignalPhase(3.0, s) if "y" in s else SignalPhase(24.0, s, 5.0, 50.0) for s in states]


def test_a_permissive_left_sharing_its_lane_splits_its_phase_by_approach():
    # A and B face each other; each lane goes straight (0, 2) and turns left (1, 3) at a permissive green
    links = {0: ("A", "A_0", "s"), 1: ("A", "A_0", "l"), 2: ("B", "B_0", "s"), 3: ("B", "B_0", "l")}
    split = split_permissive_phases(phases("GgGg", "yyyy"), links)
    assert [ph.state for ph in split] == ["GGrr", "yyrr", "rrGG", "rryy"]  # each left protected in its turn
    assert [(ph.duration_s, ph.min_s, ph.max_s) for ph in split[::2]] == [(12, 5, 25), (12, 5, 25)]
    assert [ph.duration_s for ph in split[1::2]] == [3.0, 3.0]


def test_only_the_phases_with_the_waiting_or_the_hollow_left_are_split():
    """Krems 71582001: the main road keeps its shared green with permissive lefts; its protected-left phase,
    which holds the lane's straight movement at red, becomes the approach's whole green, and the side roads'
    phase, whose lefts never get a protected one, is split."""
    links = {0: ("M", "M_0", "s"), 1: ("M", "M_0", "l"), 2: ("S", "S_0", "s"), 3: ("S", "S_0", "l"),
             4: ("T", "T_0", "s"), 5: ("T", "T_0", "l")}  # fmt: skip
    # M's left is permissive, then protected; S and T share a green with permissive lefts only
    plan = phases("Ggrrrr", "yyrrrr", "rGrrrr", "ryrrrr", "rrGgGg", "rryyyy")
    split = split_permissive_phases(plan, links)
    # M's yellow between its two greens has nothing to show: left out
    assert [ph.state for ph in split] == ["Ggrrrr", "GGrrrr", "yyrrrr", "rrGGrr", "rryyrr", "rrrrGG",
                                          "rrrryy"]  # fmt: skip


def test_a_left_turn_with_its_own_lane_keeps_the_plan():
    links = {0: ("A", "A_0", "s"), 1: ("A", "A_1", "l")}
    assert split_permissive_phases(phases("Gg", "yy"), links) is None
    assert split_permissive_phases(phases("Gg", "yy", "rG", "ry"), links) is None  # its own protected green


def test_a_protected_left_that_holds_its_lanes_straight_at_red_gets_the_whole_approach():
    """The straight car at the head of the shared lane would hold the turners, and SUMO's actuated logic has
    no detector for such a phase (a lane counts only when all its movements are green): it ended at its
    5-s minimum with the queue standing (Krems 71582001, both main-road lefts protected together)."""
    links = {0: ("A", "A_0", "s"), 1: ("A", "A_1", "s"), 2: ("A", "A_1", "l"),
             3: ("B", "B_0", "s"), 4: ("B", "B_1", "s"), 5: ("B", "B_1", "l")}  # fmt: skip
    plan = phases("GGgGGg", "yygyyg", "rrGrrG", "rryrry")
    plan[2] = SignalPhase(6.0, "rrGrrG", 5.0, 50.0)  # netconvert's left-turn phase: 6 s, the actuated max 50
    split = split_permissive_phases(plan, links)
    # the first yellow ends B's movements only: A's stay green into A's own phase; B's own phase runs on into
    # the shared green, so the yellow after it is left out
    assert [ph.state for ph in split] == ["GGgGGg", "GGgyyy", "GGGrrr", "yyyrrr", "rrrGGG"]
    # each approach gets the left-turn phase's planned time at most, so the other phases keep their share
    assert [(ph.min_s, ph.max_s) for ph in (split[2], split[4])] == [(5, 6), (5, 6)]


def test_a_light_with_a_waiting_left_gets_a_split_plan():
    shared = approach(J, ("s", 0), ("l", 1))
    plans = split_signal_plans(Net(traffic_lights=[TrafficLight("j", [shared], ["Gg", "yy", "rr"])]))
    assert [ph.state for ph in plans["j"]["0"]] == ["GG", "yy", "rr"]


def test_a_light_over_several_junctions_keeps_its_plan():
    a, b = approach(J, ("s", 0), ("l", 1)), approach(Node("k"), ("s", 2))
    assert split_signal_plans(Net(traffic_lights=[TrafficLight("joined", [a, b], ["GgG", "rrr"])])) == {}


def test_a_light_a_short_road_away_from_another_keeps_its_plan():
    """One green per approach would starve the short road between two lights (Helsinki 30259739#0)."""
    j = Node("j2")
    shared = approach(j, ("s", 0), ("l", 1), from_node=Node("other_light"), length_m=30.0)
    assert split_signal_plans(Net(traffic_lights=[TrafficLight("j2", [shared], ["Gg", "yy", "rr"])])) == {}
    far = Node("j3")
    shared = approach(far, ("s", 0), ("l", 1), from_node=Node("other_light"), length_m=200.0)
    assert list(
        split_signal_plans(Net(traffic_lights=[TrafficLight("j3", [shared], ["Gg", "yy", "rr"])]))
    ) == ["j3"]

"""Which legs the ego's route refuses as turning back (cosim.scenario.demand.RouteChainer.turns_back)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from cosim.scenario.demand import RouteChainer


class StraightEdge:
    """A straight edge of ``length_m`` heading ``heading_deg`` (counter-clockwise from east)."""

    def __init__(self, eid: str, heading_deg: float, length_m: float):
        self.eid, self.length_m = eid, length_m
        h = math.radians(heading_deg)
        self.shape = [(0.0, 0.0), (length_m * math.cos(h), length_m * math.sin(h))]

    def getID(self):  # noqa: N802 (sumolib's names)
        return self.eid

    def getLength(self):  # noqa: N802
        return self.length_m

    def getShape(self):  # noqa: N802
        return self.shape

    def getSpeed(self):  # noqa: N802
        return 13.89

    def getToNode(self):  # noqa: N802
        return SimpleNamespace(getID=lambda: f"{self.eid}:end")

    def getOutgoing(self):  # noqa: N802
        return {}


def chainer(*edges: tuple[str, float, float]) -> RouteChainer:
    return RouteChainer([StraightEdge(*e) for e in edges])


def test_a_loop_through_tiny_edges_turns_back_though_no_single_turn_is_a_hairpin():
    """Monaco 25082741: -101 then -124 deg within 6 m of road is a U-turn the car cannot steer."""
    c = chainer(("in", 0.0, 150.0), ("a", -101.0, 2.0), ("b", -225.0, 5.4), ("out", 180.0, 150.0))
    assert not any(c.hairpin(x, y) for x, y in (("in", "a"), ("a", "b")))
    assert c.turns_back(["in", "a", "b", "out"])


def test_one_sharp_turn_is_a_hairpin_and_a_block_round_or_an_s_bend_is_not():
    c = chainer(("in", 0.0, 100.0), ("back", 180.0, 100.0), ("left", 90.0, 100.0), ("west", 180.0, 100.0),
                ("jog", 90.0, 5.0), ("east", 0.0, 100.0))  # fmt: skip
    assert c.turns_back(["in", "back"])
    assert not c.turns_back(["in", "left", "west"])  # 180 deg in all, but 100 m apart: round a block
    assert not c.turns_back(["in", "jog", "east"])  # +90 then -90 within 5 m


class LinkedEdge(StraightEdge):
    """A StraightEdge with the edges it leads to."""

    def __init__(self, eid: str, heading_deg: float, length_m: float):
        super().__init__(eid, heading_deg, length_m)
        self.outs: list[LinkedEdge] = []

    def getOutgoing(self):  # noqa: N802
        return {o: [] for o in self.outs}

    def getType(self):  # noqa: N802
        return "highway.residential"


def test_endless_edges_are_those_a_route_can_leave_for_ever_without_turning_back():
    """A block of four 100-m edges (left turns all round) and a spur off it, a dead end whose only way on is
    the U-turn into the road back: a leg that ends on the spur strands the route there (graphhopper's
    Laufamholzstrasse extract: the ego stood 233 s at its route's end); the road back is reached only by
    that U-turn."""
    e = {k: LinkedEdge(k, h, 100.0) for k, h in
         (("s1", 0.0), ("s2", 90.0), ("s3", 180.0), ("s4", 270.0), ("spur", 270.0), ("back", 90.0))}  # fmt: skip
    for a, bs in {"s1": ["s2", "spur"], "s2": ["s3"], "s3": ["s4"], "s4": ["s1"], "spur": ["back"],
                  "back": ["s2"]}.items():  # fmt: skip
        e[a].outs = [e[b] for b in bs]
    c = RouteChainer(list(e.values()))
    assert c.hairpin("spur", "back")
    assert c.endless == {"s1", "s2", "s3", "s4"}
    e["s4"].outs = []  # no block: every way turns round or ends
    assert RouteChainer(list(e.values())).endless == set()


def test_a_first_leg_that_comes_back_to_the_start_junction_is_refused_when_asked():
    """Krems, seed 3: from 24864391#2 every destination was reached round the block and back through the
    junction the route set off from; with ``avoid_node`` (the start junction, for the ego's first leg) such a
    batch gives no leg, so the route starts elsewhere, and a leg that does not pass it is still taken."""
    e = {k: LinkedEdge(k, h, 100.0) for k, h in
         (("start", 0.0), ("n", 90.0), ("w", 180.0), ("s", 270.0), ("away", 0.0))}  # fmt: skip
    c = RouteChainer(list(e.values()))
    c.dest_ids, c.endless = ["away"], set()
    round_the_block = ["start", "n", "w", "s", "away"]  # "s" ends where "start" begins
    c.to_node["s"] = "junction0"

    def legs_for(pairs):
        return {p: round_the_block for p in pairs}

    route = ["start"]
    assert c.extend(route, np.random.default_rng(0), legs_for, avoid_node="junction0") == 0.0
    assert route == ["start"]
    assert c.extend(route, np.random.default_rng(0), legs_for, avoid_node="elsewhere") == 400.0
    assert route == round_the_block

"""The drivable component is the largest strongly connected part of the car network, wherever it lies."""

from __future__ import annotations

import itertools

import sumolib

from cosim.scenario.demand import drivable_component
from tests.plain_net import plain_net


def test_the_largest_component_is_found_when_the_main_roads_lie_outside_it(tmp_path):
    """Munich with short stubs closed to turning: its main roads joined the rest only by U-turns in those
    stubs, and a search seeded from the five most important roads returned one edge. Here six one-way main
    road edges lead nowhere and the streets form a two-way block: the block is the component."""
    nodes = {f"c{i}": (100.0 * i, 500.0) for i in range(7)}
    nodes |= {"sw": (0.0, 0.0), "s": (100.0, 0.0), "se": (200.0, 0.0), "ne": (200.0, 200.0), "n": (100.0, 200.0),
              "nw": (0.0, 200.0)}  # fmt: skip
    edges = {f"main{i}": (f"c{i}", f"c{i + 1}", 10) for i in range(6)}
    block = ("sw", "s", "se", "ne", "n", "nw", "sw")
    for a, b in [*itertools.pairwise(block), ("s", "n")]:  # a cross street joins the two directions
        edges[f"{a}_{b}"] = (a, b, 1)
        edges[f"{b}_{a}"] = (b, a, 1)
    net = sumolib.net.readNet(str(plain_net(tmp_path, nodes, edges)))
    comp = sorted(e.getID() for e in drivable_component(net))
    assert comp == sorted(e for e in edges if not e.startswith("main")), comp

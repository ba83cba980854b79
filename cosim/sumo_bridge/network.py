"""The read-only network view: SUMO's network file as a sumolib network, read here and only here.

Route geometry (``cosim.driver.route.RoutePath``), the drivable part of the network, the traffic
generator's spawn spots, the 3D scene, the map on ``/map`` and the scenario build all read the network
through this function; they use the returned object's getters (``getEdge``, ``getEdges``, ``getShape``,
``getLanes`` ...) and never change it. No module outside ``cosim.sumo_bridge`` imports sumolib, libsumo or
traci (tests/unit/test_import_graph.py).
"""

from __future__ import annotations

from pathlib import Path


def read_network(net_file: str | Path, *, internal: bool = False, programs: bool = False):
    """The network of ``net_file`` (a ``sumolib.net.Net``); ``internal``: with the junctions' internal
    lanes (route geometry through junctions needs them); ``programs``: with the traffic lights' plans.
    Its ``lefthand`` attribute says whether traffic keeps to the left (sumolib does not read it)."""
    import sumolib

    net = sumolib.net.readNet(str(net_file), withInternal=internal, withPrograms=programs)
    net.lefthand = is_lefthand(net_file)
    return net


def is_lefthand(net_file: str | Path) -> bool:
    """Whether the network file's traffic keeps to the left (``<net lefthand="true">``, netconvert's
    ``--lefthand``)."""
    from xml.etree import ElementTree as ET

    for _, elem in ET.iterparse(str(net_file), events=("start",)):
        if elem.tag == "net":
            return elem.get("lefthand") == "true"
    return False

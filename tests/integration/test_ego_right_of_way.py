"""SUMO's cars give the ego its right of way, although MuJoCo drives it and SUMO only sees it placed each step.

The ego's twin in SUMO moves by ``moveToXY`` and tells its speed by ``setPreviousSpeed``
(``SumoBridge.write_ego``); SUMO's junction model must still see it approach: a car on the minor road waits
for it at the give-way line, an oncoming car turning left waits for it to pass. The ego crosses at 13 m/s
while an SCV (the scenario's vehicle type) reaches the junction up to 2 s before or after it; SUMO checks
collisions on junctions too, as in a scenario's sumocfg.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
import sumolib
from plain_net import plain_net

from cosim.scenario.behaviour import ScvBehaviour
from cosim.sumo_bridge.bridge import SumoBridge
from cosim.world import EGO_ID

pytestmark = pytest.mark.own_process  # libsumo: one simulation per process

SPEED_MPS = 13.0
ARRIVAL_S = 15.0  # both would reach the crossing point this long after the start
MIN_PET_S = 0.5  # post-encroachment time: the SCV enters the conflict area this long after the ego left it


@pytest.fixture
def crossing(tmp_path):
    """A priority road W-E (both ways) across a minor road S-N (both ways) at C."""
    nodes = {"W": (-400, 0), "C": (0, 0), "E": (400, 0), "S": (0, -400), "N": (0, 400)}
    edges = {"WC": ("W", "C", 3), "CE": ("C", "E", 3), "EC": ("E", "C", 3), "CW": ("C", "W", 3),
             "SC": ("S", "C", 1), "CN": ("C", "N", 1), "NC": ("N", "C", 1), "CS": ("C", "S", 1)}  # fmt: skip
    net = plain_net(tmp_path, nodes, edges, priority_nodes=["C"])
    vtypes = ScvBehaviour(n_vtypes=1, sigma=0.0).vtype_distribution_xml(np.random.default_rng(0))
    (tmp_path / "scv.rou.xml").write_text(f"<routes>\n{vtypes}\n</routes>\n")
    (tmp_path / "signs.add.xml").write_text("<additional/>\n")  # SumoBridge loads the scenario's signs
    cfg = tmp_path / "crossing.sumocfg"
    cfg.write_text(
        f'<configuration><input><net-file value="{net}"/><route-files value="{tmp_path / "scv.rou.xml"}"/>'
        '</input><processing><collision.action value="warn"/><collision.check-junctions value="true"/>'
        '<collision.mingap-factor value="0"/></processing></configuration>'
    )
    return cfg


def cross(cfg, scv_route: list[str], scv_late_s: float) -> dict:
    """The ego drives W -> E through C at SPEED_MPS; the SCV on ``scv_route`` would reach C ``scv_late_s``
    after it at the same speed. Returns SUMO's collisions, the SCV's lowest speed [m/s], when each came out of
    the junction [s] and the post-encroachment times SUMO's SSM device measured for the SCV [s]."""
    net = sumolib.net.readNet(str(cfg.parent / "n.net.xml"))
    (x0, y0), (x1, y1) = net.getLane("WC_0").getShape()[0], net.getLane("WC_0").getShape()[-1]
    ux, uy = (x1 - x0) / math.dist((x0, y0), (x1, y1)), (y1 - y0) / math.dist((x0, y0), (x1, y1))
    heading = math.degrees(math.atan2(ux, uy))
    ssm = cfg.parent / f"ssm_{'_'.join(scv_route)}_{scv_late_s:+.1f}.xml"
    bridge = SumoBridge(
        cfg,
        seed=1,
        step_s=0.1,
        extra_args=(
            "--device.ssm.explicit",
            "scv",
            "--device.ssm.measures",
            "PET TTC",
            "--device.ssm.file",
            str(ssm),
        ),
    )
    sumo = bridge._sumo
    try:
        front = net.getEdge("WC").getLength() - SPEED_MPS * ARRIVAL_S
        bridge.add_ego(["WC", "CE"], controlled=True, length_m=4.5, width_m=1.8, front_m=front)
        sumo.route.add("scv_route", scv_route)
        scv_pos = net.getEdge(scv_route[0]).getLength() - SPEED_MPS * (ARRIVAL_S + scv_late_s)
        sumo.vehicle.add(
            "scv", "scv_route", typeID="scv", departPos=f"{scv_pos:.2f}", departSpeed=str(SPEED_MPS)
        )
        collisions, lowest, ego_out, scv_out = [], math.inf, math.inf, math.inf
        for _ in range(int(2 * ARRIVAL_S / 0.1)):
            sumo.simulationStep()
            t = sumo.simulation.getTime()
            if EGO_ID in sumo.vehicle.getIDList():  # placed: drive on at the ego's speed
                front += SPEED_MPS * 0.1
                assert bridge.write_ego(x0 + ux * front, y0 + uy * front, heading, SPEED_MPS, on_route=True,
                                        verify_on_road=False) is None  # fmt: skip
            collisions += [(c.collider, c.victim, c.lane) for c in sumo.simulation.getCollisions()]
            if "scv" in sumo.vehicle.getIDList():
                lowest = min(lowest, sumo.vehicle.getSpeed("scv"))
                if sumo.vehicle.getRoadID("scv") == scv_route[-1]:
                    scv_out = min(scv_out, t)
            if EGO_ID in sumo.vehicle.getIDList() and sumo.vehicle.getRoadID(EGO_ID) == "CE":
                ego_out = min(ego_out, t)
    finally:
        bridge.close()  # SUMO completes the SSM file when it closes
    return {
        "collisions": collisions,
        "lowest_mps": lowest,
        "ego_out_s": ego_out,
        "scv_out_s": scv_out,
        "pet_s": [float(v) for v in re.findall(r'<PET [^>]*value="([^"]*)"', ssm.read_text())],
    }


@pytest.mark.parametrize(
    "scv_route", [["SC", "CN"], ["EC", "CS"]], ids=["minor road straight across", "oncoming left turn"]
)
def test_sumo_cars_give_the_ego_its_right_of_way(crossing, scv_route):
    """Measured: the SCV passes the conflict area 0.7-1.2 s after the ego has left it (SUMO's post-
    encroachment time; above 2 s SUMO logs none) and comes out of the junction 2-3 s after it; with the
    ego's route in SUMO ending before the junction (SUMO's foes see the ego's way only as far as the route
    it holds), the SCV 2 s early goes first."""
    for late_s in (-2.0, -1.0, 0.0, 1.0, 2.0):
        r = cross(crossing, scv_route, late_s)
        assert r["collisions"] == [], (late_s, r)
        assert all(pet > MIN_PET_S for pet in r["pet_s"]), (late_s, r)  # none logged: PET above 2 s
        if (
            late_s <= 0.0
        ):  # it would have been in the crossing before or with the ego: it let the ego go first
            assert r["scv_out_s"] > r["ego_out_s"], (late_s, r)
            assert r["pet_s"], (late_s, r)  # a real conflict: SUMO's SSM saw one
    # a car that comes 2 s after the ego keeps going (the ego is no phantom obstacle for it)
    assert r["lowest_mps"] > 5.0, r

"""A side road merging into one lane of a multi-lane road yields to that lane's stream only, as in HCM 2010.

netconvert's default computes foes per edge pair: a car turning from a side road into the near lane of a
two-lane road then also waits for gaps in the far lane it never crosses (Monaco 25193333: the side
street's left turn into the left lane of a one-way road yielded to the right lane, and passed a car
every 60-75 s). HCM 2010 Chapter 19 counts only the lane merged into (Exhibit 19-14: the conflicting
flow of a minor right turn is v_2 / N, the major through flow per lane). The scenario pipeline therefore
builds its networks with ``--check-lane-foes.all`` (``cosim.scenario.network.COMMON_OPTIONS``).

A toy one-way two-lane road at 50 km/h with a Poisson stream in each lane (lane changes off, so that
each lane's arrivals stay random as Harders' formula assumes) and a saturated side road on either side:
a right turn into the right lane, a left turn into the left lane. The capacity must follow HCM's
potential capacity for the flow in the lane merged into, within test_minor_capacity's factor. With
edge-pair foes it fell to 0.13-0.32 of it at 1200-1800 veh/h on the road.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest
from plain_net import plain_net
from test_minor_capacity import FACTOR, MEASURE_S, SPEED_MPS, WARM_S, hcm_potential_capacity

from cosim.scenario.behaviour import ScvBehaviour
from cosim.scenario.network import COMMON_OPTIONS
from cosim.sumo_bridge.tools import run_tool

# side road -> the lane of the major road its turn enters (HCM Exhibit 19-10: right turn t_c 6.2, t_f 3.3 s;
# a left turn onto a one-way road merges like a right turn)
MERGES = {"SC": 0, "NC": 1}
T_C, T_F = 6.2, 3.3


@pytest.fixture(scope="module")
def road(tmp_path_factory):
    d = tmp_path_factory.mktemp("lane_merge")
    nodes = {"W": (-400, 0), "C": (0, 0), "E": (400, 0), "S": (0, -300), "N": (0, 300)}
    edges = {"WC": ("W", "C", 3, 2), "CE": ("C", "E", 3, 2), "SC": ("S", "C", 1), "NC": ("N", "C", 1)}
    plain_net(d, nodes, edges, priority_nodes=["C"], speed_mps=SPEED_MPS, options=COMMON_OPTIONS)
    return d


def merge_capacity(d, minor: str, v_total: float, seed: int = 1) -> tuple[float, float]:
    """(side-road vehicles per hour through, the flow measured in the lane they merge into [veh/h])."""
    # lane changes off on the major road: a keep-right change fills the right lane's gaps, and each lane's
    # stream would no longer be the random arrivals of HCM's model
    vtypes = ScvBehaviour().vtype_distribution_xml(np.random.default_rng(seed))
    vtypes = vtypes.replace("<vType ", '<vType lcKeepRight="0" lcSpeedGain="0" ')
    end = WARM_S + MEASURE_S
    rate = v_total / 2 / 3600.0
    flows = "".join(
        f'<flow id="M{lane}" type="scv" route="maj" begin="0" end="{end}" period="exp({rate:.6f})" '
        f'departSpeed="max" departLane="{lane}"/>'
        for lane in (0, 1)
    )
    flows += f'<flow id="m" type="scv" route="min" begin="0" end="{end}" period="2" departSpeed="0"/>'
    (d / "r.rou.xml").write_text(
        f'<routes>{vtypes}<route id="maj" edges="WC CE"/><route id="min" edges="{minor} CE"/>{flows}</routes>'
    )
    lane = MERGES[minor]
    (d / "loop.add.xml").write_text(
        f'<additional><inductionLoop id="loop" lane="WC_{lane}" pos="-15" period="{WARM_S:g}" '
        'file="loop.xml"/></additional>'
    )
    trips = d / "trips.xml"
    run = run_tool("sumo", ["-n", str(d / "n.net.xml"), "-r", str(d / "r.rou.xml"), "-a", str(d / "loop.add.xml"),
                            "--seed", str(seed), "--end", str(end), "--step-length", "0.1",
                            "--tripinfo-output", str(trips), "--no-step-log", "true", "--time-to-teleport", "-1",
                            "--max-depart-delay", "1e6"])  # fmt: skip
    assert run.returncode == 0, run.log
    left_junction = [
        float(t.get("arrival")) - 300.0 / SPEED_MPS  # the last 300 m of CE are free road
        for t in ET.parse(trips).getroot().iter("tripinfo")
        if t.get("id").startswith("m.")
    ]
    through = sum(WARM_S <= a < end for a in left_junction) * 3600.0 / MEASURE_S
    passed = sum(
        int(i.get("nVehContrib"))
        for i in ET.parse(d / "loop.xml").getroot().iter("interval")
        if float(i.get("begin")) >= WARM_S
    )
    return through, passed * 3600.0 / MEASURE_S


def test_the_pipeline_gives_each_merge_only_the_lane_it_enters_as_foe(road):
    net = ET.parse(road / "n.net.xml").getroot()
    index = {(c.get("from"), c.get("fromLane")): c.get("via") for c in net.iter("connection") if c.get("via")}
    junction = next(j for j in net.iter("junction") if j.get("id") == "C")
    lanes = junction.get("intLanes").split()
    foes = {int(r.get("index")): r.get("foes") for r in junction.iter("request")}
    for minor, lane in MERGES.items():
        link = lanes.index(index[(minor, "0")])
        foe_links = {len(lanes) - 1 - i for i, bit in enumerate(foes[link]) if bit == "1"}
        assert foe_links == {lanes.index(index[("WC", str(lane))])}, (minor, foes[link])


@pytest.mark.slow
@pytest.mark.parametrize("minor", list(MERGES))
def test_a_merge_into_one_lane_follows_hcm_2010_for_that_lane(road, minor):
    rows = []
    for v_total in (600.0, 1200.0, 1800.0):
        through, v_lane = merge_capacity(road, minor, v_total)
        hcm = hcm_potential_capacity(v_lane, T_C, T_F)
        rows.append((v_total, v_lane, through, hcm, through / hcm))
    table = "\n".join(
        f"road {v:5.0f} veh/h, lane merged into {vl:4.0f}: SUMO {s:5.0f}  HCM {h:5.0f}  ratio {r:.2f}"
        for v, vl, s, h, r in rows
    )
    print(f"{minor}\n{table}")
    assert all(1 / FACTOR <= r <= FACTOR for *_, r in rows), (
        f"{minor}: outside x{FACTOR} of HCM 2010\n{table}"
    )
    assert all(a[2] > b[2] for a, b in zip(rows, rows[1:], strict=False)), table

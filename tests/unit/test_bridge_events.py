"""What the bridge's traffic events say: a teleport names the lane it took the vehicle from (the user looks
there for the jam or the junction standoff)."""

from __future__ import annotations

from cosim.sumo_bridge.bridge import SumoBridge
from cosim.world import World


def test_a_teleport_names_the_lane_the_snapshot_last_had_the_vehicle_on():
    w = World(capacity=4)
    slot = w.add("scv7")
    w.edge_code[slot], w.lane_index[slot] = w.intern_edge("276604364#0"), 1
    assert SumoBridge._where(w, "scv7") == "from 276604364#0_1"
    w.edge_code[slot] = -1  # inside a junction: no lane of an edge to name
    assert SumoBridge._where(w, "scv7") == ""
    assert SumoBridge._where(w, "gone") == ""

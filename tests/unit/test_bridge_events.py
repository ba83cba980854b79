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


def test_a_collision_is_reported_once_while_sumo_repeats_it_and_names_pairs_in_turn():
    """Krems, make experiment P1: SUMO named ego/scv181 and ego/scv188 every other step for 3 s (30 events);
    each pair is one collision until SUMO has not reported it for COLLISION_MEMORY_STEPS."""
    from cosim.sumo_bridge.bridge import COLLISION_MEMORY_STEPS, collision_onset, forget_collisions

    seen: dict[tuple[str, str], int] = {}
    a, b = ("scv181", "ego"), ("ego", "scv188")
    onsets = []
    for step in range(100, 130):
        pair = a if step % 2 else b
        onsets += [pair] if collision_onset(seen, pair, step) else []
        forget_collisions(seen, step)
    assert onsets == [b, a]
    later = 130 + COLLISION_MEMORY_STEPS
    forget_collisions(seen, later)
    assert seen == {}
    assert collision_onset(seen, a, later)  # the same pair again after a pause: a new collision

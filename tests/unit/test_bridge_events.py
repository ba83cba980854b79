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


class _Vehicle:
    """A car driving 1 m a step towards a light 200 m ahead on its route; counts SUMO's route walks."""

    def __init__(self):
        self.odometer, self.light_at, self.walks = 0.0, 200.0, 0

    def getDistance(self, vid):
        return self.odometer

    def getNextTLS(self, vid):
        self.walks += 1
        left = self.light_at - self.odometer
        return [("tls1", 3, left, "G")] if left > 0 else []

    def setRoute(self, vid, edges):
        self.light_at = self.odometer + 120.0  # the new route passes another light sooner


def test_next_tls_within_reach_answers_as_sumo_would_without_walking_the_route_every_step():
    """The lead's getNextTLS walks its whole 15-km route; while its next light is out of reach the bridge
    does not ask, and its answers are the ones asking every step would give, also after a new route."""
    from types import SimpleNamespace

    bridge = SumoBridge.__new__(SumoBridge)
    bridge._sumo = SimpleNamespace(vehicle=_Vehicle())
    bridge._tls_beyond, bridge._route_changes = {}, {}
    veh = bridge._sumo.vehicle

    def truth(within_m):
        left = veh.light_at - veh.odometer
        return ("tls1", 3, left, "G") if 0 < left <= within_m else None

    answers = []
    for step in range(300):
        if step == 150:
            assert bridge._set_route("lead", ["a", "b"]) is None
        answers.append(bridge.next_tls("lead", within_m=70.0) == truth(70.0))
        veh.odometer += 1.0
    assert all(answers)
    # asked once out of reach, every step within 80 m of the first light (only 150 - 120 = 30 steps of it
    # before the new route), once after it and every step within 80 m of the new light
    assert veh.walks <= 1 + 30 + 1 + 80 + 1, veh.walks  # against 300 asked every step
    walks = veh.walks
    assert bridge.next_tls("lead") is None and veh.walks == walks + 1  # no reach given: SUMO is asked

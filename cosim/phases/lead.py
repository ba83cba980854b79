"""The lead vehicle of the following task (paper VII.C): a SUMO car on the ego's route that drives like a
considerate human leader, so the participant spends the drive following it.

- It starts 20 m ahead of the ego at the first step (``Simulation._place_ego``) and keeps to the ego's
  route, which ``cosim.phases.route`` extends for both as they drive.
- It drives a little below the limit (``sumo_bridge.LEAD_SPEED_FACTOR``) and waits for the participant:
  beyond ``wait_beyond_m`` of gap along the route it drives slower than the ego until the gap has closed to
  60 % of that (after a red light that stopped only the ego, a slow participant, a give-way the ego had to
  wait at).
- At a light it does not run away through a green that will stop the ego: approaching one, it reckons
  whether the ego, at its present speed, reaches the stop line before the green ends (the programme says
  when); if not, it stops at the line itself and both wait for the next green.
- A vehicle that comes between the lead and the ego (a cut-in) is logged as a ``lead_cut_in`` event.

Its speed is only ever capped (SUMO's car following, right of way and lights still hold it back).
"""

from __future__ import annotations

import math

from cosim.sumo_bridge.bridge import EGO_ID, LEAD_ID, SumoEvent

RESUME_SHARE = 0.6  # the waiting lead drives on freely once the gap is below this share of wait_beyond_m
WAIT_SLOWER_MPS = 2.0  # while waiting it drives this much slower than the ego [m/s]
LIGHT_DECIDE_M = 70.0  # the lead decides whether to stop for the ego's sake this far before a light [m]
LIGHT_MARGIN_S = 1.5  # the ego must reach the stop line this long before the green ends [s]
STOP_DECEL_MPS2 = 2.0  # the lead's planned deceleration when it stops for the ego at a green [m/s^2]
STOP_BEFORE_M = 1.0  # it stops this far before the stop line [m]


class LeadVehicle:
    def __init__(self, sim, wait_beyond_m: float):
        self.sim = sim
        self.wait_beyond_m = wait_beyond_m
        self.waiting = False
        self.cut_ins = 0
        self.gap_m = math.nan  # along the route, the lead's rear to the ego's front [m]
        self._capped = False
        self._light: tuple | None = None  # (tls id, link index, state) of the light decided on ...
        self._stop_at_light = False  # ... and whether the lead stops there for the ego
        self._lead_s: float | None = None  # the lead's rear on the ego's route path [m]
        self._ego_leader: str | None = None
        sim.add_hook("driver", self.step)

    def step(self, sim) -> None:
        w = sim.world
        lead, ego = w.slot_of.get(LEAD_ID), w.slot_of.get(EGO_ID)
        if lead is None or ego is None:
            return
        self.gap_m = self._gap(sim, lead, ego)
        self._log_cut_in(sim)
        v_ego = float(w.speed_mps[ego])
        caps = []
        if self.wait_beyond_m > 0:
            if self.gap_m > self.wait_beyond_m:
                self.waiting = True
            elif self.waiting and self.gap_m < RESUME_SHARE * self.wait_beyond_m:
                self.waiting = False
            if self.waiting:  # slower than the ego, so it closes up; standing while the ego stands
                caps.append(max(0.0, v_ego - WAIT_SLOWER_MPS))
        light_cap = self._light_cap(sim, v_ego)
        if light_cap is not None:
            caps.append(light_cap)
        if caps:
            sim.bridge.cap_speed(LEAD_ID, min(caps))
            self._capped = True
        elif self._capped:
            sim.bridge.cap_speed(LEAD_ID, None)
            self._capped = False

    def _gap(self, sim, lead: int, ego: int) -> float:
        """Bumper gap along the ego's route path (straight line when the ego has no path)."""
        w = sim.world
        ux, uy = w.heading_unit()
        rear_x = float(w.x_m[lead] - ux[lead] * w.length_m[lead])
        rear_y = float(w.y_m[lead] - uy[lead] * w.length_m[lead])
        controller = sim.ego
        if controller is None or getattr(controller, "s_front_m", None) is None:
            return math.hypot(rear_x - w.x_m[ego], rear_y - w.y_m[ego])
        near = self._lead_s if self._lead_s is not None else controller.s_front_m
        self._lead_s, _ = controller.path.project(rear_x, rear_y, near_s=near)
        return self._lead_s - controller.s_front_m

    def _light_cap(self, sim, v_ego: float) -> float | None:
        """Speed cap that stops the lead at a green light the ego would not get through, else None."""
        tls = sim.bridge.next_tls(LEAD_ID)
        if not tls or tls[2] > LIGHT_DECIDE_M:
            return None
        tls_id, link, dist, state = tls
        green = state in "Gg"
        if (tls_id, link, green) != self._light:  # a new light, or this one turned green / ended its green
            self._light = (tls_id, link, green)
            self._stop_at_light = False
            if green:
                # where the ego's front is when the lead's front is at the line, and how long it needs
                ego_to_line = dist + float(sim.world.length_m[sim.world.slot_of[LEAD_ID]]) + max(self.gap_m, 0.0)
                green_left = sim.bridge.tls_green_left_s(tls_id, link)
                self._stop_at_light = ego_to_line / max(v_ego, 1.0) + LIGHT_MARGIN_S > green_left
        if not self._stop_at_light or state in "rRuyY":  # red or amber: SUMO stops the lead by itself
            return None
        return math.sqrt(2.0 * STOP_DECEL_MPS2 * max(0.0, dist - STOP_BEFORE_M))

    def _log_cut_in(self, sim) -> None:
        """Another vehicle has become the ego's leader while the lead is still ahead of it."""
        percept = getattr(sim.ego, "percept", None)
        leader = percept.leader_id if percept is not None and percept.leader_present else None
        if self._ego_leader == LEAD_ID and leader not in (None, LEAD_ID) and self.gap_m > 0:
            self.cut_ins += 1
            sim.events.append(SumoEvent("lead_cut_in", leader, f"between the lead and the ego ({self.gap_m:.0f} m)",
                                        self.gap_m))  # fmt: skip
        self._ego_leader = leader

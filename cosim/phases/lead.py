"""The lead vehicle of the following task (paper VII.C): a SUMO car on the ego's route that waits for the
participant when the gap grows beyond ``wait_beyond_m`` (e.g. after the ego was stopped by a red light
that the lead passed), and drives freely again once the ego has closed up."""

from __future__ import annotations

import math

from cosim.sumo_bridge.bridge import EGO_ID, LEAD_ID


class LeadVehicle:
    def __init__(self, sim, wait_beyond_m: float):
        self.sim = sim
        self.wait_beyond_m = wait_beyond_m
        self.waiting = False
        if wait_beyond_m > 0:
            sim.add_hook("driver", self.step)

    def step(self, sim) -> None:
        w = sim.world
        lead, ego = w.slot_of.get(LEAD_ID), w.slot_of.get(EGO_ID)
        if lead is None or ego is None:
            return
        ux, uy = w.heading_unit()
        rear_x = w.x_m[lead] - ux[lead] * w.length_m[lead]
        rear_y = w.y_m[lead] - uy[lead] * w.length_m[lead]
        gap = math.hypot(rear_x - w.x_m[ego], rear_y - w.y_m[ego])
        veh = sim.bridge.sumo.vehicle
        if gap > self.wait_beyond_m:
            # slower than the ego, so it closes up; never below walking pace unless the ego stands
            target = max(0.0, min(float(w.speed_mps[ego]) - 2.0, veh.getAllowedSpeed(LEAD_ID)))
            veh.slowDown(LEAD_ID, target, 2.0)
            self.waiting = True
        elif self.waiting and gap < 0.6 * self.wait_beyond_m:
            veh.setSpeed(LEAD_ID, -1)  # back to SUMO's own car following
            self.waiting = False

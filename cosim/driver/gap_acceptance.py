"""Human gap acceptance where the ego must yield: stop and give-way signs, minor roads, priority to the
right, roundabout entries and permissive (unprotected) turns at lights.

A driver waiting to enter takes the next gap in the priority stream that is at least its critical gap
t_c; a driver queued right behind one that has just gone needs only the follow-up headway t_f. The base
values per movement are the Highway Capacity Manual's (TRB, HCM 2010):

- two-way stop-controlled intersections, two-lane major street, Exhibit 19-10: t_c / t_f = 4.1 / 2.2 s
  (major-street left turn, used for a permissive left turn at a light), 6.2 / 3.3 s (minor right),
  6.5 / 4.0 s (minor through), 7.1 / 3.5 s (minor left);
- single-lane roundabout entries, Chapter 21: capacity 1130 exp(-0.001 v_c) [veh/h], i.e. t_f = 3600 /
  1130 = 3.19 s and t_c = 3.6 s + t_f / 2 = 5.19 s.

Drivers who wait accept shorter gaps: the critical gap falls with the number of gaps rejected, i.e. with
waiting time (Mahmassani & Sheffi, "Using gap sequences to estimate gap acceptance functions", Transp.
Res. B 15 (1981)). SUMO models the same with its ``impatience`` (growing with waiting time up to
``--time-to-impatience``); here the critical gap falls linearly from t_c to the follow-up headway t_f over
the profile's ``time_to_impatience_s``. Below t_f nobody pulls out: a stream that never leaves a gap of
t_f truly blocks the junction (the run logs such a wait as a stall).
"""

from __future__ import annotations

import math

# (t_c, t_f) [s] by movement, HCM 2010 (see the module docstring)
HEADWAYS_S = {
    "permissive_left": (4.1, 2.2),
    "minor_right": (6.2, 3.3),
    "minor_through": (6.5, 4.0),
    "minor_left": (7.1, 3.5),
    "roundabout": (5.19, 3.19),
}
MOVEMENTS = tuple(HEADWAYS_S)
# priority vehicles farther from the junction than this do not count (paper IV.B: "approaching within 200 m")
FOE_RADIUS_M = 200.0
FOE_ACCEL_MPS2 = 1.5  # a slow or standing priority vehicle is assumed to speed up at this rate [m/s^2]
FOE_CRUISE_MPS = 5.0  # at or above this speed a priority vehicle is assumed to keep its speed [m/s]


def movement_of(direction: str, into_roundabout: bool = False, permissive: bool = False) -> str:
    """The HCM movement of a SUMO connection direction (s, r, R, l, L, t)."""
    if into_roundabout:
        return "roundabout"
    if permissive:
        return "permissive_left" if direction in ("l", "L", "t") else "minor_right"
    if direction in ("r", "R"):
        return "minor_right"
    if direction in ("l", "L", "t"):
        return "minor_left"
    return "minor_through"


def critical_gap_s(
    movement: str, waited_s: float, factor: float = 1.0, time_to_impatience_s: float = 60.0
) -> float:
    """The smallest gap [s] a driver takes after waiting ``waited_s``: t_c at first, falling linearly to t_f."""
    t_c, t_f = HEADWAYS_S[movement]
    share = min(1.0, max(0.0, waited_s) / time_to_impatience_s) if time_to_impatience_s > 0 else 1.0
    return factor * (t_c - (t_c - t_f) * share)


def follow_up_s(movement: str, factor: float = 1.0) -> float:
    """The follow-up headway t_f [s]: the gap a driver queued right behind a departing one accepts."""
    return factor * HEADWAYS_S[movement][1]


def arrival_time_s(dist_m: float, speed_mps: float) -> float:
    """When a priority vehicle ``dist_m`` from the conflict reaches it [s]: at its speed when it cruises,
    speeding up at FOE_ACCEL_MPS2 from a crawl or a stop (one that stands at a line may go at any moment)."""
    if dist_m <= 0.0:
        return 0.0
    v = max(0.0, speed_mps)
    if v >= FOE_CRUISE_MPS:
        return dist_m / v
    return (-v + math.sqrt(v * v + 2.0 * FOE_ACCEL_MPS2 * dist_m)) / FOE_ACCEL_MPS2

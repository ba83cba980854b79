"""SCV behaviour of the paper (IV.B) mapped onto SUMO vehicle types and junction-model parameters.

| paper rule | SUMO mapping | where SUMO differs |
|---|---|---|
| red light: stop 6 m before the junction | ``jmStoplineGap`` = 6 m (distance kept to a red light's stop line) | SUMO's stop line is at the junction's edge, so the 6 m are counted from there |
| stop sign: halt (>= 2 frames), go if nobody approaches within 200 m | junction type ``priority_stop`` / ``allway_stop``; ``jmStopSignWait``; ``jmStoplineGapMinor`` = 1 m; ``jmTimegapMinor`` = 200 m / reference major-road speed, capped at ``max_minor_time_gap_s`` | SUMO's gap acceptance is time-based and applies at every minor link, signed or not; the uncapped 14.4 s raised teleports on Krems from 4 % to 6 %, so the default cap is 3 s (set it to 15 for the literal rule) |
| give-way: slow to 5 km/h, stop if a vehicle approaches within 200 m | the give-way connections get a 5 km/h passage speed, so cars arrive at the line at 5 km/h; same gap rule | the 5 km/h also applies while crossing the junction, for at most 12 s: a longer passage (a roundabout entry of a large joined junction) is crossed in that time (``network.GIVE_WAY_PASSAGE_MAX_S``) |
| keep a 2-s gap to the vehicle ahead | Krauss ``tau`` = 1 s (SUMO's default reaction time); with ``sigma`` the headways in a platoon spread above it | SUMO's merge check makes the *major* follower keep ``tau`` behind a car entering from a side road: tau = 2 s cut the minor-road capacity to 10-15 % of HCM 2010's at 1200 veh/h (side roads queued for 10 min on Krems); with 1 s merges and crossings stay within x2.2 of HCM 2010 Ch. 19 potential capacity (tests/integration/test_minor_capacity.py) |
| (a side road merging into one lane of a multi-lane road waits for that lane's traffic) | netconvert ``--check-lane-foes.all`` | netconvert's default makes it wait for every lane of the road (foes per edge pair); per lane, merges follow HCM 2010 for the lane merged into (tests/integration/test_lane_merge_capacity.py) |
| slow down in curves | netconvert ``--junctions.limit-turn-speed 5.5`` (lateral accel. on junction turns) | curves inside an edge do not lower the speed in SUMO |
| (drivers avoid a jam they see) | SUMO's rerouting device on every SCV type, period ``reroute_period_s`` | without it every SCV keeps its free-flow A* route into the same bottleneck until SUMO teleports it |
| per-vehicle max accel / decel, mass, friction | a vTypeDistribution of ``n_vtypes`` types sampled from truncated normals | SUMO has no tyre friction: decel <= mu*g is enforced when sampling |
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

G = 9.81  # [m/s^2]


@dataclass(frozen=True)
class Dist:
    """A truncated normal distribution (mean, sd) clipped to [low, high]."""

    mean: float
    sd: float
    low: float
    high: float

    def __post_init__(self):
        if not self.low <= self.mean <= self.high or self.sd < 0:
            raise ValueError(f"distribution needs low <= mean <= high and sd >= 0, got {self}")

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return np.clip(rng.normal(self.mean, self.sd, n), self.low, self.high)


@dataclass(frozen=True)
class ScvBehaviour:
    time_gap_s: float = (
        1.0  # Krauss tau: the driver's reaction time, the least time gap kept [s] (see the table)
    )
    red_light_stop_gap_m: float = 6.0  # SCVs stop this far before the junction at red [m]
    stop_sign_clear_distance_m: float = 200.0  # go only if no foe is within this distance [m]
    reference_major_speed_mps: float = 13.89  # converts the clear distance into SUMO's time gap [m/s]
    max_minor_time_gap_s: float = (
        3.0  # cap: SUMO applies the gap at EVERY minor link, not only signed ones [s]
    )
    give_way_approach_speed_kmh: float = 5.0  # [km/h]
    # a driver waiting at a minor link goes when the traffic with priority stands still (a jam): without
    # it, queues that yield to each other around a block of junctions lock up until SUMO teleports them
    jammed_foe_speed_mps: float = 0.1  # priority traffic at or below this speed counts as standing [m/s]
    jammed_foe_ignore_prob: float = 0.0  # per step, chance to go past standing priority traffic [-] (off:
    # SUMO cannot tell a jam from a car that merely stopped, and 0.02 made SCVs drive into a standing ego)
    stop_sign_stop_gap_m: float = 1.0  # where SCVs halt before a stop sign's line [m]
    stop_sign_wait_s: float = 1.0  # minimum standstill at a stop sign (paper: >= 2 frames) [s]
    accel_mps2: Dist = Dist(2.6, 0.4, 1.5, 3.5)  # max acceleration [m/s^2]
    decel_mps2: Dist = Dist(4.5, 0.6, 3.0, 6.5)  # comfortable max deceleration [m/s^2]
    mass_kg: Dist = Dist(1400.0, 250.0, 900.0, 2500.0)  # [kg] (SUMO uses it for energy/emissions)
    friction: Dist = Dist(0.9, 0.08, 0.6, 1.0)  # tyre-road friction coefficient mu [-]
    speed_factor: Dist = Dist(1.0, 0.1, 0.8, 1.2)  # multiplier on the speed limit [-]
    sigma: float = 0.5  # Krauss driver imperfection [0..1]
    min_gap_m: float = 2.5  # standstill gap [m]
    n_vtypes: int = 20  # types in the distribution (per-vehicle variety)
    # drivers avoid congestion: every reroute_period_s an SCV re-plans its way to its destination on the
    # travel times SUMO currently measures (SUMO's rerouting device, SCVs only, never the ego). Without it
    # every car keeps its free-flow A* route into the same bottlenecks (a light, a stop junction fed by two
    # queues) until SUMO teleports it: Krems 53 teleports in 600 s without, 23 with. 0 = off.
    reroute_period_s: float = 30.0  # [s]

    def __post_init__(self):
        if self.time_gap_s <= 0:
            raise ValueError("time_gap_s must be > 0")
        if self.red_light_stop_gap_m < 0 or self.stop_sign_clear_distance_m < 0:
            raise ValueError("distances must be >= 0")
        if not 0 < self.give_way_approach_speed_kmh <= 50:
            raise ValueError("give_way_approach_speed_kmh must be in (0, 50]")
        if not 0 <= self.jammed_foe_ignore_prob <= 1 or self.jammed_foe_speed_mps < 0:
            raise ValueError("jammed_foe_ignore_prob must be in [0, 1] and jammed_foe_speed_mps >= 0")
        if not 0 <= self.sigma <= 1:
            raise ValueError("sigma must be in [0, 1]")
        if self.n_vtypes < 1:
            raise ValueError("n_vtypes must be >= 1")
        if self.reroute_period_s < 0:
            raise ValueError("reroute_period_s must be >= 0 (0 = off)")

    @property
    def minor_time_gap_s(self) -> float:
        return min(
            self.stop_sign_clear_distance_m / self.reference_major_speed_mps, self.max_minor_time_gap_s
        )

    def vtype_distribution_xml(self, rng: np.random.Generator, dist_id: str = "scv") -> str:
        n = self.n_vtypes
        accel = self.accel_mps2.sample(rng, n)
        mu = self.friction.sample(rng, n)
        decel = np.minimum(self.decel_mps2.sample(rng, n), mu * G)  # cannot brake harder than the tyres allow
        mass = self.mass_kg.sample(rng, n)
        speed_factor = self.speed_factor.sample(rng, n)
        reroute = (
            f'<param key="has.rerouting.device" value="true"/>'
            f'<param key="device.rerouting.period" value="{self.reroute_period_s:g}"/>'
            if self.reroute_period_s > 0
            else ""
        )
        lines = [f'    <vTypeDistribution id="{dist_id}">']
        for i in range(n):
            lines.append(
                f'        <vType id="{dist_id}_{i}" vClass="passenger" probability="1" carFollowModel="Krauss" '
                f'tau="{self.time_gap_s:.3f}" sigma="{self.sigma:.3f}" minGap="{self.min_gap_m:.2f}" '
                f'accel="{accel[i]:.3f}" decel="{decel[i]:.3f}" emergencyDecel="{max(decel[i], mu[i] * G):.3f}" '
                f'mass="{mass[i]:.1f}" speedFactor="{speed_factor[i]:.3f}" '
                f'jmTimegapMinor="{self.minor_time_gap_s:.2f}" jmStoplineGap="{self.red_light_stop_gap_m:.2f}" '
                f'jmStoplineGapMinor="{self.stop_sign_stop_gap_m:.2f}" '
                f'jmStopSignWait="{self.stop_sign_wait_s:.2f}" jmIgnoreFoeSpeed="{self.jammed_foe_speed_mps:.2f}" '
                f'jmIgnoreFoeProb="{self.jammed_foe_ignore_prob:.3f}">'
                f'<param key="friction" value="{mu[i]:.3f}"/>{reroute}</vType>'
            )
        lines.append("    </vTypeDistribution>")
        return "\n".join(lines)

"""Driver profiles: the parameters that make one scripted driver differ from another.

The paper's experiment (Sec. VII.C) had 3 daily commuters and 1 occasional driver. The presets below give
those two plus a cautious and an aggressive driver for sensitivity runs.

Values and where they come from (commuter / occasional / cautious / aggressive):

=============================  ======  =====  =====  =====  =============================================
parameter                      comm.   occ.   caut.  aggr.  source / reasoning
=============================  ======  =====  =====  =====  =============================================
reaction_time_s                0.9     1.3    1.1    0.8    Green 2000 (perception-brake time: expected
                                                            0.7-0.75 s, unexpected ~1.25 s, surprise
                                                            ~1.5 s); HDM (Treiber et al. 2006) 0.6-1.2 s.
                                                            Practice shortens it -> commuter < occasional.
desired_time_gap_s             1.2     1.6    1.8    0.9    IDM T: 1.0 s city, 1.5-1.6 s highway (Treiber &
                                                            Kesting 2013, Tab. 11.2; Treiber et al. 2000);
                                                            observed preferred headways 1-2 s (Ayres et al.
                                                            2001; Taieb-Maimon & Shinar 2001, ~1 s).
min_gap_m (s0)                 2.0     2.5    3.0    1.5    IDM s0 = 2 m (Treiber et al. 2000).
max_accel_mps2 (a)             1.5     1.0    1.0    2.0    IDM a = 1.0 m/s^2 city (Treiber & Kesting 2013);
                                                            0.73-2 m/s^2 in calibrations.
comfort_decel_mps2 (b)         2.0     1.5    1.5    2.5    IDM b = 1.5-2 m/s^2.
accel_exponent (delta)         4       4      4      4      IDM standard.
desired_speed_factor           1.05    0.95   0.92   1.12   free-flow speeds ~5-10 % above urban limits for
                                                            habitual drivers; novices/cautious below.
speed_wander_frac              0.03    0.05   0.02   0.04   slow drift of the chosen speed (assumption).
gap_error_rel (V_s)            0.08    0.12   0.08   0.10   HDM relative distance-estimation error ~0.1.
inv_ttc_error_ps (r_c)         0.01    0.015  0.01   0.012  HDM inverse-TTC estimation error 0.01 1/s.
perception_error_time_s        20      20     20     20     HDM correlation time of estimation errors 20 s.
lateral_wander_std_m           0.12    0.20   0.10   0.15   SDLP of attentive drivers ~0.18-0.25 m
                                                            (Verster & Roth 2011) incl. tracking error.
lateral_wander_time_s          5       4      6      4      slow lane-keeping drift (assumption).
preview_time_s                 1.0     1.1    1.2    0.9    far-point preview ~1 s (Donges 1978; Land &
                                                            Horwood 1995); pure pursuit look-ahead.
steer_lag_s                    0.15    0.2    0.15   0.12   neuromuscular lag 0.1-0.2 s (McRuer 1977).
pedal_rate_per_s               5       4      4      6      full pedal in 0.15-0.25 s (movement time,
                                                            Green 2000).
max_lat_accel_mps2             2.5     2.0    1.8    3.5    comfortable curve driving 2-3 m/s^2, rarely
                                                            above ~4 (Reymond et al. 2001).
yellow_max_decel_mps2          3.0     3.5    4.0    2.5    ITE yellow-interval deceleration 3.0 m/s^2.
stop_line_margin_m             0.5     0.7    0.8    0.3    bumper-to-line at a stop (assumption).
stop_dwell_s                   1.0     1.5    2.0    0.5    paper: SCVs pause >= 2 frames; humans ~1-2 s.
give_way_speed_mps             2.5     1.5    1.4    3.5    paper: SCVs slow to 5 km/h (1.4 m/s).
critical_gap_factor            1.0     1.15   1.2    0.85   x the critical / follow-up headways of HCM 2010
                                                            (cosim.driver.gap_acceptance); individual
                                                            critical gaps spread by ~+-1 s around the mean
                                                            (Brilon, Koenig, Troutbeck 1999) (assumption).
time_to_impatience_s           60      90     120    40     waiting time after which the critical gap has
                                                            shrunk to its floor (SUMO's impatience idea:
                                                            --time-to-impatience; waits < a light cycle).
a_brake_prob                   0.8     1.0    0.9    0.6    system A response (assumption, chosen to give
a_brake_decel_mps2             3.0     4.0    3.0    2.5    the paper's "sudden braking then increased
a_brake_duration_s             1.0     1.3    1.0    0.8    distance", Sec. VII.C).
a_gap_increase_s               0.6     0.9    0.8    0.4
a_gap_max_s                    1.5     2.0    2.0    1.0
a_gap_decay_s                  40      30     60     20
a_refractory_s                 6       6      6      6
b_target_gap_s                 2.0     2.0    2.0    2.0    the paper's "recommended two seconds".
b_compliance                   0.8     0.9    1.0    0.5    share of the way to 2 s a driver accepts (ass.).
b_adapt_time_s                 15      25     15     20     system B: gradual adjustment (paper Sec. VII.C:
b_warning_gain                 2.5     2.0    3.0    2.0    "adjusted their driving regularly"); warning >
b_none_gain                    0.3     0.3    0.3    0.3    advisory > plain display (assumption).
b_forget_time_s                60      60     90     30
=============================  ======  =====  =====  =====  =============================================

The perception model is the Human Driver Model (HDM): Treiber, Kesting, Helbing, "Delays, inaccuracies and
anticipation in microscopic traffic models", Physica A 360 (2006). Rows marked "assumption" are not measured
values: they are picked to reproduce the qualitative behaviour the paper reports and are parameters so a
study can vary them.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass


@dataclass(frozen=True)
class DriverProfile:
    """All parameters of a scripted driver (see the module docstring for values and sources)."""

    # -- reaction and perception (HDM) -------------------------------------------------------------------
    reaction_time_s: float = 1.0  # [s] delay between a change in the world and the driver acting on it
    gap_error_rel: float = 0.1  # [-] V_s: gap estimate = gap * exp(V_s * w), w a unit Wiener-like process
    inv_ttc_error_ps: float = 0.01  # [1/s] r_c: relative-speed estimate error = gap * r_c * w
    perception_error_time_s: float = 20.0  # [s] correlation time of the estimation errors
    # -- longitudinal (IDM) -------------------------------------------------------------------------------
    desired_time_gap_s: float = 1.4  # [s] IDM T
    min_gap_m: float = 2.0  # [m] IDM s0: bumper-to-bumper gap at standstill
    max_accel_mps2: float = 1.5  # [m/s^2] IDM a
    comfort_decel_mps2: float = 2.0  # [m/s^2] IDM b; also the planned deceleration for lines and limits
    accel_exponent: float = 4.0  # [-] IDM delta
    desired_speed_factor: float = 1.0  # [-] desired speed = factor * speed limit
    speed_wander_frac: float = 0.03  # [-] std of the slow relative drift of the desired speed
    speed_wander_time_s: float = 20.0  # [s] correlation time of that drift
    max_lat_accel_mps2: float = 2.5  # [m/s^2] curve speed = sqrt(a_lat / curvature)
    pedal_rate_per_s: float = 5.0  # [1/s] fastest pedal travel change (full travel in 1/rate s)
    # -- lateral (pure pursuit) ---------------------------------------------------------------------------
    preview_time_s: float = 1.0  # [s] look-ahead distance = max(min_lookahead_m, preview * speed)
    min_lookahead_m: float = 4.0  # [m]
    steer_lag_s: float = 0.15  # [s] first-order lag between the wanted and the applied steering
    lateral_wander_std_m: float = 0.15  # [m] std of the slowly wandering lateral target offset
    lateral_wander_time_s: float = 5.0  # [s] its correlation time
    # -- rules ----------------------------------------------------------------------------------------------
    yellow_max_decel_mps2: float = 3.0  # [m/s^2] on yellow: stop if the needed deceleration is below this
    stop_line_margin_m: float = 0.5  # [m] front bumper to line when stopped
    stop_dwell_s: float = 1.0  # [s] time at a full stop at a stop sign before looking to go
    give_way_speed_mps: float = 2.5  # [m/s] speed at a give-way line when the junction is clear
    critical_gap_factor: float = 1.0  # [-] multiplies the literature critical / follow-up headways
    time_to_impatience_s: float = 60.0  # [s] waiting until the accepted gap has shrunk to its floor
    # -- system A (rear display on the leader): sudden warning -----------------------------------------------
    a_brake_prob: float = 0.8  # [-] probability that a display onset triggers a braking response
    a_brake_decel_mps2: float = 3.0  # [m/s^2] deceleration of that response
    a_brake_duration_s: float = 1.0  # [s] its duration
    a_gap_increase_s: float = 0.6  # [s] desired time gap added per responded onset
    a_gap_max_s: float = 1.5  # [s] cap of the added gap
    a_gap_decay_s: float = 40.0  # [s] time constant of its decay once the display is dark
    a_refractory_s: float = 6.0  # [s] onsets closer than this to the last responded one are ignored
    # -- system B (in-car time-gap display): continuous -------------------------------------------------------
    b_target_gap_s: float = 2.0  # [s] the gap the display recommends
    b_compliance: float = 0.8  # [-] goal = own gap + compliance * (target - own gap)
    b_adapt_time_s: float = 15.0  # [s] adaptation time constant at the 'advisory' level
    b_warning_gain: float = 2.5  # [-] adaptation speed-up at the 'warning' level
    b_none_gain: float = 0.3  # [-] adaptation speed at level 'none' (display shows a gap, no warning)
    b_forget_time_s: float = 60.0  # [s] drift back to the own gap when the display shows no data

    def __post_init__(self) -> None:
        positive = (
            "reaction_time_s perception_error_time_s desired_time_gap_s max_accel_mps2 comfort_decel_mps2 "
            "accel_exponent desired_speed_factor speed_wander_time_s max_lat_accel_mps2 pedal_rate_per_s "
            "preview_time_s min_lookahead_m lateral_wander_time_s yellow_max_decel_mps2 give_way_speed_mps "
            "critical_gap_factor time_to_impatience_s "
            "a_brake_duration_s a_gap_decay_s b_target_gap_s b_adapt_time_s b_forget_time_s"
        ).split()
        non_negative = (
            "gap_error_rel inv_ttc_error_ps min_gap_m speed_wander_frac steer_lag_s lateral_wander_std_m "
            "stop_line_margin_m stop_dwell_s a_brake_decel_mps2 a_gap_increase_s a_gap_max_s a_refractory_s "
            "b_warning_gain b_none_gain"
        ).split()
        for name in positive:
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"DriverProfile.{name} must be a finite number > 0, got {v!r}")
        for name in non_negative:
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"DriverProfile.{name} must be a finite number >= 0, got {v!r}")
        for name in ("a_brake_prob", "b_compliance"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and 0.0 <= v <= 1.0):
                raise ValueError(f"DriverProfile.{name} must be within [0, 1], got {v!r}")
        if self.reaction_time_s > 5.0:
            raise ValueError(
                f"DriverProfile.reaction_time_s={self.reaction_time_s} s is not a human (max 5 s)"
            )
        if self.speed_wander_frac >= 0.3:
            raise ValueError("DriverProfile.speed_wander_frac must be < 0.3")
        if self.a_gap_max_s < self.a_gap_increase_s:
            raise ValueError("DriverProfile.a_gap_max_s must be >= a_gap_increase_s")

    def without_noise(self) -> DriverProfile:
        """The same driver with every random element switched off (for tests and deterministic baselines)."""
        return dataclasses.replace(
            self, gap_error_rel=0.0, inv_ttc_error_ps=0.0, speed_wander_frac=0.0, lateral_wander_std_m=0.0
        )


PROFILES: dict[str, DriverProfile] = {
    "daily_commuter": DriverProfile(
        reaction_time_s=0.9,
        desired_time_gap_s=1.2,
        min_gap_m=2.0,
        max_accel_mps2=1.5,
        comfort_decel_mps2=2.0,
        desired_speed_factor=1.05,
        speed_wander_frac=0.03,
        gap_error_rel=0.08,
        inv_ttc_error_ps=0.01,
        lateral_wander_std_m=0.12,
        lateral_wander_time_s=5.0,
        preview_time_s=1.0,
        steer_lag_s=0.15,
        pedal_rate_per_s=5.0,
        max_lat_accel_mps2=2.5,
        yellow_max_decel_mps2=3.0,
        stop_line_margin_m=0.5,
        stop_dwell_s=1.0,
        give_way_speed_mps=2.5,
        critical_gap_factor=1.0,
        time_to_impatience_s=60.0,
        a_brake_prob=0.8,
        a_brake_decel_mps2=3.0,
        a_brake_duration_s=1.0,
        a_gap_increase_s=0.6,
        a_gap_max_s=1.5,
        a_gap_decay_s=40.0,
        b_compliance=0.8,
        b_adapt_time_s=15.0,
        b_warning_gain=2.5,
    ),
    "occasional_driver": DriverProfile(
        reaction_time_s=1.3,
        desired_time_gap_s=1.6,
        min_gap_m=2.5,
        max_accel_mps2=1.0,
        comfort_decel_mps2=1.5,
        desired_speed_factor=0.95,
        speed_wander_frac=0.05,
        gap_error_rel=0.12,
        inv_ttc_error_ps=0.015,
        lateral_wander_std_m=0.20,
        lateral_wander_time_s=4.0,
        preview_time_s=1.1,
        steer_lag_s=0.2,
        pedal_rate_per_s=4.0,
        max_lat_accel_mps2=2.0,
        yellow_max_decel_mps2=3.5,
        stop_line_margin_m=0.7,
        stop_dwell_s=1.5,
        give_way_speed_mps=1.5,
        critical_gap_factor=1.15,
        time_to_impatience_s=90.0,
        a_brake_prob=1.0,
        a_brake_decel_mps2=4.0,
        a_brake_duration_s=1.3,
        a_gap_increase_s=0.9,
        a_gap_max_s=2.0,
        a_gap_decay_s=30.0,
        b_compliance=0.9,
        b_adapt_time_s=25.0,
        b_warning_gain=2.0,
    ),
    "cautious": DriverProfile(
        reaction_time_s=1.1,
        desired_time_gap_s=1.8,
        min_gap_m=3.0,
        max_accel_mps2=1.0,
        comfort_decel_mps2=1.5,
        desired_speed_factor=0.92,
        speed_wander_frac=0.02,
        gap_error_rel=0.08,
        inv_ttc_error_ps=0.01,
        lateral_wander_std_m=0.10,
        lateral_wander_time_s=6.0,
        preview_time_s=1.2,
        steer_lag_s=0.15,
        pedal_rate_per_s=4.0,
        max_lat_accel_mps2=1.8,
        yellow_max_decel_mps2=4.0,
        stop_line_margin_m=0.8,
        stop_dwell_s=2.0,
        give_way_speed_mps=1.4,
        critical_gap_factor=1.2,
        time_to_impatience_s=120.0,
        a_brake_prob=0.9,
        a_brake_decel_mps2=3.0,
        a_brake_duration_s=1.0,
        a_gap_increase_s=0.8,
        a_gap_max_s=2.0,
        a_gap_decay_s=60.0,
        b_compliance=1.0,
        b_adapt_time_s=15.0,
        b_warning_gain=3.0,
        b_forget_time_s=90.0,
    ),
    "aggressive": DriverProfile(
        reaction_time_s=0.8,
        desired_time_gap_s=0.9,
        min_gap_m=1.5,
        max_accel_mps2=2.0,
        comfort_decel_mps2=2.5,
        desired_speed_factor=1.12,
        speed_wander_frac=0.04,
        gap_error_rel=0.10,
        inv_ttc_error_ps=0.012,
        lateral_wander_std_m=0.15,
        lateral_wander_time_s=4.0,
        preview_time_s=0.9,
        steer_lag_s=0.12,
        pedal_rate_per_s=6.0,
        max_lat_accel_mps2=3.5,
        yellow_max_decel_mps2=2.5,
        stop_line_margin_m=0.3,
        stop_dwell_s=0.5,
        give_way_speed_mps=3.5,
        critical_gap_factor=0.85,
        time_to_impatience_s=40.0,
        a_brake_prob=0.6,
        a_brake_decel_mps2=2.5,
        a_brake_duration_s=0.8,
        a_gap_increase_s=0.4,
        a_gap_max_s=1.0,
        a_gap_decay_s=20.0,
        b_compliance=0.5,
        b_adapt_time_s=20.0,
        b_warning_gain=2.0,
        b_forget_time_s=30.0,
    ),
}


def profile_by_name(name: str) -> DriverProfile:
    """The named preset; ValueError listing the known names otherwise."""
    try:
        return PROFILES[name]
    except KeyError:
        raise ValueError(
            f"unknown driver profile {name!r}; known profiles: {', '.join(sorted(PROFILES))}"
        ) from None

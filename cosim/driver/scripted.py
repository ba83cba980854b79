"""A scripted human-like driver: pure pursuit + HDM/IDM car following, traffic rules, and display responses.

One step, in order:

1. Perceive: leader gap and speed (and those of the vehicle beyond it) get HDM estimation errors (Treiber,
   Kesting, Helbing 2006): the gap is multiplied by exp(V_s * w_s) and the relative speed is off by
   gap * r_c * w_l, where w_s, w_l are unit Ornstein-Uhlenbeck processes (the HDM's "Wiener process" errors
   with correlation time tau).
2. Delay: the noisy percept goes into a buffer; the driver acts on the one from ``reaction_time_s`` ago.
   Own speed is felt immediately. Distances in the delayed percept are advanced by dead reckoning (own
   odometer since then; the leader assumed to keep its perceived acceleration - brake lights, looming), the
   HDM's "temporal anticipation": without it IDM with a ~1 s delay is string-unstable and runs into a
   leader that brakes hard.
3. Decide a wanted acceleration: the minimum of the (improved) IDM (free road + leader), stop lines (red / committed yellow
   lights, stop signs until stopped and clear, give-way lines while a vehicle approaches, route end), and
   speed caps reached with the comfortable deceleration (next lower speed limit, give-way approach speed,
   curve speed sqrt(a_lat / curvature)). Then the display responses (see below).
4. Pedals: feed-forward of the wanted acceleration through a simple car model (drive-force and brake limits,
   rolling and air resistance) plus a PI loop on speed, rate-limited pedals, one foot.
5. Steering: pure pursuit (Coulter 1992) from the rear axle to a look-ahead point ``preview_time_s`` ahead on
   the path, shifted sideways by a slowly wandering offset (OU process), through a first-order lag.

Assistance-display hook (the paper's Sec. VII.C: A -> "suddenly braking and increasing the distance",
B -> "adjusted their driving regularly according to the time-gap displayed"). Both read the DELAYED percept,
so every response starts one reaction time after the display changes:

- System A (``Percept.sys_a_lit``): each onset of the rear display (dark -> lit), unless within
  ``a_refractory_s`` of the last responded onset, triggers with probability ``a_brake_prob`` a braking pulse
  of ``a_brake_decel_mps2`` for ``a_brake_duration_s`` and adds ``a_gap_increase_s`` to the desired time gap
  (capped at ``a_gap_max_s``). The addition is held while the display stays lit and decays with
  ``a_gap_decay_s`` once it is dark.
- System B (``Percept.sys_b_gap_s``, ``sys_b_level``): while the display shows a gap, the driver integrates
  the difference between a goal gap (own gap + ``b_compliance`` * (``b_target_gap_s`` - own gap)) and the
  DISPLAYED gap into an addition to the desired time gap, with rate 1 / ``b_adapt_time_s`` at 'advisory',
  times ``b_warning_gain`` at 'warning' and ``b_none_gain`` at 'none'. A displayed gap above the goal only
  gives the addition back (at the 'none' rate, never below zero): the display never makes anyone tailgate.
  Because the driver reacts to the displayed value, display errors and "no data" (None: the addition fades
  with ``b_forget_time_s``) shape behaviour.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from cosim.driver.base import Controls, Driver, Percept
from cosim.driver.gap_acceptance import critical_gap_s, follow_up_s
from cosim.driver.profiles import DriverProfile

_G = 9.81  # [m/s^2]
_CAP_GAIN_PER_S = 1.0  # [1/s] speed-tracking gain of the speed-cap / stop-line law
_CURVE_STEP_M = 2.0  # [m] resampling step of the path for the curve-speed look-ahead
_CURVE_WINDOW_M = 8.0  # [m] arc length over which curvature is measured (robust to short polyline segments)
_NEAR_LINE_M = 1.5  # [m] a stop counts as "at the line" when the bumper is this close to the stop point
_GIVE_WAY_COMMIT_M = 2.0  # [m] this close to a clear give-way line the driver commits to going
_STOPPED_MPS = 0.1  # [m/s] "full stop" at a stop sign
_CREEP_MPS = 1.0  # [m/s] slower than this near a yield line counts as waiting there
_WAIT_ZONE_M = 15.0  # [m] ... within this distance of the line (a queue in front of it included)
# [s] standing this long after deciding to go at a yield line, the driver judges the gap again
_GO_HELD_S = 1.0
_FOLLOW_THROUGH_M = 12.0  # [m] a leader whose rear is at most this far past the line has just entered
_CROSSING_MARGIN_M = 1.0  # [m] the driver stops this short of a crossing car's way
_LEADER_ACCEL_SMOOTH_S = 0.3  # [s] smoothing of the perceived leader acceleration
_MIN_TIME_GAP_S = 0.3  # [s] the desired time gap never drops below this
_B_MAX_ADD_S = 3.0  # [s]
_LEVEL_CODES = {"none": 0, "advisory": 1, "warning": 2}


@dataclass(frozen=True)
class PedalModel:
    """The car as the driver's pedal feed-forward assumes it (the real physics are cosim.ego_mujoco's)."""

    mass_kg: float = 1400.0
    max_brake_decel_mps2: float = 0.9 * _G  # [m/s^2] deceleration at brake = 1
    max_drive_accel_mps2: float = 3.0  # [m/s^2] at throttle = 1 and low speed
    max_power_w: float = 80_000.0  # [W] limits the drive acceleration at speed: P / (m v)
    rolling_resistance: float = 0.012  # [-] coefficient c_rr
    drag_area_m2: float = 0.65  # [m^2] c_d * A
    air_density_kgpm3: float = 1.2

    def __post_init__(self) -> None:
        for name in (
            "mass_kg",
            "max_brake_decel_mps2",
            "max_drive_accel_mps2",
            "max_power_w",
            "air_density_kgpm3",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"PedalModel.{name} must be a finite number > 0, got {v!r}")
        for name in ("rolling_resistance", "drag_area_m2"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"PedalModel.{name} must be a finite number >= 0, got {v!r}")

    def drive_accel_max(self, speed_mps: float) -> float:
        """[m/s^2] acceleration at full throttle (traction-limited at low speed, power-limited above)."""
        return min(self.max_drive_accel_mps2, self.max_power_w / (self.mass_kg * max(speed_mps, 1.0)))

    def resistance_decel(self, speed_mps: float) -> float:
        """[m/s^2] deceleration from rolling and air resistance while moving."""
        if speed_mps <= 0.0:
            return 0.0
        drag = 0.5 * self.air_density_kgpm3 * self.drag_area_m2 * speed_mps * speed_mps / self.mass_kg
        return self.rolling_resistance * _G + drag


@dataclass(frozen=True)
class ControllerParams:
    """Low-level speed loop that turns the wanted acceleration into pedal positions."""

    speed_kp_per_s: float = 1.0  # [1/s] P gain on (reference speed - speed)
    speed_ki_per_s2: float = 0.3  # [1/s^2] I gain
    integral_limit_mps2: float = 1.5  # [m/s^2] |I term| cap (anti-windup)
    ref_band_mps: float = 1.0  # [m/s] the reference speed stays this close to the real speed (anti-windup)
    standstill_mps: float = 0.05  # [m/s] below this with no wish to move, hold the car on the brake
    hold_brake: float = 0.4  # [0, 1] brake pedal at standstill

    def __post_init__(self) -> None:
        for name in (
            "speed_kp_per_s",
            "speed_ki_per_s2",
            "integral_limit_mps2",
            "ref_band_mps",
            "standstill_mps",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"ControllerParams.{name} must be a finite number >= 0, got {v!r}")
        if not 0.0 <= self.hold_brake <= 1.0:
            raise ValueError(f"ControllerParams.hold_brake must be within [0, 1], got {self.hold_brake!r}")


@dataclass(frozen=True)
class DriverDebug:
    """What the scripted driver was thinking at the last step (for logs and tests)."""

    t_s: float  # [s]
    mode: str  # which rule set the wanted acceleration: free, leader, limit, curve, tls, stop, give_way,
    #            route_end, a_brake
    accel_wanted_mps2: float  # [m/s^2] before the pedal controller
    desired_speed_mps: float  # [m/s] IDM v0 (speed limit * factor * wander)
    desired_time_gap_s: float  # [s] IDM T actually used (profile + A + B additions)
    a_gap_add_s: float  # [s] time gap added by system A responses
    b_gap_add_s: float  # [s] time gap added (or removed) by system B adaptation
    a_braking: bool  # a system-A braking pulse is active
    gap_est_m: float  # [m] the (noisy, delayed, dead-reckoned) gap estimate; nan without leader
    leader_speed_est_mps: float  # [m/s] the leader speed estimate; nan without leader
    tls_decision: str  # '' | 'stop' | 'go' for the next light
    sign_phase: str  # '' | 'approach' | 'wait' | 'go' for the next sign
    yielding: bool  # waiting for a gap in the priority traffic at that sign (or for a blocked junction)
    lateral_target_m: float  # [m] current wandering lateral target offset, left positive
    lookahead_m: float  # [m] pure-pursuit look-ahead distance


class _Seen:
    """One noisy percept of the outside world, kept in the reaction-delay buffer."""

    __slots__ = (
        "t", "odo", "leader", "leader_id", "gap", "vl", "al", "gap2", "vl2", "limit", "next_limit", "next_limit_d", "tls", "tls_d", "tls_id",
        "sign", "sign_d", "sign_id", "conflict", "jgap", "movement", "route_end_d", "cross_d", "merge_d", "a_lit", "b_gap",
        "b_level",
    )  # fmt: skip


def _move_toward(value: float, target: float, up: float, down: float) -> float:
    if target > value:
        return min(target, value + up)
    return max(target, value - down)


def _cap_accel(v: float, v_cap: float, dist_m: float, decel: float) -> float:
    """[m/s^2] acceleration that brings speed ``v`` to at most ``v_cap`` when ``dist_m`` further on.

    Follows the braking curve v_a(d) = sqrt(v_cap^2 + 2 decel d) (feed-forward -decel v / v_a plus a P term);
    when already above the curve, exactly the constant deceleration that still makes it. Far from the cap the
    result is large and positive, so it only matters where it is the minimum.
    """
    if dist_m <= 0.0:
        return _CAP_GAIN_PER_S * (v_cap - v)
    v_a = math.sqrt(v_cap * v_cap + 2.0 * decel * dist_m)
    if v > v_a:
        return (v_cap * v_cap - v * v) / (2.0 * dist_m)
    return -decel * v / v_a + _CAP_GAIN_PER_S * (v_a - v)


def _stop_accel(v: float, dist_m: float, decel: float) -> float:
    """[m/s^2] acceleration to stop with the front bumper exactly ``dist_m`` further on."""
    if dist_m <= 0.0:  # at or past the stop point: stop now, firmly
        return -decel - _CAP_GAIN_PER_S * v
    return _cap_accel(v, 0.0, dist_m, decel)


class ScriptedDriver(Driver):
    """Human-like scripted driver (see the module docstring for the model and the display hook).

    profile: the driver's parameters. rng: the only source of randomness (perception errors, lane wander,
    speed drift, whether a system-A warning gets a braking response). max_steer_rad [rad]: the car's maximum
    road-wheel angle, which Controls.steer = 1 maps to. wheelbase_m [m]: for pure pursuit; the car centre is
    assumed midway between the axles. car, control: pedal feed-forward model and speed-loop gains.
    """

    def __init__(
        self,
        profile: DriverProfile,
        rng: np.random.Generator,
        max_steer_rad: float,
        wheelbase_m: float,
        *,
        car: PedalModel | None = None,
        control: ControllerParams | None = None,
    ) -> None:
        if not (math.isfinite(max_steer_rad) and 0.0 < max_steer_rad < math.pi / 2):
            raise ValueError(f"max_steer_rad must be within (0, pi/2), got {max_steer_rad!r}")
        if not (math.isfinite(wheelbase_m) and wheelbase_m > 0.0):
            raise ValueError(f"wheelbase_m must be > 0, got {wheelbase_m!r}")
        if not isinstance(rng, np.random.Generator):
            raise TypeError("rng must be a numpy.random.Generator")
        self.profile = profile
        self.max_steer_rad = float(max_steer_rad)
        self.wheelbase_m = float(wheelbase_m)
        self.car = car or PedalModel()
        self.control = control or ControllerParams()
        self._rng = rng
        self.reset()

    # ------------------------------------------------------------------------------------------------------
    def reset(self, rng: np.random.Generator | None = None) -> None:
        if rng is not None:
            self._rng = rng
        # Estimation errors start in their stationary distribution: [gap, rel. speed, desired speed, lateral].
        self._w = self._rng.standard_normal(4)
        self._ou_coefs: tuple = (None, [])  # ((dt, correlation times), [(rho, sqrt(1 - rho^2))] per process)
        self._buf: deque[_Seen] = deque()
        self._t_last: float | None = None
        self._v_last = 0.0
        self._odo_m = 0.0
        self._throttle = 0.0
        self._brake = 0.0
        self._steer = 0.0
        self._v_ref = 0.0
        self._integral = 0.0
        # system A / B state
        self._a_prev_lit = False
        self._a_last_onset_s = -math.inf
        self._a_pulse_until_s = -math.inf
        self._a_add_s = 0.0
        self._b_add_s = 0.0
        # rule latches
        self._tls_key: tuple | None = None
        self._tls_prev_d = math.inf
        self._tls_decision = ""
        self._sign_key: tuple | None = None
        self._sign_prev_d = math.inf
        self._sign_phase = ""
        self._sign_stopped_s = 0.0
        self._sign_waited_s = 0.0  # waiting at the current yield line: the driver grows impatient
        self._yielding = False  # the gap at the current yield line is too short (or the junction blocked)
        self._following_through = False  # taking the gap the leader entered, behind it (follow-up headway)
        self._go_held_s = 0.0  # standing since deciding to go at the current yield line [s]
        self.debug: DriverDebug | None = None

    # ------------------------------------------------------------------------------------------------------
    def act(self, percept: Percept, dt_s: float) -> Controls:
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise ValueError(f"dt_s must be > 0, got {dt_s!r}")
        p = percept
        prof = self.profile
        t = p.t_s
        v = max(p.speed_mps, 0.0)
        if self._t_last is None:
            self._v_ref = v  # start the speed loop where the car is
        else:
            if t < self._t_last - 1e-9:
                raise ValueError(f"percept time went back from {self._t_last} to {t} s; call reset() first")
            self._odo_m += 0.5 * (self._v_last + v) * (t - self._t_last)
        self._t_last, self._v_last = t, v
        self._advance_noise(dt_s)

        seen = self._perceive(p)
        self._buf.append(seen)
        d = self._delayed(t)
        travelled = self._odo_m - d.odo
        age = t - d.t

        self._update_system_a(d, t, dt_s)
        self._update_system_b(d, dt_s)
        time_gap = max(_MIN_TIME_GAP_S, prof.desired_time_gap_s + self._a_add_s + self._b_add_s)

        a_wanted, mode, v0, gap_est, vl_est = self._longitudinal(p, d, v, travelled, age, time_gap, dt_s)
        if t < self._a_pulse_until_s and -prof.a_brake_decel_mps2 < a_wanted:
            a_wanted, mode = -prof.a_brake_decel_mps2, "a_brake"
        a_wanted = min(max(a_wanted, -self.car.max_brake_decel_mps2), self.car.max_drive_accel_mps2)
        throttle, brake = self._pedals(a_wanted, v, dt_s)
        steer, lookahead = self._steering(p, v, dt_s)

        self.debug = DriverDebug(
            t_s=t,
            mode=mode,
            accel_wanted_mps2=a_wanted,
            desired_speed_mps=v0,
            desired_time_gap_s=time_gap,
            a_gap_add_s=self._a_add_s,
            b_gap_add_s=self._b_add_s,
            a_braking=t < self._a_pulse_until_s,
            gap_est_m=gap_est,
            leader_speed_est_mps=vl_est,
            tls_decision=self._tls_decision,
            sign_phase=self._sign_phase,
            yielding=self._yielding,
            lateral_target_m=float(self._w[3] * prof.lateral_wander_std_m),
            lookahead_m=lookahead,
        )
        return Controls.clipped(throttle, brake, steer)

    # -- perception ---------------------------------------------------------------------------------------
    def _advance_noise(self, dt_s: float) -> None:
        """Exact OU update of the four unit processes (stationary variance 1)."""
        prof = self.profile
        taus = (prof.perception_error_time_s, prof.perception_error_time_s, prof.speed_wander_time_s,
                prof.lateral_wander_time_s)  # fmt: skip
        if self._ou_coefs[0] != (dt_s, taus):  # the step is constant in a run: compute the factors once
            rhos = [math.exp(-dt_s / tau) for tau in taus]
            self._ou_coefs = ((dt_s, taus), [(rho, math.sqrt(1.0 - rho * rho)) for rho in rhos])
        eta = self._rng.standard_normal(4)
        for i, (rho, gain) in enumerate(self._ou_coefs[1]):
            self._w[i] = rho * self._w[i] + gain * eta[i]

    def _perceive(self, p: Percept) -> _Seen:
        prof = self.profile
        s = _Seen()
        s.t, s.odo = p.t_s, self._odo_m
        s.leader, s.leader_id = p.leader_present, p.leader_id
        s.gap, s.vl, s.al = math.inf, 0.0, 0.0
        if p.leader_present:
            gap = max(p.leader_gap_m, 0.0)
            s.gap = gap * math.exp(prof.gap_error_rel * self._w[0])
            s.vl = max(p.leader_speed_mps - gap * prof.inv_ttc_error_ps * self._w[1], 0.0)
            prev = self._buf[-1] if self._buf else None
            if prev is not None and prev.leader and prev.leader_id == p.leader_id and p.t_s > prev.t:
                # the leader's acceleration as seen (brake lights, looming), smoothed over ~0.3 s
                raw = (s.vl - prev.vl) / (p.t_s - prev.t)
                k = min((p.t_s - prev.t) / _LEADER_ACCEL_SMOOTH_S, 1.0)
                s.al = min(max(prev.al + k * (raw - prev.al), -10.0), 5.0)
        s.gap2, s.vl2 = math.inf, 0.0
        if p.leader_present and math.isfinite(p.next_leader_gap_m):  # seen with the same kind of error
            gap2 = max(p.next_leader_gap_m, 0.0)
            s.gap2 = gap2 * math.exp(prof.gap_error_rel * self._w[0])
            s.vl2 = max(p.next_leader_speed_mps - gap2 * prof.inv_ttc_error_ps * self._w[1], 0.0)
        s.limit, s.next_limit, s.next_limit_d = (
            p.speed_limit_mps,
            p.next_speed_limit_mps,
            p.next_speed_limit_dist_m,
        )
        s.tls, s.tls_d, s.tls_id = p.tls_state, p.tls_dist_m, p.tls_id
        s.sign, s.sign_d, s.sign_id = p.sign_kind, p.sign_dist_m, p.sign_id
        s.conflict, s.route_end_d, s.cross_d = p.junction_conflict, p.route_end_dist_m, p.crossing_dist_m
        s.merge_d = p.merge_dist_m
        s.jgap, s.movement = p.junction_gap_s, p.junction_movement
        s.a_lit, s.b_gap, s.b_level = p.sys_a_lit, p.sys_b_gap_s, p.sys_b_level
        return s

    def _delayed(self, t: float) -> _Seen:
        """The newest buffered percept that is at least one reaction time old (the oldest one at start)."""
        cutoff = t - self.profile.reaction_time_s + 1e-9
        buf = self._buf
        while len(buf) > 1 and buf[1].t <= cutoff:
            buf.popleft()
        return buf[0]

    # -- assistance displays ---------------------------------------------------------------------------------
    def _update_system_a(self, d: _Seen, t: float, dt_s: float) -> None:
        prof = self.profile
        if d.a_lit and not self._a_prev_lit and t - self._a_last_onset_s >= prof.a_refractory_s:
            if self._rng.random() < prof.a_brake_prob:
                self._a_last_onset_s = t
                self._a_pulse_until_s = t + prof.a_brake_duration_s
                self._a_add_s = min(self._a_add_s + prof.a_gap_increase_s, prof.a_gap_max_s)
        if not d.a_lit:
            self._a_add_s *= math.exp(-dt_s / prof.a_gap_decay_s)
        self._a_prev_lit = d.a_lit

    def _update_system_b(self, d: _Seen, dt_s: float) -> None:
        prof = self.profile
        if d.b_gap is None:
            self._b_add_s *= math.exp(-dt_s / prof.b_forget_time_s)
            return
        goal = prof.desired_time_gap_s + prof.b_compliance * (prof.b_target_gap_s - prof.desired_time_gap_s)
        err = goal - d.b_gap if math.isfinite(d.b_gap) else -goal  # an "infinite" gap: leader far away
        if err > 0.0:  # shown closer than the goal: open the gap, faster the stronger the display insists
            gain = (prof.b_none_gain, 1.0, prof.b_warning_gain)[_LEVEL_CODES[d.b_level]] / prof.b_adapt_time_s
            self._b_add_s = min(self._b_add_s + gain * err * dt_s, _B_MAX_ADD_S)
        else:  # shown farther than the goal: slowly give back the extra margin, never below the own habit
            self._b_add_s = max(self._b_add_s + prof.b_none_gain / prof.b_adapt_time_s * err * dt_s, 0.0)

    # -- longitudinal ---------------------------------------------------------------------------------------
    def _longitudinal(
        self, p: Percept, d: _Seen, v: float, travelled: float, age: float, time_gap: float, dt_s: float
    ) -> tuple[float, str, float, float, float]:
        prof = self.profile
        a_max, b = prof.max_accel_mps2, prof.comfort_decel_mps2
        speed_mult = prof.desired_speed_factor * (1.0 + prof.speed_wander_frac * self._w[2])
        v0 = max(d.limit * speed_mult, 0.5)
        delta = prof.accel_exponent
        # Improved IDM (Treiber & Kesting 2013, Sec. 11.3.5): unlike plain IDM its equilibrium gap is
        # s0 + v T even when the leader drives close to the desired speed - a driver told to follow a lead
        # car keeps its own gap instead of falling back.
        if v <= v0:
            free = a_max * (1.0 - (v / v0) ** delta)
        else:
            free = -b * (1.0 - (v0 / v) ** (a_max * delta / b))
        best, mode = free, "free"
        gap_est = vl_est = math.nan
        if d.leader:
            # dead reckoning: the leader kept its (estimated) acceleration, we know how far we went
            if d.al < 0.0 and d.vl + d.al * age <= 0.0:  # it has stopped meanwhile
                vl_est, leader_moved = 0.0, d.vl * d.vl / (-2.0 * d.al)
            else:
                vl_est, leader_moved = d.vl + d.al * age, (d.vl + 0.5 * d.al * age) * age
            gap_est = max(d.gap + leader_moved - travelled, 0.1)
            a_follow = self._follow_accel(v, v0, free, gap_est, vl_est, time_gap)
            if math.isfinite(d.gap2):
                # multi-anticipation (the HDM of Treiber, Kesting & Helbing 2006, Physica A 360: 71-88; here the
                # smaller of the two IDM responses, not its weighted sum): the car beyond the leader,
                # dead-reckoned at its seen speed. Seeing only the nearest, a driver whose leader (a car
                # overlapping the lane from the next one) pulled away found the lead standing 2.9 m ahead one
                # reaction time late and ran into it (Helsinki, experiment P4, 81 s)
                gap2 = max(d.gap2 + d.vl2 * age - travelled, 0.1)
                a_follow = min(a_follow, self._follow_accel(v, v0, free, gap2, d.vl2, time_gap))
            if a_follow < best:
                best, mode = a_follow, "leader"

        def consider(a: float, name: str) -> None:
            nonlocal best, mode
            if a < best:
                best, mode = a, name

        margin = prof.stop_line_margin_m
        if d.next_limit is not None and d.next_limit < d.limit:
            consider(_cap_accel(v, d.next_limit * speed_mult, d.next_limit_d - travelled, b), "limit")
        consider(self._curve_accel(p, v, v0, b), "curve")
        if math.isfinite(d.route_end_d):
            consider(_stop_accel(v, d.route_end_d - travelled - margin, b), "route_end")
        if math.isfinite(d.cross_d):  # a car crossing ahead: let it through, stopping short of its way
            consider(_stop_accel(v, d.cross_d - travelled - _CROSSING_MARGIN_M, b), "crossing")
        if math.isfinite(d.merge_d):  # no gap in the lane the route moves into: wait short of it
            consider(_stop_accel(v, d.merge_d - travelled - _CROSSING_MARGIN_M, b), "merge")
        tls_d = d.tls_d - travelled
        if self._traffic_light(d, v, tls_d) == "stop":
            consider(_stop_accel(v, tls_d - margin, b), "tls")
        sign_d = d.sign_d - travelled
        phase = self._sign(d, v, sign_d, age, dt_s)
        if d.sign == "stop" and phase in ("approach", "wait"):
            consider(_stop_accel(v, sign_d - margin, b), "stop")
        elif d.sign in ("give_way", "yield") and phase == "approach":
            if self._yielding:
                consider(_stop_accel(v, sign_d - margin, b), "give_way")
            elif d.sign == "give_way" and not self._following_through:
                # at give-way speed by the commit point, where the driver decides to go (following the
                # leader through, its pace)
                consider(
                    _cap_accel(v, prof.give_way_speed_mps, sign_d - margin - _GIVE_WAY_COMMIT_M, b),
                    "give_way",
                )
        return best, mode, v0, gap_est, vl_est

    def _follow_accel(self, v: float, v0: float, free: float, gap_m: float, v_leader: float,
                      time_gap: float) -> float:  # fmt: skip
        """The improved IDM's acceleration behind a leader ``gap_m`` ahead at ``v_leader`` (``free``: its
        free-road acceleration at desired speed ``v0``)."""
        prof = self.profile
        a_max, b = prof.max_accel_mps2, prof.comfort_decel_mps2
        s_star = prof.min_gap_m + max(0.0, v * time_gap + v * (v - v_leader) / (2.0 * math.sqrt(a_max * b)))
        z = s_star / gap_m
        if v > v0:
            return free + a_max * (1.0 - z * z) if z >= 1.0 else free
        if z >= 1.0:
            return a_max * (1.0 - z * z)
        return free * (1.0 - z ** (2.0 * a_max / free)) if free > 1e-9 else free

    def _traffic_light(self, d: _Seen, v: float, dist_m: float) -> str:
        """Latch a stop/go decision per light: red -> stop; yellow -> stop if comfortably possible."""
        if d.tls is None:
            self._tls_key, self._tls_prev_d, self._tls_decision = None, math.inf, ""
            return ""
        key = (d.tls_id,)
        if key != self._tls_key or dist_m > self._tls_prev_d + 5.0:  # another light
            self._tls_key, self._tls_decision = key, ""
        self._tls_prev_d = dist_m
        if d.tls == "g":
            self._tls_decision = ""
        elif self._tls_decision == "":
            stop_d = dist_m - self.profile.stop_line_margin_m
            needed = v * v / (2.0 * stop_d) if stop_d > 0.05 else math.inf
            limit = self.profile.yellow_max_decel_mps2 if d.tls == "y" else self.car.max_brake_decel_mps2
            self._tls_decision = "stop" if needed <= limit or v < _STOPPED_MPS else "go"
        return self._tls_decision

    def _sign(self, d: _Seen, v: float, dist_m: float, age: float, dt_s: float) -> str:
        """Stop sign: approach -> full stop for stop_dwell_s at the line -> wait for a gap -> go.
        Give-way (and a green without priority): approach (slow, stop while the gap is too short) -> go once
        committed near the line with an acceptable gap.

        The gap is the time until the first priority vehicle reaches the conflict, as perceived one reaction
        time ago and aged since; it is acceptable from the critical gap of the movement on, which shrinks
        while the driver waits (cosim.driver.gap_acceptance)."""
        if d.sign is None:
            self._sign_key, self._sign_prev_d, self._sign_phase = None, math.inf, ""
            self._yielding = self._following_through = False
            return ""
        prof = self.profile
        key = (d.sign, d.sign_id)
        if key != self._sign_key or dist_m > self._sign_prev_d + 5.0:  # another sign
            self._sign_key, self._sign_phase, self._sign_stopped_s = key, "approach", 0.0
            self._sign_waited_s = 0.0
            self._following_through = False
        self._sign_prev_d = dist_m
        to_stop = dist_m - prof.stop_line_margin_m
        if v < _CREEP_MPS and to_stop < _WAIT_ZONE_M and self._sign_phase != "go":
            self._sign_waited_s += dt_s
        needed = critical_gap_s(
            d.movement, self._sign_waited_s, prof.critical_gap_factor, prof.time_to_impatience_s
        )
        just_entered = d.leader and 0.0 < d.gap - d.sign_d < _FOLLOW_THROUGH_M and dist_m < _WAIT_ZONE_M
        if just_entered or self._following_through:
            # queued right behind a vehicle that has just entered the junction: the follow-up headway; once
            # taken, it holds while the driver moves up to the line, as long as the gap lasts (re-judged on
            # the leader's distance past the line, the gap lapsed while the driver moved up at give-way speed,
            # and it stopped at the line with a 5-s gap that the leader had entered: Monaco, -166149542#0)
            needed = min(needed, follow_up_s(d.movement, prof.critical_gap_factor))
        self._yielding = d.conflict or d.jgap - age < needed
        self._following_through = (just_entered or self._following_through) and not self._yielding
        held = self._sign_phase == "go" and v < _STOPPED_MPS
        self._go_held_s = self._go_held_s + dt_s if held else 0.0
        if self._go_held_s > _GO_HELD_S and self._yielding:
            # held short of the junction after deciding to go (by the car ahead), the driver looks again
            # before pulling off: committed while the lead stood just past the line, the participant pulled
            # off behind it 4 s later into a priority road's left turner that had started meanwhile (Krems
            # 268939011, make experiment)
            self._sign_phase = "wait" if d.sign == "stop" else "approach"
        if d.sign == "stop":
            if self._sign_phase == "approach":
                if v < _STOPPED_MPS and to_stop < _NEAR_LINE_M:
                    self._sign_stopped_s += dt_s
                    if self._sign_stopped_s >= prof.stop_dwell_s - 1e-9:
                        self._sign_phase = "wait"
                else:
                    self._sign_stopped_s = 0.0
            if self._sign_phase == "wait" and not self._yielding:
                self._sign_phase = "go"
        elif self._sign_phase == "approach" and not self._yielding and to_stop < _GIVE_WAY_COMMIT_M:
            self._sign_phase = "go"
        if self._sign_phase == "go":
            self._yielding = False
        return self._sign_phase

    def _curve_accel(self, p: Percept, v: float, v0: float, b: float) -> float:
        """Slow for curves ahead: cap sqrt(a_lat / |curvature|), measured over a few metres of arc."""
        path, g = p.path_xy_m, p.path_geometry
        seg = g.seg_xy_m
        if len(seg) < 2:
            return math.inf
        # cheap exit on (nearly) straight roads: even if all the path's turning were inside one window, the
        # curve speed would be well above anything the driver wants
        turn_all = np.arctan2(
            seg[:-1, 0] * seg[1:, 1] - seg[:-1, 1] * seg[1:, 0],
            seg[:-1, 0] * seg[1:, 0] + seg[:-1, 1] * seg[1:, 1],
        )
        total = float(np.abs(turn_all).sum())
        if (
            total < 1e-9
            or self.profile.max_lat_accel_mps2 * _CURVE_WINDOW_M / total > (1.5 * max(v, v0)) ** 2
        ):
            return math.inf
        s0 = p.path_progress_m
        n_win = int(round(_CURVE_WINDOW_M / _CURVE_STEP_M))  # samples per window
        start = max(s0 - _CURVE_WINDOW_M, 0.0)  # windows containing the car: the curve it is in
        horizon = min(g.cum_m[-1] - start, max(50.0, v * v / (2.0 * b) + 30.0))
        if horizon < _CURVE_WINDOW_M + 2 * _CURVE_STEP_M:
            return math.inf
        s = start + np.arange(0.0, horizon, _CURVE_STEP_M)  # resampled: robust to any vertex spacing
        x = np.interp(s, g.cum_m, path[:, 0])
        y = np.interp(s, g.cum_m, path[:, 1])
        dx, dy = x[1:] - x[:-1], y[1:] - y[:-1]
        turn = np.arctan2(dx[:-1] * dy[1:] - dy[:-1] * dx[1:], dx[:-1] * dx[1:] + dy[:-1] * dy[1:])  # [rad]
        c = np.empty(len(turn) + 1)  # turning from the first sample on
        c[0] = 0.0
        np.cumsum(turn, out=c[1:])
        # mean curvature of window k, which spans [s_k, s_k + window]
        kappa = np.abs(c[n_win:] - c[:-n_win]) / _CURVE_WINDOW_M  # [1/m]
        v_cap = np.sqrt(self.profile.max_lat_accel_mps2 / np.maximum(kappa, 1e-6))
        # windows that start at or behind the car: the curve it is in -> plain speed tracking; windows ahead:
        # their cap applies from the window's START (conservative: a curve is never entered too fast)
        dist = s[: len(v_cap)] - s0  # [m] from the car centre to each window's start
        # dist rises with the window index (s does), so the windows with dist <= 0.5 come first
        n_under = int(dist.searchsorted(0.5, side="right"))
        here = _CAP_GAIN_PER_S * (float(v_cap[:n_under].min()) - v) if n_under else math.inf
        v_cap, dist = v_cap[n_under:], dist[n_under:]
        v_a = np.sqrt(v_cap * v_cap + 2.0 * b * dist)
        a = np.where(
            v > v_a,
            (v_cap * v_cap - v * v) / (2.0 * dist),
            -b * v / v_a + _CAP_GAIN_PER_S * (v_a - v),
        )
        return min(float(a.min()), here) if len(a) else here

    # -- pedals ------------------------------------------------------------------------------------------------
    def _pedals(self, a_wanted: float, v: float, dt_s: float) -> tuple[float, float]:
        c, car = self.control, self.car
        if v < c.standstill_mps and a_wanted <= 0.0:
            want_t, want_b = 0.0, c.hold_brake
            self._v_ref, self._integral = 0.0, 0.0
        else:
            self._v_ref = min(max(self._v_ref, v - c.ref_band_mps), v + c.ref_band_mps)
            err = self._v_ref - v
            lim = c.integral_limit_mps2
            self._integral = min(max(self._integral + c.speed_ki_per_s2 * err * dt_s, -lim), lim)
            a_cmd = a_wanted + c.speed_kp_per_s * err + self._integral
            self._v_ref = max(self._v_ref + a_wanted * dt_s, 0.0)  # where the speed should be next step
            force = a_cmd + car.resistance_decel(v)  # [m/s^2] the wheels must deliver
            if force >= 0.0:
                want_t, want_b = force / car.drive_accel_max(v), 0.0
            else:
                want_t, want_b = 0.0, -force / car.max_brake_decel_mps2
        want_t, want_b = min(want_t, 1.0), min(want_b, 1.0)
        step = self.profile.pedal_rate_per_s * dt_s
        # one foot: a pedal is only pressed further once the other one is released (released twice as fast)
        self._throttle = _move_toward(self._throttle, want_t if self._brake == 0.0 else 0.0, step, 2 * step)
        self._brake = _move_toward(self._brake, want_b if self._throttle == 0.0 else 0.0, step, 2 * step)
        return self._throttle, self._brake

    # -- steering ----------------------------------------------------------------------------------------------
    def _steering(self, p: Percept, v: float, dt_s: float) -> tuple[float, float]:
        prof = self.profile
        path, g = p.path_xy_m, p.path_geometry
        seg, seg_len, cum = g.seg_xy_m, g.seg_len_m, g.cum_m
        half_l = 0.5 * self.wheelbase_m
        cos_y, sin_y = math.cos(p.yaw_rad), math.sin(p.yaw_rad)
        rear_x, rear_y = p.x_m - half_l * cos_y, p.y_m - half_l * sin_y
        lookahead = max(prof.min_lookahead_m, prof.preview_time_s * v)
        s_goal = (
            p.path_progress_m - half_l + lookahead
        )  # the centre's projection, moved back to the rear axle
        i = min(max(int(cum.searchsorted(s_goal, side="right")) - 1, 0), len(seg) - 1)
        length_i = float(seg_len[i])
        frac = (s_goal - cum[i]) / length_i  # may exceed 1 (or be < 0) beyond the path ends: extrapolate
        ux, uy = seg[i, 0] / length_i, seg[i, 1] / length_i
        offset = self._w[3] * prof.lateral_wander_std_m
        gx = path[i, 0] + frac * seg[i, 0] - uy * offset
        gy = path[i, 1] + frac * seg[i, 1] + ux * offset
        dx, dy = gx - rear_x, gy - rear_y
        ld = max(math.hypot(dx, dy), 1e-3)
        alpha = math.atan2(
            -sin_y * dx + cos_y * dy, cos_y * dx + sin_y * dy
        )  # goal direction in the car frame
        delta = math.atan2(2.0 * self.wheelbase_m * math.sin(alpha), ld)
        cmd = min(max(delta / self.max_steer_rad, -1.0), 1.0)
        k = 1.0 - math.exp(-dt_s / prof.steer_lag_s) if prof.steer_lag_s > 0 else 1.0
        self._steer += k * (cmd - self._steer)
        return self._steer, lookahead

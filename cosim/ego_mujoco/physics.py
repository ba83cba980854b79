"""EgoCar: the MuJoCo simulation of the user-controlled car (with car.py, the only code using mujoco).

One :meth:`EgoCar.step` integrates ``round(duration / timestep)`` MuJoCo steps. They run in chunks of one
control period (default 20 ms, an ECU rate: 10 ms gave the same braking and acceleration to 0.01 m and
0.01 s at 25 % more cost); before each chunk the wrapper updates, from the state at the
chunk start:

- steering: the bicycle angle moves toward ``steer * max_steer`` at most at the rate limit; the two
  knuckle servos get the Ackermann angles of that bicycle angle;
- powertrain (:mod:`cosim.ego_mujoco.powertrain`): drive torque on the driven wheel joints, engine
  inertia as joint armature, traction control capping each driven wheel at its friction limit;
- brakes: joint friction loss on every wheel = brake torque (ABS-capped at the tyre's friction limit)
  + rolling resistance (C_rr*Fz*r); friction loss is a constraint, so a braked car holds still without
  chatter. ABS and traction control regulate the tyre force: their caps are mu*Fz*lever plus the torque
  that spins the wheel (and the engaged driveline) along with the car's acceleration;
- aerodynamic drag on the chassis;
- tyre slip stiffness (see below).

Tyre model. Every wheel touches the road in one point with an elliptic friction cone (friction circle
mu*Fz); the normal force is a penalty spring-damper (see car.py). MuJoCo's soft friction constraint
settles, for a constant force f, at the slip velocity v = R f / b (R: the friction rows' regulariser,
R_normal / impratio; b: the reference-acceleration damping, per tyre pair through ``solreffriction``).
Setting, per wheel and control period,

    c = b / R = min(C / max(|v_wheel|, v_min), 1.5 mu Fz / |v_slip|)     [N s/m]

gives force = C * slip angle (and C * slip ratio) while the tyre grips, and the cone's mu*Fz once it
slides; the secant cap keeps a sliding tyre's demand near the cone so the normal force is not inflated.
``impratio`` keeps R_friction <= R_normal / 20 (decoupling the normal force from the friction demand)
and b <= 0.5 / timestep (stability). The constraint's own lag, 1 / (c R), corresponds to a relaxation
length of ~0.4 m at 30 m/s and less at lower speed. Measured: kinematic turning at low speed, an
understeer gradient from the front/rear stiffness difference, braking at mu*g (tests/integration/ego).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np

from cosim.ego_mujoco.car import (
    CHASSIS_BODY,
    FREE_JOINT,
    TYRE_IMPEDANCE,
    WHEELS,
    Obstacle,
    ackermann_angles,
    bicycle_angle,
    compile_model,
    layout,
)
from cosim.ego_mujoco.params import CarParams
from cosim.ego_mujoco.powertrain import PowertrainState, gear_for_speed, step_powertrain
from cosim.ego_mujoco.state import EgoState

MAX_TIMESTEP_S = 0.002  # >= 500 Hz: slower stepping misrepresents the wheel-spin and steering dynamics
TCS_MARGIN = 0.95  # traction control keeps each driven wheel's torque at 95 % of mu*Fz*r
SLIDE_DEMAND = 1.5  # a sliding tyre's linear force demand is capped at this multiple of mu*Fz
MIN_IMPRATIO = 20.0  # R_normal / R_friction: keeps sliding friction from inflating the normal force


class EgoCar:
    """The ego car in its own MuJoCo world (flat road plane, optional static obstacles).

    Pose convention: centre of the car footprint, yaw counter-clockwise from +x (cosim.frames converts
    to and from SUMO). Controls: throttle and brake in [0, 1], steer in [-1, 1] with +1 = full LEFT.
    ``model`` and ``data`` are exposed for rendering; do not step them directly.
    """

    def __init__(
        self,
        params: CarParams | None = None,
        timestep_s: float = 0.002,
        *,
        control_period_s: float = 0.02,
        obstacles: Sequence[Obstacle] = (),
    ) -> None:
        self.params = p = params if params is not None else CarParams()
        if not (0.0 < timestep_s <= MAX_TIMESTEP_S + 1e-12):
            raise ValueError(
                f"EgoCar timestep_s must be in (0, {MAX_TIMESTEP_S}] s (>= 500 Hz), got {timestep_s}"
            )
        k = round(control_period_s / timestep_s)
        if k < 1 or abs(k * timestep_s - control_period_s) > 1e-9:
            raise ValueError(
                f"EgoCar control_period_s {control_period_s} must be a positive multiple of "
                f"timestep_s {timestep_s}"
            )
        self.timestep_s = float(timestep_s)
        self._chunk = int(k)
        self.model = m = compile_model(p, timestep_s, obstacles)
        self.data = d = mujoco.MjData(m)
        self._layout = lay = layout(p)

        def jid(name: str) -> int:
            return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)

        def ids(kind: mujoco.mjtObj, names: Sequence[str]) -> list[int]:
            return [mujoco.mj_name2id(m, kind, n) for n in names]

        self._body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, CHASSIS_BODY)
        self._qadr = int(m.jnt_qposadr[jid(FREE_JOINT)])
        self._vadr = int(m.jnt_dofadr[jid(FREE_JOINT)])
        self._spin_dof = [int(m.jnt_dofadr[jid(f"spin_{w}")]) for w in WHEELS]
        self._steer_qpos = [int(m.jnt_qposadr[jid(f"steer_{w}")]) for w in ("fl", "fr")]
        self._pair = ids(mujoco.mjtObj.mjOBJ_PAIR, [f"tyre_{w}" for w in WHEELS])
        self._load_adr = [
            int(m.sensor_adr[i]) for i in ids(mujoco.mjtObj.mjOBJ_SENSOR, [f"load_{w}" for w in WHEELS])
        ]
        self._steer_act = ids(mujoco.mjtObj.mjOBJ_ACTUATOR, ["steer_fl", "steer_fr"])
        wheel_body = ids(mujoco.mjtObj.mjOBJ_BODY, [f"wheel_{w}" for w in WHEELS])

        # Views into MuJoCo's arrays, taken once (the hot path runs 100 times per simulated second).
        self._qpos, self._qvel, self._qacc = d.qpos, d.qvel, d.qacc
        self._xmat = d.xmat[self._body]  # (9,) chassis rotation, row-major
        self._sensordata, self._ctrl = d.sensordata, d.ctrl
        self._qfrc, self._xfrc = d.qfrc_applied, d.xfrc_applied[self._body]
        self._frictionloss, self._armature = m.dof_frictionloss, m.dof_armature
        self._opt = m.opt  # a new wrapper object on every ``m.opt`` access: take it once
        # per tyre pair: its (stiffness, damping) row of pair_solreffriction
        self._friction_rows = [m.pair_solreffriction[i] for i in self._pair]
        # Model fields the controller rewrites at run time; reset() restores them so that a reset car
        # replays bit-identically to a fresh one.
        self._pristine = (
            m.dof_armature.copy(),
            m.dof_frictionloss.copy(),
            m.pair_solreffriction.copy(),
            m.opt.impratio,
        )

        # Tyre constants. Normal-row regulariser of each wheel contact: R = (1-d)/d * invweight0, constant
        # because the tyre impedance is constant; friction rows get R / impratio.
        self._r_normal = [
            (1.0 - TYRE_IMPEDANCE) / TYRE_IMPEDANCE * float(m.body_invweight0[b, 0]) for b in wheel_body
        ]
        self._b_max = 0.5 / self.timestep_s  # [1/s] friction reference damping: h * b <= 0.5
        tyre = p.tyre
        self._stiffness = [tyre.cornering_stiffness_front_n_per_rad] * 2 + [
            tyre.cornering_stiffness_rear_n_per_rad
        ] * 2
        self._wheel_xy = [tuple(map(float, xy)) for xy in lay.wheel_xy_m]
        self._sphere_radius = [float(v) for v in lay.sphere_radius_m]

        pt = p.powertrain
        self._driven = {"front": [0, 1], "rear": [2, 3], "all": [0, 1, 2, 3]}[pt.driven_axle]
        self._is_driven = [i in self._driven for i in range(4)]
        # derived parameters the control update reads 500 times per simulated second
        self._max_steer_rad, self._max_steer_rate = p.max_steer_rad, p.max_steer_rate_rad_s
        br = p.brakes
        front, rear = 0.5 * br.front_share * br.max_torque_nm, 0.5 * (1.0 - br.front_share) * br.max_torque_nm
        self._brake_max = [front, front, rear, rear]
        self._drag_k = 0.5 * p.air_density_kg_m3 * p.drag_coefficient * p.frontal_area_m2  # [kg/m]
        # the per-wheel constants above, one tuple per wheel for the control update's loop
        self._wheels = list(
            zip(
                self._spin_dof,
                self._load_adr,
                self._is_driven,
                self._sphere_radius,
                self._wheel_xy,
                self._brake_max,
                self._stiffness,
                self._r_normal,
                self._friction_rows,
                strict=True,
            )
        )
        self._driven_dof = [self._spin_dof[i] for i in self._driven]
        # the same indices as arrays, for _read_state's fancy indexing (a list is converted on every use)
        self._spin_dof_idx, self._load_idx = np.array(self._spin_dof), np.array(self._load_adr)
        self._acc_xy = d.qacc[self._vadr : self._vadr + 2]  # view: the chassis's linear acceleration x, y
        self._state: EgoState | None = None  # state() of the current MuJoCo state, built on first request
        self.reset(0.0, 0.0, 0.0, 0.0)

    # -- public API ------------------------------------------------------------------------------------------
    def reset(self, x_m: float, y_m: float, yaw_rad: float, speed_mps: float = 0.0) -> None:
        """Place the car (footprint centre, MuJoCo frame) at rest height on the road, wheels straight,
        rolling forward at ``speed_mps`` (>= 0) in a gear that suits it; time restarts at 0."""
        for name, value in (("x_m", x_m), ("y_m", y_m), ("yaw_rad", yaw_rad), ("speed_mps", speed_mps)):
            if not math.isfinite(value):
                raise ValueError(f"EgoCar.reset {name} must be finite, got {value}")
        if speed_mps < 0:
            raise ValueError(f"EgoCar.reset speed_mps must be >= 0 (no reverse gear), got {speed_mps}")
        m, d, p = self.model, self.data, self.params
        mujoco.mj_resetData(m, d)
        q, v = self._qadr, self._vadr
        d.qpos[q : q + 3] = (x_m, y_m, self._layout.rest_height_m)
        d.qpos[q + 3 : q + 7] = (math.cos(0.5 * yaw_rad), 0.0, 0.0, math.sin(0.5 * yaw_rad))
        d.qvel[v : v + 3] = (speed_mps * math.cos(yaw_rad), speed_mps * math.sin(yaw_rad), 0.0)
        for dof in self._spin_dof:
            d.qvel[dof] = speed_mps / p.wheel_radius_m  # the rolling radius at the static load
        self._delta_cmd = 0.0  # [rad] rate-limited bicycle steering angle
        self._pt = PowertrainState(gear=gear_for_speed(p.powertrain, speed_mps / p.wheel_radius_m))
        self._engine_rpm = p.powertrain.idle_rpm
        armature, frictionloss, solreffriction, impratio = self._pristine
        m.dof_armature[:] = armature
        m.dof_frictionloss[:] = frictionloss
        m.pair_solreffriction[:] = solreffriction
        for row in self._friction_rows:
            row[0] = -1.0  # direct format; the stiffness is unused for friction rows
        m.opt.impratio = impratio
        mujoco.mj_forward(m, d)  # poses and tyre loads for the first control update
        self._apply_controls(0.0, 0.0, 0.0, self._chunk * self.timestep_s)
        mujoco.mj_forward(m, d)
        self._state = None

    def step(self, throttle: float, brake: float, steer: float, duration_s: float) -> EgoState:
        """Integrate ``round(duration_s / timestep_s)`` steps with constant pedals and steering target.

        throttle, brake in [0, 1]; steer in [-1, 1], +1 = full left (counter-clockwise yaw). Values outside
        are clipped; NaN is rejected. Returns the state at the end.
        """
        if not all(math.isfinite(v) for v in (throttle, brake, steer, duration_s)):
            raise ValueError(
                f"EgoCar.step got a non-finite input: {throttle=}, {brake=}, {steer=}, {duration_s=}"
            )
        if duration_s < 0:
            raise ValueError(f"EgoCar.step duration_s must be >= 0, got {duration_s}")
        throttle = min(max(float(throttle), 0.0), 1.0)
        brake = min(max(float(brake), 0.0), 1.0)
        steer = min(max(float(steer), -1.0), 1.0)
        n = round(duration_s / self.timestep_s)
        m, d = self.model, self.data
        while n > 0:
            k = min(self._chunk, n)
            self._apply_controls(throttle, brake, steer, k * self.timestep_s)
            mujoco.mj_step(m, d, k)
            n -= k
        self._state = None
        return self.state()

    @property
    def time_s(self) -> float:
        return float(self.data.time)

    def state(self) -> EgoState:
        """The car's state now (the same immutable object until the next ``step`` or ``reset``)."""
        if self._state is None:
            self._state = self._read_state()
        return self._state

    def _read_state(self) -> EgoState:
        d, p = self.data, self.params
        q, v = self._qadr, self._vadr
        qpos, qvel = self._qpos, self._qvel
        r00, _, _, r10, _, _, r20, r21, r22 = self._xmat.tolist()
        yaw = math.atan2(r10, r00)
        c, s = math.cos(yaw), math.sin(yaw)
        vx, vy = qvel[v : v + 2].tolist()
        ax, ay = self._qacc[v : v + 2].tolist()
        steer = bicycle_angle(float(qpos[self._steer_qpos[0]]), float(qpos[self._steer_qpos[1]]))
        loads = self._sensordata[self._load_idx]
        x, y, z = qpos[q : q + 3].tolist()
        return EgoState(
            t_s=float(d.time),
            x_m=x,
            y_m=y,
            z_m=z,
            yaw_rad=yaw,
            pitch_rad=-math.asin(max(-1.0, min(1.0, r20))),
            roll_rad=math.atan2(r21, r22),
            speed_mps=c * vx + s * vy,
            lateral_speed_mps=-s * vx + c * vy,
            accel_mps2=c * ax + s * ay,
            lateral_accel_mps2=-s * ax + c * ay,
            yaw_rate_rps=float(self._xmat[6:9] @ qvel[v + 3 : v + 6]),  # body angular velocity -> world z
            steer_rad=steer,
            wheel_speed_radps=qvel[self._spin_dof_idx],  # fancy indexing: a copy
            wheel_load_n=loads,
            in_contact=loads > 0.0,
            gear=self._pt.gear,
            engine_rpm=float(self._engine_rpm),
            length_m=p.length_m,
        )

    # -- internals -------------------------------------------------------------------------------------------
    def _apply_controls(self, throttle: float, brake: float, steer: float, dt_s: float) -> None:
        """Set every run-time input of the next ``dt_s`` from the current state (scalar code: 4 wheels).

        Runs every control period, so it avoids builtin calls: ``b if b > a else a`` is exactly max(a, b)
        and ``b if b < a else a`` min(a, b) (also for signed zeros)."""
        p = self.params
        tyre = p.tyre
        v = self._vadr
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = self._xmat.tolist()
        qvel = self._qvel.tolist()  # Python floats: one conversion instead of one per element read
        vx, vy, _, wlx, wly, wlz = qvel[v : v + 6]
        acc_x, acc_y = self._acc_xy.tolist()
        # Longitudinal acceleration of the last step; ABS and TCS regulate the tyre force, so their
        # torque caps add the torque that spins the wheel (and engaged driveline) down or up with the car.
        accel = r00 * acc_x + r10 * acc_y
        accel_up = 0.0 if 0.0 > accel else accel
        accel_down = 0.0 if 0.0 > -accel else -accel
        omega_x = r00 * wlx + r01 * wly + r02 * wlz  # chassis angular velocity in the world frame
        omega_y = r10 * wlx + r11 * wly + r12 * wlz
        omega_z = r20 * wlx + r21 * wly + r22 * wlz
        yaw = math.atan2(r10, r00)
        sensordata = self._sensordata.tolist()

        # Steering: rate-limited bicycle angle -> Ackermann angles of the two knuckle servos.
        step = self._max_steer_rate * dt_s
        delta = steer * self._max_steer_rad - self._delta_cmd
        delta = -step if -step > delta else delta
        self._delta_cmd += step if step < delta else delta
        left, right = ackermann_angles(self._delta_cmd, p.wheelbase_m, p.track_front_m)
        ctrl, steer_act = self._ctrl, self._steer_act
        ctrl[steer_act[0]] = left
        ctrl[steer_act[1]] = right
        qpos = self._qpos
        wheel_steer = (float(qpos[self._steer_qpos[0]]), float(qpos[self._steer_qpos[1]]), 0.0, 0.0)

        # Powertrain: open differential (equal torque to the driven wheels).
        n_driven = len(self._driven_dof)
        omega_driven = sum([qvel[dof] for dof in self._driven_dof]) / n_driven
        out, self._pt = step_powertrain(p.powertrain, self._pt, throttle, omega_driven, dt_s, brake)
        self._engine_rpm = out.engine_rpm
        wheel_torque = out.axle_torque_nm / n_driven
        armature = out.reflected_inertia_kgm2 / n_driven

        # Aerodynamic drag on the chassis (horizontal, at the centre of mass).
        speed = math.hypot(vx, vy)
        xfrc = self._xfrc
        xfrc[0] = -self._drag_k * speed * vx
        xfrc[1] = -self._drag_k * speed * vy

        k_vert = tyre.vertical_stiffness_n_per_m
        vmin, mu = tyre.min_slip_speed_mps, tyre.mu
        rolling = tyre.rolling_resistance
        use_tcs, use_abs = p.powertrain.traction_control, p.brakes.abs
        abs_margin, wheel_inertia = p.brakes.abs_margin, p.wheel_inertia_kgm2
        qfrc, frictionloss, armatures = self._qfrc, self._frictionloss, self._armature
        sin, cos, hypot = math.sin, math.cos, math.hypot
        cr = []  # c * R_normal per wheel
        for i, (dof, load_adr, is_driven, radius, (wx, wy), brake_max, stiffness, r_normal, _) in enumerate(
            self._wheels
        ):
            fz = sensordata[load_adr]
            fz = 0.0 if 0.0 > fz else fz
            lever = radius - 0.5 * fz / k_vert  # wheel centre -> contact point [m]
            friction_torque = mu * fz * lever  # [N m] torque that saturates the tyre
            # Drive torque (+ traction control) and driveline inertia on the driven wheels.
            torque = 0.0
            if is_driven:
                torque = wheel_torque
                armatures[dof] = armature
                if use_tcs:
                    inertia = wheel_inertia + armature
                    cap = TCS_MARGIN * friction_torque + inertia * accel_up / lever
                    torque = cap if cap < torque else torque
            qfrc[dof] = torque
            # Brakes (+ ABS) and rolling resistance as joint friction loss.
            brake_torque = brake * brake_max
            if use_abs:
                cap = abs_margin * friction_torque + wheel_inertia * accel_down / lever
                brake_torque = cap if cap < brake_torque else brake_torque
            frictionloss[dof] = brake_torque + rolling * fz * lever
            # Tyre slip stiffness (see the module docstring): wheel centre velocity, then the contact
            # point's = centre + omega_wheel x (0, 0, -lever), omega_wheel = chassis + spin about the axle.
            rx, ry, rz = r00 * wx + r01 * wy, r10 * wx + r11 * wy, r20 * wx + r21 * wy
            cx = vx + omega_y * rz - omega_z * ry
            cy = vy + omega_z * rx - omega_x * rz
            heading = yaw + wheel_steer[i]
            spin = qvel[dof]
            ox = omega_x - spin * sin(heading)
            oy = omega_y + spin * cos(heading)
            slip = hypot(cx - lever * oy, cy + lever * ox)
            centre_speed = hypot(cx, cy)
            ci = stiffness / (vmin if vmin > centre_speed else centre_speed)
            cap = SLIDE_DEMAND * mu * fz / (1e-3 if 1e-3 > slip else slip)
            ci = cap if cap < ci else ci
            # c [N s/m] >= 1: a wheel in the air keeps a well-defined (unused) contact
            cr.append((1.0 if 1.0 > ci else ci) * r_normal)
        impratio = max(cr) / self._b_max
        impratio = impratio if impratio > MIN_IMPRATIO else MIN_IMPRATIO
        self._opt.impratio = impratio
        for c_r, wheel in zip(cr, self._wheels, strict=True):
            wheel[8][1] = -c_r / impratio * TYRE_IMPEDANCE  # b = damping / dmax (row 0 is set by reset)

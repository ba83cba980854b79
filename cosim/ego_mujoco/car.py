"""MJCF text of the ego car on a flat road plane, generated from :class:`CarParams` (pure string building).

Conventions of the generated model:

- ``<compiler angle="radian"/>``: every angle in the MJCF is in radians.
- World: x east, y north, z up, the road is the plane z = 0 (the scenario is 2-D). The car's body frame
  has its origin at the centre of the footprint at axle height, x forward, y left.
- Wheels are spheres that touch the road only through explicit ``<pair>`` contacts (one contact point per
  wheel, elliptic friction cone, condim 3); the visible tyre is a cylinder that does not collide. MuJoCo
  puts the contact point in the middle of the penetration, so the lever from the wheel centre to the
  contact is (sphere radius - deflection / 2). The sphere radius is chosen so that this lever equals
  ``wheel_radius_m`` under the static load, and the wheels are mounted so that the body rests level
  (``CarLayout.rest_height_m``). The chassis box collides with the road (roll-over) and obstacles.
- Tyre normal force: a penalty spring-damper (tyre vertical stiffness and damping). It is written in
  MuJoCo's direct ``solref`` format with a tiny constant impedance, whose scaling depends on the
  compiled model's inverse inertias, so :func:`compile_model` sets it after compiling; the raw
  :func:`build_mjcf` text carries placeholders. Why a penalty normal: with MuJoCo's usual stiff contacts
  a sliding tyre's friction demand inflates the normal force (a locked wheel at 50 km/h lifts the car);
  a normal regulariser much larger than the friction one removes that coupling.
- Front wheels hang on steering knuckles (hinge about z, position servos); every wheel spins on a hinge
  about its y axis. Drive torque, brakes (joint friction loss), rolling resistance and the tyre slip
  stiffness are set at run time by :class:`cosim.ego_mujoco.physics.EgoCar`, not here.
- Static obstacles (buildings, barriers) can be added as boxes or convex meshes; MuJoCo collides meshes
  as their convex hull.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from cosim.ego_mujoco.params import CarParams, Obstacle, StaticBox, StaticMesh

WHEELS = ("fl", "fr", "rl", "rr")  # wheel order used by every per-wheel array: front-left first
ROAD_GEOM = "road"
CHASSIS_BODY = "chassis"
FREE_JOINT = "root"

# Tyre-road contact impedance: tiny and constant (solimp d0 = dmax), so the normal row is a penalty
# spring-damper and the regulariser R of a wheel contact is a constant of the model:
# R_normal = (1 - d) / d * body_invweight0[wheel]. physics.py relies on that constant.
TYRE_IMPEDANCE = 0.002
TYRE_SOLIMP = (TYRE_IMPEDANCE, TYRE_IMPEDANCE, 0.001, 0.5, 2.0)
COLLISION_BITS = 2  # contype/conaffinity of road, chassis and obstacles (wheels use pairs only)


def _f(*values: float) -> str:
    return " ".join(f"{float(v):.9g}" for v in values)


@dataclass(frozen=True)
class CarLayout:
    """Derived positions and masses. Body frame: origin above the footprint centre at ``rest_height_m``
    (about axle height), x forward, y left, z up."""

    wheel_xy_m: np.ndarray  # (4, 2) float64 [m] wheel centres in WHEELS order
    chassis_mass_kg: float
    chassis_com_m: tuple[float, float, float]  # [m] chassis centre of mass in the body frame
    chassis_inertia_kgm2: tuple[float, float, float]  # [kg m^2] principal inertia (roll, pitch, yaw)
    knuckle_mass_kg: float
    wheel_body_mass_kg: float  # front wheels (rear wheels carry the full wheel_mass_kg)
    static_wheel_load_n: np.ndarray  # (4,) float64 [N] wheel loads at rest
    sphere_radius_m: np.ndarray  # (4,) float64 [m] collision sphere: rolling radius + static deflection / 2
    wheel_z_m: np.ndarray  # (4,) float64 [m] wheel centre height in the body frame
    rest_height_m: float  # [m] height of the body origin with the car at rest on level road


def layout(p: CarParams) -> CarLayout:
    xf, xr = p.front_axle_x_m, p.rear_axle_x_m
    wheel_xy = np.array(
        [
            [xf, 0.5 * p.track_front_m],
            [xf, -0.5 * p.track_front_m],
            [xr, 0.5 * p.track_rear_m],
            [xr, -0.5 * p.track_rear_m],
        ]
    )
    g = 9.81
    front_axle_load = p.front_weight_share * p.mass_kg * g
    loads = np.array([0.5 * front_axle_load] * 2 + [0.5 * (p.mass_kg * g - front_axle_load)] * 2)
    deflection = loads / p.tyre.vertical_stiffness_n_per_m  # [m] static tyre deflection
    rest_height = p.wheel_radius_m - 0.5 * float(deflection.mean())  # body origin above the road at rest
    wheel_z = 0.5 * (deflection.mean() - deflection)  # level body: wheel centres at r - deflection / 2
    m_c = p.mass_kg - 4.0 * p.wheel_mass_kg
    # Chassis CoM such that the total CoG is at (cog_x, 0, cog_height above the road) at rest.
    com_x = (p.mass_kg * p.cog_x_m - p.wheel_mass_kg * float(wheel_xy[:, 0].sum())) / m_c
    com_z = (p.mass_kg * (p.cog_height_m - rest_height) - p.wheel_mass_kg * float(wheel_z.sum())) / m_c
    inertia = (
        m_c * p.roll_gyration_radius_m**2,
        m_c * p.pitch_gyration_radius_m**2,
        m_c * p.yaw_gyration_radius_m**2,
    )
    return CarLayout(
        wheel_xy_m=wheel_xy,
        chassis_mass_kg=m_c,
        chassis_com_m=(com_x, 0.0, com_z),
        chassis_inertia_kgm2=inertia,
        knuckle_mass_kg=0.15 * p.wheel_mass_kg,
        wheel_body_mass_kg=0.85 * p.wheel_mass_kg,
        static_wheel_load_n=loads,
        sphere_radius_m=p.wheel_radius_m + 0.5 * deflection,
        wheel_z_m=wheel_z,
        rest_height_m=rest_height,
    )


def inner_steer_limit_rad(p: CarParams) -> float:
    """Largest Ackermann road-wheel angle (inner wheel at full lock) [rad]."""
    t = math.tan(p.max_steer_rad)
    return math.atan(p.wheelbase_m * t / (p.wheelbase_m - 0.5 * p.track_front_m * t))


def build_mjcf(p: CarParams, timestep_s: float = 0.002, obstacles: Sequence[Obstacle] = ()) -> str:
    """The complete MJCF document: options, road plane, obstacles, the car, tyre contacts, actuators."""
    lay = layout(p)
    r = p.wheel_radius_m
    tyre_w = 0.205  # [m] visual tyre width
    ground_clearance = 0.14  # [m] chassis box bottom above the road
    box_half = (0.5 * p.length_m, 0.5 * p.width_m, 0.5 * (p.height_m - ground_clearance))
    box_z = ground_clearance + box_half[2] - lay.rest_height_m  # box centre in the body frame
    steer_lim = inner_steer_limit_rad(p)
    # Steering servo: natural frequency ~60 rad/s on the knuckle + wheel inertia about z.
    steer_inertia = 0.5 * p.wheel_inertia_kgm2 + 0.05
    omega_n = 60.0
    kp, kv = steer_inertia * omega_n**2, 2.0 * steer_inertia * omega_n
    wheel_diam_inertia = 0.5 * p.wheel_inertia_kgm2 + 0.02
    mu = p.tyre.mu

    out: list[str] = []
    w = out.append
    w('<mujoco model="ego_car">')
    w('  <compiler angle="radian" autolimits="true"/>')
    # implicitfast: the steering servo damping is integrated implicitly; elliptic cones: isotropic
    # friction circle (pyramids would make the grip depend on the heading in the world frame).
    w(
        f'  <option timestep="{_f(timestep_s)}" integrator="implicitfast" cone="elliptic" solver="Newton" '
        'iterations="50" ls_iterations="20" tolerance="1e-10"/>'
    )
    w('  <visual><global offwidth="1280" offheight="720"/></visual>')
    meshes = [o for o in obstacles if isinstance(o, StaticMesh)]
    if meshes:
        w("  <asset>")
        for i, mesh in enumerate(meshes):
            verts = _f(*np.asarray(mesh.vertices_m, dtype=np.float64).ravel())
            face = f' face="{" ".join(str(int(v)) for f in mesh.faces for v in f)}"' if mesh.faces else ""
            w(f'    <mesh name="obstacle_mesh{i}" vertex="{verts}"{face}/>')
        w("  </asset>")
    w("  <worldbody>")
    w(
        f'    <geom name="{ROAD_GEOM}" type="plane" size="0 0 1" contype="{COLLISION_BITS}" '
        f'conaffinity="{COLLISION_BITS}" friction="{_f(mu, 0.005, 0.0001)}" rgba="0.3 0.3 0.32 1"/>'
    )
    i_mesh = 0
    for i, obs in enumerate(obstacles):
        if isinstance(obs, StaticBox):
            w(
                f'    <geom name="obstacle{i}" type="box" pos="{_f(*obs.centre_m)}" '
                f'size="{_f(*obs.half_size_m)}" '
                f'euler="0 0 {_f(obs.yaw_rad)}" contype="{COLLISION_BITS}" conaffinity="{COLLISION_BITS}" '
                'rgba="0.6 0.55 0.5 1"/>'
            )
        else:
            w(
                f'    <geom name="obstacle{i}" type="mesh" mesh="obstacle_mesh{i_mesh}" '
                f'contype="{COLLISION_BITS}" '
                f'conaffinity="{COLLISION_BITS}" rgba="0.6 0.55 0.5 1"/>'
            )
            i_mesh += 1
    w(f'    <body name="{CHASSIS_BODY}" pos="0 0 {_f(r)}">')
    w(f'      <freejoint name="{FREE_JOINT}"/>')
    w(
        f'      <inertial pos="{_f(*lay.chassis_com_m)}" mass="{_f(lay.chassis_mass_kg)}" '
        f'diaginertia="{_f(*lay.chassis_inertia_kgm2)}"/>'
    )
    w(
        f'      <geom name="chassis" type="box" size="{_f(*box_half)}" pos="0 0 {_f(box_z)}" '
        f'contype="{COLLISION_BITS}" conaffinity="{COLLISION_BITS}" rgba="0.15 0.35 0.75 1"/>'
    )
    for k, name in enumerate(WHEELS):
        x, y = lay.wheel_xy_m[k]
        front = name[0] == "f"
        indent = "      "
        if front:
            w(f'{indent}<body name="knuckle_{name}" pos="{_f(x, y, lay.wheel_z_m[k])}">')
            # The joint range is 2 deg wider than the servo's: a limit at the target would fight the servo.
            lim = steer_lim + math.radians(2.0)
            w(f'{indent}  <joint name="steer_{name}" type="hinge" axis="0 0 1" range="{_f(-lim, lim)}"/>')
            w(
                f'{indent}  <inertial pos="0 0 0" mass="{_f(lay.knuckle_mass_kg)}" '
                'diaginertia="0.05 0.05 0.05"/>'
            )
            indent += "  "
            w(f'{indent}<body name="wheel_{name}" pos="0 0 0">')
            mass = lay.wheel_body_mass_kg
        else:
            w(f'{indent}<body name="wheel_{name}" pos="{_f(x, y, lay.wheel_z_m[k])}">')
            mass = p.wheel_mass_kg
        # Brakes and rolling resistance act through this joint's friction loss (set at run time). A hard
        # friction-loss row (d = 0.99, time constant 4 steps) holds a braked wheel: with the default
        # softness a "locked" wheel creeps at ~1.5 rad/s under the tyre's torque; d = 0.998 chatters.
        w(
            f'{indent}  <joint name="spin_{name}" type="hinge" axis="0 1 0" '
            'solimpfriction="0.99 0.99 0.001 0.5 2" '
            f'solreffriction="{_f(4.0 * timestep_s)} 1"/>'
        )
        w(
            f'{indent}  <inertial pos="0 0 0" mass="{_f(mass)}" '
            f'diaginertia="{_f(wheel_diam_inertia, p.wheel_inertia_kgm2, wheel_diam_inertia)}"/>'
        )
        w(
            f'{indent}  <geom name="tyre_{name}" type="sphere" size="{_f(lay.sphere_radius_m[k])}" '
            'contype="0" '
            'conaffinity="0" group="3"/>'
        )
        # Touch-sensor zone around the whole tyre: the sensor sums the normal force of its contacts.
        w(
            f'{indent}  <site name="tyre_site_{name}" type="sphere" '
            f'size="{_f(lay.sphere_radius_m[k] + 0.05)}" group="4"/>'
        )
        w(
            f'{indent}  <geom name="tyre_visual_{name}" type="cylinder" size="{_f(r, 0.5 * tyre_w)}" '
            f'euler="{_f(0.5 * math.pi, 0.0, 0.0)}" contype="0" conaffinity="0" mass="0" '
            'rgba="0.08 0.08 0.08 1"/>'
        )
        w(f"{indent}</body>")
        if front:
            w("      </body>")
    w("    </body>")
    w("  </worldbody>")
    w("  <contact>")
    for name in WHEELS:
        w(
            f'    <pair name="tyre_{name}" geom1="tyre_{name}" geom2="{ROAD_GEOM}" condim="3" '
            f'friction="{_f(mu, mu, 0.005, 0.0001, 0.0001)}" solref="-1 -1" '
            f'solimp="{_f(*TYRE_SOLIMP)}" solreffriction="-1 -1"/>'
        )
    w("  </contact>")
    w("  <sensor>")
    for name in WHEELS:  # sensordata[0:4] = tyre normal forces [N] in WHEELS order
        w(f'    <touch name="load_{name}" site="tyre_site_{name}"/>')
    w("  </sensor>")
    w("  <actuator>")
    for name in ("fl", "fr"):
        w(
            f'    <position name="steer_{name}" joint="steer_{name}" kp="{_f(kp)}" kv="{_f(kv)}" '
            f'ctrlrange="{_f(-steer_lim, steer_lim)}"/>'
        )
    w("  </actuator>")
    w("</mujoco>")
    return "\n".join(out) + "\n"


def compile_model(
    p: CarParams, timestep_s: float = 0.002, obstacles: Sequence[Obstacle] = ()
) -> mujoco.MjModel:
    """Compile :func:`build_mjcf` and set the tyres' vertical spring-damper (direct-format ``solref``).

    With impedance d << 1 the normal force is (stiffness * penetration + damping * velocity) / ((1-d) A),
    A = the contact's approximate inverse inertia (``body_invweight0`` of the wheel), so the direct-format
    numbers are the physical stiffness [N/m] and damping [N s/m] times (1-d) A.
    """
    model = mujoco.MjModel.from_xml_string(build_mjcf(p, timestep_s, obstacles))
    lay = layout(p)
    k = p.tyre.vertical_stiffness_n_per_m
    d = TYRE_IMPEDANCE
    for i, name in enumerate(WHEELS):
        pair = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_PAIR, f"tyre_{name}")
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"wheel_{name}")
        a_hat = float(model.body_invweight0[body, 0])
        corner_mass = lay.static_wheel_load_n[i] / 9.81
        damping = 2.0 * p.tyre.vertical_damping_ratio * math.sqrt(k * corner_mass)
        model.pair_solref[pair] = (-k * (1.0 - d) * a_hat, -damping * (1.0 - d) * a_hat)
    return model


def ackermann_angles(delta_rad: float, wheelbase_m: float, track_m: float) -> tuple[float, float]:
    """Left and right road-wheel angles [rad] that turn about the rear-axle point of a bicycle with
    steering angle ``delta_rad`` (left positive): both front wheels roll without scrubbing."""
    t = math.tan(delta_rad)
    half = 0.5 * track_m
    return (
        math.atan(wheelbase_m * t / (wheelbase_m - half * t)),
        math.atan(wheelbase_m * t / (wheelbase_m + half * t)),
    )


def bicycle_angle(left_rad: float, right_rad: float) -> float:
    """Equivalent bicycle steering angle [rad] of two road-wheel angles: cot(delta) is their mean cot."""
    tl, tr = math.tan(left_rad), math.tan(right_rad)
    if tl * tr <= 0.0:  # straight ahead or servo jitter around zero: no common turning centre
        return 0.5 * (left_rad + right_rad)
    return math.atan(2.0 * tl * tr / (tl + tr))

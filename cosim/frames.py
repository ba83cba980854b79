"""Pose conversions between SUMO's and MuJoCo's vehicle conventions (pure numpy, no simulator import).

SUMO                                               MuJoCo (cosim.ego_mujoco)
  position: centre of the FRONT bumper [m]           position: centre of the car footprint [m]
  angle: compass degrees, clockwise from north         yaw: radians, counter-clockwise from +x
         (0 = +y, 90 = +x), in [0, 360)                     (0 = +x, pi/2 = +y), in (-pi, pi]

Both use the same axes: x east, y north, in SUMO *network* coordinates. The MuJoCo world is the SUMO
network frame, optionally shifted by an explicit ``origin_xy`` (a point of the network that becomes the
MuJoCo world origin): ``mujoco_xy = network_xy - origin_xy``. The shift exists only to keep coordinates
small where float32 matters (rendering: a float32 has ~0.5 mm resolution at 4 km, ~4 mm at 30 km from
the origin); physics runs in float64 and is translation invariant, so any origin gives the same dynamics.
Every function that touches positions takes ``origin_xy`` as an argument; nothing stores it globally.

SUMO's *network offset* (``<location netOffset=...>`` in the .net.xml) is a different thing: the
translation netconvert applied to the projected (e.g. UTM) coordinates of the map,
``network_xy = projected_xy + net_offset_xy``. SUMO (TraCI/libsumo) positions are already network
coordinates, so the ego loop never needs it; :func:`network_to_projected` / :func:`projected_to_network`
are for data that lives in projected coordinates (geo-referencing, external map layers).

All functions are vectorised: scalars or equally shaped arrays in, float64 arrays (0-d for scalars) out.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

XY = Sequence[float] | np.ndarray  # a 2-vector (x, y) [m]

_TWO_PI = 2.0 * np.pi


def wrap_rad(angle_rad: ArrayLike) -> np.ndarray:
    """Wrap an angle [rad] into (-pi, pi]."""
    a = np.asarray(angle_rad, dtype=np.float64)
    w = np.mod(a + np.pi, _TWO_PI) - np.pi  # [-pi, pi)
    return np.where(w == -np.pi, np.pi, w)


def wrap_deg360(angle_deg: ArrayLike) -> np.ndarray:
    """Wrap an angle [deg] into [0, 360) (SUMO's range for vehicle angles)."""
    w = np.mod(np.asarray(angle_deg, dtype=np.float64), 360.0)
    return np.where(w >= 360.0, 0.0, w)  # np.mod can round -1e-17 up to exactly 360.0


def sumo_angle_to_yaw(angle_deg: ArrayLike) -> np.ndarray:
    """SUMO compass angle [deg, clockwise from north] -> MuJoCo yaw [rad, ccw from +x] in (-pi, pi]."""
    return wrap_rad(np.pi / 2.0 - np.radians(np.asarray(angle_deg, dtype=np.float64)))


def yaw_to_sumo_angle(yaw_rad: ArrayLike) -> np.ndarray:
    """MuJoCo yaw [rad, ccw from +x] -> SUMO compass angle [deg, clockwise from north] in [0, 360)."""
    return wrap_deg360(90.0 - np.degrees(np.asarray(yaw_rad, dtype=np.float64)))


def _origin(origin_xy: XY) -> tuple[float, float]:
    ox, oy = (float(v) for v in np.asarray(origin_xy, dtype=np.float64).reshape(2))
    return ox, oy


def sumo_to_mujoco(
    x_m: ArrayLike, y_m: ArrayLike, angle_deg: ArrayLike, length_m: ArrayLike, origin_xy: XY = (0.0, 0.0)
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """SUMO front-bumper pose -> MuJoCo centre pose.

    x_m, y_m: front-bumper centre in network coordinates [m]; angle_deg: SUMO angle [deg];
    length_m: vehicle length [m] (bumper to bumper); origin_xy: network point that is the MuJoCo origin [m].
    Returns (cx_m, cy_m, yaw_rad): footprint centre in the MuJoCo world [m] and yaw [rad] in (-pi, pi].
    """
    ox, oy = _origin(origin_xy)
    rad = np.radians(np.asarray(angle_deg, dtype=np.float64))
    half = 0.5 * np.asarray(length_m, dtype=np.float64)
    # SUMO heading unit vector is (sin a, cos a); the centre is half a length behind the front bumper.
    cx = np.asarray(x_m, dtype=np.float64) - np.sin(rad) * half - ox
    cy = np.asarray(y_m, dtype=np.float64) - np.cos(rad) * half - oy
    return cx, cy, sumo_angle_to_yaw(angle_deg)


def mujoco_to_sumo(
    cx_m: ArrayLike, cy_m: ArrayLike, yaw_rad: ArrayLike, length_m: ArrayLike, origin_xy: XY = (0.0, 0.0)
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """MuJoCo centre pose -> SUMO front-bumper pose (the inverse of :func:`sumo_to_mujoco`).

    Returns (x_m, y_m, angle_deg): front-bumper centre in network coordinates [m] and SUMO angle [deg] in
    [0, 360), ready for ``vehicle.moveToXY(..., x, y, angle=angle_deg)``.
    """
    ox, oy = _origin(origin_xy)
    yaw = np.asarray(yaw_rad, dtype=np.float64)
    half = 0.5 * np.asarray(length_m, dtype=np.float64)
    x = np.asarray(cx_m, dtype=np.float64) + np.cos(yaw) * half + ox
    y = np.asarray(cy_m, dtype=np.float64) + np.sin(yaw) * half + oy
    return x, y, yaw_to_sumo_angle(yaw)


def network_to_projected(x_m: ArrayLike, y_m: ArrayLike, net_offset_xy: XY) -> tuple[np.ndarray, np.ndarray]:
    """SUMO network coordinates -> projected map coordinates (undo netconvert's netOffset) [m]."""
    ox, oy = _origin(net_offset_xy)
    return np.asarray(x_m, dtype=np.float64) - ox, np.asarray(y_m, dtype=np.float64) - oy


def projected_to_network(x_m: ArrayLike, y_m: ArrayLike, net_offset_xy: XY) -> tuple[np.ndarray, np.ndarray]:
    """Projected map coordinates -> SUMO network coordinates (apply netconvert's netOffset) [m]."""
    ox, oy = _origin(net_offset_xy)
    return np.asarray(x_m, dtype=np.float64) + ox, np.asarray(y_m, dtype=np.float64) + oy

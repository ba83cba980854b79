"""The MuJoCo scene of a scenario: roads, junctions, markings, buildings, signs, traffic lights, cars.

Coordinates. The scene's world frame is the SUMO network frame shifted by ``Scene.origin_xy``:
``scene_xy = network_xy - origin_xy`` (x east, y north, z up, road surface at z ~ 0). The origin is the
centre of the network's bounding box rounded to whole metres, so every coordinate stays within a few km of
0: MuJoCo's renderer works in float32 (~0.25 mm resolution at 4 km; ~4 mm at 60 km, where roads and
markings would start to flicker). It is NOT the origin of the physics car's own MjModel
(``EgoController.origin``); the ego is placed here from its network pose.

What is in the model (all visual: contype = conaffinity = 0, nothing is simulated here; the physics car
lives in its own MjModel):

- static, merged into a handful of meshes: road surfaces (lane strips + junction polygons), lane markings
  (dashed dividers, centre and edge lines, stop lines), building walls (a few tints, facade texture)
  and roofs, sign posts / faces (one texture atlas) / backs, traffic-light poles and housings;
- dynamic: one lamp per signalised approach (colour and position follow SUMO's state string), a pool of
  mocap car bodies for the SCVs (nearest to the ego), the ego car (mocap, carries the driver and chase
  cameras) and system A's rear display panel (mocap, switched between a dark and an emissive material).

Hidden objects are put into geom group 4, which MuJoCo does not draw by default.
"""

from __future__ import annotations

import math
import time
import zlib
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
import shapely
import shapely.affinity

from cosim.world3d import geometry as geo
from cosim.world3d import textures
from cosim.world3d.state import FrameState, VehiclePool

HIDDEN_GROUP = 4  # mjvOption.geomgroup[3:] are off by default
ROAD_Z = 0.02  # [m] road and junction surfaces (same colour, so overlaps cannot flicker)
MARK_Z = 0.045  # [m] markings above the road
SIGN_KINDS_DRAWN = ("stop", "allway_stop", "give_way", "speed_limit", "one_way", "no_entry", "city_limit")
_EXTENT = 100.0  # [m] model extent: MuJoCo scales znear / zfar / fog by it
_CAR_PALETTE = (
    (0.92, 0.92, 0.92), (0.75, 0.76, 0.78), (0.12, 0.12, 0.13), (0.35, 0.36, 0.38), (0.62, 0.08, 0.08),
    (0.10, 0.22, 0.50), (0.12, 0.30, 0.20), (0.70, 0.62, 0.48), (0.20, 0.45, 0.70), (0.85, 0.55, 0.10),
)  # fmt: skip
_WALL_TINTS = ((1.0, 0.96, 0.88), (0.92, 0.86, 0.78), (0.98, 0.93, 0.80), (0.86, 0.86, 0.86),
               (0.95, 0.84, 0.76), (0.80, 0.84, 0.88))  # fmt: skip
_LAMP_RGBA = {"r": (1.0, 0.08, 0.05, 1.0), "y": (1.0, 0.65, 0.0, 1.0), "g": (0.1, 1.0, 0.3, 1.0)}
_LAMP_SLOT = {"r": 0, "y": 1, "g": 2}
_SUMO_LAMP = {"r": "r", "R": "r", "s": "r", "y": "y", "Y": "y", "u": "y", "g": "g", "G": "g"}  # 'o'/'O': off
_BRAKE_ON = (1.0, 0.05, 0.05, 1.0)
_BRAKE_OFF = (0.40, 0.04, 0.04, 1.0)


@dataclass(frozen=True)
class SceneParams:
    """How the scene is built and drawn."""

    vehicle_pool: int = 48  # car bodies for SCVs; the nearest ones to the ego are shown
    vehicle_max_distance_m: float = 500.0  # [m] SCVs farther from the ego are not drawn
    lane_markings: bool = True
    facade_texture: bool = True  # windows on the walls (one repeating texture)
    wall_tints: int = 4  # building wall colours (one mesh each)
    znear_m: float = 0.15  # [m] near clipping plane
    draw_distance_m: float = 1500.0  # [m] far clipping plane
    fog_start_m: float = 250.0  # [m] haze starts here ...
    fog_end_m: float = 1400.0  # [m] ... and hides everything from here on
    msaa_samples: int = 0  # offscreen multisampling (0 = off; 4 looks smoother, costs ~2x in software GL)
    max_width: int = 1280  # [px] largest frame the renderer may ask for (offscreen buffer size)
    max_height: int = 720  # [px]
    scv_length_m: float = 4.6  # [m] visual length of SCV bodies (SUMO passenger cars are 5 m incl. slack)
    ego_rgba: tuple[float, float, float, float] = (0.85, 0.12, 0.10, 1.0)
    # [m] eye in the ego frame (x fwd, y left): the left seat; mirrored where traffic keeps left
    driver_eye_m: tuple[float, float, float] = (-0.25, 0.37, 1.22)
    driver_fovy_deg: float = 50.0  # vertical field of view of the driver camera
    chase_distance_m: float = 9.0  # [m] chase camera behind the ego centre
    chase_height_m: float = 3.4  # [m]
    chase_pitch_deg: float = 12.0  # looking down by
    ground_margin_m: float = 600.0  # [m] grass beyond the network's bounding box

    def __post_init__(self) -> None:
        if self.vehicle_pool < 0:
            raise ValueError(f"vehicle_pool must be >= 0, got {self.vehicle_pool}")
        if not 0 < self.znear_m < self.draw_distance_m:
            raise ValueError("need 0 < znear_m < draw_distance_m")
        if not 0 <= self.fog_start_m < self.fog_end_m:
            raise ValueError("need 0 <= fog_start_m < fog_end_m")
        if self.msaa_samples not in (0, 2, 4, 8, 16):
            raise ValueError(f"msaa_samples must be 0, 2, 4, 8 or 16, got {self.msaa_samples}")
        if self.max_width < 16 or self.max_height < 16:
            raise ValueError("max_width and max_height must be >= 16 px")
        if not 1 <= self.wall_tints <= len(_WALL_TINTS):
            raise ValueError(f"wall_tints must be in [1, {len(_WALL_TINTS)}], got {self.wall_tints}")
        if not 10.0 <= self.driver_fovy_deg <= 120.0:
            raise ValueError(f"driver_fovy_deg must be in [10, 120], got {self.driver_fovy_deg}")


@dataclass(frozen=True)
class Approach:
    """One signalised approach: which SUMO link its lamp shows, and where the lamp is (scene frame)."""

    tls_id: str
    link_index: int  # index into the traffic light's state string
    edge: str
    lamp_pos: np.ndarray  # (3, 3) float64 [m] lamp centre for red, yellow, green


@dataclass
class SceneStats:
    build_s: float = 0.0  # [s] wall time to generate and compile
    counts: dict[str, int] = field(default_factory=dict)  # lanes, junctions, buildings, signs, approaches
    triangles: dict[str, int] = field(default_factory=dict)  # per static mesh
    ngeom: int = 0
    nmesh: int = 0


# -- helpers ---------------------------------------------------------------------------------------------------
def _yaw_quat(yaw: float, pitch: float = 0.0, roll: float = 0.0) -> np.ndarray:
    """Quaternion (w, x, y, z) of Rz(yaw) Ry(pitch) Rx(roll)."""
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    return np.array([
        cy * cp * cr + sy * sp * sr, cy * cp * sr - sy * sp * cr, cy * sp * cr + sy * cp * sr, sy * cp * cr - cy * sp * sr,
    ])  # fmt: skip


def _camera_quat(forward: np.ndarray, up_hint=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Quaternion of a MuJoCo camera frame that looks along ``forward`` (cameras look along their -z)."""
    f = np.asarray(forward, dtype=np.float64)
    f = f / np.linalg.norm(f)
    x = np.cross(f, up_hint)
    x = x / np.linalg.norm(x)
    y = np.cross(x, f)
    mat = np.stack([x, y, -f], axis=1)  # columns: camera x, y, z in the parent frame
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, mat.ravel())
    return q


def _color_of(vehicle_id: str) -> tuple[float, float, float, float]:
    r, g, b = _CAR_PALETTE[zlib.crc32(vehicle_id.encode()) % len(_CAR_PALETTE)]
    return (r, g, b, 1.0)


def _roadside(
    shape: np.ndarray, half_width_m: float, side_m: float, at_end: bool, lefthand: bool = False
) -> tuple[float, float, float]:
    """Point beside the kerb-side edge of a road (right; left in left-hand traffic) at its start or end, and
    the travel yaw [rad]."""
    (x0, y0), (x1, y1) = (shape[-2], shape[-1]) if at_end else (shape[0], shape[1])
    n = math.hypot(x1 - x0, y1 - y0) or 1.0
    ux, uy = (x1 - x0) / n, (y1 - y0) / n
    px, py = (x1, y1) if at_end else (x0, y0)
    off = (half_width_m + side_m) * (-1.0 if lefthand else 1.0)
    return px + uy * off, py - ux * off, math.atan2(uy, ux)


def _shape_xy(obj, origin: np.ndarray) -> np.ndarray:
    return np.asarray([p[:2] for p in obj.getShape()], dtype=np.float64) - origin


# -- the scene -------------------------------------------------------------------------------------------------
class Scene:
    """A compiled MuJoCo model of one scenario plus the handles to pose its dynamic parts each frame."""

    def __init__(self, spec: mujoco.MjSpec, origin_xy: np.ndarray, params: SceneParams,
                 approaches: list[Approach], stats: SceneStats):  # fmt: skip
        self.spec = spec
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self.origin_xy = origin_xy
        self.params = params
        self.approaches = approaches
        self.stats = stats
        m = self.model

        def gid(name: str) -> int:
            return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)

        def mocap(name: str) -> int:
            return int(m.body_mocapid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)])

        self._ego_mocap = mocap("ego")
        self._ego_geoms = [gid(f"ego_{part}") for part in ("body", "dark", "lamps")]
        self._ego_lamps = gid("ego_lamps")
        n = params.vehicle_pool
        self._car_mocap = np.array([mocap(f"car{i}") for i in range(n)], dtype=np.int64)
        self._car_geoms = np.array([[gid(f"car{i}_{p}") for p in ("body", "dark", "lamps")] for i in range(n)],
                                   dtype=np.int64).reshape(n, 3)  # fmt: skip
        self._car_owner: list[str | None] = [None] * n
        self._car_braking = np.zeros(n, dtype=bool)
        self.pool = VehiclePool(n)
        self._lamp_geoms = np.array([gid(f"lamp{i}") for i in range(len(approaches))], dtype=np.int64)
        self._lamp_state: list[str | None] = [None] * len(approaches)
        self._by_tls: dict[str, list[int]] = defaultdict(list)
        for i, a in enumerate(approaches):
            self._by_tls[a.tls_id].append(i)
        self._display_mocap = mocap("rear_display")
        self._display_geom = gid("rear_display")
        self._display_mats = (
            mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_MATERIAL, "display_off"),
            mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_MATERIAL, "display_on"),
        )
        self._hide(self._ego_geoms)
        self._hide(self._car_geoms.ravel())
        self._hide([self._display_geom])
        self.has_ego = False
        self.net = None
        self.last_frame: FrameState | None = None
        mujoco.mj_kinematics(m, self.data)
        mujoco.mj_camlight(m, self.data)

    # -- frames ------------------------------------------------------------------------------------------------
    def _hide(self, geoms) -> None:
        self.model.geom_group[np.asarray(list(geoms), dtype=np.int64)] = HIDDEN_GROUP

    def _show(self, geoms) -> None:
        self.model.geom_group[np.asarray(list(geoms), dtype=np.int64)] = 0

    # -- per frame ---------------------------------------------------------------------------------------------
    def apply(self, frame: FrameState) -> None:
        """Pose every dynamic object from ``frame`` and update the kinematics (call before rendering)."""
        m, d = self.model, self.data
        ox, oy = self.origin_xy
        ego = frame.ego
        if ego is not None:
            d.mocap_pos[self._ego_mocap] = (ego.x_m - ox, ego.y_m - oy, ego.z_m)
            d.mocap_quat[self._ego_mocap] = _yaw_quat(ego.yaw_rad, ego.pitch_rad, ego.roll_rad)
            m.geom_rgba[self._ego_lamps] = _BRAKE_ON if ego.braking else _BRAKE_OFF
            if not self.has_ego:
                self._show(self._ego_geoms)
                self.has_ego = True
            vx, vy = ego.x_m, ego.y_m
        else:
            if self.has_ego:
                self._hide(self._ego_geoms)
                self.has_ego = False
            d.mocap_pos[self._ego_mocap] = (0.0, 0.0, -50.0)
            vx, vy = ox, oy
        self._apply_vehicles(frame, vx, vy)
        self._apply_lights(frame.lights)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_camlight(m, d)
        self.last_frame = frame

    def _apply_vehicles(self, frame: FrameState, vx: float, vy: float) -> None:
        m, d = self.model, self.data
        v = frame.vehicles
        p = self.params
        slots = self.pool.assign(v.ids, np.hypot(v.x_m - vx, v.y_m - vy), p.vehicle_max_distance_m)
        shown = np.zeros(len(self._car_owner), dtype=bool)
        ox, oy = self.origin_xy
        display_slot = -1
        for i in np.flatnonzero(slots >= 0).tolist():
            k = int(slots[i])
            shown[k] = True
            vid = v.ids[i]
            geoms = self._car_geoms[k]
            if self._car_owner[k] != vid:
                if self._car_owner[k] is None:
                    self._show(geoms)
                self._car_owner[k] = vid
                m.geom_rgba[geoms[0]] = _color_of(vid)
            mk = self._car_mocap[k]
            d.mocap_pos[mk] = (v.x_m[i] - ox, v.y_m[i] - oy, 0.0)
            d.mocap_quat[mk] = _yaw_quat(float(v.yaw_rad[i]))
            if bool(v.braking[i]) != self._car_braking[k]:
                self._car_braking[k] = bool(v.braking[i])
                m.geom_rgba[geoms[2]] = _BRAKE_ON if v.braking[i] else _BRAKE_OFF
            if vid == frame.leader_id:
                display_slot = k
        for k in np.flatnonzero(~shown).tolist():
            if self._car_owner[k] is not None:
                self._car_owner[k] = None
                self._hide(self._car_geoms[k])
                d.mocap_pos[self._car_mocap[k]] = (0.0, 0.0, -50.0)
        # system A: the display panel rides on the leader's rear
        if display_slot >= 0 and frame.rear_display_lit is not None:
            mk = self._car_mocap[display_slot]
            d.mocap_pos[self._display_mocap] = d.mocap_pos[mk]
            d.mocap_quat[self._display_mocap] = d.mocap_quat[mk]
            m.geom_matid[self._display_geom] = self._display_mats[1 if frame.rear_display_lit else 0]
            self._show([self._display_geom])
        else:
            self._hide([self._display_geom])

    def _apply_lights(self, lights: dict[str, str]) -> None:
        m = self.model
        for tls_id, state in lights.items():
            for i in self._by_tls.get(tls_id, ()):
                a = self.approaches[i]
                lamp = _SUMO_LAMP.get(state[a.link_index]) if a.link_index < len(state) else None
                if lamp == self._lamp_state[i]:
                    continue
                self._lamp_state[i] = lamp
                g = self._lamp_geoms[i]
                if lamp is None:
                    m.geom_group[g] = HIDDEN_GROUP
                else:
                    m.geom_group[g] = 0
                    m.geom_rgba[g] = _LAMP_RGBA[lamp]
                    m.geom_pos[g] = a.lamp_pos[_LAMP_SLOT[lamp]]

    def lamp_states(self) -> list[str | None]:
        """The colour each approach's lamp shows now ('r' | 'y' | 'g' | None = dark), in approach order."""
        return list(self._lamp_state)


# -- building --------------------------------------------------------------------------------------------------
def _add_mesh_geom(spec: mujoco.MjSpec, name: str, mesh: geo.MeshData, material: str | None = None,
                   rgba=None, body=None, stats: SceneStats | None = None):  # fmt: skip
    if mesh.empty:
        return None
    ms = spec.add_mesh(name=name)
    ms.uservert = mesh.vertices.astype(np.float32).ravel().tolist()
    ms.userface = mesh.faces.ravel().tolist()
    if mesh.texcoords is not None:
        ms.usertexcoord = mesh.texcoords.ravel().tolist()
    ms.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL  # flat meshes have no volume
    ms.maxhullvert = 4  # no collisions here: keep the (unused) convex hull tiny
    parent = body if body is not None else spec.worldbody
    g = parent.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name, contype=0, conaffinity=0,
                        group=0)  # fmt: skip
    if material:
        g.material = material
    if rgba is not None:
        g.rgba = list(rgba)
    if stats is not None:
        stats.triangles[name] = mesh.n_faces
    return g


def _add_texture(spec: mujoco.MjSpec, name: str, image: np.ndarray) -> None:
    img = np.ascontiguousarray(image[::-1])  # MuJoCo: first row = v 0 = bottom
    h, w = img.shape[:2]
    tex = spec.add_texture(name=name, type=mujoco.mjtTexture.mjTEXTURE_2D, width=w, height=h, nchannel=3)
    tex.data = img.tobytes()


def _add_material(spec: mujoco.MjSpec, name: str, rgba, texture: str | None = None, emission: float = 0.0,
                  specular: float = 0.1, shininess: float = 0.2, texrepeat=(1.0, 1.0), texuniform: bool = False):  # fmt: skip
    mat = spec.add_material(name=name)
    mat.rgba = list(rgba)
    mat.emission = emission
    mat.specular = specular
    mat.shininess = shininess
    mat.reflectance = 0.0
    if texture:
        mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = texture
        mat.texrepeat = list(texrepeat)
        mat.texuniform = texuniform
    return mat


def _visual_settings(spec: mujoco.MjSpec, p: SceneParams) -> None:
    spec.modelname = "cosim_world"
    spec.stat.extent = _EXTENT
    spec.stat.center = [0.0, 0.0, 0.0]
    vis = spec.visual
    vis.global_.offwidth = p.max_width
    vis.global_.offheight = p.max_height
    vis.map.znear = p.znear_m / _EXTENT
    vis.map.zfar = p.draw_distance_m / _EXTENT
    vis.map.fogstart = p.fog_start_m / _EXTENT
    vis.map.fogend = p.fog_end_m / _EXTENT
    vis.quality.offsamples = p.msaa_samples
    vis.quality.shadowsize = 0
    vis.headlight.ambient = [0.42, 0.42, 0.44]
    vis.headlight.diffuse = [0.25, 0.25, 0.25]
    vis.headlight.specular = [0.0, 0.0, 0.0]
    vis.rgba.fog = [0.74, 0.82, 0.90, 1.0]
    vis.rgba.haze = [0.74, 0.82, 0.90, 1.0]


def _lane_meshes(net, origin: np.ndarray, p: SceneParams, signs) -> tuple[geo.MeshData, geo.MeshData, dict]:
    """(road surfaces incl. junctions, markings, counts)."""
    roads: list[geo.MeshData] = []
    marks: list[geo.MeshData] = []
    edges = [e for e in net.getEdges() if e.getFunction() != "internal"]
    pair = {(e.getFromNode().getID(), e.getToNode().getID()): e for e in edges}
    stop_edges = {s.edge for s in signs if s.kind in ("stop", "allway_stop", "traffic_light")}
    n_lanes = 0
    for e in edges:
        lanes = e.getLanes()
        etype = e.getType() or ""
        minor = "service" in etype or "track" in etype
        shapes = [_shape_xy(lane, origin) for lane in lanes]
        widths = [lane.getWidth() for lane in lanes]
        for shp, wd in zip(shapes, widths, strict=True):
            roads.append(geo.strip(shp, wd, ROAD_Z))
            n_lanes += 1
        if not p.lane_markings or minor:
            continue
        for i in range(1, len(lanes)):  # dashed dividers between lanes of one direction
            marks.append(geo.dashes(shapes[i - 1], 0.12, MARK_Z, 3.0, 6.0, offset_m=0.5 * widths[i - 1]))
        rev = pair.get((e.getToNode().getID(), e.getFromNode().getID()))
        if rev is not None and e.getID() < rev.getID():  # centre line of a two-way road, once
            marks.append(geo.dashes(shapes[-1], 0.12, MARK_Z, 4.0, 8.0, offset_m=0.5 * widths[-1] + 0.0))
        if any(k in etype for k in ("trunk", "primary", "secondary", "tertiary", "motorway")):
            marks.append(geo.strip(shapes[0], 0.12, MARK_Z, offset_m=-0.5 * widths[0] + 0.15))  # edge line
        if e.getID() in stop_edges and e.getLength() > 5.0:  # not on stubs inside joined junctions
            for shp, wd in zip(shapes, widths, strict=True):
                marks.append(geo.bar_across(shp, wd - 0.2, 0.4, MARK_Z))
    polys = []
    for node in net.getNodes():
        shp = node.getShape()
        if len(shp) < 3:
            continue
        poly = shapely.make_valid(shapely.Polygon([q[:2] for q in shp]))
        parts = [g for g in getattr(poly, "geoms", [poly]) if g.geom_type == "Polygon" and g.area > 0.05]
        polys.extend(shapely.affinity.translate(g, -origin[0], -origin[1]) for g in parts)
    roads.append(geo.flat_polygons(np.asarray(polys, dtype=object), ROAD_Z))
    return geo.merge(roads), geo.merge(marks), {"lanes": n_lanes, "junction_polygons": len(polys)}


def _sign_meshes(
    signs, origin: np.ndarray
) -> tuple[geo.MeshData, geo.MeshData, geo.MeshData, textures.SignAtlas, int]:
    """(faces textured from the atlas, backs, posts, atlas, count)."""
    drawn = [s for s in signs if s.kind in SIGN_KINDS_DRAWN]
    keys = [f"speed:{round(s.value)}" if s.kind == "speed_limit" and s.value else s.kind for s in drawn]
    keep = [i for i, k in enumerate(keys) if k != "speed_limit"]  # a speed limit without a value: skip
    drawn, keys = [drawn[i] for i in keep], [keys[i] for i in keep]
    if not drawn:
        empty = geo.merge([])
        return empty, empty, empty, textures.sign_atlas(["one_way"]), 0
    atlas = textures.sign_atlas(keys)
    outlines = {
        "stop": geo.regular_polygon(8, 0.42, math.pi / 8),
        "allway_stop": geo.regular_polygon(8, 0.42, math.pi / 8),
        "give_way": np.array([[0.0, -0.45], [0.52, 0.35], [-0.52, 0.35]]),
        "round": geo.regular_polygon(20, 0.33),
        "one_way": np.array([[-0.3, -0.3], [0.3, -0.3], [0.3, 0.3], [-0.3, 0.3]]),
        "city_limit": np.array([[-0.5, -0.35], [0.5, -0.35], [0.5, 0.35], [-0.5, 0.35]]),
    }
    # signs at the same spot and heading are stacked on one post, in this order from the top
    order = {
        "stop": 0,
        "allway_stop": 0,
        "give_way": 0,
        "no_entry": 1,
        "speed_limit": 2,
        "one_way": 3,
        "city_limit": 4,
    }
    groups: dict[tuple, list[int]] = defaultdict(list)
    for i, s in enumerate(drawn):
        groups[(round(s.x_m * 2), round(s.y_m * 2), round(s.heading_deg / 10))].append(i)
    faces, backs, post_xy, post_h = [], [], [], []
    by_outline: dict[str, list[tuple[np.ndarray, float, tuple]]] = defaultdict(list)
    for members in groups.values():
        members.sort(key=lambda i: (order[drawn[i].kind], keys[i]))
        s0 = drawn[members[0]]
        x, y = s0.x_m - origin[0], s0.y_m - origin[1]
        top = 2.1 + 0.45 * (len(members) - 1)
        post_xy.append((x, y))
        post_h.append(top + 0.25)
        for rank, i in enumerate(members):
            s = drawn[i]
            yaw = math.radians(90.0 - s.heading_deg)
            facing = yaw + math.pi  # the face looks at the approaching traffic
            cx, cy = x + 0.06 * math.cos(facing), y + 0.06 * math.sin(facing)
            z = top - 0.9 * rank
            outline = s.kind if s.kind in outlines else "round"
            by_outline[outline].append((np.array([cx, cy, z]), facing, atlas.rects[keys[i]]))
    for name, items in by_outline.items():
        centres = np.array([c for c, _, _ in items])
        facing = np.array([f for _, f, _ in items])
        rects = np.array([r for _, _, r in items])
        faces.append(geo.upright_plates(outlines[name], centres, facing, rects))
        back_centres = centres - 0.015 * np.stack(
            [np.cos(facing), np.sin(facing), np.zeros(len(facing))], axis=1
        )
        backs.append(geo.upright_plates(outlines[name], back_centres, facing, back=True))
    post_meshes = [geo.posts(np.array([xy]), h) for xy, h in zip(post_xy, post_h, strict=True)]
    return geo.merge(faces), geo.merge(backs), geo.merge(post_meshes), atlas, len(drawn)


def _traffic_lights(net, origin: np.ndarray) -> tuple[list[Approach], geo.MeshData, geo.MeshData]:
    """One approach per (traffic light, incoming edge): its lamp positions, plus poles+housings and lenses."""
    links: dict[tuple[str, str], list[tuple[int, str]]] = defaultdict(list)
    edges: dict[str, object] = {}
    for e in net.getEdges():
        if e.getFunction() == "internal":
            continue
        for conns in e.getOutgoing().values():
            for c in conns:
                tls = c.getTLSID()
                if tls:
                    links[(tls, e.getID())].append((c.getTLLinkIndex(), c.getDirection()))
                    edges[e.getID()] = e
    approaches: list[Approach] = []
    housings, lenses = [], []
    housing_local = geo.box(-0.14, 0.14, -0.17, 0.17, 2.2, 3.2, skip_bottom=False)
    pole_local = geo.box(-0.05, 0.05, -0.05, 0.05, 0.0, 2.2)
    lens_outline = geo.regular_polygon(10, 0.11)
    for (tls, eid), lst in sorted(links.items()):
        lst.sort(key=lambda t: ({"s": 0, "r": 1, "l": 2}.get(t[1], 3), t[0]))
        e = edges[eid]
        shape = np.asarray([q[:2] for q in e.getShape()], dtype=np.float64) - origin
        half = 0.5 * sum(lane.getWidth() for lane in e.getLanes())
        x, y, yaw = _roadside(shape, half, 0.8, at_end=True, lefthand=net.lefthand)
        facing = yaw + math.pi
        fx, fy = math.cos(facing), math.sin(facing)
        housings.append(
            geo.placed(geo.merge([housing_local, pole_local]), np.array([[x, y]]), np.array([yaw]))
        )
        zs = (2.98, 2.70, 2.42)  # red, yellow, green
        lens_c = np.array([[x + 0.145 * fx, y + 0.145 * fy, z] for z in zs])
        lenses.append(geo.upright_plates(lens_outline, lens_c, np.full(3, facing)))
        lamp = np.array([[x + 0.13 * fx, y + 0.13 * fy, z] for z in zs])
        approaches.append(Approach(tls, lst[0][0], eid, lamp))
    return approaches, geo.merge(housings), geo.merge(lenses)


def _building_meshes(
    polys, heights, origin: np.ndarray, p: SceneParams
) -> tuple[list[geo.MeshData], geo.MeshData]:
    if not polys:
        return [], geo.merge([])
    arr = np.asarray([shapely.affinity.translate(g, -origin[0], -origin[1]) for g in polys], dtype=object)
    group = np.arange(len(arr)) % p.wall_tints
    walls = [geo.extrude_walls(arr[group == k], heights[group == k]) for k in range(p.wall_tints)]
    roofs = geo.flat_polygons(arr, heights)
    return walls, roofs


def build_scene(scenario, params: SceneParams | None = None, *, car=None, net=None) -> Scene:
    """Generate and compile the scene of a built scenario.

    scenario: a :class:`cosim.scenario.Scenario` or its directory (network.net.xml, buildings.poly.xml,
    signs.add.xml). car: the ego's :class:`cosim.ego_mujoco.CarParams` (sizes the visual ego; default car).
    net: an already loaded sumolib network of that scenario (saves re-reading it).
    """
    from cosim.ego_mujoco import CarParams
    from cosim.scenario.buildings import load_buildings
    from cosim.scenario.signs import load_signs
    from cosim.sumo_bridge.network import read_network

    t0 = time.perf_counter()
    p = params or SceneParams()
    sdir = Path(getattr(scenario, "dir", scenario))
    if net is None:
        net = read_network(sdir / "network.net.xml")
    (xmin, ymin), (xmax, ymax) = net.getBBoxXY()
    origin = np.array([round(0.5 * (xmin + xmax)), round(0.5 * (ymin + ymax))], dtype=np.float64)
    signs = load_signs(sdir / "signs.add.xml") if (sdir / "signs.add.xml").exists() else []
    polys, heights = (
        load_buildings(sdir / "buildings.poly.xml")
        if (sdir / "buildings.poly.xml").exists()
        else ([], np.zeros(0))
    )
    stats = SceneStats()

    spec = mujoco.MjSpec()
    _visual_settings(spec, p)
    spec.option.gravity = [0.0, 0.0, 0.0]
    _add_texture(spec, "grass", textures.ground())
    _add_texture(spec, "facade", textures.facade())
    _add_texture(spec, "display_on", textures.keep_distance_panel(True))
    _add_texture(spec, "display_off", textures.keep_distance_panel(False))
    spec.add_texture(name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX, builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
                     rgb1=[0.45, 0.62, 0.86], rgb2=[0.86, 0.91, 0.96], width=256, height=256)  # fmt: skip
    _add_material(
        spec, "grass", (1, 1, 1, 1), "grass", texrepeat=(1 / 12.0, 1 / 12.0), texuniform=True, specular=0.0
    )
    _add_material(spec, "road", (0.30, 0.30, 0.32, 1), specular=0.05)
    _add_material(spec, "marking", (0.93, 0.93, 0.90, 1), specular=0.05)
    for k in range(p.wall_tints):
        tint = (*_WALL_TINTS[k], 1.0)
        _add_material(spec, f"wall{k}", tint, "facade" if p.facade_texture else None, specular=0.05)
    _add_material(spec, "roof", (0.52, 0.30, 0.26, 1), specular=0.05)
    _add_material(spec, "metal", (0.45, 0.46, 0.48, 1), specular=0.3)
    _add_material(spec, "tl_housing", (0.12, 0.13, 0.12, 1), specular=0.2)
    _add_material(spec, "tl_lens", (0.05, 0.05, 0.04, 1), specular=0.6, shininess=0.8)
    _add_material(spec, "lamp", (1, 1, 1, 1), emission=1.0)
    _add_material(spec, "glass", (0.10, 0.12, 0.15, 1), specular=0.6, shininess=0.8)
    _add_material(spec, "car_paint", (1, 1, 1, 1), specular=0.4, shininess=0.5)
    _add_material(spec, "car_lamp", (1, 1, 1, 1), emission=0.7)
    _add_material(spec, "display_on", (1, 1, 1, 1), "display_on", emission=1.0)
    _add_material(spec, "display_off", (1, 1, 1, 1), "display_off")

    wb = spec.worldbody
    half = 0.5 * max(xmax - xmin, ymax - ymin) + p.ground_margin_m
    wb.add_geom(name="ground", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[half, half, 50.0], material="grass",
                contype=0, conaffinity=0)  # fmt: skip
    sun = wb.add_light(name="sun", pos=[0, 0, 500])
    sun.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
    sun.dir = list(np.array([0.35, 0.55, -0.76]) / np.linalg.norm([0.35, 0.55, -0.76]))
    sun.diffuse = [0.62, 0.60, 0.56]
    sun.specular = [0.15, 0.15, 0.15]
    sun.ambient = [0.0, 0.0, 0.0]
    sun.castshadow = False

    roads, marks, lane_counts = _lane_meshes(net, origin, p, signs)
    stats.counts.update(lane_counts)
    _add_mesh_geom(spec, "roads", roads, "road", stats=stats)
    _add_mesh_geom(spec, "markings", marks, "marking", stats=stats)

    walls, roofs = _building_meshes(polys, heights, origin, p)
    for k, w in enumerate(walls):
        _add_mesh_geom(spec, f"walls{k}", w, f"wall{k}", stats=stats)
    _add_mesh_geom(spec, "roofs", roofs, "roof", stats=stats)
    stats.counts["buildings"] = len(polys)

    faces, backs, sign_posts, atlas, n_signs = _sign_meshes(signs, origin)
    _add_texture(spec, "signs", atlas.image)
    _add_material(spec, "signs", (1, 1, 1, 1), "signs", specular=0.1)
    _add_mesh_geom(spec, "sign_faces", faces, "signs", stats=stats)
    _add_mesh_geom(spec, "sign_backs", backs, "metal", stats=stats)
    _add_mesh_geom(spec, "sign_posts", sign_posts, "metal", stats=stats)
    stats.counts["signs"] = n_signs

    approaches, housings, lenses = _traffic_lights(net, origin)
    _add_mesh_geom(spec, "tl_housings", housings, "tl_housing", stats=stats)
    _add_mesh_geom(spec, "tl_lenses", lenses, "tl_lens", stats=stats)
    for i, a in enumerate(approaches):
        wb.add_geom(name=f"lamp{i}", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.1, 0, 0], pos=list(a.lamp_pos[0]),
                    material="lamp", rgba=[0.3, 0.3, 0.3, 1], contype=0, conaffinity=0, group=HIDDEN_GROUP)  # fmt: skip
    stats.counts["approaches"] = len(approaches)

    # vehicles: one set of mesh assets for all SCVs, one for the ego
    c = car or CarParams()
    ego_shape = geo.CarShape(length_m=c.length_m, width_m=c.width_m, height_m=c.height_m,
                             wheel_radius_m=c.wheel_radius_m, wheelbase_m=c.wheelbase_m,
                             front_overhang_m=c.front_overhang_m)  # fmt: skip
    scv_shape = geo.CarShape(length_m=p.scv_length_m)
    for prefix, shape in (("scv", scv_shape), ("egocar", ego_shape)):
        body_m, dark_m, lamp_m = geo.car_meshes(shape, dashboard=prefix == "egocar")
        for part, mesh in (("body", body_m), ("dark", dark_m), ("lamps", lamp_m)):
            ms = spec.add_mesh(name=f"{prefix}_{part}")
            ms.uservert = mesh.vertices.astype(np.float32).ravel().tolist()
            ms.userface = mesh.faces.ravel().tolist()
            ms.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
            ms.maxhullvert = 4
    mats = {"body": "car_paint", "dark": "glass", "lamps": "car_lamp"}

    def car_body(name: str, prefix: str, rgba) -> mujoco.MjsBody:
        b = wb.add_body(name=name, mocap=True, pos=[0, 0, -50])
        for part in ("body", "dark", "lamps"):
            g = b.add_geom(name=f"{name}_{part}", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"{prefix}_{part}",
                           material=mats[part], contype=0, conaffinity=0, group=HIDDEN_GROUP, mass=0)  # fmt: skip
            if part != "dark":  # the dark parts keep their material's colour
                g.rgba = list(rgba if part == "body" else _BRAKE_OFF)
        return b

    for i in range(p.vehicle_pool):
        car_body(f"car{i}", "scv", (0.7, 0.7, 0.7, 1))
    ego = car_body("ego", "egocar", p.ego_rgba)
    eye = np.array(p.driver_eye_m)
    if net.lefthand:  # where traffic keeps left the driver sits on the right
        eye[1] = -eye[1]
    ego.add_camera(name="driver", pos=list(eye), quat=list(_camera_quat(np.array([1.0, 0.0, -0.03]))),
                   fovy=p.driver_fovy_deg)  # fmt: skip
    pitch = math.radians(p.chase_pitch_deg)
    ego.add_camera(name="chase", pos=[-p.chase_distance_m, 0.0, p.chase_height_m],
                   quat=list(_camera_quat(np.array([math.cos(pitch), 0.0, -math.sin(pitch)]))), fovy=55.0)  # fmt: skip

    # system A's display: a panel in the rear window of a car of SCV size (faces backwards)
    ms = spec.add_mesh(name="display_panel")
    hl = 0.5 * scv_shape.length_m
    panel = geo.quads(np.array([[[-hl - 0.03, 0.45, 0.50], [-hl - 0.03, -0.45, 0.50], [-hl - 0.03, -0.45, 0.78],
                                 [-hl - 0.03, 0.45, 0.78]]]), np.array([[[0, 0], [1, 0], [1, 1], [0, 1]]]))  # fmt: skip
    ms.uservert = panel.vertices.astype(np.float32).ravel().tolist()
    ms.userface = panel.faces.ravel().tolist()
    ms.usertexcoord = panel.texcoords.ravel().tolist()
    ms.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
    ms.maxhullvert = 4
    disp = wb.add_body(name="rear_display", mocap=True, pos=[0, 0, -50])
    disp.add_geom(name="rear_display", type=mujoco.mjtGeom.mjGEOM_MESH, meshname="display_panel",
                  material="display_off", contype=0, conaffinity=0, group=HIDDEN_GROUP, mass=0)  # fmt: skip

    scene = Scene(spec, origin, p, approaches, stats)
    scene.net = net  # the sumolib network the scene was built from (lane speeds, ids)
    stats.ngeom, stats.nmesh = scene.model.ngeom, scene.model.nmesh
    stats.build_s = round(time.perf_counter() - t0, 3)
    return scene

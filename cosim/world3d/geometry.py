"""Triangle meshes for the 3D scene, built with numpy and shapely only (no MuJoCo import).

Everything here works in SCENE coordinates: network x/y [m] minus the scene origin (see scene.py), z up,
the road surface near z = 0. Faces are counter-clockwise seen from outside (MuJoCo culls back faces), and
every flat face has its own vertices so that MuJoCo's normals stay sharp at the edges.

Static objects of one look (all road surfaces, all walls of one tint, all sign faces ...) are merged into
one mesh: a renderer's cost grows with the number of draw calls much faster than with triangles, so a map
of thousands of lanes and buildings becomes a handful of meshes.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import shapely


@dataclass(frozen=True, eq=False)
class MeshData:
    """One triangle mesh."""

    vertices: np.ndarray  # (V, 3) float64 [m] scene coordinates
    faces: np.ndarray  # (F, 3) int32 vertex indices, counter-clockwise seen from outside
    texcoords: np.ndarray | None = None  # (V, 2) float32 texture coordinates (u, v), or None

    def __post_init__(self) -> None:
        v = np.asarray(self.vertices, dtype=np.float64).reshape(-1, 3)
        f = np.asarray(self.faces, dtype=np.int32).reshape(-1, 3)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise ValueError(f"MeshData: face index out of range (0..{len(v) - 1})")
        if self.texcoords is not None:
            t = np.asarray(self.texcoords, dtype=np.float32).reshape(-1, 2)
            if len(t) != len(v):
                raise ValueError(f"MeshData: {len(t)} texcoords for {len(v)} vertices")
            object.__setattr__(self, "texcoords", t)

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    @property
    def empty(self) -> bool:
        return len(self.faces) == 0


def merge(meshes: Iterable[MeshData]) -> MeshData:
    """One mesh from many (texcoords kept only if every part has them)."""
    parts = [m for m in meshes if not m.empty]
    if not parts:
        return MeshData(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32))
    offsets = np.cumsum([0] + [len(m.vertices) for m in parts[:-1]])
    verts = np.concatenate([m.vertices for m in parts])
    faces = np.concatenate([m.faces + o for m, o in zip(parts, offsets, strict=True)])
    uv = None
    if all(m.texcoords is not None for m in parts):
        uv = np.concatenate([m.texcoords for m in parts])
    return MeshData(verts, faces, uv)


def quads(corners: np.ndarray, uv: np.ndarray | None = None) -> MeshData:
    """Independent quads: corners (Q, 4, 3) counter-clockwise seen from the front; uv (Q, 4, 2) or None."""
    c = np.asarray(corners, dtype=np.float64).reshape(-1, 4, 3)
    base = 4 * np.arange(len(c), dtype=np.int32)[:, None]
    faces = np.concatenate([base + (0, 1, 2), base + (0, 2, 3)], axis=1).reshape(-1, 3)
    return MeshData(c.reshape(-1, 3), faces, None if uv is None else np.asarray(uv).reshape(-1, 2))


# -- polylines -------------------------------------------------------------------------------------------------
def clean_polyline(xy: np.ndarray, min_seg_m: float = 1e-3) -> np.ndarray:
    """Drop points closer than ``min_seg_m`` to their predecessor. xy: (M, 2) [m]."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if len(xy) < 2:
        return xy
    keep = np.concatenate([[True], np.hypot(*np.diff(xy, axis=0).T) > min_seg_m])
    return xy[keep]


def offset_polyline(xy: np.ndarray, offset_m: float | np.ndarray, max_miter: float = 2.0) -> np.ndarray:
    """The polyline shifted sideways (left positive) with mitred joints. xy: (M>=2, 2); returns (M, 2).

    ``offset_m`` is a scalar or (M,) per point; the miter factor is capped at ``max_miter`` so that a sharp
    corner does not throw a vertex far away.
    """
    d = np.diff(xy, axis=0)
    seg = np.hypot(d[:, 0], d[:, 1])[:, None]
    n = np.stack([-d[:, 1], d[:, 0]], axis=1) / np.maximum(seg, 1e-12)  # left normals per segment
    vn = np.empty_like(xy)
    vn[0], vn[-1] = n[0], n[-1]
    if len(xy) > 2:
        avg = n[:-1] + n[1:]
        norm = np.hypot(avg[:, 0], avg[:, 1])[:, None]
        avg = np.where(norm > 1e-9, avg / np.maximum(norm, 1e-12), n[1:])
        cos_half = np.einsum("ij,ij->i", avg, n[1:])[:, None]
        vn[1:-1] = avg / np.maximum(cos_half, 1.0 / max_miter)
    off = np.asarray(offset_m, dtype=np.float64).reshape(-1, 1)
    return xy + vn * off


def strip(xy: np.ndarray, width_m: float, z_m: float, offset_m: float = 0.0) -> MeshData:
    """A flat band of ``width_m`` along a polyline (its centre ``offset_m`` to the left), facing up."""
    xy = clean_polyline(xy)
    if len(xy) < 2:
        return MeshData(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32))
    left = offset_polyline(xy, offset_m + 0.5 * width_m)
    right = offset_polyline(xy, offset_m - 0.5 * width_m)
    m = len(xy)
    verts = np.empty((2 * m, 3))
    verts[0::2, :2], verts[1::2, :2] = right, left
    verts[:, 2] = z_m
    i = 2 * np.arange(m - 1, dtype=np.int32)[:, None]  # right_i = i, left_i = i + 1
    faces = np.concatenate([i + (0, 2, 3), i + (0, 3, 1)], axis=1).reshape(-1, 3)
    return MeshData(verts, faces)


def dashes(
    xy: np.ndarray, width_m: float, z_m: float, dash_m: float, gap_m: float, offset_m: float = 0.0,
    margin_m: float = 0.0,
) -> MeshData:  # fmt: skip
    """Dashed line marks along a polyline: straight quads of ``dash_m`` every ``dash_m + gap_m``."""
    xy = clean_polyline(xy)
    if len(xy) < 2:
        return MeshData(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32))
    line = offset_polyline(xy, offset_m) if offset_m else xy
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(line, axis=0).T))])
    length = s[-1] - 2 * margin_m
    if length < dash_m:
        return MeshData(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32))
    period = dash_m + gap_m
    n = int((length - dash_m) // period) + 1
    s0 = margin_m + 0.5 * (length - (n - 1) * period - dash_m) + period * np.arange(n)  # centred on the line
    s1 = s0 + dash_m
    p0 = np.stack([np.interp(s0, s, line[:, 0]), np.interp(s0, s, line[:, 1])], axis=1)
    p1 = np.stack([np.interp(s1, s, line[:, 0]), np.interp(s1, s, line[:, 1])], axis=1)
    d = p1 - p0
    n_left = np.stack([-d[:, 1], d[:, 0]], axis=1) / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)[:, None]
    h = 0.5 * width_m * n_left
    corners = np.zeros((n, 4, 3))
    corners[:, 0, :2], corners[:, 1, :2] = p0 - h, p1 - h
    corners[:, 2, :2], corners[:, 3, :2] = p1 + h, p0 + h
    corners[:, :, 2] = z_m
    return quads(corners)


def bar_across(xy: np.ndarray, width_m: float, depth_m: float, z_m: float, at_end: bool = True) -> MeshData:
    """A bar across the end (or start) of a polyline, e.g. a stop line: ``width_m`` across, ``depth_m`` along."""
    xy = clean_polyline(xy)
    if len(xy) < 2:
        return MeshData(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32))
    a, b = (xy[-2], xy[-1]) if at_end else (xy[1], xy[0])
    u = (b - a) / max(float(np.hypot(*(b - a))), 1e-9)
    n = np.array([-u[1], u[0]])
    back = b - u * depth_m  # the bar ends at the line's end
    c = np.array([back - n * width_m / 2, b - n * width_m / 2, b + n * width_m / 2, back + n * width_m / 2])
    corners = np.concatenate([c, np.full((4, 1), z_m)], axis=1)[None]
    return quads(corners)


# -- polygons --------------------------------------------------------------------------------------------------
def _triangle_coords(polys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangulate polygons: ((T, 3, 2) float64 vertices CCW from above, (T,) index of the source polygon)."""
    tri_sets = shapely.constrained_delaunay_triangles(polys)
    tris, owner = shapely.get_parts(tri_sets, return_index=True)
    if len(tris) == 0:
        return np.zeros((0, 3, 2)), np.zeros(0, dtype=np.int64)
    coords = shapely.get_coordinates(tris).reshape(len(tris), 4, 2)[:, :3]  # closed rings: drop the repeat
    a, b, c = coords[:, 0], coords[:, 1], coords[:, 2]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    coords[cross < 0] = coords[cross < 0][:, ::-1]  # make every triangle counter-clockwise (normal up)
    keep = np.abs(cross) > 1e-9
    return coords[keep], owner[keep]


def flat_polygons(polys: Sequence[shapely.Polygon] | np.ndarray, z_m: float | np.ndarray) -> MeshData:
    """Polygons as horizontal surfaces facing up at height ``z_m`` (scalar or one per polygon)."""
    arr = np.asarray(polys, dtype=object)
    if arr.size == 0:
        return MeshData(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32))
    coords, owner = _triangle_coords(arr)
    z = np.broadcast_to(np.asarray(z_m, dtype=np.float64), (len(arr),))[owner]
    verts = np.concatenate([coords, np.repeat(z[:, None, None], 3, axis=1)], axis=2).reshape(-1, 3)
    faces = np.arange(len(verts), dtype=np.int32).reshape(-1, 3)
    return MeshData(verts, faces)


def extrude_walls(
    polys: Sequence[shapely.Polygon] | np.ndarray, heights_m: np.ndarray, bay_m: float = 3.5, storey_m: float = 3.0,
) -> MeshData:  # fmt: skip
    """The walls of extruded footprints, one quad per outline segment, facing outwards.

    Texture coordinates count window bays along a wall (u: a whole number of bays of about ``bay_m``) and
    storeys up it (v: whole storeys of about ``storey_m``), so a repeating facade texture puts whole windows
    on every wall.
    """
    arr = shapely.orient_polygons(np.asarray(polys, dtype=object), exterior_cw=False)  # holes clockwise
    if arr.size == 0:
        return MeshData(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32), np.zeros((0, 2)))
    rings, ring_owner = shapely.get_rings(arr, return_index=True)
    coords, ring_idx = shapely.get_coordinates(rings, return_index=True)
    same = ring_idx[:-1] == ring_idx[1:]  # consecutive points of one ring form a wall segment
    p0, p1 = coords[:-1][same], coords[1:][same]
    owner = ring_owner[ring_idx[:-1][same]]
    length = np.hypot(*(p1 - p0).T)
    ok = length > 1e-3
    p0, p1, owner, length = p0[ok], p1[ok], owner[ok], length[ok]
    h = np.asarray(heights_m, dtype=np.float64)[owner]
    n = len(p0)
    corners = np.zeros((n, 4, 3))
    corners[:, 0, :2], corners[:, 1, :2], corners[:, 2, :2], corners[:, 3, :2] = p0, p1, p1, p0
    corners[:, 2, 2] = corners[:, 3, 2] = h
    bays = np.maximum(1.0, np.round(length / bay_m))
    storeys = np.maximum(1.0, np.round(h / storey_m))
    uv = np.zeros((n, 4, 2))
    uv[:, 1, 0] = uv[:, 2, 0] = bays
    uv[:, 2, 1] = uv[:, 3, 1] = storeys
    return quads(corners, uv)


# -- solids ----------------------------------------------------------------------------------------------------
_HEX_FACES = ((0, 3, 2, 1), (4, 5, 6, 7), (1, 2, 6, 5), (0, 4, 7, 3), (0, 1, 5, 4), (3, 7, 6, 2))


def hexahedron(corners: np.ndarray, skip_bottom: bool = True) -> MeshData:
    """A six-faced solid from 8 corners: 0-3 the bottom counter-clockwise from above, 4-7 the top above them."""
    c = np.asarray(corners, dtype=np.float64).reshape(8, 3)
    faces = _HEX_FACES[1:] if skip_bottom else _HEX_FACES
    return quads(c[np.asarray(faces)])


def box(
    x0: float, x1: float, y0: float, y1: float, z0: float, z1: float, skip_bottom: bool = True
) -> MeshData:
    """An axis-aligned box."""
    c = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0]])
    top = c.copy()
    top[:, 2] = z1
    return hexahedron(np.concatenate([c, top]), skip_bottom)


def frustum(x0: float, x1: float, y_half: float, z0: float, z1: float, top_x0: float, top_x1: float,
            top_y_half: float) -> MeshData:  # fmt: skip
    """A box whose top face is smaller (a car's glasshouse): bottom [x0, x1] x [-y, y], top inset."""
    b = np.array([[x0, -y_half, z0], [x1, -y_half, z0], [x1, y_half, z0], [x0, y_half, z0]])
    t = np.array([[top_x0, -top_y_half, z1], [top_x1, -top_y_half, z1], [top_x1, top_y_half, z1],
                  [top_x0, top_y_half, z1]])  # fmt: skip
    return hexahedron(np.concatenate([b, t]))


def prism_y(cx: float, cz: float, radius: float, y0: float, y1: float, sides: int = 10) -> MeshData:
    """A polygonal cylinder along y (a wheel): centre (cx, cz), from y0 to y1."""
    a = 2 * np.pi * (np.arange(sides) + 0.5) / sides
    x, z = cx + radius * np.cos(a), cz + radius * np.sin(a)
    parts = []
    # side quads: outward normal; going around counter-clockwise seen from +y
    for i in range(sides):
        j = (i + 1) % sides
        parts.append(
            quads(np.array([[[x[i], y1, z[i]], [x[j], y1, z[j]], [x[j], y0, z[j]], [x[i], y0, z[i]]]]))
        )
    # caps: fan triangles; +y cap faces +y, -y cap faces -y
    for y, flip in ((y1, False), (y0, True)):
        v = np.stack([x, np.full(sides, y), z], axis=1)
        f = np.array([[0, i + 1, i] for i in range(1, sides - 1)], dtype=np.int32)
        parts.append(MeshData(v, f[:, ::-1] if flip else f))
    return merge(parts)


def regular_polygon(n: int, radius: float, rotation_rad: float = 0.0) -> np.ndarray:
    """(n, 2) corners counter-clockwise of a regular polygon centred on the origin."""
    a = rotation_rad + 2 * np.pi * np.arange(n) / n
    return np.stack([radius * np.cos(a), radius * np.sin(a)], axis=1)


def upright_plates(
    outline_uv: np.ndarray, centres: np.ndarray, facing_rad: np.ndarray, tex_rect: np.ndarray | None = None,
    back: bool = False,
) -> MeshData:  # fmt: skip
    """Flat vertical plates (sign faces), one per centre, all with the same convex outline.

    outline_uv: (K, 2) [m] counter-clockwise in the plate's own frame (u to the viewer's right, v up);
    centres: (N, 3) [m] plate centres; facing_rad: (N,) direction the face looks at (yaw, ccw from +x);
    tex_rect: (N, 4) (u0, v0, u1, v1) texture rectangle that the outline's bounding box maps to;
    back: build the reverse sides instead (facing away, no texture).
    """
    k = len(outline_uv)
    n = len(centres)
    if n == 0:
        return MeshData(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32))
    nx, ny = np.cos(facing_rad), np.sin(facing_rad)
    # the viewer looks along -normal; their right is the normal rotated +90 deg
    rx, ry = -ny, nx
    u, v = outline_uv[:, 0], outline_uv[:, 1]
    verts = np.empty((n, k, 3))
    verts[:, :, 0] = centres[:, None, 0] + rx[:, None] * u
    verts[:, :, 1] = centres[:, None, 1] + ry[:, None] * u
    verts[:, :, 2] = centres[:, None, 2] + v
    fan = np.array([[0, i, i + 1] for i in range(1, k - 1)], dtype=np.int32)
    if back:
        fan = fan[:, ::-1]
    faces = (fan[None] + k * np.arange(n, dtype=np.int32)[:, None, None]).reshape(-1, 3)
    uv = None
    if tex_rect is not None and not back:
        lo, hi = outline_uv.min(axis=0), outline_uv.max(axis=0)
        fu, fv = (u - lo[0]) / (hi[0] - lo[0]), (v - lo[1]) / (hi[1] - lo[1])
        r = np.asarray(tex_rect, dtype=np.float64)
        uv = np.empty((n, k, 2))
        uv[:, :, 0] = r[:, None, 0] + (r[:, None, 2] - r[:, None, 0]) * fu
        uv[:, :, 1] = r[:, None, 1] + (r[:, None, 3] - r[:, None, 1]) * fv
        uv = uv.reshape(-1, 2)
    return MeshData(verts.reshape(-1, 3), faces, uv)


def posts(xy: np.ndarray, height_m: float, half_m: float = 0.04) -> MeshData:
    """Square posts (sign poles) standing on the ground at each (x, y)."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if len(xy) == 0:
        return MeshData(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32))
    one = box(-half_m, half_m, -half_m, half_m, 0.0, height_m)
    nv = len(one.vertices)
    verts = (one.vertices[None] + np.concatenate([xy, np.zeros((len(xy), 1))], axis=1)[:, None]).reshape(
        -1, 3
    )
    faces = (one.faces[None] + nv * np.arange(len(xy), dtype=np.int32)[:, None, None]).reshape(-1, 3)
    return MeshData(verts, faces)


def placed(mesh: MeshData, xy: np.ndarray, yaw_rad: np.ndarray, z_m: float | np.ndarray = 0.0) -> MeshData:
    """Copies of a local mesh (x forward) rotated by yaw and moved to each (x, y, z)."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    n = len(xy)
    if n == 0 or mesh.empty:
        return MeshData(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32))
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    v = mesh.vertices
    out = np.empty((n, len(v), 3))
    out[:, :, 0] = xy[:, None, 0] + c[:, None] * v[:, 0] - s[:, None] * v[:, 1]
    out[:, :, 1] = xy[:, None, 1] + s[:, None] * v[:, 0] + c[:, None] * v[:, 1]
    out[:, :, 2] = np.broadcast_to(np.asarray(z_m, dtype=np.float64), (n,))[:, None] + v[:, 2]
    faces = (mesh.faces[None] + len(v) * np.arange(n, dtype=np.int32)[:, None, None]).reshape(-1, 3)
    uv = None if mesh.texcoords is None else np.tile(mesh.texcoords, (n, 1))
    return MeshData(out.reshape(-1, 3), faces, uv)


# -- vehicles --------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CarShape:
    """Proportions of the low-polygon car body (local frame: origin at the footprint centre on the road,
    x forward, y left, z up)."""

    length_m: float = 4.5
    width_m: float = 1.8
    height_m: float = 1.45
    wheel_radius_m: float = 0.31
    wheelbase_m: float = 2.65
    front_overhang_m: float = 0.9
    hood_m: float = 1.15  # [m] front bumper to the windscreen base
    trunk_m: float = 0.55  # [m] rear bumper to the rear window base
    beltline_m: float = 0.92  # [m] height of the body's top (bonnet, window sills)

    def __post_init__(self) -> None:
        for name in ("length_m", "width_m", "height_m", "wheel_radius_m", "wheelbase_m", "hood_m", "trunk_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"CarShape.{name} must be > 0, got {getattr(self, name)!r}")
        if self.hood_m + self.trunk_m >= self.length_m - 0.5:
            raise ValueError("CarShape: hood_m + trunk_m leave no room for the cabin")
        if not self.wheel_radius_m < self.beltline_m < self.height_m:
            raise ValueError("CarShape: need wheel_radius_m < beltline_m < height_m")


def car_meshes(shape: CarShape, dashboard: bool = False) -> tuple[MeshData, MeshData, MeshData]:
    """(body in the car's colour, dark parts: glasshouse + wheels, the two rear lamps) of one car.

    The glasshouse is closed, so from a camera inside it all its faces are back faces and are culled: the
    driver looks out through it. ``dashboard`` adds a dark dashboard under the windscreen (for the ego),
    which hides the body's top and bonnet from the driver's eye as a real dashboard does.
    """
    p = shape
    hl, hw = 0.5 * p.length_m, 0.5 * p.width_m
    sill = 0.28  # [m] underbody above the road
    cab_x0, cab_x1 = -hl + p.trunk_m, hl - p.hood_m
    # body: a box up to the beltline behind the windscreen, and a bonnet sloping down to the front
    rear = box(-hl, cab_x1, -hw, hw, sill, p.beltline_m)
    nose_z = p.beltline_m - 0.2
    corners = np.array([
        [cab_x1, -hw, sill], [hl, -hw, sill], [hl, hw, sill], [cab_x1, hw, sill],
        [cab_x1, -hw, p.beltline_m], [hl, -hw, nose_z], [hl, hw, nose_z], [cab_x1, hw, p.beltline_m],
    ])  # fmt: skip
    body = merge([rear, hexahedron(corners)])
    glass = frustum(cab_x0, cab_x1, hw - 0.06, p.beltline_m, p.height_m - 0.05, cab_x0 + 0.45, cab_x1 - 0.55,
                    hw - 0.18)  # fmt: skip
    roof = box(cab_x0 + 0.45, cab_x1 - 0.55, -(hw - 0.18), hw - 0.18, p.height_m - 0.05, p.height_m)
    xf = hl - p.front_overhang_m
    xr = xf - p.wheelbase_m
    r = p.wheel_radius_m
    wheels = [
        prism_y(x, r, r, y0, y1)
        for x in (xf, xr)
        for (y0, y1) in ((hw - 0.22, hw + 0.01), (-hw - 0.01, -hw + 0.22))
    ]
    lamp_z0, lamp_z1 = 0.62, 0.8
    lamps = merge([
        box(-hl - 0.02, -hl + 0.02, hw - 0.38, hw - 0.08, lamp_z0, lamp_z1),  # left
        box(-hl - 0.02, -hl + 0.02, -hw + 0.08, -hw + 0.38, lamp_z0, lamp_z1),  # right
    ])  # fmt: skip
    dark = [glass, *wheels]
    if dashboard:
        dark.append(box(cab_x1 - 1.5, cab_x1, -hw - 0.01, hw + 0.01, p.beltline_m - 0.1, p.beltline_m + 0.02))
    return merge([body, roof]), merge(dark), lamps

"""The static map of a scenario as one ``foxglove.SceneUpdate`` (the ``/map`` topic, logged once at t = 0).

The geometry is the 3D view's (``cosim.world3d.scene``: road surfaces from the lane shapes and junction
polygons, lane markings, building walls extruded to their height and roofs, sign posts and faces, traffic
light poles and housings), in the network frame (``frame_id`` "map", the frame of ``/scene``'s vehicles).
Each part is one entity with a triangle list; the sign faces are coloured from the 3D view's sign atlas,
and every sign gets a text label. Built by the log writer process (``McapLog.write_deferred``), so the
simulation does not wait for it.
"""

from __future__ import annotations

import hashlib
import math
import os
import tempfile
from pathlib import Path

import numpy as np

FRAME = "map"
_ROAD = (0.30, 0.30, 0.32, 1.0)
_MARK = (0.93, 0.93, 0.90, 1.0)
_WALL = (0.92, 0.86, 0.78, 1.0)
_ROOF = (0.52, 0.30, 0.26, 1.0)
_METAL = (0.45, 0.46, 0.48, 1.0)
_HOUSING = (0.12, 0.13, 0.12, 1.0)
_LENS = (0.25, 0.25, 0.22, 1.0)
_LABEL = (0.05, 0.05, 0.05, 1.0)
_IDENTITY = {
    "position": {"x": 0.0, "y": 0.0, "z": 0.0},
    "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
}
_EMPTY_PRIMITIVES = ("arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts", "models")
SIGN_LABELS = {"stop": "STOP", "allway_stop": "ALL-WAY STOP", "give_way": "GIVE WAY", "traffic_light": "LIGHT",
               "one_way": "ONE WAY", "no_entry": "NO ENTRY", "city_limit": "CITY LIMIT"}  # fmt: skip


def _color(rgba) -> dict:
    r, g, b, a = (round(float(c), 3) for c in rgba)
    return {"r": r, "g": g, "b": b, "a": a}


def _points(vertices: np.ndarray) -> list[dict]:
    v = np.round(np.asarray(vertices, dtype=np.float64), 3).tolist()
    return [{"x": x, "y": y, "z": z} for x, y, z in v]


def triangles(mesh, rgba, vertex_rgba: np.ndarray | None = None) -> dict:
    """A ``foxglove.TriangleListPrimitive`` of a ``MeshData`` (indexed, one colour or one per vertex)."""
    return {
        "pose": _IDENTITY, "points": _points(mesh.vertices), "color": _color(rgba),
        "colors": [] if vertex_rgba is None else [_color(c) for c in vertex_rgba],
        "indices": mesh.faces.ravel().tolist(),
    }  # fmt: skip


def entity(entity_id: str, **primitives) -> dict:
    out = {"timestamp": {"sec": 0, "nsec": 0}, "frame_id": FRAME, "id": entity_id,
           "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": False, "metadata": []}  # fmt: skip
    for name in _EMPTY_PRIMITIVES:
        out[name] = primitives.get(name, [])
    return out


def _atlas_colors(mesh, atlas, cell: int = 128) -> np.ndarray:
    """Per-vertex colours of textured sign faces: the atlas pixel a third of the way from the vertex's
    texture coordinate to its cell's centre (inside the sign's border colour)."""
    img = atlas.image
    h, w = img.shape[:2]
    px = mesh.texcoords[:, 0] * w
    py = (1.0 - mesh.texcoords[:, 1]) * h  # MuJoCo's v runs up from the bottom row
    cx = (np.floor(np.clip(px, 0, w - 1) / cell) + 0.5) * cell
    cy = (np.floor(np.clip(py, 0, h - 1) / cell) + 0.5) * cell
    sx = np.clip(px + (cx - px) / 3, 0, w - 1).astype(int)
    sy = np.clip(py + (cy - py) / 3, 0, h - 1).astype(int)
    rgb = img[sy, sx, :3].astype(np.float64) / 255.0
    return np.concatenate([rgb, np.ones((len(rgb), 1))], axis=1)


def map_entities(scenario_dir: str | Path) -> list[dict]:
    """The scenario's static scene entities (see the module doc)."""
    from cosim.scenario.buildings import load_buildings
    from cosim.scenario.signs import load_signs
    from cosim.sumo_bridge.network import read_network
    from cosim.world3d import geometry as geo
    from cosim.world3d.scene import (
        SceneParams,
        _building_meshes,
        _lane_meshes,
        _sign_meshes,
        _traffic_lights,
    )

    sdir = Path(scenario_dir)
    net = read_network(sdir / "network.net.xml")
    origin = np.zeros(2)  # the network frame, like /scene
    params = SceneParams(wall_tints=1)
    signs = load_signs(sdir / "signs.add.xml") if (sdir / "signs.add.xml").exists() else []
    out = []
    roads, marks, _ = _lane_meshes(net, origin, params, signs)
    out.append(entity("roads", triangles=[triangles(roads, _ROAD)]))
    if not marks.empty:
        out.append(entity("lane_markings", triangles=[triangles(marks, _MARK)]))
    if (sdir / "buildings.poly.xml").exists():
        polys, heights = load_buildings(sdir / "buildings.poly.xml")
        walls, roofs = _building_meshes(polys, heights, origin, params)
        if polys:
            out.append(
                entity("buildings", triangles=[triangles(geo.merge(walls), _WALL), triangles(roofs, _ROOF)])
            )
    faces, backs, posts, atlas, n_signs = _sign_meshes(signs, origin)
    if n_signs:
        texts = []
        for s in signs:
            label = (
                f"{round(s.value)} km/h" if s.kind == "speed_limit" and s.value else SIGN_LABELS.get(s.kind)
            )
            if not label:
                continue
            yaw = math.radians(90.0 - s.heading_deg) + math.pi
            texts.append({
                "pose": {"position": {"x": round(s.x_m, 3), "y": round(s.y_m, 3), "z": 3.2},
                         "orientation": {"x": 0.0, "y": 0.0, "z": round(math.sin(yaw / 2), 6),
                                         "w": round(math.cos(yaw / 2), 6)}},
                "billboard": True, "font_size": 0.6, "scale_invariant": False, "color": _color(_LABEL), "text": label,
            })  # fmt: skip
        out.append(entity("signs", texts=texts, triangles=[
            triangles(geo.merge([backs, posts]), _METAL),
            triangles(faces, (1, 1, 1, 1), _atlas_colors(faces, atlas)),
        ]))  # fmt: skip
    _, housings, lenses = _traffic_lights(net, origin)
    if not housings.empty:
        out.append(
            entity("traffic_lights", triangles=[triangles(housings, _HOUSING), triangles(lenses, _LENS)])
        )
    return out


def signal_lamps(net) -> list[tuple[str, int, np.ndarray]]:
    """(traffic light id, link index, (3, 3) lamp centres red / yellow / green in the network frame) of
    every signalised approach, as the 3D view places its lamps; ``/scene`` lights the one SUMO shows."""
    from cosim.world3d.scene import _traffic_lights

    approaches, _, _ = _traffic_lights(net, np.zeros(2))
    return [(a.tls_id, a.link_index, np.round(a.lamp_pos, 3)) for a in approaches]


def map_scene_update(scenario_dir: str | Path) -> dict:
    """The ``/map`` message: ``foxglove.SceneUpdate`` of :func:`map_entities`."""
    return {"deletions": [], "entities": map_entities(scenario_dir)}


_SCENE_INPUTS = ("network.net.xml", "buildings.poly.xml", "signs.add.xml")


def _scene_digest(sdir: Path) -> str:
    """What the ``/map`` payload depends on: the code that draws and encodes it and the scenario's files
    (size and modification time: a scenario folder is written once, but a user may edit one)."""
    import shapely

    root = Path(__file__).resolve().parents[1]
    code = [Path(__file__).resolve(), root / "log" / "writer.py", root / "scenario" / "buildings.py",
            root / "scenario" / "signs.py", root / "sumo_bridge" / "network.py",
            *sorted((root / "world3d").glob("*.py"))]  # fmt: skip
    h = hashlib.sha256(f"{np.__version__} {shapely.__version__}".encode())
    for path in code:
        h.update(path.read_bytes())
    for name in _SCENE_INPUTS:
        st = (sdir / name).stat() if (sdir / name).exists() else None
        h.update(f"{name} {st.st_size} {st.st_mtime_ns}".encode() if st else f"{name} -".encode())
    return h.hexdigest()[:20]


def map_scene_json(scenario_dir: str | Path) -> bytes:
    """:func:`map_scene_update` as the log writes it (``cosim.log.writer.encode``), kept in the scenario's
    folder after its first drawing: every run and experiment participant on the scenario logs the same
    bytes, and drawing and encoding a town's map costs seconds of the log writer's time per run. Not kept
    where the folder is read-only."""
    from cosim.log.writer import encode

    sdir = Path(scenario_dir)
    cached = sdir / f"map_scene.{_scene_digest(sdir)}.json"
    try:
        return cached.read_bytes()
    except OSError:
        pass
    data = encode(map_scene_update(sdir))
    tmp = None
    try:  # whole or not at all: written beside, then renamed (runs in parallel may race; same bytes)
        fd, tmp = tempfile.mkstemp(dir=sdir, prefix=".map_scene.", suffix=".tmp")
        os.fchmod(fd, 0o644)  # as the scenario's other files
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, cached)
        tmp = None
        for old in sdir.glob("map_scene.*.json"):  # drawn by other code or from other files
            if old != cached:
                old.unlink(missing_ok=True)
    except OSError:
        pass
    finally:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
    return data

"""Building footprints, indexed once per run and shared: the radio's shadowing (``cosim.vanet``) and system
A's line of sight (``cosim.adas.rear_stereo``) query the same object.

Pure shapely / numpy; ``cosim.scenario.buildings.load_buildings`` reads the footprints from a scenario.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import shapely


class Buildings:
    """Footprints prepared for shadowing: oriented polygons, an STRtree and flat wall-edge arrays.

    Rings are oriented so that the right-hand normal (ey, -ex) of every edge points out of the material
    (exterior counter-clockwise, holes clockwise).
    """

    def __init__(self, polygons: Sequence[shapely.Polygon] = ()):
        parts: list[shapely.Polygon] = []
        stack = [g for g in polygons if g is not None and not g.is_empty]
        while stack:
            geom = stack.pop(0)
            if not geom.is_valid:
                geom = shapely.make_valid(geom)
            if isinstance(geom, shapely.Polygon):
                if geom.area > 0:
                    parts.append(geom)
            elif isinstance(geom, (shapely.MultiPolygon, shapely.GeometryCollection)):
                stack[:0] = list(shapely.get_parts(geom))
        # exterior counter-clockwise, holes clockwise
        parts = (
            list(shapely.orient_polygons(np.array(parts, dtype=object), exterior_cw=False)) if parts else []
        )
        self.polygons = np.array(parts, dtype=object)
        self.tree = shapely.STRtree(self.polygons)
        self.boundaries = shapely.boundary(self.polygons) if len(parts) else np.array([], dtype=object)
        for poly in parts:
            shapely.prepare(poly)
        x0, y0, x1, y1 = [], [], [], []
        for poly in parts:
            for ring in [poly.exterior, *poly.interiors]:
                c = np.asarray(ring.coords)
                x0.append(c[:-1, 0])
                y0.append(c[:-1, 1])
                x1.append(c[1:, 0])
                y1.append(c[1:, 1])
        cat = (lambda a: np.concatenate(a)) if x0 else (lambda a: np.zeros(0))
        self.ex0, self.ey0, self.ex1, self.ey1 = cat(x0), cat(y0), cat(x1), cat(y1)
        keep = (self.ex0 != self.ex1) | (self.ey0 != self.ey1)
        self.ex0, self.ey0, self.ex1, self.ey1 = (
            self.ex0[keep],
            self.ey0[keep],
            self.ex1[keep],
            self.ey1[keep],
        )
        self.edge_len = np.hypot(self.ex1 - self.ex0, self.ey1 - self.ey0)

    def __len__(self) -> int:
        return len(self.polygons)

    def containing_count(self, xy: np.ndarray) -> np.ndarray:
        """Number of footprints containing each point (n,2) -> (n,) int."""
        if len(self.polygons) == 0 or len(xy) == 0:
            return np.zeros(len(xy), dtype=np.int64)
        pts = shapely.points(xy)
        hit = self.tree.query(pts, predicate="within")[0]
        return np.bincount(hit, minlength=len(xy))

    def line_of_sight(self, x0_m: float, y0_m: float, x1_m: float, y1_m: float) -> bool:
        """True when the 2-D segment (x0, y0)-(x1, y1) touches no building footprint."""
        if len(self.polygons) == 0:
            return True
        seg = shapely.LineString([(x0_m, y0_m), (x1_m, y1_m)])
        return self.tree.query(seg, predicate="intersects").size == 0

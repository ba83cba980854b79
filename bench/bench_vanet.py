"""Benchmark of the VANET layer alone: ``python -m bench.bench_vanet [--quick] [--seconds S]``.

The bench's own input (not cosim's scenario pipeline): building footprints (ways with building=*) and the
motor-road centre lines (highway = primary ... residential and links) parsed straight from
/work/shared/data/osm/helsinki.osm.gz, projected to metres with an equirectangular projection around the
bounding-box centre. Synthetic vehicles drive along the road centre lines (1.75 m to the right, so the two
directions use different lanes), turning at random at junctions, with speed targets of 7-14 m/s, random stops
(traffic lights) and random departures that free World slots for new vehicles. Every vehicle is a station.

For each configuration it reports the wall time of ``VanetLayer.step`` per simulated second after a warm-up
(and the process CPU time, steadier on a shared machine)
(the visibility cache fills while vehicles cover the road network), the cold time over the warm-up, the real-
time factor, transmissions and links evaluated per simulated second and links per wall second.
"""

from __future__ import annotations

import argparse
import gzip
import math
import time
import xml.etree.ElementTree as ET
from collections import defaultdict
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import shapely

from cosim.vanet import VanetLayer, VanetParams
from cosim.world import World

OSM = Path("/work/shared/data/osm/helsinki.osm.gz")
MOTOR = {
    "motorway",
    "trunk",
    "primary",
    "secondary",
    "tertiary",
    "unclassified",
    "residential",
    "living_street",
    "motorway_link",
    "trunk_link",
    "primary_link",
    "secondary_link",
    "tertiary_link",
}
EARTH_RADIUS_M = 6_371_008.8


@dataclass
class OsmInput:
    buildings: list[shapely.Polygon]
    roads: list[np.ndarray]  # (k, 2) polylines between junctions [m]
    road_nodes: list[tuple[int, int]]  # (start junction, end junction) of each polyline
    bbox_m: tuple[float, float, float, float]


def load_osm(path: Path = OSM) -> OsmInput:
    """Buildings and motor-road segments (split at junctions) from an OSM XML file, in metres."""
    nodes: dict[int, tuple[float, float]] = {}
    bways: list[list[int]] = []
    rways: list[list[int]] = []
    with gzip.open(path) as fh:
        for _, el in ET.iterparse(fh, events=("end",)):
            if el.tag == "node":
                nodes[int(el.get("id"))] = (float(el.get("lat")), float(el.get("lon")))
                el.clear()
            elif el.tag == "way":
                tags = {t.get("k"): t.get("v") for t in el.findall("tag")}
                refs = [int(n.get("ref")) for n in el.findall("nd")]
                if "building" in tags:
                    bways.append(refs)
                elif tags.get("highway") in MOTOR:
                    rways.append(refs)
                el.clear()
    lat = np.array([v[0] for v in nodes.values()])
    lon = np.array([v[1] for v in nodes.values()])
    lat0, lon0 = 0.5 * (lat.min() + lat.max()), 0.5 * (lon.min() + lon.max())
    kx = math.radians(1.0) * EARTH_RADIUS_M * math.cos(math.radians(lat0))
    ky = math.radians(1.0) * EARTH_RADIUS_M

    def xy(ref: int) -> tuple[float, float]:
        la, lo = nodes[ref]
        return (lo - lon0) * kx, (la - lat0) * ky

    buildings = []
    for refs in bways:
        pts = [xy(r) for r in refs if r in nodes]
        if len(pts) >= 4:
            poly = shapely.Polygon(pts)
            if not poly.is_valid:
                poly = shapely.make_valid(poly)
            if not poly.is_empty and poly.area > 1.0:
                buildings.append(poly)
    # split roads at nodes shared by several ways (junctions)
    use = defaultdict(int)
    for refs in rways:
        for r in refs:
            use[r] += 1
    roads, ends = [], []
    for refs in rways:
        refs = [r for r in refs if r in nodes]
        cur = refs[:1]
        for r in refs[1:]:
            cur.append(r)
            if use[r] > 1 or r == refs[-1]:
                if len(cur) >= 2:
                    line = np.array([xy(c) for c in cur])
                    if np.hypot(*np.diff(line, axis=0).T).sum() > 1.0:
                        roads.append(line)
                        ends.append((cur[0], cur[-1]))
                cur = [r]
    x = (lon - lon0) * kx
    y = (lat - lat0) * ky
    return OsmInput(buildings, roads, ends, (x.min(), y.min(), x.max(), y.max()))


class RoadTraffic:
    """Vectorised synthetic vehicles on road polylines, written into a cosim World each step."""

    LANE_OFFSET_M = 1.75

    def __init__(self, osm: OsmInput, n: int, rng: np.random.Generator):
        self.rng = rng
        roads = osm.roads
        self.n_roads = len(roads)
        lens = [np.r_[0.0, np.cumsum(np.hypot(*np.diff(r, axis=0).T))] for r in roads]
        self.road_len = np.array([c[-1] for c in lens])
        # global flattened polylines; each road's arc length is offset by a gap so one searchsorted works
        self.base = np.r_[0.0, np.cumsum(self.road_len + 10.0)][:-1]
        self.px = np.concatenate([r[:, 0] for r in roads])
        self.py = np.concatenate([r[:, 1] for r in roads])
        self.gcum = np.concatenate([c + b for c, b in zip(lens, self.base, strict=True)])
        self.first_pt = np.r_[0, np.cumsum([len(r) for r in roads])][:-1]
        self.n_pts = np.array([len(r) for r in roads])
        at = defaultdict(list)  # junction -> [(road, direction leaving it)]
        for i, (a, b) in enumerate(osm.road_nodes):
            at[a].append((i, +1))
            at[b].append((i, -1))
        self.leaving = at
        self.ends = osm.road_nodes
        self.world = World(capacity=max(16, 1 << math.ceil(math.log2(n + 1))))
        self.n = n
        self.counter = 0
        cap = self.world.capacity
        self.road = np.zeros(cap, dtype=np.int64)
        self.dirn = np.ones(cap, dtype=np.int64)
        self.s = np.zeros(cap)
        self.v = np.zeros(cap)
        self.v_target = np.zeros(cap)
        self.stop_left = np.zeros(cap)
        for _ in range(n):
            self._spawn()

    def _spawn(self) -> None:
        w = self.world
        slot = w.add(f"veh{self.counter}", is_ego=self.counter == 0)
        self.counter += 1
        r = int(self.rng.choice(self.n_roads, p=self.road_len / self.road_len.sum()))
        self.road[slot] = r
        self.dirn[slot] = 1 if self.rng.random() < 0.5 else -1
        self.s[slot] = self.rng.uniform(0, self.road_len[r])
        self.v_target[slot] = self.rng.uniform(7.0, 14.0)
        self.v[slot] = self.v_target[slot] * self.rng.uniform(0.3, 1.0)
        self.stop_left[slot] = 0.0
        w.length_m[slot] = 4.5
        w.width_m[slot] = 1.8
        w.lane_index[slot] = 0

    def _pose(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        r = self.road[idx]
        fwd = self.dirn[idx] > 0
        arc = np.where(fwd, self.s[idx], self.road_len[r] - self.s[idx])
        key = self.base[r] + np.clip(arc, 0.0, self.road_len[r])
        j = np.searchsorted(self.gcum, key, side="right") - 1
        j = np.clip(j, self.first_pt[r], self.first_pt[r] + self.n_pts[r] - 2)
        dx, dy = self.px[j + 1] - self.px[j], self.py[j + 1] - self.py[j]
        seg = np.maximum(np.hypot(dx, dy), 1e-9)
        u = (key - self.gcum[j]) / seg
        x, y = self.px[j] + u * dx, self.py[j] + u * dy
        ux, uy = np.where(fwd, dx, -dx) / seg, np.where(fwd, dy, -dy) / seg
        # drive on the right of the centre line; compass heading: 0 = +y, clockwise
        x, y = x + uy * self.LANE_OFFSET_M, y - ux * self.LANE_OFFSET_M
        return x, y, np.degrees(np.arctan2(ux, uy)) % 360.0

    def step(self, k: int, dt: float) -> World:
        w = self.world
        w.step = k
        w.t_s = k * dt
        idx = np.flatnonzero(w.valid)
        rng = self.rng
        # stops (traffic lights): a few vehicles brake to a halt and wait
        start_stop = (self.stop_left[idx] <= 0) & (rng.random(idx.size) < 0.02 * dt)
        self.stop_left[idx[start_stop]] = rng.uniform(5.0, 30.0, int(start_stop.sum()))
        stopping = self.stop_left[idx] > 0
        target = np.where(stopping, 0.0, self.v_target[idx])
        v_old = self.v[idx]
        a = np.clip((target - v_old) / dt, -3.0, 2.0)
        v_new = np.maximum(v_old + a * dt, 0.0)
        self.stop_left[idx] = np.where(
            stopping & (v_new == 0.0), self.stop_left[idx] - dt, self.stop_left[idx]
        )
        self.v[idx] = v_new
        self.s[idx] += v_new * dt
        w.speed_mps[idx] = v_new
        w.accel_mps2[idx] = (v_new - v_old) / dt
        w.signals[idx] = np.where(a < -0.5, 1 << 3, 0)
        # end of a road: leave the world (3 %) or turn onto a random road at the junction
        for slot in idx[self.s[idx] >= self.road_len[self.road[idx]]].tolist():
            r, d = int(self.road[slot]), int(self.dirn[slot])
            junction = self.ends[r][1] if d > 0 else self.ends[r][0]
            options = [(rr, dd) for rr, dd in self.leaving[junction] if rr != r] or self.leaving[junction]
            if rng.random() < 0.03 or not options:
                w.remove(w.ids[slot])
                self._spawn()
                continue
            rr, dd = options[int(rng.integers(len(options)))]
            self.s[slot] -= self.road_len[r]
            self.s[slot] = min(self.s[slot], self.road_len[rr])
            self.road[slot], self.dirn[slot] = rr, dd
        idx = np.flatnonzero(w.valid)
        x, y, h = self._pose(idx)
        w.x_m[idx], w.y_m[idx], w.heading_deg[idx] = x, y, h
        return w


def run(osm: OsmInput, n: int, params: VanetParams, warm_s: float, seconds: float, seed: int = 7) -> dict:
    dt = 0.1
    traffic = RoadTraffic(osm, n, np.random.default_rng(seed))
    layer = VanetLayer(params, osm.buildings, np.random.default_rng(seed + 1))
    warm_steps, steps = round(warm_s / dt), round(seconds / dt)
    k = 0
    t_warm = 0.0
    for _ in range(warm_steps):
        w = traffic.step(k, dt)
        t0 = time.perf_counter()
        layer.step(w, k, dt)
        t_warm += time.perf_counter() - t0
        k += 1
    times, tx, links, rx_ok = [], 0, 0, 0
    cpu = 0.0  # process CPU time: less sensitive than wall time to other jobs on a shared machine
    phases: dict[str, float] = defaultdict(float)
    for _ in range(steps):
        w = traffic.step(k, dt)
        c0 = time.process_time()
        t0 = time.perf_counter()
        r = layer.step(w, k, dt)
        times.append(time.perf_counter() - t0)
        cpu += time.process_time() - c0
        for name, v in r.timing_s.items():
            phases[name] += v
        tx += int(r.stats["tx_count"][0])
        links += int(r.stats["links_evaluated"][0])
        rx_ok += int(r.stats["rx_count"][0])
        k += 1
    times = np.array(times)
    shadow = layer.aether.shadow
    return {
        "n": n,
        "warm_ms_per_sim_s": 1e3 * t_warm / max(warm_s, 1e-9),
        "ms_per_sim_s": 1e3 * times.sum() / seconds,
        "cpu_ms_per_sim_s": 1e3 * cpu / seconds,
        "ms_per_step_mean": 1e3 * times.mean(),
        "ms_per_step_p95": 1e3 * float(np.percentile(times, 95)),
        "rtf": seconds / times.sum(),
        "tx_per_sim_s": tx / seconds,
        "links_per_sim_s": links / seconds,
        "links_per_wall_s": links / times.sum(),
        "decoded_per_sim_s": rx_ok / seconds,
        "maps_built": getattr(shadow, "builds", 0),
        "cache_mb": getattr(shadow, "nbytes", 0) / 1e6,
        "phases_ms_per_sim_s": {k: 1e3 * v / seconds for k, v in phases.items()},
    }


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--seconds", type=float, default=20.0, help="measured simulated seconds per configuration"
    )
    ap.add_argument("--warm", type=float, default=40.0, help="warm-up simulated seconds (cache fill)")
    ap.add_argument("--quick", action="store_true", help="only the default configuration, shorter runs")
    ap.add_argument(
        "--sizes", type=str, default="100,500,1000", help="vehicle counts of the default configuration"
    )
    ap.add_argument("--default-only", action="store_true", help="skip the other channel configurations")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    osm = load_osm()
    print(
        f"input: {OSM.name}: {len(osm.buildings)} building footprints, {len(osm.roads)} road segments "
        f"({sum(np.hypot(*np.diff(r, axis=0).T).sum() for r in osm.roads) / 1000:.1f} km), "
        f"bbox {osm.bbox_m[2] - osm.bbox_m[0]:.0f} x {osm.bbox_m[3] - osm.bbox_m[1]:.0f} m, "
        f"parsed in {time.perf_counter() - t0:.1f} s"
    )
    base = VanetParams()
    sizes = [int(v) for v in args.sizes.split(",") if v]
    configs = [(f"los polar (default) N={n}", n, base) for n in sizes]
    if not (args.quick or args.default_only):
        ch = base.channel
        configs += [
            ("no shadowing N=1000", 1000, replace(base, channel=replace(ch, shadowing="none"))),
            ("veins polar N=1000", 1000, replace(base, channel=replace(ch, shadowing="veins"))),
            ("los polar + sinr N=1000", 1000, replace(base, channel=replace(ch, interference="sinr"))),
            ("los exact (shapely) N=100", 100, replace(base, channel=replace(ch, shadow_method="exact"))),
        ]
    warm, secs = (10.0, 10.0) if args.quick else (args.warm, args.seconds)
    cols = [("cold ms/sim-s", 13), ("ms/sim-s", 9), ("cpu", 6), ("ms/step", 8), ("p95", 6), ("RTF", 6)]
    cols += [("tx/sim-s", 9), ("links/sim-s", 12), ("links/wall-s", 13), ("maps", 7), ("cacheMB", 8)]
    hdr = f"{'configuration':30s} " + " ".join(f"{name:>{w}s}" for name, w in cols)
    print(hdr)
    print("-" * len(hdr))
    for name, n, params in configs:
        r = run(osm, n, params, warm, secs)
        vals = [
            f"{r['warm_ms_per_sim_s']:13.1f}",
            f"{r['ms_per_sim_s']:9.1f}",
            f"{r['cpu_ms_per_sim_s']:6.1f}",
            f"{r['ms_per_step_mean']:8.2f}",
            f"{r['ms_per_step_p95']:6.1f}",
            f"{r['rtf']:6.1f}",
            f"{r['tx_per_sim_s']:9.0f}",
            f"{r['links_per_sim_s']:12.0f}",
            f"{r['links_per_wall_s']:13.0f}",
            f"{r['maps_built']:7d}",
            f"{r['cache_mb']:8.1f}",
        ]
        print(f"{name:30s} " + " ".join(vals), flush=True)
        ph = ", ".join(f"{k} {v:.1f}" for k, v in r["phases_ms_per_sim_s"].items())
        print(f"{'':30s}   phases [ms/sim-s]: {ph}", flush=True)


if __name__ == "__main__":
    main()

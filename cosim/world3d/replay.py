"""``cosim render RUN.mcap``: watch a logged run from the driver's seat (or chase / top), as MP4 or PNGs.

The scene is rebuilt from the run's scenario: the log's metadata names it (``scenario_key``; found in the
scenario cache) and carries the run config (to rebuild it from the map when the cache was cleared).
Replayed topics:

- ``/ego/state`` (every step): the ego pose (front bumper -> centre with the config's car length), speed,
  leader id, lane (-> speed limit from the network);
- ``/traffic/vehicles`` (every ``log.traffic_every_steps``, 2 s by default): SCVs, interpolated between
  samples (vehicles in only one sample appear / vanish at the sample);
- ``/traffic/lights`` (on change): lamp colours;
- ``/adas/state`` (cosim.phases.adas, every step): which system the driver sees (``system``), system B's
  shown gap (``time_gap_displayed_s``, null = "no data") and colour (``b_level``), system A's display
  (``a_lit``; the HUD indicator when ``a_perceived``) and the experiment ``phase``. Logs of other layouts
  are read by their columns: a ``/adas/...`` topic with ``time_gap_s`` (+ ``level``) is system B, one with
  ``display_lit`` (+ ``perceived``) system A, a ``phase`` column names the phase. Missing topics are fine
  (plain runs). The latest record at or before a frame's time applies.

MP4 goes through ``imageio-ffmpeg`` (the optional extra ``cosim[video]``), which ships its own ffmpeg.
"""

from __future__ import annotations

import json
import math
import os
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import cosim.world3d.render as render_mod  # first: sets MUJOCO_GL before MuJoCo is imported
from cosim import frames
from cosim.errors import CosimError
from cosim.world3d.hud import LEVELS, HudState
from cosim.world3d.scene import SceneParams, build_scene
from cosim.world3d.state import EgoPose, FrameState, Interpolator, VehicleFrame

BRAKE_BIT = 1 << 3  # SUMO's brake-light signal bit
TOPICS = ("/ego/state", "/traffic/vehicles", "/traffic/lights")


@dataclass(frozen=True)
class RenderParams:
    camera: str = "driver"  # 'driver' | 'chase' | 'top'
    width: int = 1280  # [px] even (H.264 with yuv420p needs even sizes)
    height: int = 720  # [px]
    fps: float = 10.0  # [1/s] frames per simulated second (1 frame = 1/fps of simulated time)
    start_s: float | None = None  # [s] simulated time of the first frame (default: the ego's first record)
    end_s: float | None = None  # [s] last frame at or before this (default: the log's end)
    hud: bool = True
    scv_length_m: float = 5.0  # [m] SCV length for front-bumper -> centre (SUMO's passenger default)

    def __post_init__(self) -> None:
        if self.camera not in render_mod.CAMERAS:
            raise ValueError(f"camera must be one of {render_mod.CAMERAS}, got {self.camera!r}")
        if not 0.1 <= self.fps <= 120:
            raise ValueError(f"fps must be in [0.1, 120], got {self.fps}")
        if self.width < 16 or self.height < 16 or self.width % 2 or self.height % 2:
            raise ValueError(f"frame size must be even and >= 16 px, got {self.width}x{self.height}")
        if self.start_s is not None and self.end_s is not None and self.end_s < self.start_s:
            raise ValueError(f"end ({self.end_s} s) is before start ({self.start_s} s)")


def _col(cols: dict[str, np.ndarray], name: str, n: int, fill=np.nan) -> np.ndarray:
    return cols[name] if name in cols else np.full(n, fill)


class _Steps:
    """Values of a topic that hold from their record's time until the next record (latest at or before t)."""

    def __init__(self, t_s: np.ndarray, values: list) -> None:
        order = np.argsort(t_s, kind="stable")
        self.t = np.asarray(t_s, dtype=np.float64)[order]
        self.values = [values[i] for i in order]

    def at(self, t_s: float, default=None):
        k = int(np.searchsorted(self.t, t_s + 1e-9, side="right")) - 1
        return self.values[k] if k >= 0 else default


class LogReplay:
    """Frames of a logged run at any simulated time (``frame_at``), from the decoded log topics."""

    def __init__(self, topics: dict[str, dict[str, np.ndarray]], *, ego_length_m: float, scv_length_m: float = 5.0,
                 lane_speed=None) -> None:  # fmt: skip
        ego = topics.get("/ego/state")
        if not ego or "t_s" not in ego or len(ego["t_s"]) == 0:
            raise CosimError("the log has no /ego/state records: nothing to show from the ego's view")
        self.lane_speed = lane_speed or (lambda edge, lane: None)
        n = len(ego["t_s"])
        order = np.argsort(ego["t_s"], kind="stable")
        self.ego_t = ego["t_s"][order].astype(np.float64)
        cx, cy, yaw = frames.sumo_to_mujoco(
            ego["x_m"][order], ego["y_m"][order], ego["heading_deg"][order], ego_length_m
        )
        self.ego_x, self.ego_y = cx, cy
        self.ego_yaw = np.unwrap(yaw)
        self.ego_speed = _col(ego, "speed_mps", n, 0.0)[order].astype(np.float64)
        self.ego_brake = _col(ego, "brake", n, 0.0)[order].astype(np.float64)
        self.ego_leader = list(_col(ego, "leader_id", n, None)[order])
        self.ego_edge = list(_col(ego, "edge", n, "")[order])
        self.ego_lane = _col(ego, "lane_index", n, -1)[order].astype(np.float64)
        self._limits: dict[int, float | None] = {}
        # traffic samples
        self.samples: list[tuple[float, VehicleFrame]] = []
        tv = topics.get("/traffic/vehicles")
        if tv and len(tv.get("t_s", ())):
            t_all = tv["t_s"].astype(np.float64)
            m = len(t_all)
            heading = tv["heading_deg"].astype(np.float64)
            vx, vy, vyaw = frames.sumo_to_mujoco(tv["x_m"].astype(np.float64), tv["y_m"].astype(np.float64), heading,
                                                 scv_length_m)  # fmt: skip
            braking = (
                np.nan_to_num(_col(tv, "signals", m, 0).astype(np.float64)).astype(np.int64) & BRAKE_BIT
            ) != 0
            ids = tv["id"]
            for t in np.unique(t_all):
                sel = np.flatnonzero(t_all == t)
                self.samples.append((float(t), VehicleFrame(tuple(str(i) for i in ids[sel]), vx[sel], vy[sel],
                                                            vyaw[sel], braking[sel])))  # fmt: skip
        self._sample_t = np.array([t for t, _ in self.samples])
        self._interp: tuple[int, Interpolator] | None = None
        # traffic lights: state per light, changes only
        self.lights: dict[str, _Steps] = {}
        tl = topics.get("/traffic/lights")
        if tl and len(tl.get("t_s", ())):
            for lid in np.unique(tl["id"]):
                sel = np.flatnonzero(tl["id"] == lid)
                self.lights[str(lid)] = _Steps(tl["t_s"][sel], [str(s) for s in tl["state"][sel]])
        self.sys_b, self.sys_a, self.phase = self._find_adas(topics)

    @staticmethod
    def _find_adas(topics) -> tuple[_Steps | None, _Steps | None, _Steps | None]:
        """(system B: (gap or None, level, shown), system A: (lit or None, perceived), phase name) over time."""

        def num(v):
            return None if v is None or (isinstance(v, float) and math.isnan(v)) else float(v)

        sys_b = sys_a = phase = None
        state = topics.get("/adas/state")
        if state and "system" in state and "t_s" in state:  # cosim.phases.adas: one record per step
            t, n = state["t_s"], len(state["t_s"])
            system = [str(v) for v in state["system"]]
            shown = _col(state, "time_gap_displayed_s", n, None)
            level = _col(state, "b_level", n, "none")
            sys_b = _Steps(t, [(num(g), str(lv) if str(lv) in LEVELS else "none", s_ == "B")
                               for g, lv, s_ in zip(shown, level, system, strict=True)])  # fmt: skip
            lit, seen = _col(state, "a_lit", n, False), _col(state, "a_perceived", n, False)
            sys_a = _Steps(t, [(bool(a), bool(b)) if s_ == "A" else (None, False)
                               for a, b, s_ in zip(lit, seen, system, strict=True)])  # fmt: skip
            if "phase" in state:
                phase = _Steps(t, [str(v) if v not in (None, "") else None for v in state["phase"]])
        for name, cols in sorted(topics.items()):  # other layouts: recognised by their columns
            if not (name.startswith("/adas") or name.startswith("/experiment")) or "t_s" not in cols:
                continue
            t, n = cols["t_s"], len(cols["t_s"])
            if sys_b is None and "time_gap_s" in cols and name.startswith("/adas"):
                levels = [str(v) if str(v) in LEVELS else "none" for v in _col(cols, "level", n, "none")]
                sys_b = _Steps(
                    t, [(num(g), lv, True) for g, lv in zip(cols["time_gap_s"], levels, strict=True)]
                )
            if sys_a is None and "display_lit" in cols and name.startswith("/adas"):
                seen = _col(cols, "perceived", n, False)
                sys_a = _Steps(
                    t, [(bool(a), bool(b)) for a, b in zip(cols["display_lit"], seen, strict=True)]
                )
            if phase is None and "phase" in cols:
                phase = _Steps(t, [str(v) if v not in (None, "") else None for v in cols["phase"]])
        return sys_b, sys_a, phase

    def _limit_at(self, k: int) -> float | None:
        """Speed limit of the ego's lane at record k; on a junction's internal lane (not in the scene's
        network) the last limit before it."""
        cache = self._limits
        while k >= 0:
            if k not in cache:
                edge, lane = self.ego_edge[k], self.ego_lane[k]
                ok = isinstance(edge, str) and edge and not edge.startswith(":") and np.isfinite(lane)
                cache[k] = self.lane_speed(edge, int(lane)) if ok else None
            if cache[k] is not None:
                return cache[k]
            k -= 1
        return None

    @property
    def t_range(self) -> tuple[float, float]:
        return float(self.ego_t[0]), float(self.ego_t[-1])

    def _vehicles_at(self, t: float) -> VehicleFrame:
        if not self.samples:
            return VehicleFrame.empty()
        k = int(np.searchsorted(self._sample_t, t, side="right")) - 1
        if k < 0:
            return self.samples[0][1]
        if k >= len(self.samples) - 1:
            return self.samples[-1][1]
        if self._interp is None or self._interp[0] != k:
            a, b = self.samples[k], self.samples[k + 1]
            self._interp = (k, Interpolator(FrameState(a[0], None, a[1]), FrameState(b[0], None, b[1])))
        t0, t1 = self._sample_t[k], self._sample_t[k + 1]
        return self._interp[1].at((t - t0) / (t1 - t0)).vehicles

    def frame_at(self, t: float) -> FrameState:
        """Everything at simulated time t [s] (the ego's track interpolated between steps)."""
        et = self.ego_t
        x, y = float(np.interp(t, et, self.ego_x)), float(np.interp(t, et, self.ego_y))
        yaw = float(np.interp(t, et, self.ego_yaw))
        k = max(0, int(np.searchsorted(et, t + 1e-9, side="right")) - 1)
        speed = float(np.interp(t, et, self.ego_speed))
        brake = self.ego_brake[k]
        ego = EgoPose(x, y, yaw, braking=bool(np.isfinite(brake) and brake > 0.05))
        leader = self.ego_leader[k]
        leader = None if leader is None or (isinstance(leader, float) and math.isnan(leader)) else str(leader)
        limit = self._limit_at(k)
        lights = {lid: s for lid, steps in self.lights.items() if (s := steps.at(t)) is not None}
        gap, level, sys_b_on = None, "none", False
        if self.sys_b is not None and (rec := self.sys_b.at(t)) is not None:
            gap, level, sys_b_on = rec
        lit = perceived = None
        if self.sys_a is not None and (rec := self.sys_a.at(t)) is not None:
            lit, perceived = rec
        phase = self.phase.at(t) if self.phase is not None else None
        hud = HudState(t_s=t, speed_mps=speed, speed_limit_mps=limit, sys_b_active=sys_b_on, sys_b_gap_s=gap,
                       sys_b_level=level, sys_a_perceived=bool(perceived), phase=phase)  # fmt: skip
        return FrameState(t, ego, self._vehicles_at(t), lights, leader, lit, hud)


# -- the run's scenario ----------------------------------------------------------------------------------------
def run_scenario(
    metadata: dict[str, dict[str, str]], scenario_dir: str | Path | None = None, quiet: bool = True
):
    """(Scenario, RunConfig) of a logged run: the given directory, the cached build, or a rebuild."""
    from cosim.config import from_dict
    from cosim.runconfig import RunConfig
    from cosim.scenario import Scenario, build_scenario, cache_dir

    meta = metadata.get("cosim")
    if not meta or "config" not in meta:
        raise CosimError("the log has no cosim metadata (config, scenario_key); was it written by cosim run?")
    try:
        config = from_dict(RunConfig, json.loads(meta["config"]))
    except (ValueError, TypeError) as exc:
        raise CosimError(f"the log's run config cannot be read by this cosim version: {exc}") from None
    if scenario_dir is not None:
        d = Path(scenario_dir)
        if not (d / "network.net.xml").exists():
            raise CosimError(f"{d} is not a scenario directory (no network.net.xml)")
        return Scenario(
            d, json.loads((d / "report.json").read_text()) if (d / "report.json").exists() else {}
        ), config
    key = meta.get("scenario_key", "")
    cached = cache_dir() / "scenarios" / key
    if key and (cached / "report.json").exists():
        return Scenario(cached, json.loads((cached / "report.json").read_text())), config
    if not Path(config.scenario.map).is_file():
        raise CosimError(
            f"the run's scenario {key or '?'} is not in the cache and its map {config.scenario.map} is gone; "
            "pass --scenario DIR or rebuild it with cosim build-scenario"
        )
    say = (lambda *a: None) if quiet else (lambda *a: print(*a, file=sys.stderr))
    return build_scenario(config.scenario.map, config=config.scenario, seed=config.seed, log=say), config


def phase_windows(
    state: dict[str, np.ndarray], systems=("A", "B"), seconds: float = 20.0
) -> list[tuple[str, float, float]]:
    """(system, start, end) of a ``seconds`` span from the middle of each listed system's phase, read from
    the decoded ``/adas/state`` columns; systems that never ran are left out."""
    t = np.asarray(state.get("t_s", ()), dtype=np.float64)
    used = np.asarray(state.get("system", ()), dtype=object)
    out = []
    for system in systems:
        when = t[used == system]
        if when.size == 0:
            continue
        mid = 0.5 * (when[0] + when[-1])
        half = 0.5 * min(seconds, when[-1] - when[0])
        out.append((system, float(mid - half), float(mid + half)))
    return out


def replayed_topic(topic: str) -> bool:
    """Whether the replay reads this topic of a log."""
    return topic in TOPICS or topic.startswith(("/adas", "/experiment"))


def render_phase_clip(log_path: str | Path, out: str | Path, systems=("A", "B"), seconds: float = 20.0,
                      params: RenderParams | None = None, **kwargs) -> dict:  # fmt: skip
    """One video of ``seconds`` from the middle of each system's phase of a run (e.g. an experiment
    participant's system A and system B), in that order; the HUD names the phase."""
    from cosim.log import read

    log = read(log_path, topics=replayed_topic)  # once: the windows come from its /adas/state
    spans = phase_windows(log.topics.get("/adas/state", {}), systems, seconds)
    if not spans:
        raise CosimError(f"{log_path} has no /adas/state records with system {' or '.join(systems)} in use")
    summary = render_log(
        log_path, out, None, params, windows=[(a, b) for _, a, b in spans], log=log, **kwargs
    )
    summary["windows"] = [{"system": s, "start_s": round(a, 2), "end_s": round(b, 2)} for s, a, b in spans]
    return summary


# -- output ----------------------------------------------------------------------------------------------------
class _Mp4Writer:
    """H.264 MP4 through imageio-ffmpeg; written to a temporary file and moved into place when complete."""

    def __init__(self, path: Path, width: int, height: int, fps: float) -> None:
        try:
            import imageio_ffmpeg
        except ImportError:
            raise CosimError(
                "MP4 output needs imageio-ffmpeg: pip install 'cosim[video]' (or use --frames DIR)"
            ) from None
        self.path = path
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=".mp4", dir=path.parent)
        os.close(fd)
        self.tmp = Path(tmp)
        self.gen = imageio_ffmpeg.write_frames(str(self.tmp), (width, height), fps=fps, codec="libx264",
                                               pix_fmt_in="rgb24", pix_fmt_out="yuv420p", quality=7,
                                               macro_block_size=2, ffmpeg_log_level="error")  # fmt: skip
        self.gen.send(None)

    def add(self, img: np.ndarray) -> None:
        self.gen.send(np.ascontiguousarray(img))

    def finish(self) -> None:
        self.gen.close()
        # mkstemp makes the file private (0600); the video gets the mode any new file of the user's gets
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(self.tmp, 0o666 & ~umask)
        os.replace(self.tmp, self.path)

    def abort(self) -> None:
        try:
            self.gen.close()
        except Exception:  # noqa: BLE001 - already failing; keep the first error
            pass
        self.tmp.unlink(missing_ok=True)


def render_log(log_path: str | Path, out: str | Path | None = None, frames_dir: str | Path | None = None,
               params: RenderParams | None = None, *, scenario_dir=None, scene_params: SceneParams | None = None,
               quiet: bool = True, windows: list[tuple[float, float]] | None = None, log=None) -> dict:  # fmt: skip
    """Render a logged run to an MP4 (``out``) and/or PNG stills (``frames_dir``); returns a summary.

    windows: (start, end) spans of simulated time [s] to show one after the other in one video (instead
    of ``params.start_s`` .. ``params.end_s``); log: the file already read with ``replayed_topic``.
    """
    from PIL import Image

    from cosim.log import read

    p = params or RenderParams()
    if out is None and frames_dir is None:
        raise CosimError("nothing to write: give an MP4 path and/or a frames directory")
    log_path = Path(log_path)
    if log is None:
        log = read(log_path, topics=replayed_topic)
    scenario, config = run_scenario(log.metadata, scenario_dir, quiet)
    t_build = time.perf_counter()
    sp = scene_params or SceneParams(max_width=max(p.width, 1280), max_height=max(p.height, 720))
    scene = build_scene(scenario, sp, car=config.ego.car)
    build_s = time.perf_counter() - t_build
    net_cache: dict[tuple[str, int], float | None] = {}

    def lane_speed(edge: str, lane: int) -> float | None:
        if (edge, lane) not in net_cache:
            try:
                net_cache[(edge, lane)] = float(scene.net.getEdge(edge).getLane(lane).getSpeed())
            except (KeyError, IndexError, AttributeError):
                net_cache[(edge, lane)] = None
        return net_cache[(edge, lane)]

    replay = LogReplay(log.topics, ego_length_m=config.ego.car.length_m, scv_length_m=p.scv_length_m,
                       lane_speed=lane_speed)  # fmt: skip
    t_first, t_last = replay.t_range
    spans = windows if windows else [(p.start_s, p.end_s)]
    parts = []
    for a, b in spans:
        start = t_first if a is None else max(a, t_first)
        end = t_last if b is None else min(b, t_last)
        if end < start:
            raise CosimError(f"no ego records between {start:.1f} s and {end:.1f} s (the ego is logged from "
                             f"{t_first:.1f} s to {t_last:.1f} s)")  # fmt: skip
        parts.append(start + np.arange(int(math.floor((end - start) * p.fps + 1e-9)) + 1) / p.fps)
    times = np.concatenate(parts)
    view = render_mod.View(scene, render_mod.ViewParams(p.width, p.height, p.camera, p.hud))
    writer = _Mp4Writer(Path(out), p.width, p.height, p.fps) if out is not None else None
    fdir = Path(frames_dir) if frames_dir is not None else None
    if fdir is not None:
        fdir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    try:
        for i, t in enumerate(times):
            img = view.render(replay.frame_at(float(t)))
            if writer is not None:
                writer.add(img)
            if fdir is not None:
                Image.fromarray(img).save(fdir / f"frame_{i:05d}.png")
            if not quiet and (i % 20 == 0 or i == len(times) - 1):
                sys.stderr.write(f"\rrendering {i + 1}/{len(times)} frames (t = {t:.1f} s)")
                sys.stderr.flush()
        if writer is not None:
            writer.finish()
    except BaseException:
        if writer is not None:
            writer.abort()
        raise
    finally:
        view.close()
        if not quiet:
            sys.stderr.write("\n")
    wall = time.perf_counter() - t0
    return {"frames": len(times), "start_s": round(float(times[0]), 3), "end_s": round(float(times[-1]), 3),
            "fps": p.fps, "camera": p.camera, "size": f"{p.width}x{p.height}", "scene_build_s": round(build_s, 2),
            "render_s": round(wall, 2), "frames_per_s": round(len(times) / wall, 1) if wall > 0 else None,
            "out": str(out) if out is not None else None, "frames_dir": str(fdir) if fdir else None}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """``python -m cosim.world3d.replay``: the same as ``cosim render``."""
    from cosim.cli import main as cosim_main

    return cosim_main(["render", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())

"""The orchestrator: owns simulated time (an integer step counter) and the fixed phase order.

One step (ARCHITECTURE.md): sumo -> vanet -> adas -> driver -> ego -> writeback -> log. What runs when is
the schedule that ``Simulation._build_schedule`` writes out, top to bottom: a list of (phase, callable).
Every callable of a step reads the same snapshot (``sim.world``), so vehicle order never matters; the
phases' results of the step are the fields of ``sim.outputs`` (a frozen ``cosim.outputs.StepOutputs``,
complete before the log phase). A study can add its own callable ``fn(sim)`` to a phase with
``Simulation.add_hook(phase, fn)``: it runs after that phase's scheduled work.

With ``radio_process`` (what ``cosim run`` and ``cosim drive`` use on a machine with a core to spare) the
radio runs in a second process:
the assistance phase gets the ego's OBU view of the step at once, and the rest of the radio step runs while
this process drives the ego and SUMO computes the next step. The step is then written to the log early in
the next ``step()`` (or by ``close()``), and ``outputs.vanet`` is filled in then; the file is the same, byte
for byte (cosim.phases.vanet_process). A script that steps the simulation itself keeps the radio in the
script's process by default, so that ``outputs.vanet`` is the step's when ``step()`` returns.
"""

from __future__ import annotations

import dataclasses
import json
import os
import sys
import time
from collections.abc import Callable
from functools import cached_property
from pathlib import Path

import numpy as np

import cosim
from cosim.childproc import available_cores
from cosim.config import to_dict
from cosim.health import DriveHealth
from cosim.log import McapLog
from cosim.outputs import StepBuffer, StepOutputs
from cosim.runconfig import RunConfig
from cosim.scenario import Scenario, build_scenario
from cosim.scenario.build import cache_dir
from cosim.seeds import stream
from cosim.sumo_bridge.bridge import SumoBridge
from cosim.sumo_bridge.network import read_network
from cosim.sumo_bridge.tools import sumo_version
from cosim.vanet.mapstore import store_dir
from cosim.world import EGO_ID, LEAD_ID, SumoEvent, World

PHASES = ("sumo", "vanet", "adas", "driver", "ego", "writeback", "log")
RADIO_TOPICS = "/vanet/*"  # stands in outputs.log for the radio's messages until the radio process has them
EGO_START_M = 2.0  # the ego's rear starts this far from the start of its route [m]
LEAD_START_GAP_M = 20.0  # the lead starts this far ahead of the ego's front bumper [m]
LEAD_LENGTH_M = 5.0  # SUMO's default car, which the lead's vType copies [m]
START_CLEAR_M = 10.0  # vehicles between the ego and up to this far ahead of the lead are taken out ...
START_CLEAR_WIDTH_M = 3.0  # ... within this distance of the line through both (their lane) ...
START_GUARD_S = 10.0  # ... during this long after they are placed [s]
# a car behind the ego when it appears (standing) is taken out when it could not stop behind it: its reaction
# time plus braking at SUMO's default passenger deceleration (sumo.dlr.de/docs/Vehicle_Type_Parameter_Defaults.html:
# decel 4.5 m/s^2, tau 1 s). Krems seed 3: the ego placed on a 100-km/h road, and an initial SCV coming up
# behind it at 24 m/s ran into it 0.1 s later
START_BRAKE_MPS2 = 4.5
START_REACTION_S = 1.0
START_SAME_WAY_DEG = 45.0  # ... when heading within this of the ego's heading (its lane, not a crossing road)


class Progress:
    """A tqdm bar on stderr: simulated time of the total, vehicles and real-time factor."""

    def __init__(self, total_s: float, enabled: bool):
        from tqdm import tqdm

        self.total_s = total_s
        self.enabled = enabled and total_s > 0
        self.t0 = time.perf_counter()
        self.last = 0.0  # wall time of the last redraw
        self._bar = None
        if self.enabled:
            self._bar = tqdm(total=round(total_s, 3), unit="sim s", file=sys.stderr, dynamic_ncols=True,
                             bar_format="{l_bar}{bar}| {n:.1f}/{total:.0f} s [{elapsed}<{remaining}{postfix}]")  # fmt: skip

    def update(self, t_s: float, vehicles: int, force: bool = False) -> None:
        now = time.perf_counter()
        if self._bar is None or (now - self.last < 0.5 and not force):
            return
        self.last = now
        wall = now - self.t0
        rtf = t_s / wall if wall > 0 else 0.0
        self._bar.n = round(min(t_s, self.total_s), 3)
        self._bar.set_postfix_str(f"{vehicles} vehicles, {rtf:.1f}x real time", refresh=False)
        self._bar.refresh()

    def done(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


class Simulation:
    """A co-simulation run. Use as a context manager so SUMO and the log are always closed."""

    def __init__(self, config: RunConfig, *, out_dir: str | Path | None = None, gui: bool = False,
                 quiet: bool = True, scenario: Scenario | None = None, log=None,
                 sumo_args: tuple[str, ...] = (), radio_process: bool | None = False):  # fmt: skip
        """``sumo_args`` are extra SUMO options (e.g. devices for a study: ``--device.ssm.explicit ego``).
        ``radio_process``: run the radio in a second process (None: ``radio_process_default()``); then the
        step's ``outputs.vanet`` is filled in only during the next ``step()`` (the commands that run a whole
        simulation use it; a script reading the radio's results each step keeps the default, False)."""
        self.config = config
        self.quiet = quiet
        say = log or (lambda *_: None if quiet else print(*_))
        self.scenario = scenario or build_scenario(
            config.scenario.map, config=config.scenario, seed=config.seed, log=say
        )
        self.step_s = config.timing.sumo_step_s
        self.steps_total = round(config.duration_s / self.step_s)
        self.world = World(capacity=1024)
        self.schedule: list[tuple[str, Callable[[Simulation], None]]] = []  # _build_schedule
        self.events: list[SumoEvent] = []  # this step's events (phases may append)
        self.outputs = StepOutputs()  # the phases' results of the last step
        self.current = StepBuffer()  # ... while the step runs (frozen into outputs before the log phase)
        self.out_dir = Path(out_dir) if out_dir else None
        self.mcap: McapLog | None = None
        self.bridge: SumoBridge | None = None
        self._net = None
        self.ego_route: list[str] = []
        self.ego = None  # the EgoController when MuJoCo drives the ego
        self.vanet = None  # the VanetPhase when the radio is on
        self.adas = None  # the AdasPhase when there is an ego
        self.lead = None  # the LeadVehicle of the following task
        self.route = None  # the EgoRoute: the ego's (and the lead's) route, extended as they drive
        self.traffic = None  # TrafficAroundEgo when the scenario's traffic is generated around the ego
        self.impatience = None  # QueueHeadImpatience: SUMO's drivers keep their impatience while they creep
        self.stats = {"teleports": 0, "collisions": 0, "ego_off_road": 0, "steps": 0}
        self.health: DriveHealth | None = None
        self.recorder = None  # the log phase (cosim.log.recorder) when there is a log
        self._start_guard_until: float | None = None
        self._placed = False  # the ego (and the lead) are placed on the route
        self.closed = False
        self._radio_overlap = False  # the radio runs in a second process, overlapping SUMO's step
        self._radio_open = False  # a radio step runs in the radio process
        self._log_later: tuple | None = None  # (events, lights) of the step whose log waits for the radio
        try:
            if config.vanet is not None:  # first: a radio process starts up while SUMO loads
                maps = store_dir(cache_dir())  # the visibility maps of earlier runs (cosim.vanet.mapstore)
                if radio_process_default() if radio_process is None else radio_process:
                    from cosim.phases.vanet_process import VanetProcess

                    self.vanet = VanetProcess(config.vanet, self.scenario.buildings_file, stream(config.seed, "vanet"),
                                              log=out_dir is not None, map_store=maps)  # fmt: skip
                    self._radio_overlap = True
                else:
                    from cosim.phases.vanet import VanetPhase

                    self.vanet = VanetPhase(config.vanet, self.buildings, stream(config.seed, "vanet"),
                                            log=out_dir is not None, map_store=maps)  # fmt: skip
            self.bridge = SumoBridge(self.scenario.sumocfg, seed=config.seed, step_s=self.step_s, gui=gui,
                                     extra_args=sumo_args)  # fmt: skip
            if self.out_dir is not None:
                self.mcap = McapLog(self.out_dir / "run.mcap", flush_every_s=config.log.flush_every_s)
                self._write_metadata()
            if config.ego.enabled:
                self._setup_ego()
                if config.ego.physics == "mujoco":
                    self.ego = self._ego_controller()
                from cosim.phases.adas import AdasPhase
                from cosim.phases.lead import LeadVehicle

                if config.ego.lead_vehicle:
                    self.lead = LeadVehicle(config.ego.lead_waits_beyond_m, bridge=self.bridge, ego=self.ego,
                                            emit=self._emit)  # fmt: skip

                self.adas = AdasPhase(config.adas, self.buildings, stream(config.seed, "system_a"), self.bridge,
                                      self.vanet)  # fmt: skip
                if config.scenario.demand.area == "around_ego":
                    from cosim.phases.traffic import TrafficAroundEgo

                    start = (
                        self.net.getEdge(self.ego_route[0]).getShape()[0] if self.ego_route else (0.0, 0.0)
                    )
                    self.traffic = TrafficAroundEgo(config.scenario.demand, self.drivable_edges,
                                                    self.scenario.routes_file, start_xy=start,
                                                    rng=stream(config.seed, "traffic"), step_s=self.step_s,
                                                    bridge=self.bridge)  # fmt: skip
                    self.stats.update(scv_generated=0, scv_removed=0)
            time_to_impatience_s = self.bridge.time_to_impatience_s()
            if time_to_impatience_s > 0:  # SUMO's switch: non-positive = no impatience growth
                from cosim.phases.impatience import QueueHeadImpatience

                self.impatience = QueueHeadImpatience(self.bridge, step_s=self.step_s,
                                                      time_to_impatience_s=time_to_impatience_s)  # fmt: skip
            self.health = DriveHealth(config.ego, self.step_s)  # scheduled after the ego's phases: it reads
            # what they decided
            if self.mcap is not None:
                from cosim.log.recorder import Recorder

                self.recorder = Recorder(self.mcap, config.log, bridge=self.bridge, scenario_dir=self.scenario.dir,
                                         network=lambda: self.net, health=self.health is not None)  # fmt: skip
            self.schedule = self._build_schedule()
        except BaseException:
            self.close()
            raise

    # -- set-up ----------------------------------------------------------------------------------------------
    @property
    def net(self):
        """The read-only network view with internal lanes (``cosim.sumo_bridge.network``; loaded on first
        use): route geometry, the drivable edges, the traffic generator's spawn spots, the scene."""
        if self._net is None:
            self._net = read_network(self.scenario.net_file, internal=True)
        return self._net

    @cached_property
    def buildings(self):
        """The scenario's building footprints, read and indexed once for the radio and system A."""
        from cosim.scenario.buildings import indexed_buildings

        return indexed_buildings(self.scenario.buildings_file)

    @cached_property
    def drivable_edges(self) -> list:
        """The network's largest strongly connected car network (computed once, for whoever needs it)."""
        from cosim.scenario.demand import drivable_component

        return drivable_component(self.net)

    def _write_metadata(self) -> None:
        self.mcap.metadata("cosim", {
            "config": json.dumps(to_dict(self.config), sort_keys=True), "seed": self.config.seed,
            "cosim_version": cosim.__version__, "sumo_version": sumo_version(),
            "scenario_key": self.scenario.report["cache"]["scenario_key"],
            "map": Path(self.config.scenario.map).name, "step_s": self.step_s,
        })  # fmt: skip

    def _setup_ego(self) -> None:
        """The ego (and the lead ahead of it) are placed on the route at the first step, not queued behind
        SUMO's pending insertions; with ``depart_s`` > 0 they are placed at that time (``_place_ego``)."""
        ego = self.config.ego
        route = list(ego.route) or list(self.scenario.report["demand"]["ego_route"])
        self.ego_route = route
        if ego.physics == "mujoco":
            from cosim.phases.route import EgoRoute

            self.route = EgoRoute(self.ego_route, rng=stream(self.config.seed, "route"),
                                  drivable_edges=lambda: self.drivable_edges, bridge=self.bridge, world=self.world,
                                  emit=self._emit, lead=bool(ego.lead_vehicle))  # fmt: skip
        if ego.depart_s == 0:
            self._place_ego()

    def _ego_controller(self):
        """The ego's phase: the MuJoCo car, its driver and their ports."""
        from cosim.driver.route import RoutePath
        from cosim.ego_mujoco import EgoCar
        from cosim.phases.ego import EgoController

        ego = self.config.ego
        return EgoController(ego, car=EgoCar(ego.car, timestep_s=self.config.timing.physics_timestep_s),
                             rng=stream(self.config.seed, "driver", ego.driver_seed), route=self.ego_route,
                             path_of=lambda edges, delays=None: RoutePath.from_network(self.net, edges, delays), extension=self.route,
                             bridge=self.bridge, step_s=self.step_s, emit=self._emit)  # fmt: skip

    def _place_ego(self) -> None:
        self._placed = True
        ego = self.config.ego
        front = ego.car.length_m + EGO_START_M
        if ego.lead_vehicle:
            self.bridge.add_lead(self.ego_route, front + LEAD_START_GAP_M + LEAD_LENGTH_M)
        self.bridge.add_ego(self.ego_route, controlled=ego.physics == "mujoco", length_m=ego.car.length_m,
                            width_m=ego.car.width_m, front_m=front)  # fmt: skip

    def _start(self, sim) -> None:
        """Places the ego (and the lead) when ``depart_s`` is due; from the next step on, keeps their start
        clear (``_clear_start``) for START_GUARD_S."""
        if self._placed:
            self._clear_start()
        elif self.world.t_s + self.step_s >= self.config.ego.depart_s - 1e-9:
            self._place_ego()

    def _clear_start(self) -> None:
        """For the first START_GUARD_S after the ego (and the lead) are placed: take out the vehicles SUMO
        inserts between them or onto the ego (an initial vehicle placed in their span of road), and at the
        first step those still waiting to be inserted on their edges, so the following task starts as
        planned. Vehicles behind the ego are left alone, except at the first step those too close to stop
        behind it (START_BRAKE_MPS2)."""
        w = self.world
        ego, lead = w.slot_of.get(EGO_ID), w.slot_of.get(LEAD_ID)
        if ego is None or (lead is None and self.config.ego.lead_vehicle):
            return
        first = self._start_guard_until is None
        if first:
            self._start_guard_until = w.t_s + START_GUARD_S
        elif w.t_s > self._start_guard_until:
            self._unschedule(self._start)
            return
        placed = [ego] if lead is None else [ego, lead]
        edge_codes = w.edge_code[placed]
        # the span from the ego's rear to the lead's front (the ego's own length without a lead), along it
        ex, ey = float(w.x_m[ego]), float(w.y_m[ego])
        if lead is None:
            ux, uy = w.heading_unit()
            dx, dy, span = float(ux[ego]), float(uy[ego]), 0.0
        else:
            span = float(np.hypot(w.x_m[lead] - ex, w.y_m[lead] - ey))
            dx, dy = (float(w.x_m[lead]) - ex) / max(span, 1e-9), (float(w.y_m[lead]) - ey) / max(span, 1e-9)
        along = (w.x_m - ex) * dx + (w.y_m - ey) * dy
        across = np.abs(-(w.x_m - ex) * dy + (w.y_m - ey) * dx)
        rear = -float(w.length_m[ego])
        inside = (w.valid & np.isin(w.edge_code, edge_codes) & (across < START_CLEAR_WIDTH_M)
                  & (along > rear - 1.0) & (along < span + START_CLEAR_M))  # fmt: skip
        if first:  # cars behind that the ego appeared in front of too close to stop
            v = np.maximum(w.speed_mps, 0.0)
            stop_m = v * START_REACTION_S + v * v / (2.0 * START_BRAKE_MPS2)
            same_way = (
                np.abs((w.heading_deg - w.heading_deg[ego] + 180.0) % 360.0 - 180.0) < START_SAME_WAY_DEG
            )
            inside |= (w.valid & same_way & (across < START_CLEAR_WIDTH_M) & (along <= rear - 1.0)
                       & (rear - along < stop_m))  # fmt: skip
        doomed = [w.ids[s] for s in np.flatnonzero(inside).tolist() if w.ids[s] not in (EGO_ID, LEAD_ID)]
        if first:
            doomed += self.bridge.pending_on([w.edge_names[c] for c in edge_codes.tolist() if c >= 0])
        for vid in doomed:
            self.bridge.remove_vehicle(vid)

    # -- the schedule ----------------------------------------------------------------------------------------
    def _build_schedule(self) -> list[tuple[str, Callable[[Simulation], None]]]:
        """One step, in order. Each entry gives a phase object the narrow inputs it needs and keeps its
        results in ``self.current`` (``self.outputs`` once the step is done)."""
        s: list[tuple[str, Callable[[Simulation], None]]] = []
        # sumo: SUMO has advanced and the snapshot is read (Simulation.step); then ...
        if self.config.ego.enabled:
            s.append(
                ("sumo", self._start)
            )  # ... the ego and the lead placed when due, their start kept clear
        if self.ego is not None:
            s.append(("sumo", self._ego_own_state))  # ... the ego's pose, speed and acceleration are MuJoCo's
        if self.vanet is not None:  # vanet: CAMs, medium access, the aether, the OBUs
            s.append(("vanet", self._vanet_step))
        if self.adas is not None:  # adas: systems A and B on what the ego could know
            s.append(("adas", self._adas_step))
        if self.ego is not None:  # driver: the ego's driver decides ...
            s.append(("driver", self._ego_drive))
        if self.lead is not None:  # ... and the lead car adapts to the ego
            s.append(("driver", self._lead_step))
        if self.ego is not None:
            s.append(("ego", self._ego_integrate))  # ego: MuJoCo integrates the car over the SUMO step
            s.append(("writeback", self._ego_write_back))  # writeback: the ego's pose into SUMO
        if self.impatience is not None:  # SUMO's queue heads: impatience held while they creep
            s.append(("writeback", self._impatience_step))
        if self.traffic is not None:
            s.append(("writeback", self._traffic_step))  # SCVs generated and removed around the ego
        if self.health is not None:
            s.append(("writeback", self._health_step))  # the run's own health record
        if self.recorder is not None:
            s.append(("log", self._log_step))  # log: the step into the MCAP file
        return s

    def _ego_own_state(self, sim) -> None:
        self.ego.own_state(self.world)

    def _ego_drive(self, sim) -> None:
        self.ego.step(self.world, self.current.adas_displays)

    def _lead_step(self, sim) -> None:
        self.lead.step(self.world)

    def _ego_integrate(self, sim) -> None:
        self.ego.integrate()

    def _ego_write_back(self, sim) -> None:
        self.current.ego_log = self.ego.write_back(self.world)
        if self.lead is not None and self.current.ego_log:  # the gap the ego keeps is partly the lead's doing
            self.current.ego_log["lead_paced"] = self.lead.paced

    def _vanet_step(self, sim) -> None:
        self.vanet.begin(self.world, self.step_s)
        if self._radio_overlap:  # finished while SUMO computes the next step (_finish_radio)
            self._radio_open = True
            self.current.log[RADIO_TOPICS] = None
        else:
            self.current.vanet, topics = self.vanet.finish()
            self.current.log.update(topics)

    def _finish_radio(self) -> None:
        """The radio step under way, finished in its process: into that step's outputs and, with its log
        messages in their place, the step into the log."""
        if not self._radio_open:
            return
        res, topics = self.vanet.finish()
        self._radio_open = False
        out = self.outputs
        if RADIO_TOPICS in out.log:  # outputs are the radio step's (a Ctrl-C may have cut that step short)
            log = {}
            for topic, msg in out.log.items():
                if topic == RADIO_TOPICS:
                    log.update(topics)
                else:
                    log[topic] = msg
            self.outputs = dataclasses.replace(out, vanet=res, log=log)
        later, self._log_later = self._log_later, None
        if later is not None:
            self.recorder.step(self.world, self.outputs, *later)

    def _adas_step(self, sim) -> None:
        out = self.adas.step(self.world)
        if out is None:
            return
        self.current.adas_displays = out.displays
        self.current.adas = out.record
        if self.mcap is not None:
            self.current.log["/adas/state"] = out.record
            if out.events is not None:
                self.current.log["/adas/events"] = out.events

    def _impatience_step(self, sim) -> None:
        self.impatience.step(self.world)

    def _traffic_step(self, sim) -> None:
        self.traffic.step(self.world)
        self.stats["scv_generated"], self.stats["scv_removed"] = self.traffic.generated, self.traffic.removed

    def _health_step(self, sim) -> None:
        ego = self.ego
        percept = getattr(ego, "percept", None)
        self.events += self.health.step(
            self.world,
            self.events,
            percept,
            lambda: getattr(getattr(getattr(ego, "driver", None), "debug", None), "mode", ""),
            self.lead.lead_is_leader if self.lead is not None else None,
            self.lead is not None and self.lead.paced,
        )

    def _log_step(self, sim) -> None:
        if self._radio_open:  # the log waits for the radio's messages (_finish_radio); SUMO steps before
            self._log_later = (self.events, self.bridge.traffic_lights())
        else:
            self.recorder.step(self.world, self.outputs, self.events)

    def _emit(self, event: SumoEvent) -> None:
        """Add an event to this step's (for phases given ``emit`` as a port)."""
        self.events.append(event)

    def add_hook(self, phase: str, fn: Callable[[Simulation], None]) -> None:
        """Run ``fn(sim)`` every step in ``phase``, after the phase's scheduled work (and earlier hooks)."""
        if phase not in PHASES:
            raise ValueError(f"unknown phase {phase!r} (phases: {', '.join(PHASES)})")
        last = max((i for i, (p, _) in enumerate(self.schedule) if PHASES.index(p) <= PHASES.index(phase)),
                   default=-1)  # fmt: skip
        self.schedule.insert(last + 1, (phase, fn))

    def _unschedule(self, fn) -> None:
        self.schedule = [(p, f) for p, f in self.schedule if f != fn]

    @property
    def t_s(self) -> float:
        return self.world.t_s

    def step(self) -> World:
        """Advance one base step through every phase in order."""
        self.current = StepBuffer()
        self.bridge.advance()  # SUMO computes the step while the radio process finishes the last one
        self._finish_radio()
        self.events = self.bridge.read(self.world)
        for phase in PHASES:
            if phase == "log":
                self.outputs = self.current.freeze()
            for p, fn in tuple(self.schedule):  # an entry may remove itself (or add one) while they run
                if p == phase:
                    fn(self)
        for ev in self.events:
            if ev.kind == "teleport":
                self.stats["teleports"] += 1
            elif ev.kind == "collision":
                self.stats["collisions"] += 1
            elif ev.kind == "ego_off_road":
                self.stats["ego_off_road"] += 1
        self.stats["steps"] += 1
        return self.world

    def run(self, duration_s: float | None = None) -> dict:
        """Run for ``duration_s`` (default: the config's); Ctrl-C stops cleanly with a valid log."""
        steps = self.steps_total if duration_s is None else round(duration_s / self.step_s)
        progress = Progress(steps * self.step_s, enabled=not self.quiet)
        t0 = time.perf_counter()
        interrupted = False
        try:
            for _ in range(steps):
                self.step()
                progress.update(self.world.t_s, self.world.n_valid)
        except KeyboardInterrupt:
            interrupted = True
        progress.update(self.world.t_s, self.world.n_valid, force=True)
        progress.done()
        wall = time.perf_counter() - t0
        # the radio access of the run (issue 18)
        vanet_mac = self.config.vanet.mac if self.config.vanet is not None else None
        return {**self.stats, "vanet_mac": vanet_mac, "simulated_s": round(self.world.t_s, 3), "wall_s": round(wall, 2),
                "real_time_factor": round(self.world.t_s / wall, 2) if wall > 0 else None,
                "interrupted": interrupted, "health": self.health.report()}  # fmt: skip

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        try:
            try:
                self._finish_radio()
            except RuntimeError as exc:  # the radio process failed: the file still closes, one step short
                print(f"warning: {exc}", file=sys.stderr)
            phases = (self.traffic, self.lead, self.ego, self.route, self.adas, self.vanet, self.recorder)
            for phase in phases:
                if phase is not None:
                    phase.close()
            if self.mcap is not None:
                if self.health is not None and self.stats["steps"]:  # the run's own verdict, last in the log
                    self.mcap.write(
                        "/health", self.world.t_s, {"t_s": self.world.t_s, **self.health.report()}
                    )
                self.mcap.close()
        finally:
            if self.bridge is not None:
                self.bridge.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def radio_process_default() -> bool:
    """The radio in a second process when a core is free for it: ``COSIM_RADIO_PROCESS`` (0 / 1) decides,
    else on with two cores or more. Pools that fill every core with runs (experiment, sweep) turn it off."""
    env = os.environ.get("COSIM_RADIO_PROCESS")
    if env is not None:
        return env.strip() not in ("", "0", "false", "no", "off")
    return available_cores() >= 2

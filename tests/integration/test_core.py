"""The lockstep core: determinism, crash-safe logs, and the ego's write-back into SUMO."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import libsumo
import pytest
from osm_factory import OsmSketch
from testpaths import shared_map

from cosim.log import read
from cosim.runconfig import load_run_config
from cosim.scenario import build_scenario
from cosim.sim import Simulation
from cosim.sumo_bridge.bridge import EGO_ID, SumoBridge
from cosim.world import World

# libsumo runs one simulation per process: each test gets its own process (tests/conftest.py)
pytestmark = pytest.mark.own_process


def run_payloads(tmp_path, seed: int, name: str) -> dict[str, list[bytes]]:
    cfg = load_run_config(None, **{"scenario.map": str(shared_map("munich")), "scenario.demand.density": "low",
                                   "duration_s": 30.0, "seed": seed, "ego.physics": "sumo",
                                   "log.traffic_every_steps": 1})  # fmt: skip
    with Simulation(cfg, out_dir=tmp_path / name) as sim:
        sim.run()
    log = read(tmp_path / name / "run.mcap", topics=["/traffic/vehicles", "/ego/state"], keep_raw=True)
    return log.raw


@pytest.mark.slow  # three 30-s runs on Munich (tests/integration/test_outputs.py checks whole files, fast)
def test_same_seed_gives_byte_identical_traces_and_another_seed_does_not(tmp_path):
    a = run_payloads(tmp_path, 5, "a")
    b = run_payloads(tmp_path, 5, "b")
    c = run_payloads(tmp_path, 6, "c")
    assert len(a["/traffic/vehicles"]) == 300 and len(a["/ego/state"]) > 100
    assert a["/traffic/vehicles"] == b["/traffic/vehicles"]
    assert a["/ego/state"] == b["/ego/state"]
    assert a["/traffic/vehicles"] != c["/traffic/vehicles"]


def _start_run(tmp_path, duration: int) -> tuple[subprocess.Popen, object]:
    out = tmp_path / "run"
    # output to files, not pipes nobody reads while the run goes on (a full pipe would stop it); its stacks
    # on SIGABRT (faulthandler) if it ever hangs
    proc = subprocess.Popen(
        [sys.executable, "-m", "cosim.cli", "run", "--map", str(shared_map("munich")), "--density", "low",
         "--duration", str(duration), "--out", str(out), "--quiet"],
        stdout=(tmp_path / "stdout").open("wb"), stderr=(tmp_path / "stderr").open("wb"),
        env={**os.environ, "PYTHONFAULTHANDLER": "1"},
    )  # fmt: skip
    mcap = out / "run.mcap"
    deadline = time.time() + 120
    while time.time() < deadline and (not mcap.exists() or mcap.stat().st_size < 50_000):
        if proc.poll() is not None:
            pytest.fail(f"the run ended early ({proc.returncode}): {_tail(tmp_path / 'stderr')}")
        time.sleep(0.2)
    assert mcap.exists(), "no log appeared"
    time.sleep(1.0)
    return proc, mcap


def _tail(path, n: int = 6000) -> str:
    return path.read_bytes()[-n:].decode(errors="replace")


def _wait_or_dump(proc: subprocess.Popen, tmp_path, timeout_s: float) -> int:
    """The run's exit code; if it does not end in time, fail with where it (and its log writer) hung."""
    try:
        return proc.wait(timeout_s)
    except subprocess.TimeoutExpired:
        children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children")
        kids = children.read_text().split() if children.exists() else []
        for pid in [proc.pid, *map(int, kids)]:
            try:
                os.kill(pid, signal.SIGABRT)
            except ProcessLookupError:
                pass
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            proc.kill()
        pytest.fail(
            f"the run did not end {timeout_s:.0f} s after the signal; its stacks:\n{_tail(tmp_path / 'stderr')}"
        )


@pytest.mark.slow  # the same path as SIGTERM, which test_outputs.py checks on a small map
def test_ctrl_c_ends_cleanly_with_a_complete_log(tmp_path):
    proc, mcap = _start_run(tmp_path, 3000)
    proc.send_signal(signal.SIGINT)
    assert _wait_or_dump(proc, tmp_path, 60) == 130, _tail(tmp_path / "stderr")
    log = read(mcap)
    assert not log.truncated
    assert log.counts["/ego/state"] > 10 and log.metadata["cosim"]["seed"]


def test_killed_run_leaves_a_readable_log(tmp_path):
    proc, mcap = _start_run(tmp_path, 3000)
    time.sleep(2.5)  # past at least one crash-safe flush
    proc.kill()
    proc.wait(30)
    log = read(mcap)
    assert log.counts.get("/traffic/vehicles", 0) > 5
    assert log.duration_s > 1.0


def test_ego_write_back_makes_a_sumo_follower_brake(tmp_path):
    """The ego (moved by moveToXY, as MuJoCo does) brakes hard; the SUMO car behind must brake too."""
    s = OsmSketch()
    s.node("a", -1500, 0)
    s.node("b", 1500, 0)
    s.node("c", 1500, 300)
    s.node("d", 1800, 0)
    s.way(["a", "b"], highway="secondary", maxspeed="50")
    s.way(["b", "c"], highway="residential")
    s.way(["b", "d"], highway="residential")
    scn = build_scenario(
        s.write(tmp_path / "m.osm"), tmp_path / "scn", density="low", seed=2, log=lambda *a: None
    )
    import sumolib

    net = sumolib.net.readNet(str(scn.net_file))
    edge = next(e for e in net.getEdges() if e.getLength() > 2000)
    bridge = SumoBridge(scn.sumocfg, seed=1, step_s=0.1, extra_args=("--route-files", ""))
    try:
        world = World(16)
        bridge.add_ego([edge.getID()], depart=0, controlled=True, length_m=4.4, width_m=1.8)
        bridge.add_vehicle("follower", [edge.getID()], depart=0, type_id="DEFAULT_VEHTYPE", depart_speed="10")
        shape = edge.getLane(0).getShape()
        (x0, y0), (x1, y1) = shape[0], shape[-1]
        assert len(shape) == 2, "a straight lane"
        heading = math.degrees(math.atan2(x1 - x0, y1 - y0)) % 360
        ux, uy = (x1 - x0) / math.dist(shape[0], shape[1]), (y1 - y0) / math.dist(shape[0], shape[1])
        pos, speed = 60.0, 13.0
        follower_speeds = []
        for step in range(400):
            bridge.step(world)
            if step < 150:
                speed = 13.0
            else:
                speed = max(0.0, speed - 6.0 * 0.1)  # emergency braking of the ego
            pos += speed * 0.1
            bridge.write_ego(x0 + ux * pos, y0 + uy * pos, heading, speed)
            if "follower" in bridge.vehicle_ids() and step > 100:
                follower_speeds.append((step, libsumo.vehicle.getSpeed("follower")))
        before = [v for s_, v in follower_speeds if 120 < s_ < 150]
        after = [v for s_, v in follower_speeds if s_ > 300]
        assert min(before) > 9.0  # it was following at speed
        assert max(after) < 0.5  # and came to a stop behind the stopped ego
        gap = bridge.leader("follower")
        assert gap is not None and gap[0] == EGO_ID and gap[1] > 0.0  # no collision
        # driving off the road is an event, not a crash
        kinds = []
        for _ in range(6):
            bridge.write_ego(x0 + ux * pos + uy * 40.0, y0 + uy * pos - ux * 40.0, heading, 0.0)
            kinds += [e.kind for e in bridge.step(world) if e.kind.startswith("ego_")]
        assert kinds == ["ego_off_road"]
        bridge.write_ego(x0 + ux * pos, y0 + uy * pos, heading, 0.0)
        assert [e.kind for e in bridge.step(world) if e.kind.startswith("ego_")] == ["ego_on_road"]
    finally:
        bridge.close()


@pytest.mark.slow
def test_an_ego_standing_for_minutes_is_never_teleported_away():
    """SUMO teleports a car that waits longer than time-to-teleport (120 s); a participant who stops must
    stay in the traffic (the ego's vType disables it)."""
    cfg = load_run_config(None, **{"scenario.map": str(shared_map("munich")), "scenario.demand.density": "low",
                                   "duration_s": 180.0, "seed": 2, "ego.physics": "sumo",
                                   "ego.lead_vehicle": False, "vanet": None})  # fmt: skip
    with Simulation(cfg) as sim:
        veh = libsumo.vehicle  # the run's SUMO: libsumo runs in this process
        while EGO_ID not in sim.world.slot_of:
            sim.step()
        veh.setSpeed(EGO_ID, 0.0)
        events, stalls = [], []
        for _ in range(1500):
            sim.step()
            events += [e for e in sim.events if e.vehicle == EGO_ID and e.kind != "ego_stall"]
            stalls += [e for e in sim.events if e.kind == "ego_stall"]
        assert veh.getWaitingTime(EGO_ID) > 140
        assert EGO_ID in sim.world.slot_of and not events, events
        assert len(stalls) == 1  # the run's health logs the standstill once, after 90 s

"""The assistance phase with fake ports: SUMO's ground-truth leader and the ego's OBU answered by fakes, a
World filled by the test (no SUMO, no MuJoCo, no radio)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from cosim.adas.config import AdasConfig
from cosim.buildings import Buildings
from cosim.phases.adas import AdasPhase
from cosim.seeds import stream
from cosim.world import EGO_ID, World


class FakeBridge:
    def __init__(self, leader=("car1", 14.0), min_gap_m=2.5):
        self._leader, self._min_gap = leader, min_gap_m

    def leader(self, vid, dist_m):
        assert vid == EGO_ID and dist_m == AdasConfig().leader_search_m
        return self._leader

    def min_gap(self, vid):
        return self._min_gap


class FakeObu:
    """The ego's OBU: one leader (station 7) whose newest CAM is ``seq``."""

    def __init__(self, w: World):
        self.w, self.seq, self.present, self.decoded = w, 1, True, []

    def find_leader(self, criteria):
        return SimpleNamespace(station_id=7, seq=self.seq) if self.present else None

    def _cam(self):
        s = self.w.slot_of["car1"]
        return SimpleNamespace(generation_t_s=self.w.t_s, x_m=float(self.w.x_m[s]), y_m=0.0, heading_deg=90.0,
                               speed_mps=10.0, length_m=4.5, accel_mps2=0.0, station_id=7)  # fmt: skip

    def cam(self, seq):
        self.decoded.append(seq)
        return self._cam()

    def latest_from(self, station_id, max_age_s=None):
        assert station_id == 7
        return self._cam(), 0.0


class FakeRadio:
    def __init__(self, obu):
        self.obu = obu

    def ego_obu(self, world):
        return self.obu

    def vehicle_of_station(self, world, station):
        return {7: "car1"}.get(station, "")


def _world() -> World:
    w = World(capacity=4)
    for vid, x in ((EGO_ID, 0.0), ("car1", 20.0)):
        s = w.add(vid, is_ego=vid == EGO_ID)
        w.x_m[s], w.y_m[s], w.heading_deg[s], w.speed_mps[s], w.length_m[s] = x, 0.0, 90.0, 10.0, 4.5
    w.step, w.t_s = 1, 0.1
    return w


def _phase(w, system="B", radio=True, bridge=None):
    obu = FakeObu(w)
    phase = AdasPhase(AdasConfig(system=system), Buildings([]), stream(1, "system_a"), bridge or FakeBridge(),
                      FakeRadio(obu) if radio else None)  # fmt: skip
    return phase, obu


def test_without_the_ego_nothing_is_evaluated():
    phase, _ = _phase(World(capacity=4))
    assert phase.step(World(capacity=4)) is None


def test_the_record_holds_the_true_gap_both_systems_and_what_the_driver_sees():
    w = _world()
    phase, obu = _phase(w, system="B")
    phase.phase_name = "P1"
    out = phase.step(w)
    r = out.record
    assert r["phase"] == "P1" and r["system"] == "B" and r["leader_id"] == "car1"
    assert r["gap_true_m"] == pytest.approx(16.5) and r["time_gap_true_s"] == pytest.approx(1.65)
    assert r["b_station"] == 7 and r["b_leader_id"] == "car1"
    assert r["b_gap_s"] == pytest.approx(1.55, abs=0.2)  # from the CAM: 20 m apart, a 4.5-m car
    assert out.displays == {"sys_b_gap_s": r["b_gap_s"], "sys_b_level": r["b_level"]}
    assert r["time_gap_displayed_s"] == r["b_gap_s"] and r["warning"] == r["b_level"]
    # the same CAM is decoded once; a new one again
    w.step, w.t_s = 2, 0.2
    phase.step(w)
    obu.seq = 2
    phase.step(w)
    assert obu.decoded == [1, 2]
    # the OBU loses the leader: B keeps showing the last one's newest CAM
    obu.present = False
    assert phase.step(w).record["b_station"] == 7
    phase.close()


def test_system_a_shown_and_nothing_without_a_leader_or_radio():
    w = _world()
    phase, _ = _phase(w, system="A", radio=False)
    out = phase.step(w)
    assert set(out.displays) == {"sys_a_lit"} and out.record["b_leader_id"] == ""
    assert out.record["b_station"] == -1 and out.record["time_gap_displayed_s"] is None
    phase, _ = _phase(w, system="none", bridge=FakeBridge(leader=None))
    r = phase.step(w).record
    assert r["leader_id"] == "" and r["gap_true_m"] is None and r["time_gap_true_s"] is None
    assert r["warning"] == "none" and not r["a_lit"]

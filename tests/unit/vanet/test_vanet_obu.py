"""OBU: neighbour table, extrapolation, criteria a-g one by one, latest CAM per station."""

import dataclasses

import numpy as np
import pytest
from vanet_testkit import records

from cosim.vanet.cam import ACC_EMERGENCY_BRAKE
from cosim.vanet.obu import (
    LeaderCriteria,
    ObuParams,
    ObuView,
    OwnState,
    RecordStore,
    criteria_masks,
    find_leader,
    neighbour_table,
)

NOW_US = 10_000_000
# receiver: heading north at 10 m/s, accelerating gently, rightmost lane
OWN = OwnState(x_m=0.0, y_m=0.0, heading_deg=0.0, speed_mps=10.0, accel_mps2=0.5, lane_position=1)
# a leader that satisfies a-g: 15 m ahead (gap 10.5 m -> 1.05 s), same lane and heading, slower accel
GOOD = dict(x_m=0.0, y_m=15.0, heading_deg=0.0, speed_mps=10.0, accel_mps2=0.0, length_m=4.5, lane_position=1)


def table(rows, own=OWN, extrapolation="none"):
    rec = records([{**r, "gen_ms": r.get("gen_ms", NOW_US // 1000)} for r in rows])
    return neighbour_table(rec, np.arange(len(rows)), NOW_US, own, extrapolation)


VIOLATORS = {
    # criterion flag: (a row that fails only that criterion, criteria overrides)
    "close": (dict(GOOD, y_m=14.0), dict(close_range_m=12.0)),
    "same_direction": (dict(GOOD, heading_deg=45.0), {}),
    "in_front": (dict(GOOD, y_m=3.0), {}),
    "same_lane": (dict(GOOD, lane_position=2), {}),
    "accel_smaller": (dict(GOOD, accel_mps2=1.0), {}),
    "time_gap": (dict(GOOD, y_m=30.0), {}),
    "no_emergency_brake": (dict(GOOD, accel_control=ACC_EMERGENCY_BRAKE), {}),
}


def test_the_good_leader_matches_all_criteria():
    t = table([GOOD])
    masks = criteria_masks(t, OWN, LeaderCriteria())
    assert all(m[0] for m in masks.values()), masks
    assert find_leader(t, OWN, LeaderCriteria()) == 0
    assert t.gap_m[0] == pytest.approx(10.5) and t.time_gap_s[0] == pytest.approx(1.05)


@pytest.mark.parametrize("flag", sorted(VIOLATORS))
def test_each_criterion_on_rejects_and_off_accepts(flag):
    row, overrides = VIOLATORS[flag]
    on = LeaderCriteria(**overrides)
    off = dataclasses.replace(on, **{flag: False})
    t = table([row])
    masks = criteria_masks(t, OWN, on)
    failing = [name for name, m in masks.items() if not m[0]]
    assert len(failing) == 1 and failing[0].split("_", 1)[1] == flag, failing
    assert find_leader(t, OWN, on) == -1
    assert find_leader(t, OWN, off) == 0


def test_same_lane_lateral_gate_uses_the_predicted_course():
    far_side = dict(GOOD, x_m=5.0)  # same lane number, 5 m to the right
    assert find_leader(table([far_side]), OWN, LeaderCriteria()) == -1
    assert find_leader(table([far_side]), OWN, LeaderCriteria(same_lane_max_lateral_m=None)) == 0
    # in a left curve of radius 100 m, a leader 20 m ahead on that curve is ~2 m to the left of the
    # straight line but on the receiver's course
    turning = dataclasses.replace(OWN, yaw_rate_dps=np.degrees(10.0 / 100.0))
    ang = 20.0 / 100.0
    on_curve = dict(
        GOOD, x_m=-(100.0 - 100.0 * np.cos(ang)), y_m=100.0 * np.sin(ang), heading_deg=-np.degrees(ang)
    )
    t = table([on_curve], own=turning)
    assert abs(t.lateral_m[0]) < 0.1
    assert find_leader(t, turning, LeaderCriteria()) == 0


def test_nearest_match_is_returned():
    t = table([dict(GOOD, y_m=18.0), GOOD, dict(GOOD, y_m=14.0, lane_position=2)])
    assert find_leader(t, OWN, LeaderCriteria()) == 1


def test_extrapolation_to_now():
    old = dict(GOOD, y_m=15.0, speed_mps=10.0, accel_mps2=-2.0, gen_ms=NOW_US // 1000 - 500)
    cv = table([old], extrapolation="constant_velocity")
    ca = table([old], extrapolation="constant_acceleration")
    assert cv.y_m[0] == pytest.approx(20.0)
    assert ca.y_m[0] == pytest.approx(15.0 + 10.0 * 0.5 - 0.5 * 2.0 * 0.25)
    assert ca.speed_mps[0] == pytest.approx(9.0)
    stopping = dict(old, speed_mps=1.0, accel_mps2=-4.0)  # stops after 0.25 s, 0.125 m
    st = table([stopping], extrapolation="constant_acceleration")
    assert st.y_m[0] == pytest.approx(15.125) and st.speed_mps[0] == 0.0
    assert table([old]).data_age_s[0] == pytest.approx(0.5)


def _store_with(rows, horizon_us=20_000_000):
    store = RecordStore(horizon_us=horizon_us, capacity=4)
    rec = records(rows)
    seqs = store.append(rec, now_us=NOW_US)
    return store, seqs


def test_view_table_ages_and_latest_from_with_staleness():
    rows = [
        dict(GOOD, station_id=7, sender_slot=3, gen_ms=9_000, rx_us=9_000_500),
        dict(GOOD, station_id=7, sender_slot=3, gen_ms=9_800, rx_us=9_800_500, y_m=16.0),
        dict(GOOD, station_id=9, sender_slot=4, gen_ms=4_000, rx_us=4_000_500),
    ]
    store, seqs = _store_with(rows)
    heard = np.full(8, -1, dtype=np.int64)
    heard[3] = seqs[1]
    heard[4] = seqs[2]
    view = ObuView(store, heard, NOW_US, OWN, ObuParams(), 1_000_000, receiver_slot=0)
    nb = view.neighbours()
    assert nb.station_id.tolist() == [7]  # station 9 last heard 6 s ago: outside the 5-s map memory
    # the memory is a time: the same with 100-ms frames, and it follows map_memory_s
    fast = ObuView(store, heard, NOW_US, OWN, ObuParams(), 100_000, receiver_slot=0)
    assert fast.neighbours().station_id.tolist() == [7]
    longer = ObuView(store, heard, NOW_US, OWN, ObuParams(map_memory_s=6.1), 1_000_000, receiver_slot=0)
    assert longer.neighbours().station_id.tolist() == [7, 9]
    assert view.neighbours(max_age_s=10.0).station_id.tolist() == [7, 9]
    cam, age = view.latest_from(7)
    assert cam is not None and age == pytest.approx(0.2)
    assert cam.y_m == pytest.approx(16.0) and cam.generation_t_s == pytest.approx(9.8)
    assert cam.rx_t_s == pytest.approx(9.8005) and cam.length_m == pytest.approx(4.5)
    cam, age = view.latest_from(9)
    assert cam is None and age == pytest.approx(6.0)  # stale: "no data"
    assert view.latest_from(9, max_age_s=10.0)[0] is not None
    assert view.latest_from(1234) == (None, float("inf"))
    lead = view.find_leader()
    assert lead is not None and lead.station_id == 7


def test_an_obu_forgets_a_cam_older_than_the_horizon_however_long_the_ring_keeps_it():
    """What an OBU holds depends on time alone, not on how many CAMs were sent since (the ring's fill), so
    a view is final before the step's own transmissions are stored (the radio process relies on it)."""
    rows = [dict(GOOD, station_id=9, sender_slot=4, gen_ms=2_000, rx_us=2_000_500)]
    heard = np.full(8, -1, dtype=np.int64)
    for horizon_s, held in ((7, False), (9, True)):
        store, seqs = _store_with(rows, horizon_us=horizon_s * 1_000_000)
        heard[4] = seqs[0]
        assert store.valid(seqs).all()  # still in the ring
        view = ObuView(store, heard, NOW_US, OWN, ObuParams(), 100_000, receiver_slot=0)
        cam, _ = view.latest_from(9, max_age_s=float("inf"))  # 8 s old
        assert (cam is not None) == held
        assert len(view.neighbours(max_age_s=100.0)) == int(held)


def test_record_store_grows_instead_of_dropping_young_records():
    store = RecordStore(horizon_us=1_000_000, capacity=2)
    a = store.append(records([dict(GOOD, rx_us=0)] * 2), now_us=0)
    b = store.append(records([dict(GOOD, rx_us=500_000)] * 3), now_us=500_000)
    assert store.valid(a).all() and store.valid(b).all() and store.cap >= 5
    # much later the oldest may be overwritten
    cap = store.cap
    c = store.append(records([dict(GOOD, rx_us=9_000_000)] * cap), now_us=9_000_000)
    assert store.cap == cap and not store.valid(a).any() and store.valid(c).all()


def test_params_validation():
    with pytest.raises(ValueError, match="replaced by obu.map_memory_s.*5 s"):
        ObuParams(table_frames=5)
    for bad in (0.0, -1.0, 61.0):
        with pytest.raises(ValueError, match="map_memory_s"):
            ObuParams(map_memory_s=bad)
    with pytest.raises(ValueError, match="must not exceed obu.map_memory_s"):
        ObuParams(map_memory_s=2.0, stale_after_s=3.0)
    assert ObuParams().map_memory_s == 5.0  # the paper's five frames of 1 s
    with pytest.raises(ValueError):
        LeaderCriteria(time_gap_max_s=0.0)

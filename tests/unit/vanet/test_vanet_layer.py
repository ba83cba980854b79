"""The lockstep layer: determinism, log columns, stations appearing / leaving, OBU timing, ego view."""

import numpy as np
import pytest
import shapely
from vanet_testkit import advance, make_world

from cosim.config import from_dict
from cosim.vanet import VanetLayer, VanetParams
from cosim.vanet.channel import OK, ChannelParams
from cosim.vanet.layer import LOAD_COLUMNS, RX_COLUMNS, STEP_COLUMNS, TX_COLUMNS
from cosim.vanet.obu import LeaderCriteria, ObuParams

DT = 0.1
CITY = [shapely.box(i * 60 + 10, j * 60 + 10, i * 60 + 50, j * 60 + 50) for i in range(5) for j in range(5)]


def city_world(n=40, seed=0):
    """Vehicles on the streets of CITY (x or y = multiple of 60), driving along them."""
    rng = np.random.default_rng(seed)
    street = rng.integers(0, 6, n) * 60.0
    along = rng.uniform(0, 300, n)
    vertical = rng.random(n) < 0.5
    xy = np.where(vertical[:, None], np.c_[street, along], np.c_[along, street])
    w = make_world(xy, capacity=64, ego=0)
    w.heading_deg[:n] = np.where(vertical, 0.0, 90.0) + np.where(rng.random(n) < 0.5, 180.0, 0.0)
    w.speed_mps[:n] = rng.uniform(0, 14, n)
    w.accel_mps2[:n] = rng.normal(0, 1, n)
    return w


def run(params, steps=40, seed=5, world_seed=0, buildings=CITY):
    w = city_world(seed=world_seed)
    layer = VanetLayer(params, buildings, np.random.default_rng(seed))
    out = []
    for k in range(steps):
        w.step = k
        out.append(layer.step(w, k, DT))
        advance(w, DT)
    return layer, out


def test_same_seed_same_results_and_seed_matters():
    for params in (
        VanetParams(rx_log="all"),
        VanetParams(channel=ChannelParams(shadowing="veins", interference="sinr"), rx_log="all"),
    ):
        _, a = run(params)
        _, b = run(params)
        for ra, rb in zip(a, b, strict=True):
            for topic, cols in ra.columns().items():
                for name, arr in cols.items():
                    assert np.array_equal(arr, rb.columns()[topic][name], equal_nan=True), (topic, name)
    _, c = run(VanetParams(rx_log="all"), seed=6)
    slots_a = np.concatenate([r.tx["slot"] for r in a])
    slots_c = np.concatenate([r.tx["slot"] for r in c])
    assert not np.array_equal(slots_a, slots_c)


def test_log_columns_have_the_documented_names_dtypes_and_lengths():
    _, res = run(VanetParams(rx_log="all"), steps=25)
    specs = {
        "/vanet/tx": TX_COLUMNS,
        "/vanet/rx": RX_COLUMNS,
        "/vanet/load": LOAD_COLUMNS,
        "/vanet/step": STEP_COLUMNS,
    }
    total = {t: 0 for t in specs}
    for r in res:
        for topic, cols in r.columns().items():
            assert list(cols) == list(specs[topic]), topic
            lengths = {len(v) for v in cols.values()}
            assert len(lengths) == 1
            total[topic] += lengths.pop()
            for name, arr in cols.items():
                assert arr.dtype == np.dtype(specs[topic][name]), (topic, name, arr.dtype)
    assert total["/vanet/tx"] > 0 and total["/vanet/rx"] > 0 and total["/vanet/step"] == 25
    assert total["/vanet/load"] == 2  # frames 0 and 1 completed in 2.5 s
    rx = np.concatenate([r.rx["outcome"] for r in res])
    assert {0, 2} <= set(rx.tolist())  # decoded and shadowed links in the city


def test_channel_load_rows_account_for_every_transmission():
    _, res = run(VanetParams(rx_log="all"), steps=30)
    load = {k: np.concatenate([r.load[k] for r in res]) for k in LOAD_COLUMNS}
    tx_frames = np.concatenate([r.tx["frame"] for r in res])
    assert load["frame"].tolist() == [0, 1, 2]
    for f, n_tx, busy in zip(load["frame"], load["tx_count"], load["busy_slots"], strict=True):
        assert n_tx == np.count_nonzero(tx_frames == f) and busy <= n_tx
    assert np.all(load["busy_ratio"] <= 1.0) and np.all(load["airtime_ratio"] < load["busy_ratio"] + 1e-6)


def test_station_leaving_and_a_new_vehicle_in_the_same_slot():
    params = VanetParams(channel=ChannelParams(shadowing="none"), rx_log="all")
    w = make_world([[0, 0], [50, 0], [100, 0]], heading_deg=90.0, speed_mps=0.0)
    layer = VanetLayer(params, [], np.random.default_rng(0))
    res = []
    for k in range(60):
        w.step = k
        if k == 30:
            w.remove("v1")
            assert w.add("new") == 1  # the freed slot is reused
            w.x_m[1], w.y_m[1], w.heading_deg[1], w.length_m[1], w.width_m[1] = 60.0, 5.0, 90.0, 4.5, 1.8
        res.append(layer.step(w, k, DT))
    old_id = [int(s) for r in res[:30] for s in r.tx["sender_station_id"][r.tx["sender_slot"] == 1]]
    new = [(r.t_s, int(s)) for r in res[30:] for s in r.tx["sender_station_id"][r.tx["sender_slot"] == 1]]
    assert set(old_id) == {2}
    assert new and {s for _, s in new} == {4}  # fresh station id
    assert min(t for t, _ in new) >= 4.0  # listened one full frame before its first transmission
    # the old vehicle's CAMs stay in the others' tables until they age out; the new one replaces them
    view = layer.obu_view(w, slot=0)
    assert 4 in view.neighbours().station_id.tolist()


def test_deliveries_visible_to_the_obu_from_the_next_step():
    params = VanetParams(channel=ChannelParams(shadowing="none"), rx_log="all")
    w = make_world([[0, 0], [0, 30]], heading_deg=0.0, ego=0)
    layer = VanetLayer(params, [], np.random.default_rng(1))
    for k in range(40):
        r = layer.step(w, k, DT)
        got = np.any((r.rx["receiver_slot"] == 0) & (r.rx["outcome"] == OK))
        if got:
            assert len(layer.obu_view(w).neighbours()) == 0
            layer.step(w, k + 1, DT)
            nb = layer.obu_view(w).neighbours()
            assert nb.station_id.tolist() == [layer.station_id_of(1)]
            return
    pytest.fail("the ego never received a CAM")


def test_ego_view_finds_the_leader_and_its_latest_cam():
    params = VanetParams(channel=ChannelParams(shadowing="none"), rx_log="all")
    w = make_world([[0, 0], [0, 16], [4, 30]], heading_deg=0.0, speed_mps=10.0, ego=0)
    w.lane_index[2] = 1  # the third car is in the next lane
    layer = VanetLayer(params, [], np.random.default_rng(2))
    for k in range(30):
        w.step = k
        layer.step(w, k, DT)
        advance(w, DT)
    view = layer.obu_view(w)
    # criterion e (the sender decelerates relative to the receiver) fails at equal accelerations
    assert view.find_leader() is None
    lead = view.find_leader(LeaderCriteria(accel_smaller=False))
    assert lead is not None and lead.station_id == layer.station_id_of(1)
    w.accel_mps2[0] = 0.5
    assert layer.obu_view(w).find_leader().station_id == lead.station_id
    assert lead.gap_m == pytest.approx(16 - 4.5, abs=1.5)
    cam, age = view.latest_from(lead.station_id)
    assert cam is not None and 0 <= age <= 1.1 + 1e-9
    assert cam.speed_mps == pytest.approx(10.0) and cam.length_m == pytest.approx(4.5)
    assert layer.obu_view(w, slot=7) is None


@pytest.mark.parametrize("mode", ["ego", "none"])
def test_rx_log_modes(mode):
    p = VanetParams(rx_log=mode)
    _, res = run(p, steps=20)
    rx = np.concatenate([r.rx["receiver_slot"] for r in res])
    if mode == "none":
        assert rx.size == 0
    else:
        assert rx.size > 0 and set(rx.tolist()) == {0}


def test_world_capacity_growth_mid_run():
    params = VanetParams(channel=ChannelParams(shadowing="none"), rx_log="all")
    w = make_world([[i * 10.0, 0] for i in range(4)], capacity=4)
    layer = VanetLayer(params, [], np.random.default_rng(0))
    for k in range(25):
        w.step = k
        if k == 12:
            slot = w.add("late")
            assert w.capacity == 8
            w.x_m[slot], w.y_m[slot], w.heading_deg[slot], w.length_m[slot], w.width_m[slot] = (
                5.0,
                5.0,
                0.0,
                4,
                2,
            )
        r = layer.step(w, k, DT)
    assert r.stats["n_stations"][0] == 5


def test_bad_base_steps_rejected():
    w = make_world([[0, 0]])
    with pytest.raises(ValueError):
        VanetLayer(VanetParams(), [], np.random.default_rng(0)).step(w, 0, 0.0125)  # not whole ms
    with pytest.raises(ValueError):
        VanetLayer(VanetParams(), [], np.random.default_rng(0)).step(w, 0, 0.03)  # 100 ms check period
    layer = VanetLayer(VanetParams(), [], np.random.default_rng(0))
    layer.step(w, 0, 0.1)
    with pytest.raises(ValueError):
        layer.step(w, 1, 0.05)


def test_params_load_from_yaml_mapping():
    p = from_dict(
        VanetParams,
        {"channel": {"shadowing": "veins", "wall_db": 6.0}, "sotdma": {"listen_frames": 0}, "rx_log": "ego"},
    )
    assert p.channel.wall_db == 6.0 and p.sotdma.listen_frames == 0 and p.obu == ObuParams()

"""The aether: link budget, building shadowing (paper LOS, Veins) and same-slot rules, hand-computed."""

import math

import numpy as np
import pytest
import shapely

from cosim.vanet.channel import (
    BELOW_SENSITIVITY,
    COLLIDED,
    DAMAGED,
    OK,
    SHADOWED,
    Aether,
    Buildings,
    ChannelParams,
    ExactShadowing,
    PathLoss,
    PolarShadowing,
)

LAMBDA = 299_792_458.0 / 5.89e9
BUDGET_DB = 10 * math.log10(20.0) + 89.0  # 20 mW, -89 dBm
RANGE_M = LAMBDA / (4 * math.pi) * 10 ** (BUDGET_DB / 20)  # Friis: 510.5 m


def evaluate(aether, tx_xy, rx_xy, groups=None, tx_station=None):
    """Every station is a receiver (ids 0..M-1); transmitters given by their station index."""
    rx_xy = np.asarray(rx_xy, dtype=float)
    tx_station = np.asarray(tx_station if tx_station is not None else range(len(tx_xy)))
    tx_xy = rx_xy[tx_station] if tx_xy is None else np.asarray(tx_xy, dtype=float)
    groups = np.zeros(len(tx_station), dtype=np.int64) if groups is None else np.asarray(groups)
    res = aether.evaluate(tx_xy, tx_station, groups, rx_xy, np.arange(len(rx_xy)))
    return {
        (int(t), int(r)): (int(o), float(p))
        for t, r, o, p in zip(res.tx, res.rx, res.outcome, res.power_dbm, strict=True)
    }


def test_free_space_range_from_link_budget():
    a = Aether(ChannelParams(shadowing="none"), [])
    assert a.comm_range_m == pytest.approx(RANGE_M, rel=1e-9)
    assert a.comm_range_m == pytest.approx(510.5, abs=0.1)


def test_two_cars_just_inside_and_just_outside_range():
    a = Aether(ChannelParams(shadowing="none"), [])
    inside = evaluate(a, None, [[0, 0], [RANGE_M - 1.0, 0]], tx_station=[0])
    assert inside[(0, 1)][0] == OK
    assert inside[(0, 1)][1] >= -89.0
    outside = evaluate(a, None, [[0, 0], [RANGE_M + 1.0, 0]], tx_station=[0])
    assert (0, 1) not in outside  # beyond the range: no link at all
    pl = PathLoss(ChannelParams())
    assert 10 * math.log10(20.0) - pl.loss_db(RANGE_M + 1.0) < -89.0


def test_received_power_hand_computed():
    a = Aether(ChannelParams(shadowing="none"), [])
    got = evaluate(a, None, [[0, 0], [0, 100.0]], tx_station=[0])[(0, 1)][1]
    want = 10 * math.log10(20.0) - 20 * math.log10(4 * math.pi * 100.0 / LAMBDA)
    assert got == pytest.approx(want, abs=1e-3)  # float32 on the hot path


def test_log_distance_and_two_ray_ranges():
    p = ChannelParams(path_loss="log_distance", log_distance_exponent=3.0)
    fs1 = 20 * math.log10(4 * math.pi / LAMBDA)
    assert Aether(p, []).comm_range_m == pytest.approx(10 ** ((BUDGET_DB - fs1) / 30.0), rel=1e-9)
    tr = Aether(ChannelParams(path_loss="two_ray"), [])
    # the ground reflection adds at most +6 dB: the range is within (0, 2x free space]
    assert 0 < tr.comm_range_m <= 2 * RANGE_M + 1
    d = np.arange(1.0, tr.comm_range_m + 50.0, 0.5)
    loss = tr.path_loss.loss_db(d)
    assert np.all(loss[d > tr.comm_range_m] > BUDGET_DB)
    # near field: two-ray interference oscillates around free space
    assert np.any(loss[d < 300] < PathLoss(ChannelParams()).free_space_db(d[d < 300]) - 3)


BLOCK = shapely.box(190.0, -10.0, 210.0, 10.0)  # 20 m x 20 m building between x = 0 and x = 400


@pytest.mark.parametrize("method", ["exact", "polar"])
def test_building_on_the_line_blocks_line_of_sight(method):
    a = Aether(ChannelParams(shadowing="los", shadow_method=method), [BLOCK])
    res = evaluate(a, None, [[2, 2], [398, 2], [398, 30], [2, 30]], tx_station=[0, 3], groups=[0, 1])
    assert res[(0, 1)][0] == SHADOWED and res[(0, 1)][1] == -np.inf
    assert res[(0, 2)][0] == OK  # (2,2) -> (398,30) passes 5 m north of the block (next test)
    assert res[(1, 2)][0] == OK  # (2,30) -> (398,30): 20 m clear of the block


def test_exact_los_geometry_of_the_diagonal_case():
    # the diagonal link of the previous test: y at x=190..210 is 2 + 28*(188..208)/396 = 15.3..16.7 > 10
    seg = shapely.LineString([(2, 2), (398, 30)])
    assert not seg.intersects(BLOCK)


@pytest.mark.parametrize("method", ["exact", "polar"])
def test_veins_obstacle_loss_for_a_known_polygon(method):
    p = ChannelParams(shadowing="veins", shadow_method=method, wall_db=9.0, per_meter_db=0.4)
    a = Aether(p, [BLOCK])
    # 2 -> 302 m along y = 2: two walls and 20 m inside the block: 2 x 9 + 20 x 0.4 = 26 dB
    res = evaluate(a, None, [[2, 2], [302, 2], [2, 40]], tx_station=[0])
    free = 10 * math.log10(20.0) - 20 * math.log10(4 * math.pi * 300.0 / LAMBDA)  # -84.4 dBm
    assert res[(0, 1)][1] == pytest.approx(free - 26.0, abs=0.05)
    assert res[(0, 1)][0] == SHADOWED  # -110.4 dBm < -89 dBm
    assert res[(0, 2)][0] == OK and res[(0, 2)][1] == pytest.approx(
        10 * math.log10(20.0) - 20 * math.log10(4 * math.pi * 38.0 / LAMBDA), abs=1e-3
    )


def test_veins_loss_values_exact_vs_polar_inside_building_and_two_buildings():
    bl = Buildings([BLOCK, shapely.box(250, -5, 260, 5)])
    ex = ExactShadowing(bl, "veins", 9.0, 0.4)
    po = PolarShadowing(bl, "veins", 600.0, 4.0, 1024, 64, 9.0, 0.4, 80.0)
    tx = np.array([[2.0, 2.0], [198.0, 2.0]])  # the second one sits inside the first building
    link_tx = np.array([0, 0, 1, 1])
    rx = np.array([[302.0, 2.0], [230.0, 2.0], [170.0, 2.0], [202.0, 2.0]])
    want = np.array([2 * 9 + 20 * 0.4 + 2 * 9 + 10 * 0.4, 2 * 9 + 20 * 0.4, 9 + 8 * 0.4, 4 * 0.4])
    got_ex = ex.loss_db(tx, link_tx, rx[:, 0], rx[:, 1])
    assert got_ex == pytest.approx(want, abs=1e-6)
    # polar: the transmitter cell centre (2,2) / (198,2) is the transmitter itself
    got_po = po.loss_db(tx, link_tx, rx[:, 0], rx[:, 1])
    assert got_po == pytest.approx(want, abs=0.1)


def test_veins_attenuation_can_push_a_link_below_sensitivity():
    p = ChannelParams(shadowing="veins", shadow_method="exact")
    a = Aether(p, [shapely.box(190.0, -10.0, 260.0, 10.0)])  # 70 m deep: 18 + 28 = 46 dB
    res = evaluate(a, None, [[0, 0], [400, 0]], tx_station=[0])
    assert res[(0, 1)][0] == SHADOWED and np.isfinite(res[(0, 1)][1])


def test_courtyard_hole_is_open_space():
    ring = shapely.Polygon(
        shapely.box(0, 0, 100, 100).exterior.coords, [shapely.box(30, 30, 70, 70).exterior.coords]
    )
    for method in ("exact", "polar"):
        a = Aether(ChannelParams(shadow_method=method), [ring])
        res = evaluate(a, None, [[40, 42], [62, 58], [150, 50]], tx_station=[0])
        assert res[(0, 1)][0] == OK  # both in the courtyard
        assert res[(0, 2)][0] == SHADOWED  # through the ring building


def test_paper_rule_damages_messages_in_the_overlap_only():
    # A and C send in the same slot; B hears both, D only A, E only C
    xy = [[0, 0], [400, 0], [800, 0], [-300, 0], [1100, 0]]
    a = Aether(ChannelParams(shadowing="none"), [])
    res = evaluate(a, None, xy, tx_station=[0, 2], groups=[5, 5])
    assert res[(0, 1)][0] == DAMAGED and res[(1, 1)][0] == DAMAGED
    assert res[(0, 3)][0] == OK and res[(1, 4)][0] == OK
    # different slots: no interference
    res = evaluate(a, None, xy, tx_station=[0, 2], groups=[5, 6])
    assert res[(0, 1)][0] == OK and res[(1, 1)][0] == OK


def test_paper_rule_shadowed_interferer_does_not_damage():
    block = shapely.box(590, -10, 610, 10)  # between B (400) and C (800)
    a = Aether(ChannelParams(shadowing="los", shadow_method="exact"), [block])
    res = evaluate(a, None, [[0, 0], [400, 0], [800, 0]], tx_station=[0, 2], groups=[1, 1])
    assert res[(0, 1)][0] == OK and res[(1, 1)][0] == SHADOWED


def test_sinr_capture():
    a = Aether(ChannelParams(shadowing="none", interference="sinr", capture_threshold_db=6.0), [])
    # B 100 m from A, 400 m from C: S/I = 20 log10(4) = 12 dB >= 6 -> A captured, C lost
    res = evaluate(a, None, [[0, 0], [100, 0], [500, 0]], tx_station=[0, 2], groups=[0, 0])
    assert res[(0, 1)][0] == OK and res[(1, 1)][0] == DAMAGED
    # equidistant: 0 dB, both lost
    res = evaluate(a, None, [[0, 0], [250, 0], [500, 0]], tx_station=[0, 2], groups=[0, 0])
    assert res[(0, 1)][0] == DAMAGED and res[(1, 1)][0] == DAMAGED
    # an interferer beyond the communication range still counts under the SINR rule
    assert a.link_range_m > a.comm_range_m
    res = evaluate(a, None, [[0, 0], [480, 0], [1100, 0]], tx_station=[0, 2], groups=[0, 0])
    s = res[(0, 1)][1]
    i = 10 * math.log10(20.0) - 20 * math.log10(4 * math.pi * 620.0 / LAMBDA)
    expect_ok = s - 10 * math.log10(10 ** (i / 10) + 10 ** (-11.0)) >= 6.0
    assert res[(0, 1)][0] == (OK if expect_ok else DAMAGED)
    assert (1, 1) not in res  # 620 m: not logged, beyond the communication range


def test_half_duplex_receiver_sending_in_the_same_slot_is_collided():
    a = Aether(ChannelParams(shadowing="none"), [])
    res = evaluate(a, None, [[0, 0], [100, 0]], tx_station=[0, 1], groups=[3, 3])
    assert res[(0, 1)][0] == COLLIDED and res[(1, 0)][0] == COLLIDED
    res = evaluate(a, None, [[0, 0], [100, 0]], tx_station=[0, 1], groups=[3, 4])
    assert res[(0, 1)][0] == OK and res[(1, 0)][0] == OK


def test_two_ray_null_inside_range_is_below_sensitivity():
    # with epsilon_r = 1.02 and 1.5 m antennas the last null is at 2 h^2 / lambda = 88 m and ~8 dB deep;
    # a -75 dBm receiver has its range beyond it, so links in the null fail on path loss alone
    a = Aether(ChannelParams(shadowing="none", path_loss="two_ray", sensitivity_dbm=-75.0), [])
    d = np.arange(50.0, a.comm_range_m, 0.05)
    below = d[10 * math.log10(20) - a.path_loss.loss_db(d) < -75.0]
    assert below.size, "the two-ray model has nulls inside its maximum range"
    res = evaluate(a, None, [[0, 0], [below[0], 0]], tx_station=[0])
    assert res[(0, 1)][0] == BELOW_SENSITIVITY
    assert np.any(np.abs(below - 88.4) < 1.0)


def _city(n=6, block=40.0, street=20.0):
    pitch = block + street
    return [
        shapely.box(i * pitch, j * pitch, i * pitch + block, j * pitch + block)
        for i in range(n)
        for j in range(n)
    ]


@pytest.mark.parametrize("model", ["los", "veins"])
def test_polar_cache_agrees_with_exact_on_a_city_grid(model):
    bl = Buildings(_city())
    rng = np.random.default_rng(3)
    # points on the streets (x or y inside a street band)
    pts = rng.uniform(-10, 350, size=(600, 2))
    on_street = ~Buildings(_city()).containing_count(pts).astype(bool)
    pts = pts[on_street][:300]
    tx = pts[:60]
    link_tx = np.repeat(np.arange(60), 40)
    rx = pts[rng.integers(0, len(pts), link_tx.size)]
    ex = ExactShadowing(bl, model, 9.0, 0.4).loss_db(tx, link_tx, rx[:, 0], rx[:, 1])
    po = PolarShadowing(bl, model, 600.0, 4.0, 1024, 64, 9.0, 0.4, 80.0).loss_db(
        tx, link_tx, rx[:, 0], rx[:, 1]
    )
    if model == "los":
        agree = np.mean(np.isinf(ex) == np.isinf(po))
        assert agree >= 0.95, agree
    else:
        both = np.isfinite(ex) & np.isfinite(po)
        blocked_ex, blocked_po = ex > 0, po > 0
        assert np.mean(blocked_ex == blocked_po) >= 0.95
        assert np.median(np.abs(ex[both] - po[both])) < 1.0


def test_polar_cache_is_reused_and_flushing_does_not_change_results():
    bl = Buildings(_city())
    po = PolarShadowing(bl, "los", 600.0, 4.0, 1024, 16, 9.0, 0.4, 80.0)
    tx = np.array([[50.0, 50.0], [51.0, 51.0], [110.0, 50.0]])  # first two share a lattice cell
    rx = np.random.default_rng(0).uniform(0, 350, (200, 2))
    link_tx = np.repeat(np.arange(3), 200)
    r = np.tile(rx, (3, 1))
    first = po.loss_db(tx, link_tx, r[:, 0], r[:, 1])
    assert po.builds == 2
    po._flush()
    again = po.loss_db(tx, link_tx, r[:, 0], r[:, 1])
    assert np.array_equal(first, again) and po.builds == 4


@pytest.mark.parametrize(
    "kw", [{"tx_power_mw": 0.0}, {"sensitivity_dbm": 20.0}, {"polar_bins": 4}, {"capture_threshold_db": -1.0}]
)
def test_impossible_params_rejected(kw):
    with pytest.raises(ValueError):
        ChannelParams(**kw)


def test_transmitters_must_be_receivers():
    a = Aether(ChannelParams(shadowing="none"), [])
    with pytest.raises(ValueError):
        a.evaluate(np.zeros((1, 2)), np.array([7]), np.zeros(1, int), np.zeros((2, 2)), np.array([0, 1]))

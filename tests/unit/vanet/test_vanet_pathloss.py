"""Path-loss models against values computed by hand from their defining formulas, and the shadowing field."""

import math

import numpy as np
import pytest

from cosim.vanet.channel import Aether, ChannelParams
from cosim.vanet.pathloss import (
    PathLoss,
    ShadowingField,
    free_space_db,
    tr37885_highway_los_db,
    tr37885_nlos_db,
    tr37885_urban_los_db,
    winner_b1_los_db,
    winner_b1_nlos_db,
)

F = 5.9e9  # log10(5.9) = 0.770852


def test_3gpp_tr37885_table_6_2_1_1_by_hand():
    # highway LOS: 32.4 + 20 log10(100) + 20 log10(5.9) = 32.4 + 40 + 15.41704
    assert tr37885_highway_los_db(100.0, F) == pytest.approx(87.81704, abs=1e-4)
    # urban LOS: 38.77 + 16.7 * 2 + 18.2 * 0.770852 = 38.77 + 33.4 + 14.02951
    assert tr37885_urban_los_db(100.0, F) == pytest.approx(86.19951, abs=1e-4)
    # NLOS: 36.85 + 30 * 2 + 18.9 * 0.770852 = 36.85 + 60 + 14.56910
    assert tr37885_nlos_db(100.0, F) == pytest.approx(111.41910, abs=1e-4)


def test_winner_plus_b1_by_hand():
    # h' = 1.5 - 1 = 0.5 m; d'BP = 4 * 0.5 * 0.5 * 5.9e9 / c = 19.68 m
    # 15 m (before the breakpoint): 22.7 log10(15) + 27 + 20 log10(5.9) = 26.69727 + 27 + 15.41704
    assert winner_b1_los_db(15.0, F) == pytest.approx(69.11431, abs=1e-4)
    # 100 m: 40 * 2 + 7.56 - 2 * 17.3 log10(0.5) + 2.7 log10(5.9) = 80 + 7.56 + 10.41564 + 2.08130
    assert winner_b1_los_db(100.0, F) == pytest.approx(100.05694, abs=1e-4)
    # below 10 m the model is evaluated at 10 m (its validity range)
    assert winner_b1_los_db(3.0, F) == winner_b1_los_db(10.0, F)
    # NLOS d1 = 100, d2 = 50: PL(50, 100) = PL_LOS(50) + 20 - 12.5 * 2.68 + 26.8 log10(100) + 3 log10(5.9 / 5)
    #   = 88.01574 + 20 - 33.5 + 53.6 + 0.21565 = 128.33139, below PL(100, 50) = 131.76622
    assert winner_b1_nlos_db(100.0, 50.0, F) == pytest.approx(128.33139, abs=1e-4)
    assert winner_b1_nlos_db(50.0, 100.0, F) == pytest.approx(128.33139, abs=1e-4)


def test_free_space_by_hand_and_model_dispatch():
    # 20 log10(4 pi 100 / (c / 5.9e9)) = 20 log10(24731.1) = 87.86482
    assert free_space_db(100.0, F) == pytest.approx(87.86482, abs=1e-4)
    for name, fn in (("3gpp_highway", tr37885_highway_los_db), ("3gpp_urban", tr37885_urban_los_db),
                     ("winner_b1", winner_b1_los_db)):  # fmt: skip
        pl = PathLoss(ChannelParams(frequency_hz=F, path_loss=name))
        d = np.array([20.0, 150.0, 600.0])
        assert np.allclose(pl.loss_db(d), fn(d, F))
        r = pl.max_range_m(100.0)
        assert float(pl.loss_db(r)) == pytest.approx(100.0, abs=1e-6)


def test_3gpp_highway_range_for_the_reference_budget():
    # 20 mW (13.01 dBm) - (-89 dBm) = 102.01 dB: 10 ** ((102.01 - 32.4 - 20 log10(5.89)) / 20) = 513.3 m
    a = Aether(ChannelParams(path_loss="3gpp_highway", lognormal_sigma_db=0.0, shadowing="none"), [])
    expected = 10 ** ((10 * math.log10(20.0) + 89.0 - 32.4 - 20 * math.log10(5.89)) / 20)
    assert a.comm_range_m == pytest.approx(expected, rel=1e-6)


def test_shadowing_field_sigma_correlation_and_reproducibility():
    sigma, dc = 3.0, 25.0
    # many independent fields, values at two points dc apart: std sigma, correlation exp(-1)
    a, b = [], []
    for seed in range(400):
        f = ShadowingField.draw(sigma, dc, np.random.default_rng(seed))
        v = f.at(np.array([[0.0, 0.0], [dc, 0.0]]))
        a.append(v[0])
        b.append(v[1])
    a, b = np.array(a), np.array(b)
    assert np.std(a) == pytest.approx(sigma, rel=0.12)
    assert np.corrcoef(a, b)[0, 1] == pytest.approx(math.exp(-1.0), abs=0.12)
    # the same seed gives the same value at the same place, in any order; the link value is reciprocal
    f1 = ShadowingField.draw(sigma, dc, np.random.default_rng(7))
    f2 = ShadowingField.draw(sigma, dc, np.random.default_rng(7))
    pts = np.array([[1.0, 2.0], [300.0, -40.0]])
    assert np.array_equal(f1.at(pts), f2.at(pts[::-1])[::-1])
    x = f1.at(pts)
    assert f1.link_db(x[0], x[1]) == f1.link_db(x[1], x[0])
    # one field over many places: std sigma too (the field is ergodic)
    many = f1.at(np.random.default_rng(1).uniform(0, 20_000, (4000, 2)))
    assert np.std(many) == pytest.approx(sigma, rel=0.15)

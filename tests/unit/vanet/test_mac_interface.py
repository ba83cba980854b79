"""The common MAC interface: output invariants of every MAC, the aether link budget, reactive DCC."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from mac_testkit import step_input

from cosim.vanet.channel import Aether, ChannelParams
from cosim.vanet.dcc import DccParams, ReactiveDcc
from cosim.vanet.mac import OUTCOME_NAMES, aether_link_budget
from cosim.vanet.mac_80211p import Mac80211p, Mac80211pParams
from cosim.vanet.mac_cv2x import Cv2xParams, MacCv2x

MACS = {
    "80211p": lambda n, rng: Mac80211p(Mac80211pParams(), n, rng),
    "cv2x": lambda n, rng: MacCv2x(Cv2xParams(), n, rng),
}


@pytest.mark.parametrize("name", sorted(MACS))
def test_output_invariants(name):
    rng = np.random.default_rng(1)
    xy = np.stack([rng.uniform(0, 1500, 60), rng.integers(0, 4, 60) * 4.0], axis=1)
    mac = MACS[name](60, np.random.default_rng(2))
    mac.start(np.arange(60), 0, 100_000)
    for k in range(4):
        out = mac.step(step_input(k, xy))
        t = out.tx_station.size
        assert out.tx_start_us.shape == out.tx_duration_us.shape == out.tx_resource.shape == (t,)
        assert np.all(np.diff(out.tx_start_us) >= 0)
        assert np.all((out.tx_start_us >= k * 100_000) & (out.tx_start_us < (k + 1) * 100_000))
        key = out.rx_tx * 1000 + out.rx_rx
        assert np.all(np.diff(key) > 0)  # sorted by (tx, rx), unique
        assert np.all(out.rx_rx != out.tx_station[out.rx_tx])
        assert out.rx_outcome.max(initial=0) < len(OUTCOME_NAMES)
        assert out.busy_us.shape == (60,) and np.all((out.busy_us >= 0) & (out.busy_us <= 100_000))
        assert out.sent.shape == (60,)
        held = out.tx_held if out.tx_held is not None else np.zeros(t, dtype=bool)
        assert np.array_equal(np.flatnonzero(out.sent), np.unique(out.tx_station[~held]))


def test_aether_link_budget_matches_the_aether():
    square = shapely.box(200, -50, 260, 50)
    aether = Aether(ChannelParams(shadowing="los"), [square])
    link = aether_link_budget(aether)
    tx = np.array([[0.0, 0.0]])
    rx = np.array([[0.0, 0.0], [100.0, 0.0], [400.0, 0.0], [100.0, 300.0], [2000.0, 0.0]])
    lp = link(tx, rx)
    p0 = aether.p.tx_power_dbm - aether.path_loss.loss_db(np.array([100.0, np.hypot(100, 300)]))
    assert lp.power_dbm[0, 0] == -np.inf and not lp.in_range[0, 0]  # itself
    assert lp.power_dbm[0, 1] == pytest.approx(p0[0], abs=1e-3)
    assert lp.power_dbm[0, 3] == pytest.approx(p0[1], abs=1e-3)
    assert lp.power_dbm[0, 2] == -np.inf and lp.in_range[0, 2]  # behind the building: shadowed, reported
    assert not lp.in_range[0, 4]


def test_reactive_dcc_table_a2_gradual():
    dcc = ReactiveDcc(DccParams(enabled=True), 2)
    dcc.start(np.arange(2))
    st = np.arange(2)
    dcc.sent(st, np.array([0, 0]))
    assert dcc.earliest_us(st).tolist() == [50_000, 50_000]  # relaxed: 50 ms
    dcc.update(st, np.array([0.7, 0.35]))  # one state up at most
    assert dcc.state.tolist() == [1, 1]
    for _ in range(5):
        dcc.update(st, np.array([0.7, 0.35]))
    assert dcc.state.tolist() == [4, 1]
    assert dcc.earliest_us(st).tolist() == [1_000_000, 100_000]
    off = ReactiveDcc(DccParams(), 1)
    assert off.earliest_us(np.array([0]))[0] < -1e12  # off by default: no limit

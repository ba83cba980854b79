"""The shared receiver: noise floor, capture, hidden terminal, carrier sense; the aether uses it."""

import numpy as np
import pytest

from cosim.vanet.channel import DAMAGED, OK, Aether, ChannelParams
from cosim.vanet.receiver import ReceiverParams, noise_floor_dbm, receive


def test_noise_floor_is_thermal_plus_noise_figure():
    assert noise_floor_dbm(10e6, 9.0) == pytest.approx(-95.0)  # -174 + 70 + 9
    assert ReceiverParams().noise_floor_dbm == pytest.approx(-95.0)
    assert ReceiverParams().floor_dbm == pytest.approx(-115.0)
    assert ChannelParams().receiver.cs_threshold_dbm == -85.0


def test_capture_near_sender_survives_far_interferer():
    # receiver at 0; A 10 m away and C 400 m away send in the same slot (free space, 13 dBm)
    a = Aether(ChannelParams(shadowing="none"), [])
    xy = np.array([[0.0, 0.0], [10.0, 0.0], [400.0, 0.0]])
    b = a.evaluate(xy[[1, 2]], np.array([1, 2]), np.array([5, 5]), xy, np.array([0, 1, 2]))
    at0 = {int(t): int(o) for t, r, o in zip(b.tx, b.rx, b.outcome, strict=True) if r == 0}
    assert at0 == {0: OK, 1: DAMAGED}
    # the paper's rule (no capture) loses both
    a = Aether(ChannelParams(shadowing="none", interference="paper"), [])
    b = a.evaluate(xy[[1, 2]], np.array([1, 2]), np.array([5, 5]), xy, np.array([0, 1, 2]))
    assert {int(o) for r, o in zip(b.rx, b.outcome, strict=True) if r == 0} == {DAMAGED}


def test_hidden_terminal_collides_with_sinr_capture():
    # A and C 800 m apart (out of each other's range), B in the middle: equal powers, SINR 0 dB
    a = Aether(ChannelParams(shadowing="none"), [])
    xy = np.array([[0.0, 0.0], [400.0, 0.0], [800.0, 0.0]])
    b = a.evaluate(xy[[0, 2]], np.array([0, 2]), np.array([3, 3]), xy, np.array([0, 1, 2]))
    at_b = [int(o) for r, o in zip(b.rx, b.outcome, strict=True) if r == 1]
    assert at_b == [DAMAGED, DAMAGED]


def test_receive_api_for_other_macs():
    p = ReceiverParams()
    # two overlapping transmissions (an 802.11p-style overlap matrix) at three receivers
    power = np.array([[-60.0, -80.0, -95.0], [-90.0, -70.0, -75.0]])
    overlap = np.array([[True, True], [True, True]])
    r = receive(power, overlap, p, tx_receiver=np.array([-1, -1]))
    # rx 0: -60 vs -90: decoded; rx 1: -70 vs -80 -> 10 dB; rx 2: -75 vs -95 -> ~20 dB
    assert r.decoded.tolist() == [[True, False, False], [False, True, True]]
    # -60 dBm over -90 dBm interference + -95 dBm noise: 10 log10(1e-6 / (1e-9 + 10 ** -9.5)) = 28.807 dB
    assert r.sinr_db[0, 0] == pytest.approx(28.807, abs=0.001)
    assert r.sensed.all()  # every receiver gets >= -85 dBm during both
    # the same as SOTDMA groups; and half duplex: receiver 0 sending the second transmission
    g = receive(power, np.array([7, 7]), p, tx_receiver=np.array([-1, 0]))
    assert not g.decoded[:, 0].any() and not g.sensed[:, 0].any()
    # the paper's rule: two senders above the sensitivity at a receiver (rx 1) lose both; one alone is kept
    pp = receive(power, np.array([7, 7]), ReceiverParams(rule="paper"))
    assert pp.decoded.tolist() == [[True, False, False], [False, False, True]]

"""SOTDMA: frame layout, slot selection statistics, entry / continuous operation, hidden terminal."""

import numpy as np
import pytest
from vanet_testkit import make_world

from cosim.vanet import VanetLayer, VanetParams
from cosim.vanet.channel import DAMAGED, OK, ChannelParams
from cosim.vanet.sotdma import ACTIVE, SotdmaMac, SotdmaParams, report_rate, select_slot


def test_frame_layout_from_largest_cam():
    p = SotdmaParams()
    # 243 B CAM + 80 B headers = 2606 bit incl. service + tail -> 55 symbols of 8 us + 40 us preamble/SIGNAL
    assert p.air_time_us(243) == 40 + 8 * 55
    assert p.frame_layout(243) == (1_000_000, 480 + 32, 1953)
    assert p.air_times_us(np.array([243, 42])) == pytest.approx([480.0, 40 + 8 * 21])
    with pytest.raises(ValueError):
        SotdmaParams(n_slots=5000).frame_layout(243)  # 5000 x 512 us > 1 s
    with pytest.raises(ValueError):
        SotdmaParams(bit_rate_mbps=5.1)  # 40.8 data bits per OFDM symbol: not an 802.11 rate


def test_report_rate_follows_t_gen_cam():
    assert report_rate(np.array([1000, 500, 300, 100, 50]), 1000, 10).tolist() == [1, 2, 4, 10, 10]


def _empty_map(n):
    return np.full(n, -1, dtype=np.int32), np.zeros(n, dtype=np.float32)


def test_selection_uniform_over_free_slots_of_the_interval():
    n = 1953
    until, dist = _empty_map(n)
    rng = np.random.default_rng(0)
    lo, hi = 1000, 1038  # 39 slots
    picks, sizes = zip(
        *(select_slot(until, dist, np.array([1010]), lo, hi, n, 4, rng) for _ in range(7600)), strict=True
    )
    picks = np.array(picks)
    assert set(sizes) == {38}  # own slot 1010 excluded
    assert picks.min() >= lo and picks.max() <= hi and 1010 not in picks
    counts = np.bincount(picks - lo, minlength=39)
    counts = np.delete(counts, 10)
    assert counts.min() > 140 and counts.max() < 260  # expected 200 each


def test_candidate_set_is_filled_with_the_farthest_stations_slots():
    n = 1953
    until, dist = _empty_map(n)
    lo, hi = 100, 119
    until[lo : hi + 1] = 5  # reserved through frame 5 (we select in frame 0)
    dist[lo : hi + 1] = np.arange(20) * 10.0  # slot 119 belongs to the farthest station
    until[[103, 111]] = -1  # only two free slots
    rng = np.random.default_rng(1)
    res = [select_slot(until, dist, np.array([], dtype=int), lo, hi, n, 4, rng) for _ in range(4000)]
    picks = np.array([r[0] for r in res])
    assert {r[1] for r in res} == {4}
    assert set(picks.tolist()) == {103, 111, 118, 119}
    assert np.all(np.abs(np.bincount(picks)[[103, 111, 118, 119]] - 1000) < 120)


def test_no_free_slot_reuses_the_farthest_stations_slot():
    n = 1953
    until, dist = _empty_map(n)
    until[:] = 3
    dist[:] = 50.0
    dist[207] = 480.0
    g, size = select_slot(until, dist, np.array([], dtype=int), 200, 220, n, 4, np.random.default_rng(0))
    assert (g, size) == (207, 1)
    # a reservation that ends before the frame we select in counts as free again
    g, size = select_slot(
        until, dist, np.array([], dtype=int), 4 * n + 200, 4 * n + 220, n, 4, np.random.default_rng(0)
    )
    assert size == 21


def test_entry_slots_in_selection_intervals_and_timeouts_uniform():
    p = SotdmaParams()
    n = 1953
    mac = SotdmaMac(p, n, 600, np.random.default_rng(4))
    stations = np.arange(600)
    mac.start(stations, 0)
    mac.rate[:300] = 1
    mac.rate[300:] = 5
    assert mac.enter(0).size == 0  # still listening
    assert mac.enter(n).size == 600
    assert np.all(mac.state == ACTIVE)
    # rate 5: NI = 390, SI = +-39 around NSS + j NI
    s5 = stations[300:]
    ni, delta = n // 5, int(0.1 * (n // 5))
    for j in range(5):
        nominal = (mac.nss[s5] + j * ni) % n
        off = (mac.res_slot[s5, j] - nominal + n // 2) % n - n // 2
        assert np.all(np.abs(off) <= delta)
        assert np.all(mac.res_nominal[s5, j] == nominal)
    assert np.all(mac.res_slot[:300, 1:] == -1) and np.all(mac.res_slot[:300, 0] >= 0)
    t = mac.res_timeout[mac.res_slot >= 0]
    assert t.min() == 3 and t.max() == 7
    counts = np.bincount(t, minlength=8)[3:]
    assert np.all(np.abs(counts - t.size / 5) < 0.15 * t.size / 5)


def test_continuous_operation_counts_down_then_reselects_in_the_same_interval():
    n = 1953
    mac = SotdmaMac(SotdmaParams(listen_frames=0), n, 1, np.random.default_rng(2))
    mac.start(np.array([0]), 0)
    mac.rate[0] = 2
    mac.enter(0)
    mac.force_reservation(0, 0, 500, 500, timeout=2)
    nominal = int(mac.res_nominal[0, 0])
    seen = []
    pending = np.array([True])
    for f in range(5):
        pending[:] = True
        tx = mac.transmissions(f * n, (f + 1) * n, pending)
        mac.resolve(tx)  # nobody else on the air: the reselection sees an empty map
        mine = tx.g[tx.g % n == 500] if f < 3 else tx.g
        seen.append((f, tx.timeout.tolist(), tx.offset.tolist(), (tx.g % n).tolist(), mine.tolist()))
    # frames 0..2 use slot 500 with timeouts 2, 1, 0; the last use announces the offset to the new slot
    assert [s[1][0] for s in seen[:3]] == [2, 1, 0]
    new_slot = (500 + seen[2][2][0]) % n
    assert seen[2][2][0] != 0 and new_slot == int(mac.res_slot[0, 0])
    delta = int(0.1 * (n // 2))  # SI half-width at rate 2
    assert abs((new_slot - nominal + n // 2) % n - n // 2) <= delta
    assert new_slot in seen[3][3]


def test_a_pending_cam_goes_out_in_the_first_reserved_slot_only():
    n = 100
    mac = SotdmaMac(SotdmaParams(n_slots=n, listen_frames=0), n, 1, np.random.default_rng(0))
    mac.start(np.array([0]), 0)
    mac.rate[0] = 4
    mac.enter(0)
    pending = np.array([True])
    tx = mac.transmissions(0, n, pending)
    assert tx.g.size == 1 and not pending[0]
    pending[:] = False
    assert mac.transmissions(n, 2 * n, pending).g.size == 0  # silent slots: nothing to send


def test_rate_change_adds_and_drops_reservations():
    n = 1953
    mac = SotdmaMac(SotdmaParams(listen_frames=0), n, 1, np.random.default_rng(3))
    mac.start(np.array([0]), 0)
    mac.enter(0)
    first = int(mac.res_slot[0, 0])
    mac.set_rates(np.array([0]), np.array([4]), 10)
    assert np.count_nonzero(mac.res_slot[0] >= 0) == 4 and first in mac.res_slot[0]
    noms = np.sort(mac.res_nominal[0, :4])
    gaps = np.diff(np.r_[noms, noms[0] + n])
    assert gaps.min() > n // 4 - n // 10  # spread over the frame
    mac.set_rates(np.array([0]), np.array([3]), 20)  # 3 > 4 // 2: hysteresis keeps 4
    assert np.count_nonzero(mac.res_slot[0] >= 0) == 4
    mac.set_rates(np.array([0]), np.array([2]), 30)
    assert np.count_nonzero(mac.res_slot[0] >= 0) == 2


def _run_hidden_terminal(seed):
    """A at 0 m, B at 400 m, C at 800 m: A and C cannot hear each other (free space range 510 m)."""
    params = VanetParams(channel=ChannelParams(shadowing="none"), rx_log="all")
    w = make_world([[0, 0], [400, 0], [800, 0]], heading_deg=90.0)
    layer = VanetLayer(params, [], np.random.default_rng(seed))
    k = 0
    rows = []
    for _ in range(25):  # listen 1 frame, enter, settle
        layer.step(w, k, 0.1)
        k += 1
    mac, n = layer.mac, layer.n_slots
    assert np.all(mac.state[:3] == ACTIVE) and np.all(mac.rate[:3] == 1)
    # force the hidden-terminal collision: C takes A's slot; A's timeout runs out first
    ja, jc = 0, 0
    g_next = int(mac.res_next_g[0, ja])
    slot = int(mac.res_slot[0, ja])
    mac.force_reservation(0, ja, slot, g_next, timeout=2)
    mac.force_reservation(2, jc, slot, g_next, timeout=6)
    f0 = g_next // n
    for _ in range(90):
        r = layer.step(w, k, 0.1)
        k += 1
        rx = r.rx
        at_b = rx["receiver_slot"] == 1
        rows += list(zip(rx["frame"][at_b], rx["sender_slot"][at_b], rx["outcome"][at_b], strict=True))
    return f0, rows, layer


def test_hidden_terminal_b_gets_damaged_messages_then_sotdma_moves_a():
    f0, rows, layer = _run_hidden_terminal(seed=11)
    damaged = [(f, s) for f, s, o in rows if o == DAMAGED]
    assert damaged, "B must see the collision of A and C"
    assert {s for _, s in damaged} == {0, 2}
    # A's timeout (2) ends at frame f0 + 2: from frame f0 + 3 on, B decodes both every frame
    assert max(f for f, _ in damaged) <= f0 + 2
    later = [(f, s, o) for f, s, o in rows if f >= f0 + 3]
    assert later and all(o == OK for _, _, o in later)
    assert {s for _, s, _ in later} == {0, 2}
    assert layer.mac.res_slot[0, 0] != layer.mac.res_slot[2, 0]


def test_hidden_terminal_resolves_within_the_timeout_for_most_seeds():
    resolved = 0
    for seed in range(8):
        f0, rows, _ = _run_hidden_terminal(seed)
        dmg = [f for f, _, o in rows if o == DAMAGED]
        resolved += bool(dmg) and max(dmg) <= f0 + 2
    assert resolved >= 7


def _two_choosers(order_aware: bool) -> tuple[int, int]:
    """Stations 0 and 1 (in range of each other) both reach timeout 0 in one window, at slots 10 and 12, with
    overlapping selection intervals in which one slot is free; every other slot is held by far stations."""
    n = 100
    p = SotdmaParams(n_slots=n, listen_frames=0, min_candidates=1, selection_interval_frac=0.1)
    mac = SotdmaMac(p, n, 2, np.random.default_rng(0))
    mac.start(np.array([0, 1]), 0)
    mac.rate[:] = 1
    mac.enter(0)
    mac.force_reservation(0, 0, 10, 10, timeout=0)
    mac.force_reservation(1, 0, 12, 12, timeout=0)
    mac.res_nominal[0, 0], mac.res_nominal[1, 0] = 10, 12
    mac.first_frame_end_g[:] = 0
    mac.map_until[:] = 99  # reserved for a long time by stations 900 m away ...
    mac.map_dist[:] = 900.0
    mac.map_until[:, 15] = -1  # ... except slot 15, free in both intervals (0-20 and 2-22)
    pending = np.array([True, True])
    tx = mac.transmissions(0, 50, pending)  # one window holds both uses
    assert tx.g.tolist() == [10, 12] and tx.offset.tolist() == [0, 0]  # the choices are still open

    def decoded_by(stations):  # each station decodes the other's transmission, 50 m away
        rx = [s for s in stations.tolist() for t in (0, 1) if t != s]
        lt = [1 - s for s in stations.tolist()]
        return np.array(rx), np.array(lt), np.full(len(rx), 50.0, dtype=np.float32)

    mac.resolve(tx, decoded_by if order_aware else None)
    return int(mac.res_next_g[0, 0]), int(mac.res_next_g[1, 0])


def test_a_reservation_made_earlier_in_the_step_is_seen_by_later_choosers():
    a, b = _two_choosers(order_aware=True)
    assert a == n_plus(15)  # station 0 chooses first (slot 10): the one free slot, a frame later
    assert b != a  # station 1 (slot 12) heard station 0's announcement at slot 10: slot 15 is taken
    # without hearing it (the maps as they were at the start of the step) both take slot 15
    a0, b0 = _two_choosers(order_aware=False)
    assert a0 == b0 == n_plus(15)


def n_plus(slot: int, n: int = 100) -> int:
    return n + slot


def test_a_move_decided_at_a_silent_use_is_announced_by_the_next_transmission():
    """Station 0 reaches timeout 0 at slot 10 with no CAM waiting: it sends nothing there, so its next
    transmission (slot 30, a CAM) carries the offset to the new slot (ITU-R M.1371 ITDMA slot increment), and a
    neighbour that decodes it holds that slot; without a transmission in between, the move stays unknown."""
    n = 100
    p = SotdmaParams(n_slots=n, listen_frames=0, min_candidates=1, selection_interval_frac=0.1)
    mac = SotdmaMac(p, n, 2, np.random.default_rng(0))
    mac.start(np.array([0, 1]), 0)
    mac.rate[:] = 2
    mac.enter(0)
    mac.force_reservation(0, 0, 10, 10, timeout=0)
    mac.force_reservation(0, 1, 30, 30, timeout=5)
    mac.res_nominal[0, 0], mac.res_nominal[0, 1] = 10, 30
    mac.res_next_g[1] = -1  # station 1 only listens
    mac.first_frame_end_g[:] = 0
    tx = mac.transmissions(0, 20, np.array([False, False]))  # slot 10 used without a CAM: silent
    assert tx.g.size == 0
    mac.resolve(tx)
    new_g = int(mac.res_next_g[0, 0])
    assert n <= new_g < 2 * n and mac.res_timeout[0, 0] >= p.timeout_min_frames
    tx = mac.transmissions(20, 50, np.array([True, False]))  # slot 30 carries a CAM
    mac.resolve(tx)
    assert tx.g.tolist() == [30] and tx.timeout.tolist() == [5]
    assert tx.offset.tolist() == [new_g - 30]  # the announcement of the move
    mac.hear(np.array([1]), np.array([0]), tx.g, tx.timeout, tx.offset, np.array([40.0], dtype=np.float32))
    assert mac.map_until[1, new_g % n] >= new_g // n + p.timeout_min_frames  # station 1 holds the new slot
    assert not mac._unannounced  # announced once

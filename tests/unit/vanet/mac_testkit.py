"""Helpers for the MAC unit tests: free-space link budget and a step driver."""

from __future__ import annotations

import numpy as np

from cosim.vanet.mac import MacInput, distance_link_budget

LAMBDA_M = 299_792_458.0 / 5.89e9


def free_space_dbm(d_m):
    """13 dBm, free space at 5.89 GHz [dBm]: -85 dBm at 321 m, -89 dBm at 510 m."""
    return 13.0 - 20.0 * np.log10(4.0 * np.pi * np.asarray(d_m) / LAMBDA_M)


LINK = distance_link_budget(free_space_dbm, 510.5)


def step_input(k, xy, pending=None, size=190, dt_us=100_000):
    xy = np.asarray(xy, dtype=float)
    n = len(xy)
    pend = np.ones(n, dtype=bool) if pending is None else np.asarray(pending, dtype=bool)
    return MacInput(k * dt_us, dt_us, np.arange(n), xy, pend, np.full(n, size), np.full(n, k * dt_us), LINK)


def outcome_at(out, sender, receiver):
    """Outcome code of sender's transmission at receiver (None when not reported)."""
    t = np.flatnonzero(out.tx_station == sender)
    if t.size == 0:
        return None
    m = (out.rx_tx == t[0]) & (out.rx_rx == receiver)
    return int(out.rx_outcome[m][0]) if m.any() else None

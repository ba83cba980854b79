"""IEEE 802.11p and C-V2X mode 4 behind ``cosim radio``'s MAC interface (``radio.MACS``), issue 18.

The radio scenario's aether is the link budget (``mac.aether_link_budget``: its path loss and log-normal
shadowing) and its receiver decides every frame (``channel.receiver``), as for SOTDMA: the three MACs run on
the same layout, seed, channel and receiver. Defaults: ``Mac80211pParams()`` / ``Cv2xParams()`` (sources in
their modules).
"""

from __future__ import annotations

import numpy as np

from cosim.vanet.mac import MacInput, aether_link_budget


class MacLinks:
    """What ``run_radio`` asks of a window's links, from a ``MacOutput``."""

    def __init__(self, out, xy: np.ndarray, active: np.ndarray):
        self.out = out
        lt, lr = out.decoded()
        self._lt, self._lr = lt, active[lr]
        snd = active[out.tx_station[lt]]
        self._d = np.hypot(*(xy[snd] - xy[self._lr]).T).astype(np.float32)
        self._busy = np.zeros(xy.shape[0])
        self._busy[active] = out.busy_us

    def decoded(self):
        """(transmission index, receiver station, distance [m]) of every decoded frame."""
        return self._lt, self._lr, self._d

    def sensed_busy_us(self, air_us=None) -> np.ndarray:
        """Busy time each station sensed in the window [us] (the MAC's own carrier sense)."""
        return self._busy


class InterfaceRadioMac:
    """A ``mac.Mac`` (802.11p, C-V2X) as a ``cosim radio`` MAC."""

    has_slots = False
    mac_cls = None
    params_cls = None

    def __init__(self, sc, n: int, rng: np.random.Generator):
        self.sc = sc
        self.n = n
        self.mac = self.mac_cls(self.params_cls(**(sc.mac_params or {})), n, rng)
        self.started = np.zeros(n, dtype=bool)
        self.held_gen = np.full(n, -1, dtype=np.int64)
        self._tx_held = None
        self._taken = None
        self.aether = self.xy = self.link = None

    def bind(self, aether, xy: np.ndarray) -> None:
        """The scenario's aether and (live) station positions."""
        self.aether, self.xy = aether, xy
        self.link = aether_link_budget(aether)

    def start(self, stations: np.ndarray, t_us: int) -> None:
        self.mac.start(stations, t_us, 100_000)
        self.started[stations] = True

    def window(self, t_lo_us: int, t_hi_us: int, pending: np.ndarray, evaluate):
        active = np.flatnonzero(self.started)
        rx = self.aether.rx
        inp = MacInput(
            t0_us=t_lo_us,
            dt_us=t_hi_us - t_lo_us,
            stations=active,
            xy=self.xy[active],
            pending=pending[active],
            size_bytes=np.full(active.size, self.sc.size_bytes, dtype=np.int64),
            gen_us=np.full(active.size, t_lo_us, dtype=np.int64),
            link=self.link,
            sensitivity_dbm=rx.sensitivity_dbm,
            noise_dbm=rx.noise_floor_dbm,
            receiver=rx,
        )
        out = self.mac.step(inp)
        pending[active[out.sent]] = False
        self._taken = active[out.taken] if out.taken is not None else active[:0]
        pending[self._taken] = False
        tx_st = active[out.tx_station]
        self._tx_held = out.tx_held if out.tx_held is not None else np.zeros(tx_st.size, dtype=bool)
        return tx_st, out.tx_resource, MacLinks(out, self.xy, active), out.tx_duration_us.astype(np.float64)

    def tx_gen(self, gen_of: np.ndarray, tx_st: np.ndarray) -> np.ndarray:
        """Generation step of the CAM each transmission carries: the pending one's, or (C-V2X) the one the MAC
        took over in an earlier window; then remembers the CAMs taken over in this one."""
        gen = gen_of[tx_st].copy()
        held = self._tx_held
        if held is not None and held.any():
            gen[held] = self.held_gen[tx_st[held]]
        if self._taken is not None and self._taken.size:
            self.held_gen[self._taken] = gen_of[self._taken]
        return gen


class Ieee80211pRadioMac(InterfaceRadioMac):
    from cosim.vanet.mac_80211p import Mac80211p as mac_cls
    from cosim.vanet.mac_80211p import Mac80211pParams as params_cls


class Cv2xRadioMac(InterfaceRadioMac):
    from cosim.vanet.mac_cv2x import Cv2xParams as params_cls
    from cosim.vanet.mac_cv2x import MacCv2x as mac_cls

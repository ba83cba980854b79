"""Independent reference for cosim's C-V2X mode 4 MAC: the analytical model of

    M. Gonzalez-Martin, M. Sepulcre, R. Molina-Masegosa, J. Gozalvez, "Analytical Models of the Performance of
    C-V2X Mode 4 Vehicular Communications", IEEE Trans. Veh. Technol. 68(2):1155-1166, 2019,
    DOI 10.1109/TVT.2018.2888704 (post-print arXiv:1807.06508).

Written for cosim from the paper's equations (numbers in brackets below), with the parameters the authors'
MATLAB release states (github.com/msepulcre/C-V2X, commit 71d4c25: CV2XMode4.m, get_PL_SH.m, get_BLER.m);
no cosim code is used, so it can judge cosim's SB-SPS. Vehicles stand every 1/beta m on a line; every one
sends a packet of B bytes every 1/lambda s on one of S subchannels with Pt.

PDR(d) = 1 - dHD - dSEN - dPRO - dCOL [6], the four losses being exclusive (each counted only when the
earlier ones did not occur, [6.1]-[6.5]):

* half duplex [7]: the receiver transmits in the same subframe, lambda / 1000;
* sensing [10]: the received power is below P_SEN = -90.5 dBm (3 dB log-normal shadowing around the path
  loss);
* propagation [13]: the mean block error rate at the SNR, over the received power given it exceeds P_SEN,
  from the BLER-vs-SINR curve of the MCS (3GPP R1-160284: 190 B in 10 RBs, QPSK r ~ 0.7, 280 km/h relative
  speed, for S = 4; r ~ 0.5 on 12 RBs for S = 2); noise -95 dBm in 10 MHz scaled to the data RBs;
* collision [14], [15]: 1 - prod_i (1 - p_sim,i p_int,i) over interferers i every 1/beta m up to 1 km from the
  receiver; p_int [17], [18]: the extra block errors an interferer on the same subchannel causes (one
  interferer at a time, its power log-normal too); p_sim: the probability that the interferer and the
  transmitter use the same resource, from the resources each excludes (senses above the threshold) and the
  candidates they share, [23]-[31]: step 2 of the SB-SPS (threshold P_SEN) and step 3 (threshold raised
  until 20 % of the resources remain), weighted by alpha(CBR) [21], [22].

Run ``python validation/cv2x/gm2019.py`` to print the model's PDR per 50-m band for the configurations the
validation uses (what ``gm2019_bands.csv`` holds).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

C_LIGHT = 3e8  # [m/s] as the authors' release


@dataclass(frozen=True)
class Gm2019:
    beta: float = 0.1  # traffic density [veh/m]
    lam_hz: float = 10.0  # packets per second per vehicle
    pt_dbm: float = 20.0  # transmit power [dBm]
    subchannels: int = 4  # S: subchannels of the 10-MHz channel; a 190-B packet takes one
    psen_dbm: float = -90.5  # P_SEN: sensing (and step-2 exclusion) threshold [dBm]
    fc_hz: float = 5.91e9
    h_m: float = 1.5  # both antennas; WINNER+ B1 with environment height 0 (effective height = h)
    sigma_db: float = 3.0  # log-normal shadowing
    step_db: float = 0.1  # grid of the received-power integrals and of the step-3 threshold raise [dB]
    reach_m: int = 1500  # interferer distances considered in the exclusion sums [m]
    interferer_reach_m: float = 1000.0  # interferers counted in the collision product [m]

    # ---- channel -------------------------------------------------------------------------------------------
    def path_loss_db(self, d_m) -> np.ndarray:
        """WINNER+ B1 LOS (breakpoint 4 h h f / c, heights above a 0-m environment), never below free space,
        distances under 3 m taken at 3 m (the release's get_PL_SH.m)."""
        d = np.maximum(np.abs(np.asarray(d_m, dtype=np.float64)), 3.0)
        fg = self.fc_hz / 1e9
        d_bp = 4.0 * self.h_m * self.h_m * self.fc_hz / C_LIGHT
        near = 22.7 * np.log10(d) + 27.0 + 20.0 * math.log10(fg)
        far = 40.0 * np.log10(d) + 7.56 - 2.0 * 17.3 * math.log10(self.h_m) + 2.7 * math.log10(fg)
        free = 20.0 * np.log10(d) + 46.4 + 20.0 * math.log10(fg / 5.0)
        return np.maximum(np.where(d < d_bp, near, far), free)

    @property
    def data_rbs(self) -> int:
        return {4: 10, 2: 12}[self.subchannels]  # RBs of a 190-B packet's data field (CV2XMode4.m)

    @property
    def noise_dbm(self) -> float:
        return -95.0 - 10.0 * math.log10(50.0 / self.data_rbs)  # -95 dBm in 50 RBs (NF 9 dB, 10 MHz)

    def bler(self, sinr_db) -> np.ndarray:
        """BLER vs SINR, linear in dB between the points (R1-160284 as read by the authors, get_BLER.m):
        1 below the first point, 1e-3 up to 20 dB, 1e-4 above."""
        if self.subchannels == 4:  # 190 B, QPSK r ~ 0.7
            s = [0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 20 + 1e-6]
            p = [1, 0.9, 0.7, 0.4, 0.13, 0.045, 0.017, 0.007, 1e-3, 1e-3, 1e-3, 1e-4]
        else:  # 190 B, QPSK r ~ 0.5
            s = [-2, 0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 20 + 1e-6]
            p = [1, 0.9, 0.7, 0.3, 0.09, 0.02, 0.002, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-4]
        return np.interp(sinr_db, s, p)

    def _phi(self, x) -> np.ndarray:
        """Standard normal CDF."""
        return 0.5 * np.vectorize(math.erfc, otypes=[float])(
            -np.asarray(x, dtype=np.float64) / math.sqrt(2.0)
        )

    def psr(self, d_m, threshold_dbm: float | None = None) -> np.ndarray:
        """Probability that a packet sent d_m away arrives at or above the threshold [11]."""
        th = self.psen_dbm if threshold_dbm is None else threshold_dbm
        return 1.0 - self._phi((th - self.pt_dbm + self.path_loss_db(d_m)) / self.sigma_db)

    def mean_bler(self, d_m: float, interferer_m=None) -> np.ndarray:
        """Mean BLER of a packet from d_m away that arrives above P_SEN [13]; with interferers (array of
        distances to the receiver), one value per interferer: the SINR with that one alone [17]."""
        mu = self.pt_dbm - float(self.path_loss_db(d_m))
        lo = self.psen_dbm
        hi = max(mu + 8.0 * self.sigma_db, lo + self.step_db)
        s = np.arange(lo, hi, self.step_db) + 0.5 * self.step_db  # received power, conditional on >= P_SEN
        w = np.exp(-0.5 * ((s - mu) / self.sigma_db) ** 2)
        w /= w.sum()
        noise = 10.0 ** (self.noise_dbm / 10.0)
        if interferer_m is None:
            return float(w @ self.bler(s - self.noise_dbm))
        z, wz = np.polynomial.hermite_e.hermegauss(48)  # E over the interferer's shadowing, N(0, sigma)
        wz = wz / wz.sum()
        mi = self.pt_dbm - self.path_loss_db(np.asarray(interferer_m, dtype=np.float64))  # (K,)
        i_mw = 10.0 ** ((mi[:, None] + self.sigma_db * z[None, :]) / 10.0)  # (K, Z)
        j_db = 10.0 * np.log10(i_mw + noise)
        sinr = s[None, None, :] - j_db[:, :, None]  # (K, Z, S)
        return np.einsum("kzs,z,s->k", self.bler(sinr), wz, w)

    # ---- the four errors -----------------------------------------------------------------------------------
    @property
    def n_resources(self) -> float:
        return self.subchannels * 1000.0 / self.lam_hz  # N [28]: subchannels x subframes of one RRI

    def excluded(self, s_psr: float) -> float:
        """Mean number of resources a station excludes when it senses s_psr vehicles on average [29], [33]."""
        n, half = self.n_resources, s_psr / 2.0
        k = np.arange(1, math.floor(half) + 1)
        return half + float(np.maximum(1.0 - k / (n - half), 0.0).sum())

    @cached_property
    def _grid(self) -> np.ndarray:
        return np.arange(-self.reach_m, self.reach_m + 1, dtype=np.float64)  # 1-m grid of interferer offsets

    def _p_sim(self, psr_at_psen: np.ndarray, ne: float, s_psr: float) -> np.ndarray:
        """Mean common candidate resources over Nc^2, per distance between the two stations (1-m lags)
        [26], [27], [30]: shared exclusions from the autocorrelation of the PSR profile."""
        n = self.n_resources
        nc = 0.2 * n
        r = np.correlate(psr_at_psen, psr_at_psen, mode="full")[psr_at_psen.size - 1 :]  # lags 0, 1, ... [m]
        r0 = r[0]
        ce = (r / r0) * (self.beta * ne * r0 / s_psr - ne * ne / n) + ne * ne / n
        ca = n - 2.0 * ne + ce
        return ca * (nc / (n - ne)) ** 2 / (nc * nc)

    def cbr(self) -> float:
        return self.excluded(self.beta * float(self.psr(self._grid).sum())) / self.n_resources  # [34]

    def errors(self, distances_m) -> dict[str, np.ndarray]:
        """dHD, dSEN, dPRO, dCOL and the PDR at each Tx-Rx distance [m] (after [6.1]-[6.5])."""
        d = np.asarray(distances_m, dtype=np.float64)
        n = self.n_resources
        hd = np.full(d.shape, self.lam_hz / 1000.0)  # [7]
        sen = self._phi((self.psen_dbm - self.pt_dbm + self.path_loss_db(d)) / self.sigma_db)  # [10]
        pro = np.array([self.mean_bler(x) for x in d])  # [13]
        psr = self.psr(self._grid)
        s_psr = self.beta * float(psr.sum())  # [29.1]
        ne2 = self.excluded(s_psr)
        cbr = ne2 / n
        alpha = 0.0 if cbr < 0.2 else (2.0 * cbr - 0.4 if cbr <= 0.7 else 1.0)  # [22]
        k_max = round(self.interferer_reach_m * self.beta)
        offs = np.arange(1, k_max + 1) / self.beta
        offs = np.concatenate([-offs[::-1], offs])  # interferers around the receiver [m]
        # step 3: the threshold raised (here in step_db) until at least 20 % of the resources remain [32], [33]
        th3, ne3 = self.psen_dbm, None
        if alpha < 1.0:
            while True:
                ne3 = self.excluded(2.0 * self.beta * float(self.psr(self._grid, th3).sum()))
                if n - ne3 >= 0.2 * n:
                    break
                th3 += self.step_db
        col = {2: np.zeros(d.shape), 3: np.zeros(d.shape)}
        p_int_cache: dict[float, np.ndarray] = {}
        for j, x in enumerate(d.tolist()):
            if pro[j] >= 1.0:
                continue
            if x not in p_int_cache:
                p_sinr = self.mean_bler(x, np.abs(offs))
                p_int_cache[x] = (p_sinr - pro[j]) / (1.0 - pro[j])  # [18]
            p_int = p_int_cache[x]
            to_tx = np.abs(offs + x)  # interferer to transmitter [m]
            lag = np.rint(to_tx).astype(np.int64)
            for step, ne, th in ((2, ne2, self.psen_dbm), (3, ne3, th3)):
                if ne is None:
                    continue
                shared = self._p_sim(psr, ne, s_psr)[lag]
                p_s = 1.0 - (1.0 - 1.0 / self.lam_hz) * self.psr(to_tx, th)  # [24]: tau = lambda (counter)
                col[step][j] = 1.0 - np.prod(1.0 - p_s * shared * p_int)  # [23]/[31], [15], [14]
        good = (1.0 - hd) * (1.0 - sen)
        out = {
            "hd": hd,
            "sen": sen * (1.0 - hd),
            "pro": pro * good,
            "col": (alpha * col[2] + (1.0 - alpha) * col[3]) * good * (1.0 - pro),  # [21]
        }
        out["pdr"] = 1.0 - out["hd"] - out["sen"] - out["pro"] - out["col"]
        out["cbr"] = cbr
        out["alpha"] = alpha
        return out

    def pdr_bands(self, band_m: float = 50.0, to_m: float = 500.0, points_per_band: int = 5) -> list[dict]:
        """The PDR averaged over each band [a, a + band_m) (receivers are uniform in distance on a road):
        the mean of the model at the band's sub-interval midpoints."""
        rows = []
        for a in np.arange(0.0, to_m, band_m):
            xs = a + (np.arange(points_per_band) + 0.5) * band_m / points_per_band
            pdr = float(self.errors(xs)["pdr"].mean())
            rows.append({"from_m": float(a), "to_m": float(a + band_m), "pdr": pdr})
        return rows


if __name__ == "__main__":
    print("beta_veh_per_m,lambda_hz,pt_dbm,subchannels,from_m,to_m,pdr")
    for beta in (0.1, 0.3):
        m = Gm2019(beta=beta)
        for b in m.pdr_bands():
            cfg = f"{beta:g},{m.lam_hz:g},{m.pt_dbm:g},{m.subchannels}"
            print(f"{cfg},{b['from_m']:g},{b['to_m']:g},{b['pdr']:.4f}")

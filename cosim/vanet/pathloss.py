"""Path loss and log-normal shadowing, shared by every MAC (SOTDMA, 802.11p, C-V2X) through the aether.

Models (``ChannelParams.path_loss``); d is the antenna distance [m] (equal antenna heights: 2-D = 3-D),
fc the carrier [GHz] unless said otherwise:

* ``free_space``: Friis, 20 log10(4 pi d / lambda).
* ``two_ray``: two-ray interference (Sommer, Joerer, Dressler, "On the Applicability of Two-Ray Path Loss
  Models for Vehicular Network Simulation", IEEE VNC 2012; Veins' TwoRayInterferenceModel): ground
  reflection with relative permittivity epsilon_r, both antennas at h.
* ``log_distance``: free space up to d0, then + 10 n log10(d / d0).
* ``winner_b1``: WINNER+ B1 urban micro-cell (WINNER+ D5.3 "WINNER+ Final Channel Models", 2010, Table 4-4;
  adopted for V2V by 3GPP TR 36.885 V14.0.0 Table A.1.4-1 with both antennas at 1.5 m and effective
  heights h' = h - 1 m):
  LOS: 22.7 log10(d) + 27.0 + 20 log10(fc) for d <= d'BP, and
  40 log10(d) + 7.56 - 17.3 log10(h'1) - 17.3 log10(h'2) + 2.7 log10(fc) beyond,
  d'BP = 4 h'1 h'2 f / c (f in Hz); valid from 10 m (shorter distances are evaluated at 10 m).
  Three options (``ChannelParams.winner_*``) give the variant other V2V studies use: the height offset
  (``winner_height_offset_m``, 1 m; 0 takes the antennas' own heights, breakpoint 177 m at 5.9 GHz), the
  shortest distance evaluated (``winner_min_m``, 10 m) and a free-space floor (``winner_free_space_floor``:
  max(PL, Friis)). Gonzalez-Martin et al., IEEE TVT 68(2), 2019 (their C-V2X mode 4 model, the reference of
  ``validation/cv2x/``) use offset 0, 3 m and the floor.
  NLOS (Manhattan grid, the receiver round a corner, d1 and d2 the legs along the two streets):
  min(PL(d1, d2), PL(d2, d1)), PL(dk, dl) = PL_LOS(dk) + 20 - 12.5 nj + 10 nj log10(dl) + 3 log10(fc / 5),
  nj = max(2.8 - 0.0024 dk, 1.84) (WINNER II D1.1.2 Table 4-4, kept in WINNER+). Without street geometry
  the aether takes the symmetric corner d1 = d2 = d / sqrt(2) (our reading).
* ``3gpp_highway``: 3GPP TR 37.885 V15.3.0 Table 6.2.1-1, highway LOS: 32.4 + 20 log10(d) + 20 log10(fc).
* ``3gpp_urban``: the same table, urban LOS: 38.77 + 16.7 log10(d) + 18.2 log10(fc); NLOS (buildings):
  36.85 + 30 log10(d) + 18.9 log10(fc). Both 3GPP models are evaluated from d = 3 m on (our floor: the
  table gives no lower bound; 3 m is a car length apart).

Shadowing: log-normal (Gaussian in dB) with standard deviation sigma and exponential spatial correlation
exp(-dx / d_corr). Defaults per model (``default_shadowing``): TR 37.885 Table 6.2.1-1 (sigma 3 dB LOS,
4 dB NLOS) with Table 6.2.3-1's decorrelation distances (highway 25 m, urban 10 m LOS / 13 m NLOS); WINNER+
B1: 3 dB LOS, 4 dB NLOS (D5.3 Table 4-4), decorrelation 10 m (D5.3 Table 4-5, B1 LOS SF); none for the
deterministic models. The value of the link between stations at p and q is
S(p, q) = (X(p) + X(q)) / sqrt(2), X a stationary Gaussian field of standard deviation sigma with
correlation exp(-|dp| / d_corr), drawn from the run seed (random Fourier features: K cosines whose
frequencies follow the field's spectral density, a 2-D Cauchy law). So S is reciprocal (S(p, q) =
S(q, p)), has standard deviation sigma, keeps the correlation exp(-dx / d_corr) when both ends move by dx,
and two links sharing an end are correlated by 1/2. It costs K cosines per station and step, not per link,
and depends only on positions: the same seed gives the same value at the same place, whatever the order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SPEED_OF_LIGHT_MPS = 299_792_458.0

PATH_LOSS_MODELS = ("free_space", "two_ray", "log_distance", "winner_b1", "3gpp_highway", "3gpp_urban")

WINNER_B1_MIN_M = 10.0  # WINNER+ D5.3 Table 4-4: B1 valid for 10 m < d
WINNER_EFFECTIVE_HEIGHT_OFFSET_M = 1.0  # h' = h - 1.0 m (WINNER+ D5.3 Table 4-4 note; TR 36.885 A.1.4)
TR37885_MIN_M = 3.0  # our floor for the TR 37.885 formulas (see the module docstring)


# ---- the defining formulas, one function each (tests check them against hand-computed values) ------------
def free_space_db(d_m, frequency_hz: float) -> np.ndarray:
    lam = SPEED_OF_LIGHT_MPS / frequency_hz
    d = np.maximum(np.asarray(d_m, dtype=np.float64), 1.0)
    return 20.0 * np.log10(4.0 * np.pi * d / lam)


def winner_b1_los_db(
    d_m,
    frequency_hz: float,
    h1_m: float = 1.5,
    h2_m: float = 1.5,
    height_offset_m: float = WINNER_EFFECTIVE_HEIGHT_OFFSET_M,
    min_m: float = WINNER_B1_MIN_M,
    free_space_floor: bool = False,
) -> np.ndarray:
    """WINNER+ B1 LOS [dB] (D5.3 Table 4-4): two slopes around the breakpoint d'BP = 4 h'1 h'2 f / c,
    h' = h - height_offset_m; distances below min_m evaluated at min_m; optionally never below free space."""
    fc = frequency_hz / 1e9
    h1, h2 = h1_m - height_offset_m, h2_m - height_offset_m
    if h1 <= 0 or h2 <= 0:
        raise ValueError(
            f"WINNER+ B1 needs antennas higher than {height_offset_m:g} m (effective height > 0)"
        )
    d_bp = 4.0 * h1 * h2 * frequency_hz / SPEED_OF_LIGHT_MPS
    d = np.maximum(np.asarray(d_m, dtype=np.float64), min_m)
    near = 22.7 * np.log10(d) + 27.0 + 20.0 * math.log10(fc)
    far = 40.0 * np.log10(d) + 7.56 - 17.3 * math.log10(h1) - 17.3 * math.log10(h2) + 2.7 * math.log10(fc)
    pl = np.where(d <= d_bp, near, far)
    return np.maximum(pl, free_space_db(d, frequency_hz)) if free_space_floor else pl


def winner_b1_nlos_db(d1_m, d2_m, frequency_hz: float, h1_m: float = 1.5, h2_m: float = 1.5) -> np.ndarray:
    """WINNER+ B1 NLOS, Manhattan grid [dB]: min(PL(d1, d2), PL(d2, d1)) (WINNER II D1.1.2 Table 4-4)."""
    fc = frequency_hz / 1e9

    def pl(dk, dl):
        dk = np.maximum(np.asarray(dk, dtype=np.float64), WINNER_B1_MIN_M)
        dl = np.maximum(np.asarray(dl, dtype=np.float64), 1.0)
        nj = np.maximum(2.8 - 0.0024 * dk, 1.84)
        los = winner_b1_los_db(dk, frequency_hz, h1_m, h2_m)
        return los + 20.0 - 12.5 * nj + 10.0 * nj * np.log10(dl) + 3.0 * math.log10(fc / 5.0)

    return np.minimum(pl(d1_m, d2_m), pl(d2_m, d1_m))


def tr37885_highway_los_db(d_m, frequency_hz: float) -> np.ndarray:
    """3GPP TR 37.885 Table 6.2.1-1, highway LOS [dB]."""
    d = np.maximum(np.asarray(d_m, dtype=np.float64), TR37885_MIN_M)
    return 32.4 + 20.0 * np.log10(d) + 20.0 * math.log10(frequency_hz / 1e9)


def tr37885_urban_los_db(d_m, frequency_hz: float) -> np.ndarray:
    """3GPP TR 37.885 Table 6.2.1-1, urban LOS [dB]."""
    d = np.maximum(np.asarray(d_m, dtype=np.float64), TR37885_MIN_M)
    return 38.77 + 16.7 * np.log10(d) + 18.2 * math.log10(frequency_hz / 1e9)


def tr37885_nlos_db(d_m, frequency_hz: float) -> np.ndarray:
    """3GPP TR 37.885 Table 6.2.1-1, NLOS (buildings) [dB]."""
    d = np.maximum(np.asarray(d_m, dtype=np.float64), TR37885_MIN_M)
    return 36.85 + 30.0 * np.log10(d) + 18.9 * math.log10(frequency_hz / 1e9)


def default_shadowing(model: str) -> tuple[float, float]:
    """(sigma [dB], decorrelation distance [m]) of a model's LOS shadowing (see the module docstring)."""
    return {
        "3gpp_highway": (3.0, 25.0),  # TR 37.885 Table 6.2.1-1 (3 dB LOS), Table 6.2.3-1 (25 m highway)
        "3gpp_urban": (3.0, 10.0),  # TR 37.885 Table 6.2.1-1 (3 dB LOS), Table 6.2.3-1 (10 m urban LOS)
        "winner_b1": (3.0, 10.0),  # WINNER+ D5.3 Table 4-4 (3 dB LOS), Table 4-5 (B1 LOS SF: 10 m)
    }.get(model, (0.0, 25.0))


def nlos_shadowing_sigma_db(model: str) -> float:
    """Sigma of the NLOS state [dB]: 4 dB (TR 37.885 Table 6.2.1-1; WINNER+ D5.3 Table 4-4 B1 NLOS)."""
    return 4.0 if model in ("3gpp_urban", "winner_b1") else 0.0


# ---- the model used by the aether --------------------------------------------------------------------------
class PathLoss:
    """Deterministic path loss [dB] as a function of the ground distance [m], for ``params.path_loss``.

    ``params`` needs frequency_hz, path_loss, antenna_height_m, ground_permittivity, log_distance_exponent
    and log_distance_ref_m (``ChannelParams``).
    """

    def __init__(self, params):
        self.p = params
        self.lam = SPEED_OF_LIGHT_MPS / params.frequency_hz
        if params.path_loss not in PATH_LOSS_MODELS:
            raise ValueError(
                f"unknown path loss model {params.path_loss!r}; one of {', '.join(PATH_LOSS_MODELS)}"
            )

    @property
    def has_nlos(self) -> bool:
        """The model has its own NLOS formula (used for links whose line of sight buildings block)."""
        return self.p.path_loss in ("winner_b1", "3gpp_urban")

    def free_space_db(self, d_m: np.ndarray) -> np.ndarray:
        return free_space_db(d_m, self.p.frequency_hz)

    def loss_db(self, d_m: np.ndarray) -> np.ndarray:
        p = self.p
        f = p.frequency_hz
        d = np.maximum(np.asarray(d_m, dtype=np.float64), 1.0)
        if p.path_loss == "free_space":
            return self.free_space_db(d)
        if p.path_loss == "log_distance":
            d0 = p.log_distance_ref_m
            beyond = self.free_space_db(d0) + 10.0 * p.log_distance_exponent * np.log10(d / d0)
            return np.where(d > d0, beyond, self.free_space_db(d))
        if p.path_loss == "winner_b1":
            h = p.antenna_height_m
            return winner_b1_los_db(
                d,
                f,
                h,
                h,
                getattr(p, "winner_height_offset_m", WINNER_EFFECTIVE_HEIGHT_OFFSET_M),
                getattr(p, "winner_min_m", WINNER_B1_MIN_M),
                getattr(p, "winner_free_space_floor", False),
            )
        if p.path_loss == "3gpp_highway":
            return tr37885_highway_los_db(d, f)
        if p.path_loss == "3gpp_urban":
            return tr37885_urban_los_db(d, f)
        # two-ray interference (Sommer, Joerer, Dressler 2012), as in Veins' TwoRayInterferenceModel
        h = p.antenna_height_m
        d_dir = d  # equal antenna heights
        d_ref = np.sqrt(d * d + (2.0 * h) ** 2)
        sin_t = 2.0 * h / d_ref
        cos_t = d / d_ref
        root = np.sqrt(p.ground_permittivity - cos_t * cos_t)
        gamma = (sin_t - root) / (sin_t + root)
        phi = 2.0 * np.pi / self.lam * (d_dir - d_ref)
        mag = np.abs(1.0 + gamma * np.exp(1j * phi))
        return 20.0 * np.log10(4.0 * np.pi * d / self.lam) - 20.0 * np.log10(np.maximum(mag, 1e-12))

    def nlos_db(self, d_m: np.ndarray) -> np.ndarray:
        """NLOS path loss [dB] of the models that have one (``has_nlos``)."""
        p = self.p
        d = np.maximum(np.asarray(d_m, dtype=np.float64), 1.0)
        if p.path_loss == "3gpp_urban":
            return tr37885_nlos_db(d, p.frequency_hz)
        if p.path_loss == "winner_b1":
            leg = d / math.sqrt(2.0)
            return winner_b1_nlos_db(leg, leg, p.frequency_hz, p.antenna_height_m, p.antenna_height_m)
        raise ValueError(f"{p.path_loss} has no NLOS formula")

    def loss_db_from_d2(self, d2_m2: np.ndarray) -> np.ndarray:
        """``loss_db`` from squared distances, in float32 for free space / log-distance (the hot path)."""
        p = self.p
        if p.path_loss not in ("free_space", "log_distance"):
            return self.loss_db(np.sqrt(d2_m2.astype(np.float64))).astype(np.float32)
        d2 = np.maximum(d2_m2.astype(np.float32, copy=False), np.float32(1.0))
        fs1 = np.float32(20.0 * np.log10(4.0 * np.pi / self.lam))  # free-space loss at 1 m
        if p.path_loss == "free_space":
            return fs1 + np.float32(10.0) * np.log10(d2)
        d0 = p.log_distance_ref_m
        beyond = np.float32(self.free_space_db(d0)) + np.float32(5.0 * p.log_distance_exponent) * np.log10(
            d2 / np.float32(d0 * d0)
        )
        return np.where(d2 > np.float32(d0 * d0), beyond, fs1 + np.float32(10.0) * np.log10(d2))

    def max_range_m(self, budget_db: float) -> float:
        """Largest distance at which the path loss can still be <= budget_db [m]."""
        fs = self.lam / (4.0 * np.pi) * 10.0 ** (budget_db / 20.0)
        p = self.p
        if p.path_loss == "free_space":
            return float(fs)
        if p.path_loss == "log_distance":
            d0 = p.log_distance_ref_m
            if fs <= d0:
                return float(fs)
            extra = budget_db - float(self.free_space_db(d0))
            return float(d0 * 10.0 ** (extra / (10.0 * p.log_distance_exponent)))
        if p.path_loss in ("winner_b1", "3gpp_highway", "3gpp_urban"):
            # monotone in d: bisection on a log scale between 1 m and 100 km
            lo, hi = 0.0, 5.0
            if float(self.loss_db(1.0)) > budget_db:
                return 1.0
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if float(self.loss_db(10.0**mid)) <= budget_db else (lo, mid)
            return float(10.0**lo)
        # two-ray: the reflected ray adds at most +6 dB, so the range is below 2x free space; scan finely
        d = np.arange(1.0, 2.0 * fs + 10.0, 0.25)
        ok = np.flatnonzero(self.loss_db(d) <= budget_db)
        return float(d[ok[-1]] + 0.25) if ok.size else 1.0


# ---- log-normal shadowing ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class ShadowingField:
    """Reproducible, spatially correlated log-normal shadowing (see the module docstring).

    ``ShadowingField.draw(sigma_db, decorrelation_m, rng)`` draws the field; ``at(xy)`` gives X at station
    positions and ``link_db(x_tx, x_rx)`` combines two of those into the link value S [dB].
    """

    sigma_db: float
    omega: np.ndarray  # (K, 2) spatial angular frequencies [rad/m]
    phase: np.ndarray  # (K,) phases [rad]

    N_FEATURES = 256  # K: the marginal is a sum of K cosines, Gaussian to well within 1 % at this K

    @classmethod
    def draw(cls, sigma_db: float, decorrelation_m: float, rng: np.random.Generator, k: int | None = None):
        if not sigma_db >= 0 or not decorrelation_m > 0:
            raise ValueError("shadowing: sigma_db must be >= 0 and decorrelation_m > 0")
        k = k or cls.N_FEATURES
        # the spectral density of exp(-r / d) in 2-D is the bivariate Cauchy law of scale 1 / d: a standard
        # normal vector divided by |N(0, 1)| (a multivariate t with one degree of freedom)
        z = rng.standard_normal((k, 2))
        w = np.abs(rng.standard_normal((k, 1)))
        omega = z / np.maximum(w, 1e-12) / decorrelation_m
        phase = rng.uniform(0.0, 2.0 * np.pi, k)
        return cls(float(sigma_db), omega, phase)

    def at(self, xy: np.ndarray) -> np.ndarray:
        """X at positions (n, 2) [m] -> (n,) [dB], standard deviation sigma_db."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        if self.sigma_db == 0 or xy.shape[0] == 0:
            return np.zeros(xy.shape[0])
        arg = xy @ self.omega.T + self.phase
        return self.sigma_db * math.sqrt(2.0 / self.omega.shape[0]) * np.cos(arg).sum(axis=1)

    @staticmethod
    def link_db(x_tx: np.ndarray, x_rx: np.ndarray) -> np.ndarray:
        """S = (X(tx) + X(rx)) / sqrt(2), broadcast: (T, 1) and (1, M) give (T, M) [dB]."""
        return (np.asarray(x_tx) + np.asarray(x_rx)) * (1.0 / math.sqrt(2.0))

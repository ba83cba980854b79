"""ETSI Cooperative Awareness Messages (EN 302 637-2 V1.4.1 / TS 102 894-2 data elements), vectorised.

Which reading each default follows
----------------------------------
* Generation rules (EN 302 637-2 §6.1.3): checked every ``check_period_s`` (T_CheckCamGen <= T_GenCamMin).
  Condition 1: time since the last CAM >= T_GenCamDcc and (heading changed > 4 deg, position changed > 4 m
  or speed changed > 0.5 m/s, all relative to the values in the last CAM). Condition 2: time since the last
  CAM >= T_GenCam (and >= T_GenCamDcc). A condition-1 CAM sets T_GenCam to the elapsed time; T_GenCam keeps
  that value for N_GenCam (3) consecutive condition-2 CAMs and is then reset to T_GenCamMax (1 s). Without
  DCC, T_GenCamDcc = T_GenCamMin = 100 ms. A station's first check always generates a CAM.
* Low-frequency container: in the first CAM and then whenever >= 500 ms passed since the last CAM that
  carried one.
* Units are the ETSI ones: heading 0.1 deg (0 = north, clockwise, the same as SUMO's compass angle), speed
  0.01 m/s, length/width 0.1 m, longitudinal acceleration 0.1 m/s^2, curvature 1/10000 m^-1 (positive =
  left, ISO 8855), yaw rate 0.01 deg/s (positive = counter-clockwise). The reference position is the centre
  of the vehicle's front side (ETSI's reference point, and SUMO's position); we keep it in the network's
  metric frame in centimetres because the snapshot carries no geo-projection.
* ``lane_position``: ETSI counts lanes from the inside; the snapshot has no lane count per edge, so we send
  SUMO's lane index + 1 (1 = rightmost driving lane), -1 when unknown. Receivers only compare it for
  equality (OBU criterion d), for which either counting works.
* ``accel_control`` bit k (value ``1 << k``) is ASN.1 bit k of AccelerationControl: brakePedalEngaged (0)
  from SUMO's brake light or a deceleration >= ``brake_pedal_decel_mps2``; gasPedalEngaged (1) when
  accelerating; emergencyBrakeEngaged (2) at a deceleration >= ``emergency_brake_decel_mps2`` (4 m/s^2, the
  hard-braking threshold of the emergency electronic brake light use case).
* Path history: one point each time the vehicle has moved ``path_point_spacing_m`` (10 m) from the last
  point, up to ``path_history_max_points`` (23, i.e. ~230 m; the ASN.1 type allows 0..40). Only the number of
  points is kept, because it is all the simulation uses (it sets the message size and slot air time).
* Size: the exact UPER bit count of the CAM PDU with the optional fields we send (accelerationControl,
  lanePosition), computed from the ASN.1 constraints (see ``cam_size_bytes``): 42 B without the LF
  container, 44 B with an empty path history, + 69 bit per path point (243 B with 23 points). Security
  headers are not included (see ``SotdmaParams.mac_overhead_bytes``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# --- SUMO signal bits used here (https://sumo.dlr.de/docs/TraCI/Vehicle_Signalling.html) -------------------
_SUMO_BLINKER_RIGHT = 1 << 0
_SUMO_BLINKER_LEFT = 1 << 1
_SUMO_BLINKER_EMERGENCY = 1 << 2
_SUMO_BRAKELIGHT = 1 << 3
_SUMO_FRONTLIGHT = 1 << 4
_SUMO_FOGLIGHT = 1 << 5
_SUMO_HIGHBEAM = 1 << 6
_SUMO_BACKDRIVE = 1 << 7

# --- ETSI AccelerationControl / ExteriorLights bits (value 1 << asn1_bit) -----------------------------------
ACC_BRAKE_PEDAL = 1 << 0
ACC_GAS_PEDAL = 1 << 1
ACC_EMERGENCY_BRAKE = 1 << 2
LIGHT_LOW_BEAM = 1 << 0
LIGHT_HIGH_BEAM = 1 << 1
LIGHT_LEFT_TURN = 1 << 2
LIGHT_RIGHT_TURN = 1 << 3
LIGHT_REVERSE = 1 << 5
LIGHT_FOG = 1 << 6

STATION_TYPE_PASSENGER_CAR = 5
DRIVE_FORWARD, DRIVE_BACKWARD = 0, 1

# Why a CAM was generated
TRIGGER_NONE, TRIGGER_FIRST, TRIGGER_DYNAMICS, TRIGGER_TIMER = 0, 1, 2, 3

# --- UPER bit counts (constraints of CAM-PDU-Descriptions / ITS-Container v2) -------------------------------
_BITS_HEADER = 8 + 8 + 32  # protocolVersion, messageID, stationID
_BITS_GEN_DELTA_TIME = 16
_BITS_CAM_PARAMETERS = 1 + 2  # extension bit + presence of lowFrequency / specialVehicle containers
# stationType 8, latitude 31, longitude 32, confidence ellipse 12+12+12, altitude 20+4, extension bit 1
_BITS_BASIC_CONTAINER = 1 + 8 + 31 + 32 + 36 + 24
_BITS_HF_CONTAINER = (
    2  # CHOICE with extension: extension bit + 1 index bit
    + 7  # presence bits of the 7 optional components
    + 12
    + 7  # heading value + confidence
    + 14
    + 7  # speed value + confidence
    + 2  # driveDirection
    + 10
    + 3  # vehicleLength value + confidence indication
    + 6  # vehicleWidth
    + 9
    + 7  # longitudinalAcceleration value + confidence
    + 11
    + 3  # curvature value + confidence
    + 3  # curvatureCalculationMode (extensible enum)
    + 16
    + 4  # yawRate value + confidence
    + 7  # accelerationControl (optional, sent)
    + 4  # lanePosition (optional, sent)
)
_BITS_LF_FIXED = 1 + 4 + 8 + 6  # CHOICE ext bit, vehicleRole, exteriorLights, pathHistory length (0..40)
_BITS_PATH_POINT = (
    1 + 18 + 18 + 15 + 1 + 16
)  # presence, dLat, dLon, dAlt, PathDeltaTime (extensible) 1..65535


def cam_size_bytes(has_lf: np.ndarray, n_path_points: np.ndarray) -> np.ndarray:
    """UPER size [B] of a CAM (shape of the inputs, uint16): the bit count rounded up to whole octets."""
    has_lf = np.asarray(has_lf, dtype=bool)
    n = np.asarray(n_path_points, dtype=np.int64)
    bits = (
        _BITS_HEADER
        + _BITS_GEN_DELTA_TIME
        + _BITS_CAM_PARAMETERS
        + _BITS_BASIC_CONTAINER
        + _BITS_HF_CONTAINER
    )
    bits = bits + np.where(has_lf, _BITS_LF_FIXED + _BITS_PATH_POINT * n, 0)
    return ((bits + 7) // 8).astype(np.uint16)


def _ms(value_s: float, name: str) -> int:
    ms = round(value_s * 1000.0)
    if abs(value_s * 1000.0 - ms) > 1e-6:
        raise ValueError(f"{name} = {value_s} s must be a whole number of milliseconds")
    return ms


@dataclass(frozen=True)
class CamParams:
    """CAM generation (EN 302 637-2 §6.1.3) and content parameters."""

    check_period_s: float = 0.1  # T_CheckCamGen [s]; must be <= T_GenCamMin and a multiple of the base step
    t_gen_cam_min_s: float = 0.1  # T_GenCamMin [s]
    t_gen_cam_max_s: float = 1.0  # T_GenCamMax [s]
    t_gen_cam_dcc_s: float = 0.1  # T_GenCamDcc [s] (no DCC: equal to T_GenCamMin)
    n_gen_cam: int = 3  # N_GenCam: condition-2 CAMs kept at a shortened T_GenCam
    heading_threshold_deg: float = 4.0  # condition 1: heading change [deg]
    position_threshold_m: float = 4.0  # condition 1: position change [m]
    speed_threshold_mps: float = 0.5  # condition 1: speed change [m/s]
    lf_interval_s: float = 0.5  # minimum time between CAMs with a low-frequency container [s]
    path_history_max_points: int = 23  # path points in the LF container (ASN.1 allows 0..40)
    path_point_spacing_m: float = 10.0  # distance travelled between two path points [m]
    station_type: int = STATION_TYPE_PASSENGER_CAR  # ETSI StationType
    brake_pedal_decel_mps2: float = 0.5  # deceleration that sets brakePedalEngaged (besides the brake light)
    emergency_brake_decel_mps2: float = 4.0  # deceleration that sets emergencyBrakeEngaged [m/s^2]

    def __post_init__(self) -> None:
        check = _ms(self.check_period_s, "cam.check_period_s")
        tmin = _ms(self.t_gen_cam_min_s, "cam.t_gen_cam_min_s")
        tmax = _ms(self.t_gen_cam_max_s, "cam.t_gen_cam_max_s")
        tdcc = _ms(self.t_gen_cam_dcc_s, "cam.t_gen_cam_dcc_s")
        _ms(self.lf_interval_s, "cam.lf_interval_s")
        if check <= 0 or tmin <= 0:
            raise ValueError("cam.check_period_s and cam.t_gen_cam_min_s must be > 0")
        if check > tmin:
            raise ValueError(
                "cam.check_period_s must be <= cam.t_gen_cam_min_s (T_CheckCamGen <= T_GenCamMin)"
            )
        if not tmin <= tdcc <= tmax:
            raise ValueError("cam: need t_gen_cam_min_s <= t_gen_cam_dcc_s <= t_gen_cam_max_s")
        if self.n_gen_cam < 1:
            raise ValueError("cam.n_gen_cam must be >= 1")
        for name in (
            "heading_threshold_deg",
            "position_threshold_m",
            "speed_threshold_mps",
            "path_point_spacing_m",
        ):
            if not getattr(self, name) > 0:
                raise ValueError(f"cam.{name} must be > 0")
        if self.lf_interval_s < 0:
            raise ValueError("cam.lf_interval_s must be >= 0")
        if not 0 <= self.path_history_max_points <= 40:
            raise ValueError("cam.path_history_max_points must be in 0..40 (ASN.1 PathHistory SIZE(0..40))")
        if not 0 <= self.station_type <= 255:
            raise ValueError("cam.station_type must be in 0..255")
        if self.brake_pedal_decel_mps2 < 0 or self.emergency_brake_decel_mps2 <= 0:
            raise ValueError("cam: brake thresholds must be positive decelerations")

    @property
    def max_size_bytes(self) -> int:
        """Size of the largest CAM these parameters can produce (LF container, full path history) [B]."""
        return int(cam_size_bytes(np.array(True), np.array(self.path_history_max_points)))


# Fields of one CAM as sent (ETSI units); name -> dtype. Arrays of these make up a CamBatch / record store.
CAM_FIELDS: dict[str, np.dtype] = {
    "station_id": np.dtype(np.uint32),
    "station_type": np.dtype(np.uint8),
    "gen_ms": np.dtype(np.int64),  # generation time on the simulation clock [ms]
    "generation_delta_time": np.dtype(np.uint16),  # gen_ms mod 65536 (ETSI GenerationDeltaTime)
    "ref_x_cm": np.dtype(np.int32),  # reference position (front centre), network x [cm]
    "ref_y_cm": np.dtype(np.int32),  # reference position, network y [cm]
    "heading_01deg": np.dtype(np.uint16),  # 0..3599, 0 = north, clockwise [0.1 deg]
    "speed_001mps": np.dtype(np.uint16),  # 0..16382 [0.01 m/s]
    "drive_direction": np.dtype(np.uint8),  # 0 forward, 1 backward
    "length_01m": np.dtype(np.uint16),  # 1..1022 [0.1 m]
    "width_01m": np.dtype(np.uint8),  # 1..61 [0.1 m]
    "long_accel_01mps2": np.dtype(np.int16),  # -160..160 [0.1 m/s^2]
    "curvature": np.dtype(np.int16),  # -1023..1022 [1/10000 m^-1], positive = left
    "yaw_rate_001degps": np.dtype(np.int16),  # -32766..32766 [0.01 deg/s], positive = counter-clockwise
    "accel_control": np.dtype(np.uint8),  # ACC_* bits
    "lane_position": np.dtype(np.int8),  # SUMO lane index + 1, -1 unknown
    "has_lf": np.dtype(np.bool_),  # low-frequency container present
    "exterior_lights": np.dtype(np.uint8),  # LIGHT_* bits (only meaningful with has_lf)
    "n_path_points": np.dtype(np.uint8),  # path history length in the LF container
    "size_bytes": np.dtype(np.uint16),  # UPER size [B]
    "trigger": np.dtype(np.uint8),  # TRIGGER_* that generated it
}


# The same fields as one record: a batch of CAMs moves between stores in one gather / scatter, not one per field.
CAM_DTYPE = np.dtype(list(CAM_FIELDS.items()))


def empty_cam_arrays(n: int) -> np.ndarray:
    """n zeroed CAMs: a CAM_DTYPE array, indexed by field name like a dict of CAM_FIELDS arrays."""
    return np.zeros(n, dtype=CAM_DTYPE)


def quantize_heading(heading_deg: np.ndarray) -> np.ndarray:
    return (np.rint(np.mod(heading_deg, 360.0) * 10.0).astype(np.int64) % 3600).astype(np.uint16)


def _round_clip(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """np.clip(np.round(x), lo, hi) without the Python-level wrappers of round and clip (the per-call cost
    of a small batch): round(x) with 0 decimals is rint(x), clip is maximum then minimum, NaN included."""
    r = np.rint(x)
    np.maximum(r, lo, out=r)
    return np.minimum(r, hi, out=r)


def _exterior_lights(s: np.ndarray) -> np.ndarray:
    out = np.zeros(s.shape, dtype=np.int64)
    out |= np.where(s & _SUMO_FRONTLIGHT, LIGHT_LOW_BEAM, 0)
    out |= np.where(s & _SUMO_HIGHBEAM, LIGHT_HIGH_BEAM, 0)
    out |= np.where(s & (_SUMO_BLINKER_LEFT | _SUMO_BLINKER_EMERGENCY), LIGHT_LEFT_TURN, 0)
    out |= np.where(s & (_SUMO_BLINKER_RIGHT | _SUMO_BLINKER_EMERGENCY), LIGHT_RIGHT_TURN, 0)
    out |= np.where(s & _SUMO_BACKDRIVE, LIGHT_REVERSE, 0)
    out |= np.where(s & _SUMO_FOGLIGHT, LIGHT_FOG, 0)
    return out.astype(np.uint8)


# every light comes from one of the low 8 SUMO signal bits: a table of their 256 combinations
_LIGHTS_OF_LOW_BITS = _exterior_lights(np.arange(256))


def exterior_lights_from_sumo(signals: np.ndarray) -> np.ndarray:
    """ExteriorLights bits (uint8) of SUMO signal bit fields."""
    return _LIGHTS_OF_LOW_BITS[np.asarray(signals, dtype=np.int64) & 0xFF]


def _wrap_deg(d: np.ndarray) -> np.ndarray:
    """Angle difference wrapped to (-180, 180] [deg]."""
    return 180.0 - np.mod(180.0 - d, 360.0)


@dataclass
class CamDecision:
    """Result of one generation check over all station slots (arrays of shape (capacity,))."""

    generate: np.ndarray  # bool: a CAM is generated now
    lf: np.ndarray  # bool: it carries the low-frequency container
    trigger: np.ndarray  # uint8 TRIGGER_*


class CamGenerator:
    """Per-station CAM generation state over fixed-capacity slot arrays (one station per World slot).

    ``check`` applies the ETSI rules to every active station at once and commits the new state;
    ``build`` fills the message fields (ETSI units) of the stations that generated.
    """

    def __init__(self, params: CamParams, capacity: int):
        self.params = params
        self.check_ms = _ms(params.check_period_s, "check_period_s")
        self.tmin_ms = _ms(params.t_gen_cam_min_s, "t_gen_cam_min_s")
        self.tmax_ms = _ms(params.t_gen_cam_max_s, "t_gen_cam_max_s")
        self.tdcc_ms = _ms(params.t_gen_cam_dcc_s, "t_gen_cam_dcc_s")
        self.lf_ms = _ms(params.lf_interval_s, "lf_interval_s")
        self.capacity = 0
        self._alloc(capacity)

    # -- state -----------------------------------------------------------------------------------------------
    _STATE: dict[str, tuple[type, float | int]] = {
        "last_gen_ms": (np.int64, -1),  # time of the last CAM [ms]; -1 = none yet
        "last_x_m": (np.float64, 0.0),  # position / heading / speed in the last CAM
        "last_y_m": (np.float64, 0.0),
        "last_heading_deg": (np.float64, 0.0),
        "last_speed_mps": (np.float64, 0.0),
        "t_gen_cam_ms": (np.int64, 0),  # current T_GenCam [ms]
        "n_short_left": (np.int32, 0),  # condition-2 CAMs left at the shortened T_GenCam
        "last_lf_ms": (np.int64, -1),  # last CAM with a low-frequency container [ms]
        "path_count": (np.int32, 0),  # path history points recorded
        "path_x_m": (np.float64, np.nan),  # last path point (NaN = none)
        "path_y_m": (np.float64, np.nan),
        "prev_heading_deg": (np.float64, np.nan),  # heading at the previous observation (for yaw rate)
        "prev_obs_ms": (np.int64, -1),
        "yaw_rate_dps": (np.float64, 0.0),  # yaw rate, counter-clockwise positive [deg/s]
    }

    def _alloc(self, capacity: int) -> None:
        old = self.capacity
        for name, (dtype, fill) in self._STATE.items():
            arr = np.full(capacity, fill, dtype=dtype)
            if old:
                arr[:old] = getattr(self, name)
            setattr(self, name, arr)
        if not old:
            self.t_gen_cam_ms[:] = self.tmax_ms
        else:
            self.t_gen_cam_ms[old:] = self.tmax_ms
        self.capacity = capacity

    def ensure_capacity(self, capacity: int) -> None:
        if capacity > self.capacity:
            self._alloc(capacity)

    def reset(self, slots: np.ndarray) -> None:
        """A new station occupies these slots: forget everything about the previous one."""
        for name, (_, fill) in self._STATE.items():
            getattr(self, name)[slots] = fill
        self.t_gen_cam_ms[slots] = self.tmax_ms

    # -- per step --------------------------------------------------------------------------------------------
    def observe(
        self, now_ms: int, active: np.ndarray, x_m: np.ndarray, y_m: np.ndarray, heading_deg: np.ndarray
    ):
        """Track yaw rate and path history every base step (the CAM content needs them)."""
        idx = active.nonzero()[0]
        if idx.size == 0:
            return
        prev_h = self.prev_heading_deg[idx]
        prev_t = self.prev_obs_ms[idx]
        h = heading_deg[idx]
        dt_s = (now_ms - prev_t) / 1000.0
        ok = (prev_t >= 0) & (dt_s > 0) & np.isfinite(prev_h)
        rate = np.zeros(idx.size)
        # compass angles grow clockwise; ISO 8855 yaw rate is positive counter-clockwise
        rate[ok] = -_wrap_deg(h[ok] - prev_h[ok]) / dt_s[ok]
        self.yaw_rate_dps[idx] = rate
        self.prev_heading_deg[idx] = h
        self.prev_obs_ms[idx] = now_ms
        # path history: a point whenever the vehicle has moved path_point_spacing_m from the last one
        px, py = self.path_x_m[idx], self.path_y_m[idx]
        first = ~np.isfinite(px)
        moved = np.hypot(x_m[idx] - px, y_m[idx] - py) >= self.params.path_point_spacing_m
        add = first | moved
        sel = idx[add]
        self.path_x_m[sel] = x_m[sel]
        self.path_y_m[sel] = y_m[sel]
        self.path_count[idx[moved & ~first]] += 1

    def check(
        self,
        now_ms: int,
        active: np.ndarray,
        x_m: np.ndarray,
        y_m: np.ndarray,
        heading_deg: np.ndarray,
        speed_mps: np.ndarray,
    ) -> CamDecision:
        """Apply the generation rules to all active stations at ``now_ms`` and commit generated CAMs."""
        p = self.params
        cap = self.capacity
        gen = np.zeros(cap, dtype=bool)
        lf = np.zeros(cap, dtype=bool)
        trig = np.zeros(cap, dtype=np.uint8)
        idx = active[:cap].nonzero()[0]
        if idx.size == 0:
            return CamDecision(gen, lf, trig)
        last = self.last_gen_ms[idx]
        first = last < 0
        elapsed = now_ms - last
        dyn = (
            (np.abs(_wrap_deg(heading_deg[idx] - self.last_heading_deg[idx])) > p.heading_threshold_deg)
            | (
                np.hypot(x_m[idx] - self.last_x_m[idx], y_m[idx] - self.last_y_m[idx])
                > p.position_threshold_m
            )
            | (np.abs(speed_mps[idx] - self.last_speed_mps[idx]) > p.speed_threshold_mps)
        )
        cond1 = ~first & (elapsed >= self.tdcc_ms) & dyn
        cond2 = ~first & ~cond1 & (elapsed >= np.maximum(self.t_gen_cam_ms[idx], self.tdcc_ms))
        g = first | cond1 | cond2
        t = np.where(
            first, TRIGGER_FIRST, np.where(cond1, TRIGGER_DYNAMICS, np.where(cond2, TRIGGER_TIMER, 0))
        )
        # T_GenCam bookkeeping
        tg = self.t_gen_cam_ms[idx]
        left = self.n_short_left[idx]
        tg = np.where(cond1, np.minimum(np.maximum(elapsed, self.tmin_ms), self.tmax_ms), tg)
        left = np.where(cond1, p.n_gen_cam, left)
        short_used = cond2 & (tg < self.tmax_ms)
        left = np.where(short_used, left - 1, left)
        reset = short_used & (left <= 0)
        tg = np.where(reset, self.tmax_ms, tg)
        left = np.where(reset, 0, left)
        self.t_gen_cam_ms[idx] = tg
        self.n_short_left[idx] = left
        # low-frequency container: first CAM, then >= lf_interval since the last one
        last_lf = self.last_lf_ms[idx]
        with_lf = g & ((last_lf < 0) | (now_ms - last_lf >= self.lf_ms))
        sel = idx[g]
        self.last_gen_ms[sel] = now_ms
        self.last_x_m[sel] = x_m[sel]
        self.last_y_m[sel] = y_m[sel]
        self.last_heading_deg[sel] = heading_deg[sel]
        self.last_speed_mps[sel] = speed_mps[sel]
        self.last_lf_ms[idx[with_lf]] = now_ms
        gen[idx] = g
        lf[idx] = with_lf
        trig[idx] = t
        return CamDecision(gen, lf, trig)

    def build(
        self,
        slots: np.ndarray,
        now_ms: int,
        station_id: np.ndarray,
        lf: np.ndarray,
        trigger: np.ndarray,
        x_m: np.ndarray,
        y_m: np.ndarray,
        heading_deg: np.ndarray,
        speed_mps: np.ndarray,
        accel_mps2: np.ndarray,
        length_m: np.ndarray,
        width_m: np.ndarray,
        lane_index: np.ndarray,
        signals: np.ndarray,
    ) -> np.ndarray:
        """CAMs (CAM_DTYPE, ETSI units) of the stations in ``slots``; other inputs are full (capacity,) arrays."""
        p = self.params
        n = slots.size
        out = empty_cam_arrays(n)
        v = speed_mps[slots]
        a = accel_mps2[slots]
        out["station_id"][:] = station_id[slots]
        out["station_type"][:] = p.station_type
        out["gen_ms"][:] = now_ms
        out["generation_delta_time"][:] = now_ms % 65536
        out["ref_x_cm"][:] = np.rint(x_m[slots] * 100.0).astype(np.int64)
        out["ref_y_cm"][:] = np.rint(y_m[slots] * 100.0).astype(np.int64)
        out["heading_01deg"][:] = quantize_heading(heading_deg[slots])
        out["speed_001mps"][:] = _round_clip(np.abs(v) * 100.0, 0, 16382)
        out["drive_direction"][:] = np.where(v < 0, DRIVE_BACKWARD, DRIVE_FORWARD)
        out["length_01m"][:] = _round_clip(length_m[slots] * 10.0, 1, 1022)
        out["width_01m"][:] = _round_clip(width_m[slots] * 10.0, 1, 61)
        out["long_accel_01mps2"][:] = _round_clip(a * 10.0, -160, 160)
        yaw = self.yaw_rate_dps[slots]
        out["yaw_rate_001degps"][:] = _round_clip(yaw * 100.0, -32766, 32766)
        with np.errstate(divide="ignore", invalid="ignore"):
            curv = np.where(np.abs(v) > 0.1, np.radians(yaw) / np.abs(v), 0.0)  # [1/m]
        out["curvature"][:] = _round_clip(curv * 10000.0, -1023, 1022)
        sig = signals[slots].astype(np.int64)
        braking = ((sig & _SUMO_BRAKELIGHT) != 0) | (a <= -p.brake_pedal_decel_mps2)
        acc = np.where(braking, ACC_BRAKE_PEDAL, 0)
        acc |= np.where((a > 0.0) & ~braking, ACC_GAS_PEDAL, 0)
        acc |= np.where(a <= -p.emergency_brake_decel_mps2, ACC_EMERGENCY_BRAKE, 0)
        out["accel_control"][:] = acc
        lane = lane_index[slots].astype(np.int64)
        out["lane_position"][:] = np.where(lane >= 0, np.minimum(lane + 1, 14), -1)
        has_lf = lf[slots]
        out["has_lf"][:] = has_lf
        out["exterior_lights"][:] = np.where(has_lf, exterior_lights_from_sumo(sig), 0)
        npath = np.where(has_lf, np.minimum(self.path_count[slots], p.path_history_max_points), 0)
        out["n_path_points"][:] = npath
        out["size_bytes"][:] = cam_size_bytes(has_lf, npath)
        out["trigger"][:] = trigger[slots]
        return out


def decode_cam(f: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Physical values (SI, SUMO conventions) from CAM fields; arrays keep their shape."""
    speed = f["speed_001mps"].astype(np.float64) / 100.0
    speed = np.where(f["drive_direction"] == DRIVE_BACKWARD, -speed, speed)
    return {
        "x_m": f["ref_x_cm"].astype(np.float64) / 100.0,
        "y_m": f["ref_y_cm"].astype(np.float64) / 100.0,
        "heading_deg": f["heading_01deg"].astype(np.float64) / 10.0,
        "speed_mps": speed,
        "accel_mps2": f["long_accel_01mps2"].astype(np.float64) / 10.0,
        "length_m": f["length_01m"].astype(np.float64) / 10.0,
        "width_m": f["width_01m"].astype(np.float64) / 10.0,
        "yaw_rate_dps": f["yaw_rate_001degps"].astype(np.float64) / 100.0,
        "curvature_per_m": f["curvature"].astype(np.float64) / 10000.0,
    }

"""System A (paper VII.A): rear-mounted stereo distance warning.

The LEADING vehicle carries two low-cost cameras behind its rear window, looking backwards. From their
disparity it estimates the distance to its follower, compares it with the distance its own speed calls
for (a time-gap rule), and lights a "keep distance" text display on its rear. The follower's driver gets
the message only by seeing that display: it must be in line of sight and close enough to be read.

Stereo error model (pinhole pair, rectified): true disparity d = f * B / Z [px]; the matcher returns
d + N(0, sigma_d), rounded to the sub-pixel step q; Z_measured = f * B / d_measured. To first order the
depth error is sigma_Z = Z^2 * sigma_d / (f * B) (plus q^2 / 12 in the disparity variance when quantised),
so the error grows with the square of the distance. A disparity that rounds to <= 0 gives no measurement.

Default camera (low-cost VGA pair): f = 800 px, 640 px wide image -> horizontal FOV 2*atan(320/800)
~= 43.6 deg; baseline 0.5 m (two cameras in the corners of a rear window); sigma_d = 0.25 px and a 0.25 px
sub-pixel step, typical of block matching. That gives sigma_Z ~= 0.26 m at 20 m and 2.3 m (4 %) at 60 m,
the default range limit (at 60 m the disparity is only 6.7 px).

Warning rule: required distance = max(time_gap_s * v_leader, min_distance_m). The display lights when the
measured distance is below it and goes dark when the distance is back above release_ratio * required
(hysteresis against measurement noise), but not before it has been lit for min_on_s (a "keep distance"
flash shorter than a glance is never read). With the leader below min_speed_mps (standing or creeping in
a queue) the display stays dark: a text at every red light would teach drivers to ignore it.

Legibility (default 50 m): the display shows a short text with letters of about 10 cm. Road-sign practice
gives a legibility index of about 40 ft per inch of letter height (MUTCD), i.e. ~4.8 m per cm, so ~48 m for
10-cm letters; 50 m is that figure rounded, and the 40-60 m span is the plausible range for 8-12 cm letters.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import shapely

from cosim.adas.common import EventRecorder, VehicleState, heading_unit, left_unit
from cosim.buildings import Buildings

MeasureStatus = Literal["ok", "behind_camera", "outside_fov", "too_close", "out_of_range", "no_disparity"]
PerceiveStatus = Literal["perceived", "display_off", "outside_view_angle", "too_far", "occluded"]


@dataclass(frozen=True)
class StereoCameraParams:
    """The rear stereo pair. Mounted at the centre of the leader's rear, optical axis pointing backwards."""

    baseline_m: float = 0.5  # distance between the two camera centres [m]
    focal_px: float = 800.0  # focal length [px]
    disparity_noise_px: float = 0.25  # std of the disparity error sigma_d [px]
    disparity_step_px: float = 0.25  # sub-pixel quantisation step of the matcher [px]; 0 = none
    hfov_deg: float = 44.0  # horizontal field of view (full angle) [deg]
    min_range_m: float = 0.5  # closer than this the images do not overlap [m]
    max_range_m: float = 60.0  # farther than this no measurement is reported [m]

    def __post_init__(self) -> None:
        if not self.baseline_m > 0.0:
            raise ValueError(f"baseline_m must be > 0, got {self.baseline_m}")
        if not self.focal_px > 0.0:
            raise ValueError(f"focal_px must be > 0, got {self.focal_px}")
        if not self.disparity_noise_px >= 0.0:
            raise ValueError(f"disparity_noise_px must be >= 0, got {self.disparity_noise_px}")
        if not self.disparity_step_px >= 0.0:
            raise ValueError(
                f"disparity_step_px must be >= 0 (0 = no quantisation), got {self.disparity_step_px}"
            )
        if not 0.0 < self.hfov_deg < 180.0:
            raise ValueError(f"hfov_deg must be in (0, 180), got {self.hfov_deg}")
        if not 0.0 <= self.min_range_m < self.max_range_m:
            raise ValueError(
                f"need 0 <= min_range_m < max_range_m, got min_range_m={self.min_range_m}, "
                f"max_range_m={self.max_range_m}"
            )

    def depth_sigma_m(self, depth_m: float) -> float:
        """First-order depth error std at depth Z [m]: Z^2 * sqrt(sigma_d^2 + q^2/12) / (f * B)."""
        sigma_d = math.sqrt(self.disparity_noise_px**2 + self.disparity_step_px**2 / 12.0)
        return depth_m**2 * sigma_d / (self.focal_px * self.baseline_m)


@dataclass(frozen=True)
class RearWarningParams:
    """System A: camera, warning rule and what the follower's driver can read."""

    camera: StereoCameraParams = field(default_factory=StereoCameraParams)
    time_gap_s: float = 2.0  # the "2-s rule" the leader judges the measured distance by [s]
    min_distance_m: float = 5.0  # required distance never drops below this at low speed [m]
    min_speed_mps: float = 1.5  # leader slower than this: display stays dark [m/s]
    release_ratio: float = 1.15  # dark again once measured >= release_ratio * required [-]
    min_on_s: float = 2.0  # once lit, stays lit at least this long [s]
    legible_distance_m: float = 50.0  # the follower's driver can read the text up to this distance [m]
    display_view_half_angle_deg: float = 60.0  # display readable within this angle of its normal [deg]
    driver_eye_back_m: float = 1.8  # driver's eye behind the follower's front bumper [m]
    driver_eye_left_m: float = 0.35  # driver's eye left of the follower's centre line [m]

    def __post_init__(self) -> None:
        if not self.time_gap_s > 0.0:
            raise ValueError(f"time_gap_s must be > 0, got {self.time_gap_s}")
        if not self.min_distance_m >= 0.0:
            raise ValueError(f"min_distance_m must be >= 0, got {self.min_distance_m}")
        if not self.min_speed_mps >= 0.0:
            raise ValueError(f"min_speed_mps must be >= 0, got {self.min_speed_mps}")
        if not self.release_ratio >= 1.0:
            raise ValueError(f"release_ratio must be >= 1 (1 = no hysteresis), got {self.release_ratio}")
        if not self.min_on_s >= 0.0:
            raise ValueError(f"min_on_s must be >= 0, got {self.min_on_s}")
        if not self.legible_distance_m > 0.0:
            raise ValueError(f"legible_distance_m must be > 0, got {self.legible_distance_m}")
        if not 0.0 < self.display_view_half_angle_deg <= 90.0:
            raise ValueError(
                f"display_view_half_angle_deg must be in (0, 90], got {self.display_view_half_angle_deg}"
            )
        if not self.driver_eye_back_m >= 0.0:
            raise ValueError(f"driver_eye_back_m must be >= 0, got {self.driver_eye_back_m}")

    def required_distance_m(self, leader_speed_mps: float) -> float:
        """The distance the leader's speed calls for [m]."""
        return max(self.time_gap_s * leader_speed_mps, self.min_distance_m)


@dataclass(frozen=True)
class RearWarningOutput:
    """What system A did at one step."""

    t_s: float  # simulated time [s]
    true_distance_m: (
        float  # true depth of the follower's front bumper behind the camera [m]; <= 0: not behind
    )
    measured_distance_m: float | None  # stereo estimate [m]; None when there was no measurement
    required_distance_m: float  # distance the leader's speed calls for [m]
    display_lit: bool  # the "keep distance" display on the leader's rear is on
    perceived: bool  # lit AND readable by the follower's driver (line of sight, distance, angle)
    measurement: MeasureStatus  # why there is (no) measurement
    perception: PerceiveStatus  # why the driver does (not) perceive the display

    @property
    def reason(self) -> str:
        """Both statuses in one string for logs, e.g. 'ok/occluded'."""
        return f"{self.measurement}/{self.perception}"


def camera_frame(leader: VehicleState, follower: VehicleState) -> tuple[float, float]:
    """The follower's front bumper in the rear camera frame: (depth along the optical axis, lateral) [m]."""
    rx, ry = leader.rear_xy()
    ux, uy = leader.unit()
    dx, dy = follower.x_m - rx, follower.y_m - ry
    depth = -(dx * ux + dy * uy)  # the camera looks along -heading
    lateral = dx * uy - dy * ux  # to the camera's right; sign does not matter for a symmetric FOV
    return depth, lateral


def stereo_depth(depth_m: float, camera: StereoCameraParams, rng: np.random.Generator) -> float | None:
    """One noisy, quantised stereo estimate of a true depth [m]; None when the disparity is not positive."""
    fb = camera.focal_px * camera.baseline_m
    disparity = fb / depth_m + rng.normal(0.0, camera.disparity_noise_px)
    if camera.disparity_step_px > 0.0:
        disparity = round(disparity / camera.disparity_step_px) * camera.disparity_step_px
    if disparity <= 0.0:
        return None
    return fb / disparity


class RearStereoWarning:
    """System A as a stateful object: call ``update`` once per step with the leader and its follower.

    ``rng`` draws the disparity noise (one normal draw per step with a measurable follower), so the same
    seed and the same inputs give identical outputs. Transitions of the display ('display' off/on) and of
    its perception by the follower's driver ('perceived' off/on) are recorded as events.
    """

    def __init__(
        self,
        params: RearWarningParams | None = None,
        buildings: Buildings | Iterable[shapely.Geometry] = (),
        *,
        rng: np.random.Generator,
    ) -> None:
        self.params = params if params is not None else RearWarningParams()
        self.buildings = buildings if isinstance(buildings, Buildings) else Buildings(list(buildings))
        self.rng = rng
        self.recorder = EventRecorder("A")
        self._lit = False
        self._lit_since_s = -math.inf
        self._perceived = False

    @property
    def events(self):
        return self.recorder.events

    def pop_events(self):
        return self.recorder.pop_events()

    def update(self, t_s: float, leader: VehicleState, follower: VehicleState) -> RearWarningOutput:
        p = self.params
        cam = p.camera
        depth, lateral = camera_frame(leader, follower)
        measured: float | None = None
        if depth <= 0.0:
            status: MeasureStatus = "behind_camera"
        elif math.degrees(math.atan2(abs(lateral), depth)) > 0.5 * cam.hfov_deg:
            status = "outside_fov"
        elif depth < cam.min_range_m:
            status = "too_close"
        elif depth > cam.max_range_m:
            status = "out_of_range"
        else:
            measured = stereo_depth(depth, cam, self.rng)
            status = "ok" if measured is not None else "no_disparity"

        required = p.required_distance_m(leader.speed_mps)
        if measured is not None and leader.speed_mps >= p.min_speed_mps:
            if measured < required:
                want = True
            elif measured >= p.release_ratio * required:
                want = False
            else:  # inside the hysteresis band: keep what is shown
                want = self._lit
        else:
            want = False
        if self._lit and not want and t_s - self._lit_since_s < p.min_on_s:
            want = True
        if want != self._lit:
            self.recorder.record(t_s, "display", _onoff(self._lit), _onoff(want), measured)
            if want:
                self._lit_since_s = t_s
            self._lit = want

        perception = self._perception(leader, follower)
        perceived = perception == "perceived"
        if perceived != self._perceived:
            self.recorder.record(t_s, "perceived", _onoff(self._perceived), _onoff(perceived), measured)
            self._perceived = perceived
        return RearWarningOutput(
            t_s=float(t_s),
            true_distance_m=float(depth),
            measured_distance_m=None if measured is None else float(measured),
            required_distance_m=float(required),
            display_lit=self._lit,
            perceived=perceived,
            measurement=status,
            perception=perception,
        )

    def _perception(self, leader: VehicleState, follower: VehicleState) -> PerceiveStatus:
        if not self._lit:
            return "display_off"
        p = self.params
        ex, ey = eye_xy(follower, p.driver_eye_back_m, p.driver_eye_left_m)
        rx, ry = leader.rear_xy()
        ux, uy = leader.unit()
        vx, vy = ex - rx, ey - ry  # display -> eye
        dist = math.hypot(vx, vy)
        # the display faces backwards (-heading); the eye must lie inside its viewing cone
        if dist == 0.0 or -(vx * ux + vy * uy) < dist * math.cos(math.radians(p.display_view_half_angle_deg)):
            return "outside_view_angle"
        if dist > p.legible_distance_m:
            return "too_far"
        if not self.buildings.line_of_sight(ex, ey, rx, ry):
            return "occluded"
        return "perceived"


def eye_xy(vehicle: VehicleState, back_m: float, left_m: float) -> tuple[float, float]:
    """The driver's eye in network coordinates [m] (2-D: height is ignored)."""
    ux, uy = heading_unit(vehicle.heading_deg)
    lx, ly = left_unit(vehicle.heading_deg)
    return vehicle.x_m - back_m * ux + left_m * lx, vehicle.y_m - back_m * uy + left_m * ly


def _onoff(flag: bool) -> str:
    return "on" if flag else "off"

"""The head-up display drawn onto a rendered frame (numpy + Pillow).

It shows what the participant sees besides the road: speed, the current speed limit, system B's in-car
time-gap display with its warning colour, the active experiment phase and (live) the real-time factor.
Live driving and replay fill the same :class:`HudState`, so a replayed video shows exactly what the live
window showed.

System A has no in-car part: its warning exists only on the leading car's rear display, which the 3D scene
draws on the leader (the paper's system). The HUD therefore never shows it to the driver. For someone
watching a run, ``HudState.observer_overlay`` adds a small, clearly labelled observer note when the driver
perceives that display; it is off by default and never set in ``cosim drive`` or a participant's view.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from PIL import Image, ImageDraw

from cosim.world3d.textures import font

LEVELS = ("none", "advisory", "warning")
# system B's display colours by warning level (background, text)
LEVEL_COLOURS = {
    "none": ((24, 110, 48), (255, 255, 255)),
    "advisory": ((235, 160, 0), (0, 0, 0)),
    "warning": ((205, 20, 20), (255, 255, 255)),
}
NO_DATA_COLOURS = ((70, 70, 70), (220, 220, 220))
OBSERVER_COLOURS = ((40, 40, 120, 200), (230, 230, 255))  # the observer overlay (background, text)


@dataclass(frozen=True)
class HudState:
    """What the HUD shows at one instant."""

    t_s: float  # [s] simulated time
    speed_mps: float  # [m/s] ego speed
    speed_limit_mps: float | None = None  # [m/s] limit where the ego is; None = unknown
    sys_b_active: bool = False  # system B's in-car display is switched on (this phase)
    sys_b_gap_s: float | None = None  # [s] time gap it shows; None = 'no data'
    sys_b_level: str = "none"  # 'none' | 'advisory' (amber) | 'warning' (red)
    sys_a_perceived: bool = False  # the driver perceives the leader's rear display (data, not drawn)
    observer_overlay: bool = False  # draw an observer's note of sys_a_perceived (never in a driver's view)
    phase: str | None = None  # active experiment phase (e.g. 'baseline', 'system A'), None = not in one
    real_time_factor: float | None = None  # simulated / wall time (live only)
    note: str | None = None  # one line of status (e.g. 'ego off road')

    def __post_init__(self) -> None:
        if self.sys_b_level not in LEVELS:
            raise ValueError(f"HudState.sys_b_level must be one of {LEVELS}, got {self.sys_b_level!r}")
        if not math.isfinite(self.speed_mps):
            raise ValueError(f"HudState.speed_mps must be finite, got {self.speed_mps!r}")
        if self.sys_b_gap_s is not None and not self.sys_b_gap_s >= 0.0:
            raise ValueError(f"HudState.sys_b_gap_s must be >= 0 or None, got {self.sys_b_gap_s!r}")


def _box(d: ImageDraw.ImageDraw, xy, fill, radius: int) -> None:
    d.rounded_rectangle(xy, radius=radius, fill=fill)


def draw_hud(frame: np.ndarray, hud: HudState) -> np.ndarray:
    """A copy of ``frame`` ((H, W, 3) uint8) with the HUD drawn on it; sizes scale with the frame height."""
    h, w = frame.shape[:2]
    img = Image.fromarray(np.ascontiguousarray(frame))
    d = ImageDraw.Draw(img, "RGBA")
    s = h / 720.0  # layout designed at 1280 x 720
    pad = max(4, int(16 * s))
    big, mid, small = font(max(10, int(64 * s))), font(max(9, int(30 * s))), font(max(8, int(20 * s)))

    # speed, bottom left
    kmh = max(0.0, hud.speed_mps) * 3.6
    bw, bh = int(230 * s), int(110 * s)
    x0, y0 = pad, h - pad - bh
    _box(d, (x0, y0, x0 + bw, y0 + bh), (0, 0, 0, 150), int(12 * s))
    d.text((x0 + bw - int(70 * s), y0 + bh // 2), f"{kmh:.0f}", fill=(255, 255, 255), font=big, anchor="rm")
    d.text((x0 + bw - int(12 * s), y0 + bh // 2 + int(14 * s)), "km/h", fill=(210, 210, 210), font=small,
           anchor="rm")  # fmt: skip

    # speed-limit sign beside it
    if hud.speed_limit_mps is not None and hud.speed_limit_mps > 0:
        r = int(46 * s)
        cx, cy = x0 + bw + pad + r, h - pad - bh // 2
        d.ellipse((cx - r, cy - r, cx + r, cy + r), fill=(200, 25, 30))
        ri = int(r * 0.78)
        d.ellipse((cx - ri, cy - ri, cx + ri, cy + ri), fill=(250, 250, 250))
        lim = f"{round(hud.speed_limit_mps * 3.6):.0f}"
        d.text((cx, cy), lim, fill=(0, 0, 0), font=mid if len(lim) < 3 else small, anchor="mm")

    # system B: the in-car time-gap display, top centre
    if hud.sys_b_active:
        if hud.sys_b_gap_s is None:
            (bg, fg), text = NO_DATA_COLOURS, "no data"
        else:
            bg, fg = LEVEL_COLOURS[hud.sys_b_level]
            text = f"{hud.sys_b_gap_s:.1f} s" if hud.sys_b_gap_s < 10 else ">10 s"
        bw2, bh2 = int(250 * s), int(84 * s)
        x1 = (w - bw2) // 2
        _box(d, (x1, pad, x1 + bw2, pad + bh2), (*bg, 230), int(12 * s))
        d.text((x1 + bw2 // 2, pad + int(20 * s)), "time gap", fill=fg, font=small, anchor="mm")
        d.text((x1 + bw2 // 2, pad + int(56 * s)), text, fill=fg, font=mid, anchor="mm")

    # system A is on the leader's rear display only: nothing in the car. An observer (not the driver) may
    # ask for a note that the driver perceives it, bottom right, in the observer's colours.
    if hud.observer_overlay and hud.sys_a_perceived:
        text = "observer: driver sees system A"
        tw = int(d.textlength(text, font=small)) + 2 * pad
        bh3 = int(34 * s)
        x2, y2 = w - pad - tw, h - pad - bh3
        _box(d, (x2, y2, x2 + tw, y2 + bh3), OBSERVER_COLOURS[0], int(6 * s))
        d.text((x2 + tw // 2, y2 + bh3 // 2), text, fill=OBSERVER_COLOURS[1], font=small, anchor="mm")

    # phase and time, top left; real-time factor and notes, top right
    lines = [f"t = {hud.t_s:7.1f} s"]
    if hud.phase:
        lines.insert(0, f"phase: {hud.phase}")
    ty = pad
    for line in lines:
        d.text((pad, ty), line, fill=(255, 255, 255), font=small, stroke_width=max(1, int(2 * s)),
               stroke_fill=(0, 0, 0))  # fmt: skip
        ty += int(28 * s)
    right = []
    if hud.real_time_factor is not None:
        right.append(f"{hud.real_time_factor:.2f}x real time")
    if hud.note:
        right.append(hud.note)
    ty = pad
    for line in right:
        d.text((w - pad, ty), line, fill=(255, 255, 255), font=small, anchor="ra", stroke_width=max(1, int(2 * s)),
               stroke_fill=(0, 0, 0))  # fmt: skip
        ty += int(28 * s)
    return np.asarray(img)

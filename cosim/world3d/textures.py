"""Procedural textures for the scene (numpy + Pillow, deterministic): facades, ground, sign faces, the
rear "keep distance" display. Images are (H, W, 3) uint8 arrays, row 0 at the TOP of the picture; scene.py
flips them for MuJoCo, whose texture coordinate v = 0 is the bottom row.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from PIL import Image, ImageDraw, ImageFont

RED = (200, 25, 30)
WHITE = (245, 245, 245)
BLUE = (20, 70, 170)
YELLOW = (250, 205, 20)
BLACK = (20, 20, 20)


@lru_cache(maxsize=16)
def font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    """Pillow's bundled scalable font (a bitmap fallback when Pillow was built without FreeType)."""
    try:
        return ImageFont.load_default(size=size)
    except (TypeError, OSError):  # old Pillow / no FreeType
        return ImageFont.load_default()


def facade(px: int = 64) -> np.ndarray:
    """One window bay of one storey: pale wall, a dark window with a light frame (tinted by the material)."""
    img = np.full((px, px, 3), 236, dtype=np.uint8)
    x0, x1 = int(0.28 * px), int(0.72 * px)
    y0, y1 = int(0.22 * px), int(0.70 * px)  # row 0 is the top of the storey
    img[y0 - 2 : y1 + 3, x0 - 2 : x1 + 2] = (250, 250, 250)
    img[y0:y1, x0:x1] = (62, 78, 98)
    img[y0 : y0 + (y1 - y0) // 3, x0:x1] = (84, 104, 126)  # sky reflection in the upper pane
    img[y1 + 1 : y1 + 4, x0 - 3 : x1 + 3] = (200, 200, 200)  # sill
    return img


def ground(px: int = 256, seed: int = 3) -> np.ndarray:
    """Grass: green with soft low-contrast blotches and fine grain, so that motion over it is visible."""
    rng = np.random.default_rng(seed)
    coarse = Image.fromarray(((rng.normal(0.0, 1.0, (16, 16)) * 40) + 128).clip(0, 255).astype(np.uint8))
    blotches = (np.asarray(coarse.resize((px, px), Image.Resampling.BICUBIC), dtype=np.float64) - 128) / 40
    noise = 0.8 * blotches + 0.5 * rng.normal(0.0, 1.0, (px, px))
    base = np.array([92, 128, 64], dtype=np.float64)
    img = base[None, None, :] * (1.0 + 0.06 * noise[:, :, None])
    return np.clip(img, 0, 255).astype(np.uint8)


@dataclass(frozen=True)
class SignAtlas:
    """All sign faces in one texture; ``rects[key]`` = (u0, v0, u1, v1) in MuJoCo texture coordinates."""

    image: np.ndarray  # (H, W, 3) uint8, row 0 at the top
    rects: dict[str, tuple[float, float, float, float]]


def _draw_sign(key: str, cell: int) -> Image.Image:
    img = Image.new("RGB", (cell, cell), (128, 128, 128))
    d = ImageDraw.Draw(img)
    c = cell / 2
    r = cell / 2 - 1
    if key in ("stop", "allway_stop"):
        pts = [(c + r * np.cos(a), c + r * np.sin(a)) for a in np.pi / 8 + np.pi / 4 * np.arange(8)]
        d.polygon(pts, fill=WHITE)
        pts = [
            (c + (r - 5) * np.cos(a), c + (r - 5) * np.sin(a)) for a in np.pi / 8 + np.pi / 4 * np.arange(8)
        ]
        d.polygon(pts, fill=RED)
        d.text((c, c), "STOP", fill=WHITE, font=font(int(cell * 0.27)), anchor="mm")
    elif key == "give_way":  # triangle pointing down, red border
        d.polygon([(1, 1), (cell - 1, 1), (c, cell - 1)], fill=RED)
        d.polygon([(16, 10), (cell - 16, 10), (c, cell - 20)], fill=WHITE)
    elif key.startswith("speed:") or key == "no_entry":
        d.ellipse((1, 1, cell - 1, cell - 1), fill=RED)
        if key == "no_entry":
            d.rectangle((0.2 * cell, 0.42 * cell, 0.8 * cell, 0.58 * cell), fill=WHITE)
        else:
            m = int(0.11 * cell)
            d.ellipse((m, m, cell - m, cell - m), fill=WHITE)
            value = key.split(":", 1)[1]
            d.text(
                (c, c),
                value,
                fill=BLACK,
                font=font(int(cell * (0.42 if len(value) < 3 else 0.33))),
                anchor="mm",
            )
    elif key == "one_way":
        d.rectangle((0, 0, cell, cell), fill=BLUE)
        d.rectangle((4, 4, cell - 5, cell - 5), outline=WHITE, width=3)
        d.polygon([(c, 14), (c + 26, 50), (c - 26, 50)], fill=WHITE)
        d.rectangle((c - 9, 48, c + 9, cell - 16), fill=WHITE)
    elif key == "city_limit":
        d.rectangle((0, 0, cell, cell), fill=YELLOW)
        d.rectangle((4, 4, cell - 5, cell - 5), outline=BLACK, width=4)
        for y in (0.36, 0.56):
            d.rectangle((0.18 * cell, y * cell, 0.82 * cell, (y + 0.08) * cell), fill=BLACK)
    else:
        raise ValueError(f"no sign face for {key!r}")
    return img


def sign_atlas(keys: list[str], cell: int = 128) -> SignAtlas:
    """Draw every sign face once into a grid of ``cell``-pixel squares."""
    keys = sorted(set(keys))
    cols = max(1, int(np.ceil(np.sqrt(len(keys)))))
    rows = max(1, int(np.ceil(len(keys) / cols)))
    img = Image.new("RGB", (cols * cell, rows * cell), (128, 128, 128))
    rects: dict[str, tuple[float, float, float, float]] = {}
    inset = 1.5  # [px] keep the sampler away from the neighbouring cell
    w, h = cols * cell, rows * cell
    for i, key in enumerate(keys):
        col, row = i % cols, i // cols
        img.paste(_draw_sign(key, cell), (col * cell, row * cell))
        u0, u1 = (col * cell + inset) / w, ((col + 1) * cell - inset) / w
        # MuJoCo's v runs from the bottom row up; scene.py flips the image rows when uploading
        v1 = 1.0 - (row * cell + inset) / h
        v0 = 1.0 - ((row + 1) * cell - inset) / h
        rects[key] = (u0, v0, u1, v1)
    return SignAtlas(np.asarray(img, dtype=np.uint8), rects)


def keep_distance_panel(lit: bool, width: int = 256, height: int = 64) -> np.ndarray:
    """System A's rear display: amber 'KEEP DISTANCE' on black when lit, a dark screen when off."""
    img = Image.new("RGB", (width, height), (12, 12, 14))
    d = ImageDraw.Draw(img)
    d.rectangle((0, 0, width - 1, height - 1), outline=(60, 60, 60), width=3)
    if lit:
        d.text((width / 2, height / 2), "KEEP DISTANCE", fill=(255, 170, 20), font=font(int(height * 0.45)),
               anchor="mm")  # fmt: skip
    return np.asarray(img, dtype=np.uint8)

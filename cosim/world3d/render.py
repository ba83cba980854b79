"""Offscreen rendering of the scene: driver, chase and top cameras, with the HUD on top.

MuJoCo picks its OpenGL backend from ``MUJOCO_GL`` when ``mujoco`` is FIRST imported. This module sets
``MUJOCO_GL=egl`` (headless, works with Mesa's software rasteriser) unless the variable is already set; the
``cosim`` commands that render import it before anything imports MuJoCo. Set ``MUJOCO_GL=osmesa`` or
``glfw`` yourself for other setups.
"""

from __future__ import annotations

import os
import sys

if "mujoco" not in sys.modules:
    os.environ.setdefault("MUJOCO_GL", "egl")
else:  # imported before us without a choice (GLFW, which needs a display): make EGL the default anyway
    try:
        from mujoco.rendering.classic import gl_context as _glc

        if (
            sys.platform.startswith("linux")
            and getattr(_glc, "_MUJOCO_GL", None) == ""
            and not os.environ.get("MUJOCO_GL")
        ):
            from mujoco.egl import GLContext as _EglContext

            _glc.GLContext = _EglContext
            os.environ["MUJOCO_GL"] = "egl"
    except Exception:  # noqa: BLE001 - keep MuJoCo's own choice; open_renderer reports a failure clearly
        pass

from dataclasses import dataclass  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from cosim.errors import CosimError  # noqa: E402
from cosim.world3d.hud import draw_hud  # noqa: E402
from cosim.world3d.scene import Scene  # noqa: E402

CAMERAS = ("driver", "chase", "top")


@dataclass(frozen=True)
class ViewParams:
    width: int = 1280  # [px]
    height: int = 720  # [px]
    camera: str = "driver"  # 'driver' | 'chase' | 'top'
    hud: bool = True
    top_view_m: float = 120.0  # [m] height of the ground area the top camera shows (orthographic)
    fog: bool = True

    def __post_init__(self) -> None:
        if self.camera not in CAMERAS:
            raise ValueError(f"camera must be one of {CAMERAS}, got {self.camera!r}")
        if self.width < 16 or self.height < 16:
            raise ValueError(f"frame size must be at least 16 x 16 px, got {self.width} x {self.height}")
        if not self.top_view_m > 0:
            raise ValueError(f"top_view_m must be > 0, got {self.top_view_m}")


def open_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    """A MuJoCo offscreen renderer, or one clear CosimError when no OpenGL context can be made."""
    if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
        raise CosimError(
            f"frame {width}x{height} is larger than the scene's offscreen buffer "
            f"{model.vis.global_.offwidth}x{model.vis.global_.offheight}; build the scene with larger "
            "SceneParams.max_width / max_height"
        )
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as exc:  # no EGL / no display: one line, with the fix
        gl = os.environ.get("MUJOCO_GL", "(unset)")
        raise CosimError(
            f"cannot create an OpenGL context for rendering (MUJOCO_GL={gl}): {exc}. Install Mesa's EGL "
            "(apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri) and run with MUJOCO_GL=egl, or use "
            "MUJOCO_GL=osmesa"
        ) from None


class View:
    """Renders a :class:`Scene` from one camera at one size; ``render(frame_state)`` returns an RGB image."""

    def __init__(self, scene: Scene, params: ViewParams | None = None) -> None:
        self.scene = scene
        self.params = p = params or ViewParams()
        self.renderer = open_renderer(scene.model, p.width, p.height)
        flags = self.renderer.scene.flags
        flags[mujoco.mjtRndFlag.mjRND_FOG] = p.fog
        flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = True
        self.option = mujoco.MjvOption()
        self._cam = mujoco.MjvCamera()
        self._closed = False

    def camera(self, name: str | None = None) -> mujoco.MjvCamera:
        """The MjvCamera for a camera name at the scene's current pose."""
        name = name or self.params.camera
        cam = self._cam
        if name in ("driver", "chase") and self.scene.has_ego:
            cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
            cam.fixedcamid = mujoco.mj_name2id(self.scene.model, mujoco.mjtObj.mjOBJ_CAMERA, name)
            return cam
        # top view (also the fallback without an ego): orthographic, north up, centred on the ego
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.fixedcamid = -1
        d = self.scene.data
        ego = self.scene.model.body("ego").mocapid[0]
        centre = d.mocap_pos[ego] if self.scene.has_ego else np.zeros(3)
        cam.lookat[:] = (centre[0], centre[1], 0.0)
        cam.distance = 300.0
        cam.azimuth = 90.0
        cam.elevation = -90.0
        cam.orthographic = 1
        return cam

    def render(self, frame=None, camera: str | None = None, hud=None) -> np.ndarray:
        """(H, W, 3) uint8 image. ``frame`` (a FrameState) is applied first if given; the HUD is drawn from
        ``hud`` or ``frame.hud`` when the view has ``hud`` on."""
        if frame is not None:
            self.scene.apply(frame)
        name = camera or self.params.camera
        cam = self.camera(name)
        vis = self.scene.model.vis
        if cam.type == mujoco.mjtCamera.mjCAMERA_FREE:
            saved = vis.global_.fovy
            vis.global_.fovy = self.params.top_view_m  # orthographic: fovy is the view height in metres
            self.renderer.update_scene(self.scene.data, cam, self.option)
            vis.global_.fovy = saved
        else:
            self.renderer.update_scene(self.scene.data, cam, self.option)
        img = self.renderer.render()
        state = hud if hud is not None else (frame.hud if frame is not None else None)
        if self.params.hud and state is not None:
            img = draw_hud(img, state)
        return img

    def segmentation(self, camera: str | None = None) -> np.ndarray:
        """(H, W) int32 geom id per pixel (-1 = sky) for the scene's current pose (for tests and tools)."""
        self.renderer.enable_segmentation_rendering()
        try:
            cam = self.camera(camera or self.params.camera)
            vis = self.scene.model.vis
            saved = vis.global_.fovy
            if cam.type == mujoco.mjtCamera.mjCAMERA_FREE:
                vis.global_.fovy = self.params.top_view_m
            self.renderer.update_scene(self.scene.data, cam, self.option)
            vis.global_.fovy = saved
            seg = self.renderer.render()
        finally:
            self.renderer.disable_segmentation_rendering()
        ids = seg[:, :, 0].astype(np.int32)
        ids[seg[:, :, 1] != int(mujoco.mjtObj.mjOBJ_GEOM)] = -1
        return ids

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self.renderer.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

"""The 3D view: a MuJoCo scene generated from a scenario, driver / chase / top cameras with a HUD, the
real-time window of ``cosim drive`` and the video of ``cosim render``.

- ``scene``: :func:`build_scene` (scenario -> :class:`Scene`; coordinates: network minus ``Scene.origin_xy``),
  ``Scene.apply(FrameState)`` poses cars, lamps and system A's display for one frame;
- ``render``: :class:`View` (offscreen MuJoCo renderer, EGL by default) -> RGB frames;
- ``hud``: :class:`HudState` and :func:`draw_hud` (shared by live driving and replay);
- ``state``: :class:`FrameState` and friends (pure data), the vehicle pool rule, interpolation;
- ``live``: :class:`LiveSource` (a running Simulation -> FrameState);
- ``cli``: ``add_drive_parser`` / ``main_drive``, ``add_render_parser`` / ``main_render`` (light imports);
- ``drive``: :class:`DriveSession` (the real-time loop; the window is the viewer's), :func:`run_drive`;
- ``viewer``: :class:`Viewer` (the drive view in its own process: window, input devices, interpolated frames);
- ``replay``: :func:`render_log` (MCAP -> MP4 / PNG).

Geometry, state, HUD and textures import without MuJoCo; the rest loads it (rendering sets ``MUJOCO_GL=egl``
unless it is set).
"""

from __future__ import annotations

import importlib
from typing import Any

_LAZY = {
    "build_scene": "cosim.world3d.scene",
    "Scene": "cosim.world3d.scene",
    "SceneParams": "cosim.world3d.scene",
    "View": "cosim.world3d.render",
    "ViewParams": "cosim.world3d.render",
    "HudState": "cosim.world3d.hud",
    "draw_hud": "cosim.world3d.hud",
    "EgoPose": "cosim.world3d.state",
    "FrameState": "cosim.world3d.state",
    "VehicleFrame": "cosim.world3d.state",
    "LiveSource": "cosim.world3d.live",
    "DriveParams": "cosim.world3d.drive",
    "DriveSession": "cosim.world3d.drive",
    "run_drive": "cosim.world3d.drive",
    "main_drive": "cosim.world3d.cli",
    "add_drive_parser": "cosim.world3d.cli",
    "RenderParams": "cosim.world3d.replay",
    "render_log": "cosim.world3d.replay",
    "main_render": "cosim.world3d.cli",
    "add_render_parser": "cosim.world3d.cli",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str) -> Any:  # PEP 562: import MuJoCo / pygame only when needed
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)

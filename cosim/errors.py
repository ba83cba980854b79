"""Errors a user can cause. The CLI turns each into one line on stderr and exit code 2."""


class CosimError(Exception):
    """A problem with the user's input (file, config, map, parameter): message names it and the fix."""


class ConfigError(CosimError):
    """A config value is missing, unknown, of the wrong type or impossible. The message starts with the key path."""

    def __init__(self, path: str, problem: str):
        self.path = path
        self.problem = problem
        super().__init__(f"config {path}: {problem}" if path else f"config: {problem}")


def require_display(what: str) -> None:
    """Refuse ``what`` (a window a person looks at or types into) when there is no display to show it on:
    on Linux neither DISPLAY nor WAYLAND_DISPLAY is set and SDL is not told to use a real video driver."""
    import os
    import sys

    if not sys.platform.startswith("linux"):
        return
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return
    if os.environ.get("SDL_VIDEODRIVER", "").lower() not in ("", "dummy", "offscreen", "x11", "wayland"):
        return  # e.g. kmsdrm: a console without X
    raise CosimError(f"{what} needs a display and there is none (DISPLAY / WAYLAND_DISPLAY not set): run it "
                     f"in a desktop session or under xvfb-run")  # fmt: skip

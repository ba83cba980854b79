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
    on Linux neither DISPLAY nor WAYLAND_DISPLAY names a server that answers, and SDL is not told to use a
    real video driver. A DISPLAY left over from a closed session would otherwise make sumo-gui fail and
    TraCI retry its connection for a minute."""
    import os
    import sys

    if not sys.platform.startswith("linux"):
        return
    if os.environ.get("SDL_VIDEODRIVER", "").lower() not in ("", "dummy", "offscreen", "x11", "wayland"):
        return  # e.g. kmsdrm: a console without X
    x11, wayland = os.environ.get("DISPLAY", ""), os.environ.get("WAYLAND_DISPLAY", "")
    if not x11 and not wayland:
        raise CosimError(f"{what} needs a display and there is none (DISPLAY / WAYLAND_DISPLAY not set): run "
                         f"it in a desktop session or under xvfb-run")  # fmt: skip
    if (x11 and _x11_answers(x11)) or (wayland and _wayland_answers(wayland)):
        return
    named = " and ".join(f"{k}={v}" for k, v in (("DISPLAY", x11), ("WAYLAND_DISPLAY", wayland)) if v)
    raise CosimError(f"{what} needs a display, but no display server answers at {named}: start one, fix the "
                     f"variable, or run under xvfb-run")  # fmt: skip


def _x11_answers(display: str) -> bool:
    """Whether an X server accepts connections at ``display`` ([host]:number[.screen], as X(7) defines it):
    the local socket /tmp/.X11-unix/X<n> (or its abstract twin), else TCP port 6000 + n on the host."""
    import socket

    host, sep, rest = display.rpartition(":")
    number = rest.split(".", 1)[0]
    if not sep or not number.isdigit():
        return False
    if host in ("", "unix"):
        path = f"/tmp/.X11-unix/X{number}"
        return any(_connects(socket.AF_UNIX, addr) for addr in (path, "\0" + path))
    return _connects(socket.AF_INET, (host, 6000 + int(number)))


def _wayland_answers(name: str) -> bool:
    import os
    import socket

    path = name if name.startswith("/") else os.path.join(os.environ.get("XDG_RUNTIME_DIR", ""), name)
    return _connects(socket.AF_UNIX, path)


def _connects(family, address) -> bool:
    import socket

    try:
        with socket.socket(family, socket.SOCK_STREAM) as s:
            s.settimeout(1.0)
            s.connect(address)
        return True
    except OSError:
        return False

"""The display probe behind every window cosim opens: a variable that names no live server is refused."""

import socket

import pytest

from cosim.errors import CosimError, require_display


def test_a_local_x_socket_that_listens_counts(tmp_path, monkeypatch):
    # the probe connects to /tmp/.X11-unix/X<n>; stand a listener up on its abstract-namespace twin
    n = 4242
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as srv:
        srv.bind(f"\0/tmp/.X11-unix/X{n}")
        srv.listen(1)
        monkeypatch.setenv("DISPLAY", f":{n}.0")
        monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
        monkeypatch.delenv("SDL_VIDEODRIVER", raising=False)
        require_display("a window")  # no error


@pytest.mark.parametrize("display", [":4243", "localhost:4243", "garbage"])
def test_a_display_nobody_answers_is_refused(monkeypatch, display):
    monkeypatch.setenv("DISPLAY", display)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.delenv("SDL_VIDEODRIVER", raising=False)
    with pytest.raises(CosimError, match=f"no display server answers at DISPLAY={display}"):
        require_display("a window")


def test_no_display_at_all(monkeypatch):
    for k in ("DISPLAY", "WAYLAND_DISPLAY", "SDL_VIDEODRIVER"):
        monkeypatch.delenv(k, raising=False)
    with pytest.raises(CosimError, match="DISPLAY / WAYLAND_DISPLAY not set"):
        require_display("a window")

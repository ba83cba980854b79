"""Helper processes of a run (the log writer, the radio): started, fed and read the same way.

A child is ``python -c <code>`` importing this same cosim, in its own session (a Ctrl-C at the terminal
reaches the run only, which then ends its children in order). Records go through pipes as pickles; a
Ctrl-C or SIGTERM waits until a record is through, since half a record would break the stream for good.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import signal
import subprocess
import sys
import threading
from pathlib import Path


def available_cores() -> int:
    """Cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def start_child(code: str, *, replies: bool) -> subprocess.Popen:
    """``python -c code`` with pickles on its stdin (and, with ``replies``, from its stdout)."""
    import cosim

    root = str(Path(cosim.__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")]))}
    proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, env=env,
                            stdout=subprocess.PIPE if replies else subprocess.DEVNULL, bufsize=1 << 16,
                            start_new_session=True)  # fmt: skip
    widen_pipe(proc.stdin)
    if replies:
        widen_pipe(proc.stdout)
    return proc


def widen_pipe(stream) -> None:
    """A 1 MiB pipe (Linux; 64 KiB by default) lets the sender go on while the other side catches up with a
    burst (the per-vehicle columns), instead of waiting for it at every large record."""
    try:
        import fcntl

        fcntl.fcntl(stream.fileno(), fcntl.F_SETPIPE_SZ, 1 << 20)
    except (ImportError, AttributeError, OSError):  # not Linux, or above /proc/sys/fs/pipe-max-size
        pass


@contextlib.contextmanager
def signals_held():
    """Ctrl-C / SIGTERM arrive after the block (only the main thread can hold them)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def send(stream, record, *, flush: bool = True) -> None:
    """Pickle ``record`` into ``stream`` whole (``flush``: now, for a reply to wait for; else when the
    stream's buffer is full)."""
    data = pickle.dumps(record, protocol=pickle.HIGHEST_PROTOCOL)
    with signals_held():
        stream.write(data)
        if flush:
            stream.flush()


def receive(stream):
    """The next pickled record of ``stream``, read whole (EOFError when the other side is gone)."""
    with signals_held():
        return pickle.load(stream)


def serve_stdio():
    """In a child: (its stdin, a private stream for replies). Anything printed goes to stderr, so a stray
    print of a library cannot corrupt the replies."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the run decides when its helpers end
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # ... also when a service manager stops every process
    replies = os.fdopen(os.dup(1), "wb", buffering=1 << 16)
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    return sys.stdin.buffer, replies

"""Independent runs of a comparison side by side: some in a forked child process, the rest here.

A comparison's closed-loop runs (each controller on the plant, then judged) do not depend on
each other. :func:`side_by_side` forks one child that runs part of them while this process
runs the others; the child inherits everything built so far (the controllers, the plant, the
compiled functions) and hands its results back pickled through a temporary file. The
numbers are those of running them here: the same code on the same memory.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import signal
import sys
import tempfile

__all__ = ["side_by_side", "can_fork"]


def can_fork() -> bool:
    """Whether :func:`side_by_side` can run anything in a child (``fork``, at least 2 processors)."""
    return hasattr(os, "fork") and (os.cpu_count() or 1) >= 2


def _child(run, names, path: str) -> None:
    """In the child: ``{name: run(name)}`` (or the exception) pickled into ``path``; never returns."""
    code = 0
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)       # Ctrl-C is the parent's to handle
        try:
            payload = ("ok", {name: run(name) for name in names})
        except Exception as exc:                           # noqa: BLE001 (handed to the parent)
            payload = ("error", exc)
        with open(path, "wb") as fh:
            try:
                pickle.dump(payload, fh)
            except Exception:                              # noqa: BLE001 (an unpicklable result)
                fh.seek(0)
                fh.truncate()
                code = 1
    finally:
        with contextlib.suppress(Exception):
            sys.stdout.flush()
            sys.stderr.flush()
        os._exit(code)


def side_by_side(names, run, here=None) -> dict:
    """``{name: run(name)}`` for every name, part of them run in a forked child.

    Parameters
    ----------
    names : sequence of str
        The runs, in order.
    run : callable
        ``run(name)`` -> a picklable result; it may raise (the exception is raised here).
    here : callable, optional
        ``here()``: work only this process needs, done here after the fork and before this
        process's own runs (while the child runs its share, which is the larger one); without a
        child, before the runs. Its exception stops the child and is raised.

    Returns
    -------
    dict
        Name -> result, in the order of ``names``. Names the child could not hand back (it was
        killed, or a result would not pickle) are run here.
    """
    names = list(names)
    theirs = names[1::2] + (names[-1:] if len(names) % 2 else [])
    if len(names) < 2 or not can_fork():
        if here is not None:
            here()
        return {name: run(name) for name in names}
    fd, path = tempfile.mkstemp(prefix="hubbeam-runs-", suffix=".pickle")
    os.close(fd)
    try:
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:                                       # pragma: no cover (the child exits in _child)
            _child(run, theirs, path)
        try:
            if here is not None:
                here()
            out = {name: run(name) for name in names if name not in theirs}
            os.waitpid(pid, 0)
        except BaseException:                              # also Ctrl-C while waiting: no child left running
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
            with contextlib.suppress(OSError):
                os.waitpid(pid, 0)
            raise
        payload = None
        with contextlib.suppress(OSError, EOFError, pickle.UnpicklingError), open(path, "rb") as fh:
            payload = pickle.load(fh)
        if payload is not None and payload[0] == "error":
            raise payload[1]
        got = payload[1] if payload is not None else {}
        for name in theirs:                                # what the child did not hand back: here
            out[name] = got[name] if name in got else run(name)
        return {name: out[name] for name in names}
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)

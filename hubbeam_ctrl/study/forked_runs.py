"""Independent runs side by side: some in forked child processes, the rest here.

A comparison's closed-loop runs (each controller on the plant, then judged) do not depend on
each other, nor do the rig ladder's. :class:`ForkedRuns` forks children that each run their
share while this process goes on; every child inherits everything built so far (the
controllers, the plant, the compiled functions) and hands its results back pickled through a
temporary file. The numbers are those of running them here: the same code on the same memory.
:func:`side_by_side` is the common case: one child runs part of the runs while this process
runs the others.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import signal
import sys
import tempfile

__all__ = ["ForkedRuns", "side_by_side", "can_fork"]


def can_fork() -> bool:
    """Whether :class:`ForkedRuns` can run anything in a child (``fork``, at least 2 processors)."""
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


class ForkedRuns:
    """Runs handed to forked children at construction, collected by :meth:`collect`.

    Parameters
    ----------
    shares : sequence of sequence
        One child per non-empty share: the run names (hashable, picklable) it runs, in order.
    run : callable
        ``run(name)`` -> a picklable result; it may raise (the exception is raised by
        :meth:`collect`).

    Notes
    -----
    Use it as a context manager (or call :meth:`stop`): leaving the block by an exception, Ctrl-C
    included, kills and reaps every child still running, so none is left behind. Without
    ``fork`` (or on one processor) no child is made and :meth:`collect` runs everything here.
    """

    def __init__(self, shares, run):
        self._run = run
        self._shares = [list(s) for s in shares if len(s)]
        self._children = []                                # (pid, path, names)
        if not can_fork():
            return
        sys.stdout.flush()
        sys.stderr.flush()
        try:
            for names in self._shares:
                fd, path = tempfile.mkstemp(prefix="hubbeam-runs-", suffix=".pickle")
                os.close(fd)
                pid = os.fork()
                if pid == 0:                               # pragma: no cover (the child exits in _child)
                    _child(run, names, path)
                self._children.append((pid, path, names))
        except BaseException:
            self.stop()
            raise

    def __enter__(self) -> "ForkedRuns":
        return self

    def __exit__(self, kind, exc, tb) -> None:
        self.stop()

    def stop(self) -> None:
        """Kill and reap the children still running and remove their files (idempotent)."""
        for pid, path, _ in self._children:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
            with contextlib.suppress(OSError):
                os.waitpid(pid, 0)
            with contextlib.suppress(OSError):
                os.unlink(path)
        self._children = []

    def collect(self) -> dict:
        """Wait for the children and return ``{name: result}`` for every name of every share.

        Returns
        -------
        dict
            Name -> result, share by share. Names a child could not hand back (it was killed, or
            a result would not pickle) are run here.

        Raises
        ------
        Exception
            The first exception a child's run raised (the other children are stopped).
        """
        got = {}
        try:
            for pid, path, _ in self._children:
                os.waitpid(pid, 0)
                payload = None
                with contextlib.suppress(OSError, EOFError, pickle.UnpicklingError), open(path, "rb") as fh:
                    payload = pickle.load(fh)
                if payload is not None and payload[0] == "error":
                    raise payload[1]
                got.update(payload[1] if payload is not None else {})
        finally:
            self.stop()
        return {name: got[name] if name in got else self._run(name) for share in self._shares for name in share}


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
    with ForkedRuns([theirs], run) as child:
        if here is not None:
            here()
        out = {name: run(name) for name in names if name not in theirs}
        out.update(child.collect())
    return {name: out[name] for name in names}

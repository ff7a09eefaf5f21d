"""Native libraries' output (CasADi, SUNDIALS, IPOPT, qpOASES print with ``printf``).

Under the command line that output must never reach stdout (``--json`` must stay clean)
and must not flood the terminal: :class:`capture_native_output` sends file descriptors 1
and 2 to a temporary file while Python's own ``sys.stdout`` and ``sys.stderr`` keep
writing to the terminal; the captured text can go to a log file (``--verbose``).
:class:`stdout_to_stderr` is the lighter form that only keeps stdout clean.
"""

from __future__ import annotations

import io
import os
import sys
import tempfile

__all__ = ["stdout_to_stderr", "capture_native_output"]


class stdout_to_stderr:
    """Send file descriptor 1 to stderr for a while (native libraries such as qpOASES
    print banners with printf; ``--json`` output must stay clean)."""

    def __enter__(self):
        sys.stdout.flush()
        self._saved = os.dup(1)
        os.dup2(2, 1)
        return self

    def __exit__(self, *exc):
        sys.stdout.flush()
        os.dup2(self._saved, 1)
        os.close(self._saved)
        return False


def _fd_of(stream):
    try:
        return stream.fileno()
    except (AttributeError, OSError, ValueError, io.UnsupportedOperation):
        return None


class capture_native_output:
    """Capture what native code writes to file descriptors 1 and 2.

    Python's ``sys.stdout`` / ``sys.stderr``, when they are the process's descriptors 1 and
    2, are replaced for the duration by streams on copies of the original descriptors, so
    Python output still reaches the terminal; streams that are not (pytest's capture) are
    left alone.

    Parameters
    ----------
    log : str or Path, optional
        File the captured text is appended to at the end (``--verbose``).

    Attributes
    ----------
    text : str
        What was captured (after the block).
    lines : int
        Its number of non-empty lines.

    Examples
    --------
    >>> with capture_native_output() as cap:
    ...     _ = os.write(1, b"native banner\\n")
    >>> cap.lines
    1
    """

    def __init__(self, log=None):
        self.log, self.text, self.lines = log, "", 0

    def __enter__(self):
        sys.stdout.flush()
        sys.stderr.flush()
        self._file = tempfile.TemporaryFile()
        self._saved = {fd: os.dup(fd) for fd in (1, 2)}
        self._streams = {}
        for name, fd in (("stdout", 1), ("stderr", 2)):
            stream = getattr(sys, name)
            if _fd_of(stream) == fd:
                self._streams[name] = stream
                setattr(sys, name, open(os.dup(self._saved[fd]), "w", encoding=getattr(stream, "encoding", None)
                                        or "utf-8", errors="backslashreplace", buffering=1))
        for fd in (1, 2):
            os.dup2(self._file.fileno(), fd)
        return self

    def __exit__(self, *exc):
        for name, original in self._streams.items():
            getattr(sys, name).flush()
            getattr(sys, name).close()
            setattr(sys, name, original)
        for fd, saved in self._saved.items():
            os.dup2(saved, fd)
            os.close(saved)
        self._file.seek(0)
        self.text = self._file.read().decode("utf-8", "backslashreplace")
        self._file.close()
        self.lines = sum(1 for line in self.text.splitlines() if line.strip())
        if self.log and self.text:
            with open(self.log, "a", encoding="utf-8") as fh:
                fh.write(self.text if self.text.endswith("\n") else self.text + "\n")
        return False

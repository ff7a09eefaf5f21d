"""Native libraries' output (CasADi, SUNDIALS, IPOPT, qpOASES print with ``printf``).

Under the command line that output must never reach stdout (``--json`` must stay clean)
and must not flood the terminal: :class:`capture_native_output` sends file descriptors 1
and 2, and ``sys.stdout`` (CasADi prints through it), to a temporary file while
``sys.stderr`` keeps writing to the terminal; the captured text can go to a log file
(``--verbose``).
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
        _flush_c_streams()
        self._saved = os.dup(1)
        os.dup2(2, 1)
        return self

    def __exit__(self, *exc):
        sys.stdout.flush()
        _flush_c_streams()
        os.dup2(self._saved, 1)
        os.close(self._saved)
        return False


def _flush_c_streams() -> None:
    """Flush the C library's stdio buffers (``printf`` output is buffered when fd 1 is a file,
    and would otherwise come out later, after the descriptors are restored)."""
    try:
        import ctypes
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError, TypeError):
        pass


def _fd_of(stream):
    try:
        return stream.fileno()
    except (AttributeError, OSError, ValueError, io.UnsupportedOperation):
        return None


class capture_native_output:
    """Capture what native code and CasADi write to standard output and error.

    File descriptors 1 and 2 go to a temporary file, and so does ``sys.stdout`` (CasADi's
    Python bindings print through it): whatever the block writes to standard output is
    captured, so the caller prints its own results to :attr:`stdout`, or after the block.
    ``sys.stderr`` keeps reaching the terminal (progress lines, warnings) when it is the
    process's descriptor 2; a stream that is not (pytest's capture) is left alone.

    Parameters
    ----------
    log : str or Path, optional
        File the captured text is appended to at the end (``--verbose``).

    Attributes
    ----------
    stdout : file
        The real standard output during the block (for the caller's own results).
    text : str
        What was captured (after the block).
    lines : int
        Its number of non-empty lines.

    Examples
    --------
    >>> with capture_native_output() as cap:
    ...     _ = os.write(1, b"native banner\\n")
    ...     print("casadi's printout")
    >>> cap.lines
    2
    """

    def __init__(self, log=None):
        self.log, self.text, self.lines = log, "", 0

    def __enter__(self):
        sys.stdout.flush()
        sys.stderr.flush()
        _flush_c_streams()
        self._file = tempfile.TemporaryFile()
        self._saved = {fd: os.dup(fd) for fd in (1, 2)}
        self._streams = {"stdout": sys.stdout}
        self._own_stdout = _fd_of(sys.stdout) == 1
        self.stdout = (open(os.dup(self._saved[1]), "w", encoding=getattr(sys.stdout, "encoding", None) or "utf-8",
                            errors="backslashreplace", buffering=1) if self._own_stdout else sys.stdout)
        sys.stdout = open(os.dup(self._file.fileno()), "w", encoding="utf-8", errors="backslashreplace",
                          buffering=1)
        if _fd_of(sys.stderr) == 2:
            self._streams["stderr"] = sys.stderr
            sys.stderr = open(os.dup(self._saved[2]), "w", encoding=getattr(sys.stderr, "encoding", None)
                              or "utf-8", errors="backslashreplace", buffering=1)
        for fd in (1, 2):
            os.dup2(self._file.fileno(), fd)
        return self

    def __exit__(self, *exc):
        _flush_c_streams()
        self.stdout.flush()
        if self._own_stdout:
            self.stdout.close()
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

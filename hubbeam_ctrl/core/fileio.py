"""Atomic file writes: a temporary file in the target folder, then a rename."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["atomic_write", "atomic_write_text"]


def atomic_write(path, write, suffix: str | None = None) -> Path:
    """Write a file atomically.

    Parameters
    ----------
    path : str or Path
        Final file name.
    write : callable
        ``write(tmp_path)`` writes the whole content to the temporary path it is given.
    suffix : str, optional
        Suffix of the temporary file (some writers insist on an extension). Defaults to
        the suffix of ``path``.

    Returns
    -------
    Path
        The final path.

    Raises
    ------
    ParameterError
        If the folder does not exist or no file can be created in it.
    Exception
        Whatever ``write`` raises, unchanged. In every case the temporary file is removed
        and an existing file at ``path`` keeps its old content.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ParameterError(f"out: folder {folder} does not exist")
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{path.name}.", suffix=suffix or path.suffix)
    except OSError as exc:
        raise ParameterError(f"out: cannot write to {folder}: {exc.strerror}") from None
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def atomic_write_text(path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (UTF-8)."""
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))

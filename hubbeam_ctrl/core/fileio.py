"""File helpers: atomic writes, and NPZ files of arrays plus JSON metadata.

Every file the toolbox writes goes through :func:`atomic_write` (a temporary file in the
target folder, then a rename), so an interrupted write never leaves a half-written file.
:func:`write_npz` and :func:`read_npz` are the one NPZ layout of the toolbox: named arrays
plus a ``metadata`` entry holding a JSON document; :func:`read_npz` turns every way a file
can be unreadable into a one-line :class:`~hubbeam_ctrl.core.errors.ParameterError`.
"""

from __future__ import annotations

import dataclasses
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["atomic_write", "atomic_write_text", "json_ready", "write_npz", "read_npz",
           "check_regular_file"]


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
        Naming the path (as option ``out``) when its folder is missing, it is a folder, or
        the system refuses the write; no file is left behind.
    Exception
        Whatever else ``write`` raises, unchanged; the temporary file is removed and an
        existing file at ``path`` keeps its old content.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ParameterError(f"out: folder {folder} does not exist")
    if path.is_dir():
        raise ParameterError(f"out: {path} is a folder, not a file name")
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{path.name}.", suffix=suffix or path.suffix)
    except OSError as exc:
        raise ParameterError(f"out: cannot write to {folder}: {exc.strerror}") from None
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        _remove(tmp)
        raise ParameterError(f"out: cannot write {path}: {exc.strerror or exc}") from None
    except BaseException:
        _remove(tmp)
        raise
    return path


def _remove(tmp):
    if os.path.exists(tmp):
        os.unlink(tmp)


def atomic_write_text(path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (UTF-8).

    Parameters
    ----------
    path : str or Path
        Final file name.
    text : str
        Whole content.

    Returns
    -------
    Path
    """
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def _json_default(obj):
    """``json.dumps`` fallback: NumPy scalars and arrays, dataclasses, paths, else ``str``."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return dataclasses.asdict(obj)
    return str(obj)


def _dumps(value) -> str:
    return json.dumps(value, default=_json_default)


def json_ready(value):
    """``value`` as it reads back from JSON: tuples become lists, NumPy scalars plain numbers.

    Storing metadata in this form makes a save/load round trip return equal values.

    Parameters
    ----------
    value : object
        Nested dicts, lists, numbers, strings; NumPy values, dataclasses and paths are
        converted, anything else becomes its ``str``.

    Returns
    -------
    object
    """
    return json.loads(_dumps(value))


def write_npz(path, arrays: dict, metadata: dict) -> Path:
    """Write named arrays and a JSON ``metadata`` entry to an ``.npz`` file, atomically.

    Parameters
    ----------
    path : str or Path
        File name (``.npz``).
    arrays : dict
        Name -> ndarray (not ``metadata``); stored bit for bit.
    metadata : dict
        JSON-serialisable document (see :func:`json_ready`).

    Returns
    -------
    Path
    """
    text = _dumps(metadata)

    def write(tmp):
        with open(tmp, "wb") as fh:
            np.savez(fh, metadata=np.array(text), **arrays)
    return atomic_write(path, write)


def check_regular_file(path, option: str = "path") -> Path:
    """Return ``Path(path)``; raise unless it names an existing regular file.

    Parameters
    ----------
    path : str or Path
    option : str
        The argument's name as the caller spelled it (starts the error message).

    Returns
    -------
    Path
    """
    path = Path(path)
    if not path.exists():
        raise ParameterError(f"{option}: file {path} does not exist")
    if not path.is_file():
        raise ParameterError(f"{option}: {path} is not a regular file")
    return path


def read_npz(path, option: str = "path", what: str = "hubbeam file") -> tuple:
    """Read a file written by :func:`write_npz`.

    Parameters
    ----------
    path : str or Path
    option : str
        The argument's name as the caller spelled it (starts the error message).
    what : str
        What the file should be, for the error message (e.g. ``"hubbeam result file"``).

    Returns
    -------
    arrays : dict
        Name -> ndarray, every entry except ``metadata``.
    metadata : dict

    Raises
    ------
    ParameterError
        One line naming the file: missing or not a regular file, not an NPZ archive,
        object arrays, no ``metadata`` entry or metadata that is not a JSON object.
    """
    path = check_regular_file(path, option)

    def bad(reason):
        return ParameterError(f"{option}: {path} is not a {what} ({reason})")

    try:
        with open(path, "rb") as fh:
            magic = fh.read(4)
        if magic[:2] != b"PK":
            raise bad("not an NPZ archive")
        with np.load(path, allow_pickle=False) as data:
            if "metadata" not in data.files:
                raise bad("no metadata entry")
            text = data["metadata"]
            arrays = {k: data[k] for k in data.files if k != "metadata"}
    except ParameterError:
        raise
    except Exception as exc:        # BadZipFile, OSError, EOFError, ValueError (pickles), ...
        detail = str(exc).splitlines()[0] if str(exc) else ""
        raise bad(f"{type(exc).__name__}: {detail}") from None
    if text.dtype.kind != "U" or text.ndim != 0:
        raise bad("metadata is not a string")
    try:
        metadata = json.loads(str(text))
    except ValueError as exc:
        raise bad(f"metadata is not JSON: {exc}") from None
    if not isinstance(metadata, dict):
        raise bad("metadata is not a JSON object")
    return arrays, metadata

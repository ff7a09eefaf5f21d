"""Reading inputs: paths that may be refused, TOML documents, regular files; every way
an input cannot be read is one line of :class:`~hubbeam_ctrl.core.errors.ParameterError`.
"""

from __future__ import annotations

import os
from pathlib import Path

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["read_toml", "read_text", "path_exists", "check_regular_file", "MAX_TOML_BYTES"]


#: Largest TOML input read (parameters, study specs, settings) [bytes].
MAX_TOML_BYTES = 1_000_000


def _short_path(path) -> str:
    """``path`` as shown in a one-line message: at most 120 characters (a name past PATH_MAX is cut
    in the middle, so the message still ends with its reason)."""
    text = str(path)
    return text if len(text) <= 120 else f"{text[:60]}...{text[-40:]}"


def _require_regular(path: Path, missing: str, other: str) -> None:
    """Raise ``"<missing> does not exist"`` or ``"<other> is not a regular file"`` (OSError passes)."""
    if not path.exists():
        raise ParameterError(f"{missing} does not exist")
    if not path.is_file():
        raise ParameterError(f"{other} is not a regular file")


def path_exists(path) -> bool:
    """``Path(path).exists()``, False for a name the system refuses (past NAME_MAX or PATH_MAX):
    the reader that follows names the reason.

    Parameters
    ----------
    path : str or Path
    """
    try:
        return Path(path).exists()
    except (OSError, ValueError):
        return False


def read_toml(path, what: str = "file", max_bytes: int = MAX_TOML_BYTES) -> dict:
    """The TOML document at ``path``, or a one-line :class:`ParameterError` naming the file.

    The one reader of every TOML input (``--params``, study specs, ``--settings``). Refused
    without blocking or a traceback: a missing path, a folder, a FIFO or device (never
    opened), an unreadable file, a file over ``max_bytes``, bytes that are not UTF-8,
    invalid or too deeply nested TOML.

    Parameters
    ----------
    path : str or Path
        The file.
    what : str
        What the file is, as the message starts (``"params file"``, ``"spec: file"``).
    max_bytes : int
        Largest size read [bytes].

    Returns
    -------
    dict
    """
    import tomllib
    text = read_text(path, what, max_bytes)
    name = _short_path(path)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"{what} {name} is not valid TOML: {' '.join(str(exc).split())[:200]}") from None
    except RecursionError:
        raise ParameterError(f"{what} {name} is nested too deeply") from None


def read_text(path, what: str = "file", max_bytes: int = MAX_TOML_BYTES) -> str:
    """The UTF-8 text of the regular file at ``path``, or a one-line :class:`ParameterError` naming
    the file: a missing path, a folder, a FIFO or device (never opened), an unreadable file, a file
    over ``max_bytes``, bytes that are not UTF-8 or hold a NUL.

    Parameters
    ----------
    path : str or Path
        The file.
    what : str
        What the file is, as the message starts (``"params file"``, ``"--modal-table file"``).
    max_bytes : int
        Largest size read [bytes].

    Returns
    -------
    str
    """
    if path is None or not isinstance(path, (str, os.PathLike)) or str(path).strip() == "" \
            or "\x00" in str(path):
        raise ParameterError(f"{what} must be named by a path, got {path!r}")
    path = Path(path)
    name = _short_path(path)
    try:
        _require_regular(path, f"{what} {name}", f"{what} {name}")
        if path.stat().st_size > max_bytes:
            raise ParameterError(f"{what} {name} is larger than {max_bytes} bytes")
        with open(path, "rb") as fh:
            data = fh.read(max_bytes + 1)
        if len(data) > max_bytes:
            raise ParameterError(f"{what} {name} is larger than {max_bytes} bytes")
        text = data.decode("utf-8")
    except OSError as exc:
        raise ParameterError(f"{what} {name} cannot be read ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise ParameterError(f"{what} {name} is not UTF-8 text (byte {exc.start})") from None
    if "\x00" in text:
        raise ParameterError(f"{what} {name} is not a text file (NUL byte)")
    return text


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
    try:
        _require_regular(path, f"{option}: file {_short_path(path)}", f"{option}: {_short_path(path)}")
    except OSError as exc:             # a name past NAME_MAX or PATH_MAX
        raise ParameterError(f"{option}: {_short_path(path)} cannot be read ({exc.strerror or exc})") from None
    return path


#: Largest total uncompressed size of the arrays of an ``.npz`` file read [bytes] (the limit

"""The one NPZ layout of the toolbox: named arrays plus a ``metadata`` entry holding a JSON
document. :func:`write_npz` writes it atomically; :func:`read_npz` turns every way a file can
be unreadable into a one-line :class:`~hubbeam_ctrl.core.errors.ParameterError`.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write
from hubbeam_ctrl.core.jsonio import json_text
from hubbeam_ctrl.core.reading import check_regular_file

__all__ = ["write_npz", "read_npz", "MAX_NPZ_BYTES"]


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
    text = json_text(metadata)

    def write(tmp):
        with open(tmp, "wb") as fh:
            np.savez(fh, metadata=np.array(text), **arrays)
    return atomic_write(path, write)


#: is on what is unpacked, not on the compressed file: a small zip bomb is refused).
MAX_NPZ_BYTES = 2 * 1024 ** 3
#: Most entries of an ``.npz`` file read.
MAX_NPZ_MEMBERS = 1000


def _check_npz_members(path: Path, bad, max_bytes: int) -> None:
    """Refuse an archive whose entries would unpack to more than ``max_bytes``, or whose
    ``.npy`` headers announce more data than the entry holds (numpy allocates the announced
    size before reading), before anything is unpacked."""
    import zipfile
    with zipfile.ZipFile(path) as zf:
        infos = zf.infolist()
        if len(infos) > MAX_NPZ_MEMBERS:
            raise bad(f"{len(infos)} entries, more than {MAX_NPZ_MEMBERS}")
        total = sum(i.file_size for i in infos)
        if total > max_bytes:
            raise bad(f"its arrays unpack to {total} bytes, more than the {max_bytes} read")
        if "metadata.npy" not in {i.filename for i in infos}:
            raise bad("no metadata entry")
        for info in infos:
            with zf.open(info) as fh:
                fmt = np.lib.format
                version = fmt.read_magic(fh)
                header = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
                shape, _, dtype = header(fh)
                if dtype.hasobject:
                    raise bad(f"entry {info.filename} holds Python objects")
                size = int(np.prod(shape, dtype=object)) * dtype.itemsize
                if size > info.file_size:
                    raise bad(f"entry {info.filename} announces {size} bytes but holds {info.file_size}")


def read_npz(path, option: str = "path", what: str = "hubbeam file", max_bytes: int | None = None) -> tuple:
    """Read a file written by :func:`write_npz`.

    Parameters
    ----------
    path : str or Path
    option : str
        The argument's name as the caller spelled it (starts the error message).
    what : str
        What the file should be, for the error message (e.g. ``"hubbeam result file"``).
    max_bytes : int, optional
        Largest total uncompressed size of its entries [bytes] (default
        :data:`MAX_NPZ_BYTES`; checked on the archive's directory and the arrays' headers
        before anything is unpacked).

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
        _check_npz_members(path, bad, MAX_NPZ_BYTES if max_bytes is None else max_bytes)
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

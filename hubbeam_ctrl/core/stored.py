"""Arrays computed once and kept in the build cache, for the next process.

Some set-up values take a noticeable share of a short command and depend only on their
inputs and on the package's sources: e.g. the converged bending frequencies of a beam (a
20-mode SFOAM linearised, 0.2 s of ``hubbeam compare``'s start). :func:`stored_array` keeps
such an array in ``results/`` of the build cache (:func:`hubbeam_ctrl.core.compiled.cache_dir`),
named by a SHA-256 of its key, NumPy's version and the digest of the sources that compute
it (:data:`hubbeam_ctrl.core.compiled.RECIPE_SOURCES`), so a later process reads the same
numbers bit for bit instead of computing them. A file that cannot be read or written is
ignored: the array is computed.
"""

from __future__ import annotations

import contextlib
import hashlib
import os

import numpy as np

from hubbeam_ctrl.core.compiled import _sources_digest, cache_dir

__all__ = ["stored_array"]


def _path(key: tuple):
    h = hashlib.sha256()
    for part in (np.__version__, _sources_digest(), repr(key)):
        h.update(str(part).encode() + b"\0")
    return cache_dir() / "results" / f"{key[0]}-{h.hexdigest()[:32]}.npy"


def stored_array(key: tuple, compute) -> np.ndarray:
    """``compute()``, read from the build cache when a process computed it before.

    Parameters
    ----------
    key : tuple
        What the array depends on besides the sources: its name first (a str, part of the file
        name), then values with a stable ``repr`` (numbers, frozen dataclasses such as
        :class:`~hubbeam_ctrl.plant.params.Params`).
    compute : callable
        ``compute() -> ndarray`` of floats (any shape), called when the array is not stored.

    Returns
    -------
    ndarray
        Read-only; the stored array, bit for bit what ``compute()`` returned.
    """
    path = _path(key)
    out = None
    with contextlib.suppress(OSError, ValueError, EOFError):
        out = np.load(path, allow_pickle=False)
    if out is None or out.dtype != np.float64:
        out = np.asarray(compute(), dtype=np.float64)
        with contextlib.suppress(OSError):
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(f".{path.name}.{os.getpid()}")
            with open(tmp, "wb") as fh:
                np.save(fh, out, allow_pickle=False)
            os.replace(tmp, path)
    out.setflags(write=False)
    return out

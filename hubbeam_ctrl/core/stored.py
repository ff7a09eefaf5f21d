"""Arrays computed once and kept in the build cache, for the next process.

Some set-up values take a noticeable share of a short command and depend only on their
inputs and on the package's sources: the converged bending frequencies of a beam (a 20-mode
SFOAM linearised, 0.2 s of ``hubbeam compare``'s start), a slew planned on the design model
(two large KKT solves, 0.2-1 s). :func:`stored_arrays` keeps such arrays in ``results/`` of
the build cache (:func:`hubbeam_ctrl.core.compiled.cache_dir`), named by a SHA-256 of their
key, NumPy's, SciPy's and CasADi's versions and the digest of the sources that compute them, so a later process
reads the same numbers bit for bit instead of computing them. A file that cannot be read or
written is ignored: the arrays are computed.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import sys
import zipfile

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.compiled import cache_dir
from hubbeam_ctrl.core.recipes import RECIPE_SOURCES, _sources_digest

__all__ = ["stored_arrays", "stored_array"]


def _versions() -> tuple:
    """NumPy's, SciPy's and CasADi's versions (their routines compute the stored arrays)."""
    scipy = sys.modules.get("scipy")
    scipy_version = getattr(scipy, "__version__", None)
    if scipy_version is None:
        with contextlib.suppress(Exception):
            from importlib.metadata import version
            scipy_version = version("scipy")
    return np.__version__, scipy_version, ca.__version__


def _path(key: tuple, sources: tuple):
    h = hashlib.sha256()
    for part in (*_versions(), _sources_digest(tuple(sources)), repr(key)):
        h.update(str(part).encode() + b"\0")
    return cache_dir() / "results" / f"{key[0]}-{h.hexdigest()[:32]}.npz"


def stored_arrays(key: tuple, compute, sources: tuple = RECIPE_SOURCES) -> dict:
    """``compute()``, read from the build cache when a process computed it before.

    Parameters
    ----------
    key : tuple
        What the arrays depend on besides the sources: a name first (a str, part of the file
        name), then values with a stable ``repr`` (numbers, strings, frozen dataclasses such as
        :class:`~hubbeam_ctrl.plant.params.Params`).
    compute : callable
        ``compute() -> dict`` of name -> array (numbers or strings, any shape), called when the
        arrays are not stored.
    sources : tuple of str
        Folders (from the one holding ``hubbeam_ctrl``) whose ``.py`` files compute them.

    Returns
    -------
    dict
        Name -> read-only ndarray: bit for bit what ``compute()`` returned.
    """
    path = _path(key, sources)
    out = None
    with contextlib.suppress(OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError):
        with np.load(path, allow_pickle=False) as npz:
            out = {name: npz[name] for name in npz.files}
    if out is None:
        out = {name: np.asarray(a) for name, a in compute().items()}
        with contextlib.suppress(OSError, ValueError):
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(f".{path.name}.{os.getpid()}")
            with open(tmp, "wb") as fh:
                np.savez(fh, allow_pickle=False, **out)
            os.replace(tmp, path)
    for a in out.values():
        a.setflags(write=False)
    return out


def stored_array(key: tuple, compute, sources: tuple = RECIPE_SOURCES) -> np.ndarray:
    """One array of :func:`stored_arrays`: ``compute() -> ndarray``.

    Parameters
    ----------
    key : tuple
        As for :func:`stored_arrays`.
    compute : callable
        ``compute() -> ndarray``.
    sources : tuple of str
        As for :func:`stored_arrays`.

    Returns
    -------
    ndarray
        Read-only.
    """
    return stored_arrays(key, lambda: {"a": compute()}, sources)["a"]

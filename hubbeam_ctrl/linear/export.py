"""Save and load linear models (:class:`~hubbeam_ctrl.linear.statespace.LinearModel`).

Three formats, chosen by the file extension, all holding the same content:

``.mat`` (MATLAB / Octave, written by :func:`scipy.io.savemat`, format 5)
    Variables ``A``, ``B``, ``C``, ``D`` (double matrices), ``state_names``,
    ``input_names``, ``output_names``, ``state_units``, ``input_units``,
    ``output_units`` (column cell arrays of char), ``dt`` (sample time [s], 0 for
    continuous time, MATLAB's ``Ts`` convention), ``spin_rad_s``, ``model``, ``name``,
    ``reduction``, ``hub``, ``params`` (struct of every parameter in SI units, ``l``
    resolved to a number), ``param_units`` (struct of unit strings) and
    ``hubbeam_metadata`` (the same metadata as one JSON string, used by
    :func:`load_model` for an exact round trip). In MATLAB::

        S = load('model.mat');
        sys = ss(S.A, S.B, S.C, S.D, S.dt, 'StateName', S.state_names, ...
                 'InputName', S.input_names, 'OutputName', S.output_names);

``.npz`` (NumPy)
    Arrays ``A``, ``B``, ``C``, ``D`` and a 0-d string ``metadata`` (JSON), loadable
    with ``allow_pickle=False``.

``.json``
    One object: ``format``, ``version``, ``A``, ``B``, ``C``, ``D`` (lists of rows) and the
    metadata keys. Floats are written with ``repr`` precision, so they read back exactly.

Writes are atomic (temporary file in the target folder, then a rename); errors are
:class:`~hubbeam_ctrl.core.errors.ParameterError` with a one-line message and leave no file.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write, check_regular_file, read_npz, write_npz
from hubbeam_ctrl.linear.statespace import LinearModel, _make_ss
from hubbeam_ctrl.plant.params import Params

__all__ = ["save_model", "load_model", "FORMATS"]

#: File extensions understood by :func:`save_model` and :func:`load_model`.
FORMATS = (".mat", ".npz", ".json")

_FORMAT_TAG = "hubbeam-linear-model"
_VERSION = 1
_MATRICES = ("A", "B", "C", "D")


def _suffix(path: Path, option: str) -> str:
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise ParameterError(f"{option}: unknown extension {path.suffix or '(none)'!r} in "
                             f"{path.name!r}; allowed: {', '.join(FORMATS)}")
    return suffix


def save_model(model: LinearModel, path) -> Path:
    """Write a linear model to ``.mat``, ``.npz`` or ``.json`` (by extension), atomically.

    Parameters
    ----------
    model : LinearModel
    path : str or Path

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    ParameterError
        Unknown extension, missing or unwritable folder (no file is left behind).
    """
    if not isinstance(model, LinearModel):
        raise ParameterError(f"model must be a LinearModel, got {type(model).__name__}")
    path = Path(path)
    suffix = _suffix(path, "out")
    meta = model.metadata()
    mats = {k: np.array(getattr(model, k), dtype=float) for k in _MATRICES}
    if suffix == ".npz":
        return write_npz(path, mats, meta)
    if suffix == ".mat":
        write = lambda tmp: _write_mat(tmp, mats, meta, model.params)
    else:
        doc = {"format": _FORMAT_TAG, "version": _VERSION}
        doc.update({k: v.tolist() for k, v in mats.items()})
        doc.update(meta)
        text = json.dumps(doc, indent=1, allow_nan=False) + "\n"
        write = lambda tmp: Path(tmp).write_text(text, encoding="utf-8")
    return atomic_write(path, write)


def _cell(strings) -> np.ndarray:
    cell = np.empty((len(strings), 1), dtype=object)
    for i, s in enumerate(strings):
        cell[i, 0] = s
    return cell


def _write_mat(tmp, mats, meta, params: Params):
    from scipy.io import savemat
    data = dict(mats)
    for key in ("state_names", "input_names", "output_names", "state_units", "input_units",
                "output_units"):
        data[key] = _cell(meta[key])
    data["dt"] = float(meta["dt"])
    data["spin_rad_s"] = float(meta["spin_rad_s"])
    for key in ("model", "name", "reduction", "hub"):
        data[key] = meta[key]
    data["params"] = {k: float(params.tip_position if v is None else v)   # l resolved
                      for k, v in params.to_dict().items()}
    data["param_units"] = dict(meta["param_units"])
    data["hubbeam_metadata"] = json.dumps(meta)
    with open(tmp, "wb") as fh:
        savemat(fh, data, format="5", oned_as="column")


def _from_parts(mats: dict, meta: dict, path: Path) -> LinearModel:
    try:
        params = Params(**meta["params"])
        sys = _make_ss(*(np.asarray(mats[k], dtype=float) for k in _MATRICES), meta["dt"],
                       meta["state_names"], meta["output_names"], meta["name"])
        lm = LinearModel(sys=sys, model=meta["model"], spin=float(meta["spin_rad_s"]),
                         params=params, reduction=meta["reduction"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ParameterError(f"path: {path} is not a valid hubbeam model file ({exc})") from None
    if lm.input_names != list(meta["input_names"]):
        raise ParameterError(f"path: {path} has inputs {meta['input_names']}, expected ['tau']")
    return lm


def load_model(path) -> LinearModel:
    """Read a model written by :func:`save_model` (``.mat``, ``.npz`` or ``.json``).

    The round trip is exact: ``load_model(save_model(lm, p)) == lm`` bit for bit.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    LinearModel
    """
    path = Path(path)
    suffix = _suffix(path, "path")
    check_regular_file(path, "path")
    if suffix == ".npz":
        mats, meta = read_npz(path, "path", "hubbeam model file")
    try:
        if suffix == ".mat":
            from scipy.io import loadmat
            data = loadmat(path)
            meta = json.loads(str(np.asarray(data["hubbeam_metadata"]).ravel()[0]))
            mats = {k: data[k] for k in _MATRICES}
        elif suffix == ".npz":
            mats = {k: mats[k] for k in _MATRICES}
        else:
            doc = json.loads(path.read_text(encoding="utf-8"))
            if doc.get("format") != _FORMAT_TAG:
                raise KeyError("format")
            mats = {k: np.array(doc[k], dtype=float).reshape(_json_shape(doc, k))
                    for k in _MATRICES}
            meta = doc
    except (KeyError, ValueError, OSError, IndexError) as exc:
        raise ParameterError(f"path: {path} is not a hubbeam model file "
                             f"({type(exc).__name__}: {exc})") from None
    except Exception as exc:   # scipy/numpy readers raise assorted errors on garbage
        raise ParameterError(f"path: cannot read {path}: {exc}") from None
    return _from_parts(mats, meta, path)


def _json_shape(doc: dict, key: str) -> tuple:
    """Shape of a matrix stored as a list of rows (keeps empty dimensions right)."""
    n, m, p = len(doc["state_names"]), len(doc["input_names"]), len(doc["output_names"])
    return {"A": (n, n), "B": (n, m), "C": (p, n), "D": (p, m)}[key]

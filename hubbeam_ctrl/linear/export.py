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
import re
from pathlib import Path

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write
from hubbeam_ctrl.core.npz import read_npz, write_npz
from hubbeam_ctrl.core.reading import check_regular_file
from hubbeam_ctrl.linear.statespace import DT_RANGE, LinearModel, named_ss
from hubbeam_ctrl.plant.models import MODEL_NAMES
from hubbeam_ctrl.plant.params import Params, check_spin

__all__ = ["save_model", "load_model", "save_system", "load_system", "FORMATS"]

#: File extensions understood by :func:`save_model` and :func:`load_model`.
FORMATS = (".mat", ".npz", ".json")

_FORMAT_TAG = "hubbeam-linear-model"
_VERSION = 1
_MATRICES = ("A", "B", "C", "D")
_NAME_LISTS = ("state_names", "input_names", "output_names", "state_units", "input_units",
               "output_units")


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
        From :func:`~hubbeam_ctrl.linear.statespace.linearize` (sampled, reduced or not).
    path : str or Path
        A ``.mat``, ``.npz`` or ``.json`` file name (:data:`FORMATS`).

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
    return save_system(path, {k: getattr(model, k) for k in _MATRICES}, model.metadata(), _FORMAT_TAG,
                       _VERSION, model.params)


def save_system(path, matrices: dict, metadata: dict, tag: str, version: int,
                params: Params | None = None) -> Path:
    """Write a state-space system (matrices plus metadata) in the toolbox's export layout.

    The layout of :func:`save_model`, shared with the controllers' export
    (:mod:`controllers.export`): ``.mat`` (the matrices, the name and unit lists as column
    cell arrays, every scalar string or number of ``metadata`` as a variable, ``params``
    and ``param_units`` as structs, the whole metadata as the JSON string
    ``hubbeam_metadata``), ``.npz`` (the matrices and a JSON ``metadata``) or ``.json``
    (``format``, ``version``, the matrices as lists of rows, the metadata keys).

    Parameters
    ----------
    path : str or Path
        Output file; the format follows the extension (:data:`FORMATS`).
    matrices : dict
        Name -> 2-D array (e.g. ``A, B, C, D``), stored as float bit for bit.
    metadata : dict
        JSON-ready metadata; must hold ``state_names``, ``input_names`` and
        ``output_names`` (they give the matrices' shapes when read back).
    tag : str
        Value of the JSON ``format`` key (what the file is).
    version : int
        Layout version.
    params : Params, optional
        Written to ``.mat`` files as the struct ``params`` (``l`` resolved to a number).

    Returns
    -------
    Path
    """
    path = Path(path)
    suffix = _suffix(path, "out")
    matrices = {k: np.array(v, dtype=float) for k, v in matrices.items()}
    metadata = {"format": tag, "version": version, **metadata}     # what the file is, in every format
    if suffix == ".npz":
        return write_npz(path, matrices, metadata)
    if suffix == ".mat":
        write = lambda tmp: _write_mat(tmp, matrices, metadata, params)
    else:
        doc = {"format": tag, "version": version}
        doc.update({k: v.tolist() for k, v in matrices.items()})
        doc.update(metadata)
        text = json.dumps(doc, indent=1, allow_nan=False) + "\n"
        write = lambda tmp: Path(tmp).write_text(text, encoding="utf-8")
    return atomic_write(path, write)


def _cell(strings) -> np.ndarray:
    cell = np.empty((len(strings), 1), dtype=object)
    for i, s in enumerate(strings):
        cell[i, 0] = s
    return cell


def _write_mat(tmp, mats, meta, params: Params | None):
    from scipy.io import savemat
    data = dict(mats)
    for key, value in meta.items():
        if key in _NAME_LISTS:
            data[key] = _cell(value)
        elif isinstance(value, (str, int, float)) and not isinstance(value, bool):
            data[key] = float(value) if isinstance(value, (int, float)) else value
    if params is not None:
        data["params"] = {k: (np.asarray(v, dtype=float) if isinstance(v, tuple)     # per-mode damping
                              else float(params.tip_position if v is None else v))   # l resolved
                          for k, v in ((k, getattr(params, k)) for k in Params.units())}
        data["param_units"] = dict(Params.units())
    data["hubbeam_metadata"] = json.dumps(meta)
    with open(tmp, "wb") as fh:
        savemat(fh, data, format="5", oned_as="column")


def _from_parts(mats: dict, meta: dict, path: Path) -> LinearModel:
    def bad(reason):
        return ParameterError(f"path: {path} is not a valid hubbeam model file ({reason})")
    if not isinstance(meta, dict):
        raise bad("its metadata is not an object")
    try:
        params = Params.from_dict(meta["params"])
        A, B, C, D = (_real_matrix(k, mats[k]) for k in _MATRICES)
        states, outputs = _names(meta, "state_names"), _names(meta, "output_names")
        _check_shapes(A, B, C, D, states, outputs)
        if list(meta["input_names"]) != ["tau"]:
            raise ValueError(f"inputs {str(meta['input_names'])[:60]}, expected ['tau']")
        model, reduction, name = meta["model"], meta["reduction"], meta["name"]
        if model not in MODEL_NAMES:
            raise ValueError(f"model {str(model)[:40]!r} is not one of {', '.join(MODEL_NAMES)}")
        if not isinstance(reduction, str) or not _REDUCTION.match(reduction):
            raise ValueError(f"reduction {str(reduction)[:40]!r} is not none, modal:K or balanced:K")
        if not isinstance(name, str) or not name or "." in name:
            raise ValueError(f"name {str(name)[:40]!r} is not a non-empty string without '.'")
        dt = meta["dt"]
        lo, hi = DT_RANGE
        if isinstance(dt, bool) or not isinstance(dt, (int, float)) or not (dt == 0 or lo <= dt <= hi):
            raise ValueError(f"dt {str(dt)[:40]} is not 0 or in [{DT_RANGE[0]:g}, {DT_RANGE[1]:g}] s")
        spin = check_spin("spin_rad_s", meta["spin_rad_s"], params)
        sys = named_ss(A, B, C, D, dt, states, outputs, name)
        return LinearModel(sys=sys, model=model, spin=spin, params=params, reduction=reduction)
    except KeyError as exc:
        raise bad(f"no {exc}") from None
    except (TypeError, ValueError) as exc:    # ParameterError too
        raise bad(" ".join(str(exc).split())[:200]) from None


_REDUCTION = re.compile(r"^(none|modal:[1-9][0-9]*|balanced:[1-9][0-9]*)$")


def _real_matrix(name: str, value) -> np.ndarray:
    """A stored matrix as a float array, refusing complex, boolean, text and non-finite entries."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "fiu":
        raise ValueError(f"{name} holds {arr.dtype} values, not real numbers")
    if arr.ndim != 2:
        raise ValueError(f"{name} has {arr.ndim} dimensions, not 2")
    arr = arr.astype(float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} holds NaN or infinity")
    return arr


def _names(meta: dict, key: str) -> list:
    names = meta[key]
    if not isinstance(names, (list, tuple)) or not all(isinstance(n, str) and n for n in names):
        raise ValueError(f"{key} is not a list of non-empty strings")
    if len(set(names)) != len(names):
        raise ValueError(f"{key} repeats a name")
    return list(names)


def _check_shapes(A, B, C, D, states: list, outputs: list) -> None:
    n, p = len(states), len(outputs)
    want = {"A": (n, n), "B": (n, 1), "C": (p, n), "D": (p, 1)}
    for key, M in zip(_MATRICES, (A, B, C, D)):
        if M.shape != want[key]:
            raise ValueError(f"{key} has shape {M.shape}, expected {want[key]} for {n} states and "
                             f"{p} outputs")


#: Largest model file read [bytes].
MAX_MODEL_FILE_BYTES = 200_000_000


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
    mats, meta = load_system(path, _MATRICES, _FORMAT_TAG, "hubbeam model file")
    return _from_parts(mats, meta, Path(path))


def load_system(path, names=_MATRICES, tag: str = _FORMAT_TAG, what: str = "hubbeam model file",
                version: int = _VERSION):
    """Read the matrices and metadata of a file written by :func:`save_system`.

    Parameters
    ----------
    path : str or Path
    names : sequence of str
        The four matrix names, in the order ``A, B, C, D`` (e.g. ``("Ac", "Bc", "Cc", "Dc")``).
    tag : str
        Expected ``format`` tag (required in .json; in .mat and .npz checked when present,
        files of earlier versions have none).
    what : str
        What the file should be, for error messages.
    version : int
        The layout version this toolbox reads (another is refused).

    Returns
    -------
    matrices : dict
        Name -> float array of the shape the name lists give (empty ones included).
    metadata : dict

    Raises
    ------
    ParameterError
        One line naming the file when it is missing, unreadable or not such a file.
    """
    path = Path(path)
    suffix = _suffix(path, "path")
    check_regular_file(path, "path")
    if path.stat().st_size > MAX_MODEL_FILE_BYTES:
        raise ParameterError(f"path: {path} is larger than {MAX_MODEL_FILE_BYTES} bytes")
    if suffix == ".npz":
        mats, meta = read_npz(path, "path", what)
    try:
        if suffix == ".mat":
            from scipy.io import loadmat
            data = loadmat(path)
            meta = json.loads(str(np.asarray(data["hubbeam_metadata"]).ravel()[0]))
            mats = {k: data[k] for k in names}
        elif suffix == ".npz":
            mats = {k: mats[k] for k in names}
        else:
            meta = json.loads(path.read_text(encoding="utf-8"))
            if not isinstance(meta, dict) or meta.get("format") != tag:
                raise KeyError("format")
            mats = {k: np.array(meta[k]) for k in names}
        if not isinstance(meta, dict):
            raise ValueError("metadata is not a JSON object")
        # files written before the tag was stored in .mat/.npz have none; a tag or version
        # that is there must be this toolbox's
        if meta.get("format", tag) != tag:
            raise ValueError(f"format tag {meta.get('format')!r}"[:60] + f", expected {tag!r}")
        if isinstance(meta.get("version"), bool) or meta.get("version", version) != version:
            raise ValueError(f"format version {meta.get('version')!r}"[:60] + f"; this toolbox reads version {version}")
        shapes = _shapes(meta, names)
        # the formats lose the dimensions of empty matrices: restore them from the name lists;
        # the values are checked by the caller (real, finite, shapes: ``_real_matrix``)
        mats = {k: v.reshape(shapes[k]) if v.size == 0 and np.prod(shapes[k]) == 0 else v
                for k, v in ((k, np.asarray(v)) for k, v in mats.items())}
    except (KeyError, ValueError, OSError, IndexError, TypeError, AttributeError) as exc:
        raise ParameterError(f"path: {path} is not a {what} "
                             f"({type(exc).__name__}: {' '.join(str(exc).split())[:200]})") from None
    except Exception as exc:   # scipy/numpy readers raise assorted errors on garbage
        raise ParameterError(f"path: cannot read {path}: {type(exc).__name__}: "
                             f"{' '.join(str(exc).split())[:200]}") from None
    return mats, meta


def _shapes(meta: dict, names) -> dict:
    """Shapes of ``A, B, C, D`` (under ``names``) from the name lists (keeps empty dimensions)."""
    n, m, p = len(meta["state_names"]), len(meta["input_names"]), len(meta["output_names"])
    return dict(zip(names, ((n, n), (n, m), (p, n), (p, m))))

"""The result of a run: time series plus the parameters, settings and statistics that made them.

One type, :class:`Result`, for every simulator of the toolbox; its ``kind`` says which made
it:

* ``"open_loop"``: :func:`hubbeam_ctrl.sim.simulate.simulate` (IDAS, free or prescribed hub),
  with accelerations and the model's derived outputs (``q_theta``, ``energy``,
  ``angular_momentum``);
* ``"fixed_step"``: :func:`hubbeam_ctrl.sim.stepper.simulate_fixed_step` (the closed loop's
  plant integrator under a torque profile);
* ``"closed_loop"``: :func:`hubbeam_ctrl.sim.closedloop.simulate_closed_loop`, with the
  controller's name, its time per call and statistics, the root bending moment and the
  task's reference.

:meth:`Result.save` writes ``.npz`` (every array, metadata as JSON; :func:`load_result`
reads it back bit for bit) or ``.csv`` (the 1-D series, one column each, a header of names
with units). ``SimulationResult`` and ``ClosedLoopResult`` are aliases of :class:`Result`,
kept so that existing imports keep working.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write
from hubbeam_ctrl.core.jsonio import json_ready
from hubbeam_ctrl.core.npz import read_npz, write_npz
from hubbeam_ctrl.core.validation import check_positive
from hubbeam_ctrl.plant.params import Params

__all__ = ["Result", "load_result", "describe_input", "CSV_COLUMNS", "RESULT_KINDS",
           "SimulationResult", "ClosedLoopResult"]

#: The simulators a result can come from.
RESULT_KINDS = ("open_loop", "fixed_step", "closed_loop")

#: Every 1-D series a result may hold, in CSV column order, with its unit.
CSV_COLUMNS = {"t": "s", "theta": "rad", "theta_dot": "rad/s", "v_tip": "m", "u_tip": "m",
               "tau": "N m", "q_theta": "N m", "energy": "J", "angular_momentum": "kg m^2/s",
               "root_moment": "N m", "theta_ref": "rad", "theta_dot_ref": "rad/s",
               "step_time_s": "s"}

#: Array fields: name -> number of dimensions (1: one value per sample, 2: per sample and
#: generalised coordinate).
_ARRAY_NDIM = {"t": 1, "q": 2, "v": 2, "a": 2, "v_tip": 1, "u_tip": 1, "tau": 1, "q_theta": 1,
               "energy": 1, "angular_momentum": 1, "root_moment": 1, "step_time_s": 1,
               "theta_ref": 1, "theta_dot_ref": 1}

#: Arrays every result has, and those each kind adds.
_REQUIRED = ("t", "q", "v", "v_tip", "u_tip", "tau")
_REQUIRED_BY_KIND = {"open_loop": ("a", "q_theta", "energy", "angular_momentum"),
                     "fixed_step": (),
                     "closed_loop": ("root_moment", "step_time_s")}

#: Metadata fields (everything that is not an array), and the file format's tag.
_META_FIELDS = ("kind", "model", "hub", "controller", "settings", "stats", "controller_stats",
                "stopped", "message", "wall_s")
_FORMAT, _VERSION = "hubbeam-result", 1


@dataclass(eq=False)
class Result:
    """Time series of one run, with the parameters, settings and statistics that made it.

    Attributes
    ----------
    kind : {"open_loop", "fixed_step", "closed_loop"}
        Which simulator made it (see the module docstring).
    model : str
        Plant model name (``"cfoam"``, ``"foam"``, ``"tlam"``, ``"sfoam"``); also
        readable as ``plant``.
    t : ndarray (N,)
        Sample times [s], finite.
    q, v : ndarray (N, n_q)
        Generalised coordinates ``[theta, q1, q2]`` [rad, m] and their rates [rad/s, m/s].
    v_tip : ndarray (N,)
        Transverse tip displacement ``w2(L)`` in the hub frame [m].
    u_tip : ndarray (N,)
        Axial tip displacement ``w1(L) + wc(L)`` in the hub frame [m].
    tau : ndarray (N,)
        Hub torque [N m]: required by the motion (open loop), applied (fixed step), or
        commanded at ``t_k`` and held until ``t_{k+1}`` (closed loop; the last one is
        computed but not applied, and is NaN when the run stopped before computing it).
    params : Params
        The plant's parameters.
    hub : {"free", "prescribed"}
        Hub condition (closed-loop and fixed-step runs: ``"free"``).
    a : ndarray (N, n_q) or None
        Accelerations [rad/s^2, m/s^2] (open-loop and fixed-step runs).
    q_theta : ndarray (N,) or None
        The paper's inertia force on the hub ``Q_theta`` [N m] (open loop).
    energy : ndarray (N,) or None
        ``T + U`` [J] (open loop).
    angular_momentum : ndarray (N,) or None
        ``dT/d theta_dot`` [kg m^2/s] (open loop).
    root_moment : ndarray (N,) or None
        Root bending moment ``EI f2''(0) q2`` [N m], noise-free (closed loop).
    controller : str or None
        Controller name (closed loop).
    step_time_s : ndarray (N,) or None
        Wall time of each controller call [s] (closed loop).
    theta_ref, theta_dot_ref : ndarray (N,) or None
        The task's hub reference [rad, rad/s], when the caller gave one (closed loop).
    settings : dict
        The settings of the run (simulator settings, ``t_end``, maneuver...), stored as
        they read back from JSON.
    stats : dict
        The simulator's statistics (e.g. ``plant_fallbacks``, ``ms_per_step``).
    controller_stats : dict
        What the controller's ``stats()`` returned at the end (e.g. QP fallbacks).
    stopped : bool
        True when the run ended early (passed the divergence limit, by default L;
        integrator failure, non-finite torque, time limit); ``message`` says why. Also
        readable as ``diverged``. Passing the models' validated range (0.3 L by default) does
        not stop a run: ``outside_validated_range`` and ``outside_range_time_s`` say when.
    message : str
        How the run ended.
    wall_s : float
        Wall time of the run [s].

    Notes
    -----
    ``res == other`` is True when every array is bitwise identical (same dtype and shape)
    and the metadata are equal, as after a :meth:`save` / :func:`load_result` round trip.
    """

    kind: str
    model: str
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    v_tip: np.ndarray
    u_tip: np.ndarray
    tau: np.ndarray
    params: Params
    hub: str = "free"
    a: np.ndarray | None = None
    q_theta: np.ndarray | None = None
    energy: np.ndarray | None = None
    angular_momentum: np.ndarray | None = None
    root_moment: np.ndarray | None = None
    controller: str | None = None
    step_time_s: np.ndarray | None = None
    theta_ref: np.ndarray | None = None
    theta_dot_ref: np.ndarray | None = None
    settings: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)
    controller_stats: dict = field(default_factory=dict)
    stopped: bool = False
    message: str = "completed"
    wall_s: float = 0.0

    def __post_init__(self):
        self._check_scalars()
        self._check_arrays()
        for name in ("settings", "stats", "controller_stats"):
            value = getattr(self, name)
            if not isinstance(value, dict):
                raise ParameterError(f"{name} must be a dict, got {type(value).__name__}")
            setattr(self, name, json_ready(value))

    def _check_scalars(self):
        _check_choice("kind", self.kind, RESULT_KINDS)
        _check_choice("hub", self.hub, ("free", "prescribed"))
        if not isinstance(self.params, Params):
            raise ParameterError(f"params must be a Params, got {type(self.params).__name__}")
        for name in ("model", "message") + (("controller",) if self.controller is not None else ()):
            if not isinstance(getattr(self, name), str):
                raise ParameterError(f"{name} must be a string, got {getattr(self, name)!r}")
        if not isinstance(self.stopped, (bool, np.bool_)):
            raise ParameterError(f"stopped must be True or False, got {self.stopped!r}")
        self.stopped = bool(self.stopped)
        if not (isinstance(self.wall_s, (int, float)) and math.isfinite(self.wall_s) and self.wall_s >= 0):
            raise ParameterError(f"wall_s must be a finite number >= 0 [s], got {self.wall_s!r}")
        self.wall_s = float(self.wall_s)

    def _check_arrays(self):
        missing = [k for k in _REQUIRED + _REQUIRED_BY_KIND[self.kind] if getattr(self, k) is None]
        if missing:
            raise ParameterError(f"a {self.kind} result needs {', '.join(missing)}")
        n_t = n_q = None
        for name, ndim in _ARRAY_NDIM.items():          # t first, then q
            value = getattr(self, name)
            if value is None:
                continue
            arr = np.asarray(value)
            if arr.dtype.kind != "f":
                raise ParameterError(f"{name} must hold real floating-point numbers, got dtype {arr.dtype}")
            if name == "t":
                if arr.ndim != 1 or arr.size == 0:
                    raise ParameterError(f"t must be a non-empty 1-D array of times [s], got shape {arr.shape}")
                if not np.all(np.isfinite(arr)):
                    raise ParameterError("t must hold finite times [s], got NaN or infinity")
                n_t = arr.shape[0]
            if name == "q" and arr.ndim == 2 and arr.shape[1] >= 1:
                n_q = arr.shape[1]
            expected = (n_t,) if ndim == 1 else (n_t, n_q)
            if arr.shape != expected:
                want = f"({n_t},)" if ndim == 1 else f"({n_t}, n_q)" if n_q is None else str(expected)
                raise ParameterError(f"{name} must have shape {want} (one row per sample), got {arr.shape}")
            setattr(self, name, arr)

    # -- views ---------------------------------------------------------------------
    @property
    def theta(self) -> np.ndarray:
        """Hub angle [rad]."""
        return self.q[:, 0]

    @property
    def theta_dot(self) -> np.ndarray:
        """Hub rate [rad/s]."""
        return self.v[:, 0]

    @property
    def plant(self) -> str:
        """The plant model name (same as ``model``)."""
        return self.model

    @property
    def diverged(self) -> bool:
        """True when the run ended early (same as ``stopped``)."""
        return self.stopped

    @property
    def outside_range_time_s(self) -> float | None:
        """When ``|v_tip|`` first passed the models' validated range (``range_limit * L``,
        default 0.3 L) [s]; ``None`` if it never did (``stats["outside_range_time_s"]``)."""
        value = self.stats.get("outside_range_time_s")
        return None if value is None else float(value)

    @property
    def outside_validated_range(self) -> bool:
        """True when the run passed the models' validated range (and went on)."""
        return self.outside_range_time_s is not None

    def window(self, t_start: float, t_stop: float | None = None) -> np.ndarray:
        """Boolean mask of the samples with ``t_start <= t <= t_stop``.

        Parameters
        ----------
        t_start : float
            [s]
        t_stop : float, optional
            [s]; ``None``: to the end.

        Returns
        -------
        ndarray of bool (N,)
        """
        stop = self.t[-1] if t_stop is None else t_stop
        return (self.t >= t_start - 1e-12) & (self.t <= stop + 1e-12)

    def summary(self, residual_window_s: float = 10.0) -> dict:
        """Key figures: peak and residual tip deflection, final hub state, flags.

        Parameters
        ----------
        residual_window_s : float
            The residual is ``max |v_tip|`` over the last ``residual_window_s`` seconds
            [s], > 0.

        Returns
        -------
        dict
            ``kind``, ``model``, ``controller`` (closed loop), ``peak_tip_m``,
            ``residual_tip_m``, ``peak_axial_m``, ``final_theta_rad``,
            ``final_theta_dot_rad_s``, ``diverged`` (the run ended early), ``message``,
            ``wall_s``.
        """
        last = self.window(self.t[-1] - check_positive("residual_window_s", residual_window_s, "s"))
        out = {"kind": self.kind, "model": self.model}
        if self.controller is not None:
            out["controller"] = self.controller
        out.update({
            "peak_tip_m": float(np.max(np.abs(self.v_tip))),
            "residual_tip_m": float(np.max(np.abs(self.v_tip[last]))),
            "peak_axial_m": float(np.max(np.abs(self.u_tip))),
            "final_theta_rad": float(self.theta[-1]),
            "final_theta_dot_rad_s": float(self.theta_dot[-1]),
            "diverged": self.stopped,
            "message": self.message,
            "wall_s": self.wall_s,
        })
        return out

    # -- saving ----------------------------------------------------------------------
    def columns(self) -> dict:
        """The 1-D series this result holds, in :data:`CSV_COLUMNS` order.

        Returns
        -------
        dict
            Name -> ndarray (N,).
        """
        return {name: getattr(self, name) for name in CSV_COLUMNS if getattr(self, name) is not None}

    def arrays(self) -> dict:
        """Every array this result holds (what ``.npz`` stores).

        Returns
        -------
        dict
            Name -> ndarray.
        """
        return {name: getattr(self, name) for name in _ARRAY_NDIM if getattr(self, name) is not None}

    def metadata(self) -> dict:
        """Everything but the arrays, as stored in ``.npz`` (a JSON document).

        Returns
        -------
        dict
            The format tag and version, ``params`` and the metadata fields.
        """
        meta = {"format": _FORMAT, "version": _VERSION, "params": self.params.to_dict()}
        meta.update({name: getattr(self, name) for name in _META_FIELDS})
        return json_ready(meta)

    def save(self, path) -> Path:
        """Save atomically to ``.npz`` (everything) or ``.csv`` (the 1-D series).

        The CSV has one column per series of :meth:`columns`; its header names each with
        its unit (``t [s],theta [rad],...``), and its numbers are written with 17
        significant digits (they read back exactly).

        Parameters
        ----------
        path : str or Path
            File name; its extension picks the format.

        Returns
        -------
        Path

        Raises
        ------
        ParameterError
            Unknown extension, missing folder or failed write (no file is left behind).
        """
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix == ".npz":
            return write_npz(path, self.arrays(), self.metadata())
        if suffix == ".csv":
            cols = self.columns()
            data = np.column_stack(list(cols.values()))
            header = ",".join(f"{name} [{CSV_COLUMNS[name]}]" for name in cols)

            def write(tmp):
                with open(tmp, "w", encoding="utf-8") as fh:
                    np.savetxt(fh, data, delimiter=",", header=header, comments="", fmt="%.17g")
            return atomic_write(path, write)
        raise ParameterError(f"out: unknown extension {suffix!r}; allowed: .csv, .npz")

    def __eq__(self, other) -> bool:
        if not isinstance(other, Result):
            return NotImplemented
        mine, theirs = self.arrays(), other.arrays()
        return (mine.keys() == theirs.keys()
                and all(_identical(mine[k], theirs[k]) for k in mine)
                and _metadata_text(self) == _metadata_text(other))

    __hash__ = None


def _identical(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and np.ascontiguousarray(a).tobytes() == \
        np.ascontiguousarray(b).tobytes()


def _metadata_text(result: Result) -> str:
    """The metadata as JSON text (compares NaN and floats bit for bit)."""
    return json.dumps(result.metadata(), sort_keys=True)


def _check_choice(name, value, allowed):
    if value not in allowed:
        raise ParameterError(f"{name} must be one of {', '.join(allowed)}, got {value!r}")


def describe_input(obj) -> str:
    """How a result's ``settings`` record a maneuver or torque profile.

    Parameters
    ----------
    obj : object or None
        A maneuver (dataclass), a torque function, or ``None``.

    Returns
    -------
    str
        The dataclass's ``repr`` (its parameters), the type name of anything else, or
        ``"none"``.
    """
    if obj is None:
        return "none"
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return repr(obj)
    return type(obj).__name__


#: Aliases of :class:`Result` (one type for every run), kept for existing imports.
SimulationResult = Result
ClosedLoopResult = Result


def _non_finite(value, where: str):
    """The path (``settings.dt``) of the first NaN or infinity in a JSON document, or None."""
    if isinstance(value, float) and not math.isfinite(value):
        return where
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, list):
        items = ((str(i), v) for i, v in enumerate(value))
    else:
        return None
    for key, item in items:
        found = _non_finite(item, f"{where}.{key}" if not key.isdigit() else f"{where}[{key}]")
        if found is not None:
            return found
    return None


def load_result(path) -> Result:
    """Load a :class:`Result` saved as ``.npz`` by :meth:`Result.save`.

    The round trip is bit-exact: ``load_result(res.save(p)) == res``.

    Parameters
    ----------
    path : str or Path
        An ``.npz`` file (a ``.csv`` holds only the series and cannot be loaded).

    Returns
    -------
    Result

    Raises
    ------
    ParameterError
        One line naming the file: not a regular file, not an NPZ archive, not a hubbeam
        result (format tag, missing or unexpected entries), or arrays of the wrong shape
        or type.
    """
    path = Path(path)
    if path.suffix.lower() != ".npz":
        raise ParameterError(f"path: only .npz results can be loaded, got {path.name!r} "
                             "(a .csv holds only the series)")
    arrays, meta = read_npz(path, "path", "hubbeam result file")

    def bad(reason):
        return ParameterError(f"path: {path} is not a valid hubbeam result file ({reason})")

    if meta.get("format") != _FORMAT:
        raise bad(f"format tag {meta.get('format')!r}, expected {_FORMAT!r}")
    if meta.get("version") != _VERSION:
        raise bad(f"format version {meta.get('version')!r}; this toolbox reads version {_VERSION}")
    missing = [k for k in _META_FIELDS + ("params",) if k not in meta]
    if missing:
        raise bad(f"metadata lacks {', '.join(missing)}")
    unexpected = sorted(set(arrays) - set(_ARRAY_NDIM))
    if unexpected:
        raise bad(f"unexpected array(s) {', '.join(unexpected)}")
    if not isinstance(meta["kind"], str) or meta["kind"] not in RESULT_KINDS:
        raise bad(f"kind must be one of {', '.join(RESULT_KINDS)}, got {meta['kind']!r}")
    absent = [k for k in _REQUIRED + _REQUIRED_BY_KIND[meta["kind"]] if k not in arrays]
    if absent:
        raise bad(f"a {meta['kind']} result needs {', '.join(absent)}")
    if not isinstance(meta["params"], dict):
        raise bad(f"params must be a JSON object, got {type(meta['params']).__name__}")
    if not isinstance(meta["settings"], dict):
        raise bad(f"settings must be a JSON object, got {type(meta['settings']).__name__}")
    where = _non_finite(meta["settings"], "settings")
    if where is not None:
        raise bad(f"{where} is not a finite number")
    try:
        params = Params.from_dict(meta["params"])
        return Result(params=params, **{k: meta[k] for k in _META_FIELDS}, **arrays)
    except ParameterError as exc:
        raise bad(str(exc)) from None
    except (TypeError, ValueError) as exc:
        raise bad(f"{type(exc).__name__}: {exc}") from None

"""Study specifications: the task, the controllers, and the plant spread of a sweep.

A study spec says what to run (scenario, plant model, controllers and their settings, base
parameters) and how the **plant** varies from case to case: a full grid and/or Monte Carlo
samples of any :class:`~hubbeam_ctrl.plant.params.Params` field, the spin-up rate ``w_f``
and the sensor-noise ``seed``. The design stays at the base parameters unless
``design = "matched"`` (each case redesigns on its own plant).

TOML form (every key optional except where noted)::

    [study]
    scenario = "slew"                 # slew | spinup
    plant = "foam"                    # foam | cfoam | ancf (the exact beam, extra "exact")
    controllers = ["openloop", "lqr", "mpc"]
    design = "base"                   # base | matched
    t_f = 10.0                        # [s]; also tau_max [N m] (default: params.tau_max, the
                                      # motor's), t_end [s], dt [s], w_f [rad/s],
                                      # horizon, solver, design_modes, plant_modes
    slew_angle = 1.5708               # [rad] (slew; default the Eq. 44 angle)
    shaping = "zvd"                   # zv | zvd | ei: input shaper of the tracked reference
    schedule = 3                      # spin rates of the design schedule (1: one design)
    backend = "auto"                  # auto | compiled | vm (default $HUBBEAM_BACKEND)
    rig = "servo_link"                # a rig preset or file: its beam is [params]' base, its dt and
                                      # the task's t_end the defaults, its hardware in every case
    integral = true                   # integral action on the rig (default: with friction or a motor)
    tolerances = {angle_error = 5e-4} # controllers.scaling.Tolerances fields over the defaults
    [params]                          # base Params fields (SI units)
    m_t = 0.1
    [settings.lqr]                    # controller settings replacing the defaults
    weights = {tip = 1e4}
    [grid]                            # full grid, factors in this order
    m_t = [0.0, 0.1, 0.3, 0.5]
    [random]                          # Monte Carlo, crossed with the grid
    n = 20
    seed = 1
    method = "lhs"                    # lhs (default) | sobol | halton | random
    E = {dist = "normal", mean = 6.9e10, std = 3e9}
    rho = {dist = "uniform", low = 2600.0, high = 2800.0}
    damping_ratio = {dist = "lognormal", median = 0.005, sigma = 0.5, high = 0.05}

``normal`` and ``lognormal`` accept ``low``/``high`` to truncate (the samples stay stratified).
Every error is a one-line :class:`~hubbeam_ctrl.core.errors.ParameterError` naming the key.

Examples
--------
>>> spec = StudySpec.from_dict({"study": {"controllers": ["lqr"]},
...                              "grid": {"m_t": [0.0, 0.2]}, "random": {"n": 3, "seed": 1,
...                              "E": {"dist": "uniform", "low": 6.5e10, "high": 7.0e10}}})
>>> [sorted(c) for c in spec.cases()][:1]
[['E', 'm_t']]
>>> len(spec.cases())
6
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from controllers import CONTROLLERS
from controllers.scaling import default_tolerances
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.reading import path_exists
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.study.bands import with_task_bands
from hubbeam_ctrl.study.scenarios import make_scenario
from hubbeam_ctrl.study.spec_checks import check_spec
from hubbeam_ctrl.study.spread import FACTORS_EXTRA, _grid, _random, _unit_samples

__all__ = ["StudySpec"]

_STUDY_KEYS = {"scenario": "slew", "plant": "foam", "controllers": ("openloop", "lqr"), "design": "base",
               "tau_max": None, "t_f": 10.0, "t_end": 30.0, "dt": 0.01, "w_f": 3.0, "horizon": 50,
               "solver": "daqp", "design_modes": None, "plant_modes": None, "slew_angle": None,
               "shaping": None, "schedule": 1, "tolerances": None, "backend": None, "rig": None,
               "integral": None}


def _controller_list(value) -> tuple:
    """``study.controllers`` (a list of names) checked against the registry; a string is refused
    (``controllers = "openloop"`` for ``["openloop"]``), not read as a list."""
    items = value
    if not isinstance(items, (list, tuple)):
        raise ParameterError(f"study.controllers must be a list of names (controllers = [\"lqr\"]), "
                             f"got {value!r}"[:200])
    names = tuple(str(c).strip().lower() for c in items if str(c).strip())
    bad = [n for n in names if n not in CONTROLLERS]
    if not names or bad or len(set(names)) != len(names):
        raise ParameterError(f"study.controllers must name each of {', '.join(CONTROLLERS)} at most once "
                             f"(at least one), got {', '.join(map(str, items)) or 'none'}")
    return names


@dataclass(frozen=True)
class StudySpec:
    """A robustness study: task, controllers and the plant spread (see the module docstring).

    Built from TOML tables by :meth:`from_dict` (or :func:`~hubbeam_ctrl.study.spec_files.load_spec`)
    and checked by :meth:`validate`; the constructor itself checks nothing.

    Attributes
    ----------
    scenario : {"slew", "spinup"}
    plant : {"foam", "cfoam", "ancf"}
        Evaluation plant model (``ancf``: the geometrically exact beam of Exudyn,
        :class:`~hubbeam_ctrl.exact.ExactBeamPlant`, extra ``exact``).
    controllers : tuple of str
    design : {"base", "matched"}
        ``base``: every controller designed once on the base parameters; ``matched``:
        redesigned on each case's plant.
    tau_max : float or None
        Torque budget [N m] (None: the motor's, ``Params.tau_max`` of the parameters each
        scenario is built on; see :attr:`torque_budget`).
    t_f, t_end, dt : float
        Maneuver time, simulated time, controller sample time [s].
    w_f : float
        Spin-up final rate [rad/s] (spinup).
    horizon : int
        MPC horizon [samples].
    solver : str
        MPC QP solver.
    design_modes : int or None
        Transverse modes of the design model (default: the base plant's).
    plant_modes : int or None
        Transverse modes of the evaluation plant (default: the rule of
        :func:`hubbeam_ctrl.sim.evaluation.evaluation_plant`, more modes than the design).
    slew_angle : float or None
        Slew angle [rad] (default: the Eq. 44 angle of ``tau_max`` and ``t_f``).
    shaping : {"zv", "zvd", "ei"} or None
        Input shaper of the reference of the controllers that track it, designed on the
        design model's first mode (as :func:`~hubbeam_ctrl.study.compare.compare`).
    schedule : int
        Spin rates of the design schedule of the scheduled controllers (1: one design).
    tolerances : dict or None
        :class:`controllers.scaling.Tolerances` fields [-] replacing those of the task's
        defaults (:func:`controllers.scaling.default_tolerances`).
    backend : {"auto", "compiled", "vm"} or None
        How the plant is evaluated (default ``$HUBBEAM_BACKEND`` or ``"auto"``); the
        results agree to 1e-9 relative, not bit for bit, across backends.
    rig : Rig or None
        The rig every case runs on (``study.rig``: a preset or a rig file beside the spec):
        its beam is the base of ``params``, its ``timing.dt`` the default ``dt``, the task's
        simulated time the default ``t_end``, its hardware in every case's plant, the
        controllers on it as in :func:`~hubbeam_ctrl.study.compare.compare` with ``rig=``.
    integral : bool or None
        Integral action of LQR, LQG and MPC on the rig (default: the rig's,
        :func:`hubbeam_ctrl.study.rig_loop.integral_default`).
    params : Params
        Base parameters (design, and plant where no factor changes them).
    settings : dict
        Controller name -> {setting: value} replacing its defaults (nested tables for
        dataclass-valued settings such as ``weights``).
    grid : dict
        Factor -> list of values (full grid, in order).
    random : dict or None
        ``{"n", "seed", "method", "factors": {name: Distribution}}``.
    """

    scenario: str = "slew"
    plant: str = "foam"
    controllers: tuple = ("openloop", "lqr")
    design: str = "base"
    tau_max: float | None = None
    t_f: float = 10.0
    t_end: float = 30.0
    dt: float = 0.01
    w_f: float = 3.0
    horizon: int = 50
    solver: str = "daqp"
    design_modes: int | None = None
    plant_modes: int | None = None
    slew_angle: float | None = None
    shaping: str | None = None
    schedule: int = 1
    tolerances: dict | None = None
    backend: str | None = None
    rig: object = None
    integral: bool | None = None
    params: Params = field(default_factory=Params)
    settings: dict = field(default_factory=dict)
    grid: dict = field(default_factory=dict)
    random: dict | None = None

    # -- construction ------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, data: dict) -> "StudySpec":
        """Build and validate a spec from its TOML tables (``study``, ``params``, ``settings``,
        ``grid``, ``random``).

        Parameters
        ----------
        data : dict
            The spec's TOML tables.
        """
        if not isinstance(data, dict):
            raise ParameterError(f"spec must be a table, got {type(data).__name__}")
        try:
            return cls._from_tables(data)
        except ParameterError:
            raise
        except (TypeError, ValueError, KeyError, AttributeError, OverflowError, IndexError) as exc:
            # a mistyped value the checks above did not name (the guard of the whole class)
            raise ParameterError(f"spec: a value has the wrong type or form ({_one_line(exc)})") from None

    @classmethod
    def _from_tables(cls, data: dict) -> "StudySpec":
        if not set(data) - {"_dir"}:
            raise ParameterError("spec is empty: a study names at least its controllers ([study] controllers = "
                                 "[\"lqr\"]; docs/studies.md)")
        extra = sorted(set(data) - {"study", "params", "settings", "grid", "random", "tune", "_dir"})
        if extra:
            raise ParameterError(f"spec: unknown table(s) {', '.join(extra)}; allowed: study, params, "
                                 "settings, grid, random, tune")
        for table in ("study", "params", "settings", "grid", "random", "tune"):
            if table in data and not isinstance(data[table], dict):
                raise ParameterError(f"spec: {table} must be a table ([{table}]), got {table} = "
                                     f"{data[table]!r}"[:300])
        for name, table in data.get("settings", {}).items():
            if not isinstance(table, dict):
                raise ParameterError(f"settings.{name} must be a table ([settings.{name}]), got {table!r}"[:300])
        study = dict(data.get("study", {}))
        bad = sorted(set(study) - set(_STUDY_KEYS))
        if bad:
            raise ParameterError(f"study: unknown key(s) {', '.join(bad)}; allowed: {', '.join(_STUDY_KEYS)}")
        kw = {k: study.get(k, v) for k, v in _STUDY_KEYS.items()}
        kw["controllers"] = _controller_list(kw["controllers"])
        kw["rig"] = _spec_rig(kw["rig"], data.get("_dir"))
        if kw["integral"] is not None and not isinstance(kw["integral"], bool):
            raise ParameterError(f"study.integral must be true or false, got {kw['integral']!r}")
        if kw["rig"] is not None and "dt" not in study and kw["rig"].timing.dt is not None:
            kw["dt"] = kw["rig"].timing.dt
        try:
            params = Params.from_dict(dict(data.get("params", {}))) if kw["rig"] is None else \
                kw["rig"].plant_params.replace(**dict(data.get("params", {})))
        except (ParameterError, TypeError) as exc:  # name the spec key: params.m_t, not m_t
            text = str(exc)
            head = text.split(" ", 1)[0]
            raise ParameterError(f"params.{text}" if head in {f.name for f in dataclasses.fields(Params)}
                                 else f"params: {text}") from None
        grid = _grid("grid", data.get("grid", {}), kw["scenario"])
        random = None
        if "random" in data:
            n, seed, method, dists = _random("random", data["random"], kw["scenario"], grid)
            random = {"n": n, "seed": seed, "method": method, "factors": dists}
        spec = cls(params=params, settings=dict(data.get("settings", {})), grid=grid, random=random, **kw)
        if spec.rig is not None and "t_end" not in study:       # the task's simulated time, as compare
            from hubbeam_ctrl.study.yardstick import task_t_end
            try:
                spec = dataclasses.replace(spec, t_end=task_t_end(spec.scenario_for(params)))
            except ParameterError:
                pass                                            # validate() names the bad value
        spec.validate()
        for key in ("horizon", "solver"):         # keys no chosen controller uses (to_dict writes the defaults)
            if key in study and study[key] != _STUDY_KEYS[key] and not spec._uses(key):
                raise ParameterError(f"study.{key}: no controller of study.controllers "
                                     f"({', '.join(spec.controllers)}) uses it")
        if "shaping" in study and study["shaping"] is not None \
                and not any(CONTROLLERS[n].tracks_reference for n in spec.controllers):
            raise ParameterError(f"study.shaping: no controller of study.controllers ({', '.join(spec.controllers)}) "
                                 "tracks a reference")
        return spec

    def validate(self) -> None:
        """Raise :class:`ParameterError` on any bad field (the constructor does not check;
        :func:`~hubbeam_ctrl.study.spec_checks.check_spec`)."""
        check_spec(self)

    def _uses(self, setting: str) -> bool:
        """Whether a controller of the study has the setting (``horizon``, ``solver``)."""
        return any(setting in {f.name for f in dataclasses.fields(CONTROLLERS[n].settings)}
                   for n in self.controllers if dataclasses.is_dataclass(CONTROLLERS[n].settings))

    @property
    def torque_budget(self) -> float:
        """The torque budget of the base scenario [N m]: ``study.tau_max``, or ``params.tau_max``."""
        return self.params.tau_max if self.tau_max is None else float(self.tau_max)

    @property
    def factors(self) -> tuple:
        """Names of the varied factors, grid first, in spec order."""
        rnd = tuple(self.random["factors"]) if self.random else ()
        return tuple(self.grid) + rnd

    # -- cases -------------------------------------------------------------------------------
    def cases(self) -> list:
        """Every case as a dict factor -> value: the grid points crossed with the random
        samples (the same samples at every grid point). One empty case if nothing varies."""
        names = list(self.grid)
        points = [dict(zip(names, combo)) for combo in itertools.product(*self.grid.values())]
        if not self.random:
            return points
        dists = self.random["factors"]
        u = _unit_samples(self.random["method"], len(dists), self.random["n"], self.random["seed"])
        cols = {name: d.ppf(u[:, j]) for j, (name, d) in enumerate(dists.items())}
        samples = [{name: float(cols[name][i]) for name in dists} for i in range(self.random["n"])]
        return [{**p, **s} for p in points for s in samples]

    def plant_params(self, case: dict) -> Params:
        """The evaluation plant's parameters of one case.

        Parameters
        ----------
        case : dict
            Factor name -> value of one case.
        """
        changes = {k: v for k, v in case.items() if k not in FACTORS_EXTRA}
        try:
            return self.params.replace(**changes) if changes else self.params
        except ParameterError as exc:
            raise ParameterError(f"case {case}: {exc}") from None

    def design_params(self, case: dict) -> Params:
        """The design model's parameters (base, or the case's plant when ``design = "matched"``).

        Parameters
        ----------
        case : dict
            Factor name -> value of one case.
        """
        return self.plant_params(case) if self.design == "matched" else self.params

    def scenario_for(self, params: Params, w_f: float | None = None):
        """The scenario (reference, design spin) built on ``params`` (spin-up rate ``w_f``).

        Parameters
        ----------
        params : Params
            Parameters the scenario is built on.
        w_f : float, optional
            Spin-up final rate [rad/s] (default: the spec's).
        """
        tol = None
        if self.tolerances:
            try:
                tol = default_tolerances(self.scenario, params.J_h / params.total_inertia).replace(**self.tolerances)
            except (ParameterError, TypeError) as exc:
                raise ParameterError(f"study.tolerances: {_one_line(exc)}") from None
        sc = make_scenario(self.scenario, plant=self.plant, params=params, tau_max=self.tau_max,
                           t_f=self.t_f, t_end=self.t_end, dt=self.dt,
                           w_f=self.w_f if w_f is None else w_f,
                           slew_angle=self.slew_angle if self.scenario == "slew" else None, tolerances=tol)
        return with_task_bands(sc, self.rig)     # on a rig: the angle band at least two counts of its sensor

    # -- serialisation -------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The TOML tables of this spec (plain data; ``from_dict`` of it gives the same spec)."""
        study = {k: getattr(self, k) for k in _STUDY_KEYS if getattr(self, k) is not None}
        study["controllers"] = list(self.controllers)
        if self.rig is not None:             # the rig itself, so a changed rig file is another study
            study["rig"] = self.rig.to_tables()
        out = {"study": study, "params": {k: v for k, v in self.params.to_dict().items() if v is not None}}
        for key in ("settings", "grid"):
            if getattr(self, key):
                out[key] = json.loads(json.dumps(getattr(self, key), default=_plain))
        if self.random:
            rnd = {k: self.random[k] for k in ("n", "seed", "method")}
            rnd.update({k: d.to_dict() for k, d in self.random["factors"].items()})
            out["random"] = rnd
        return out

    def hash(self) -> str:
        """SHA-256 of the canonical JSON of :meth:`to_dict` (what an output folder is keyed by)."""
        text = json.dumps(self.to_dict(), sort_keys=True, default=_plain)
        return hashlib.sha256(text.encode()).hexdigest()

    def replace(self, **changes) -> "StudySpec":
        """A validated copy with some fields changed."""
        out = dataclasses.replace(self, **changes)
        out.validate()
        return out



def _spec_rig(value, folder=None):
    """The spec's ``study.rig``: None, a preset name or a file (relative to the spec's folder), or
    the tables of a rig (what :meth:`StudySpec.to_dict` writes)."""
    if value is None:
        return None
    from hubbeam_ctrl.plant.rig import Rig, load_rig, rig_from_dict
    try:
        if isinstance(value, Rig):
            return value
        if isinstance(value, dict):
            return rig_from_dict(value)
        if isinstance(value, str) and value.strip():
            path = Path(folder) / value if folder is not None and not Path(value).is_absolute() else Path(value)
            return load_rig(str(path) if path_exists(path) else value)
    except ParameterError as exc:
        raise ParameterError(f"study.rig: {exc}") from None
    raise ParameterError(f"study.rig must name a rig file or a preset (servo_link, paper), got {value!r}"[:200])


def _one_line(exc: BaseException) -> str:
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def _plain(obj):
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if dataclasses.is_dataclass(obj):
        return dataclasses.asdict(obj)
    raise TypeError(f"{type(obj).__name__} is not plain data")

"""The checks of a study spec: every field in its range, named by its spec key, the
controllers' settings, the grid and random samples valid parameters, and the size and run
budget of the sweep (:func:`check_spec`, run by :meth:`StudySpec.validate
<hubbeam_ctrl.study.spec.StudySpec.validate>`).
"""

from __future__ import annotations

import dataclasses
import math

from controllers import SHAPERS
from controllers.scaling import Tolerances
from controllers.schedule import MAX_SCHEDULE_POINTS
from hubbeam_ctrl.core.compiled import check_backend
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.exact import require_exudyn
from hubbeam_ctrl.plant.params import MAX_MODES
from hubbeam_ctrl.study.scenarios import PLANTS, SCENARIOS
from hubbeam_ctrl.study.settings_table import controller_settings
from hubbeam_ctrl.study.spread import FACTORS_EXTRA, MAX_CASES

__all__ = ["check_spec"]

#: The names make_scenario's messages start with -> the spec key that sets them.
_SCENARIO_KEYS = {"tau_max": "study.tau_max", "tf": "study.t_f", "t_f": "study.t_f", "t_end": "study.t_end",
                  "dt": "study.dt", "wf": "study.w_f", "w_f": "study.w_f", "slew_angle": "study.slew_angle"}


def _as_study_key(message: str) -> str:
    """A scenario's one-line error with the spec key in front (``tau_max must`` -> ``study.tau_max must``)."""
    if message.startswith("study."):
        return message
    head, _, rest = message.partition(" ")
    key = _SCENARIO_KEYS.get(head.rstrip(":"))
    return f"{key}{head[len(head.rstrip(':')):]} {rest}" if key else f"study: {message}"


def check_spec(spec) -> None:
    """Raise :class:`~hubbeam_ctrl.core.errors.ParameterError` on any bad field of ``spec``
    (what :meth:`StudySpec.validate <hubbeam_ctrl.study.spec.StudySpec.validate>` runs).

    Parameters
    ----------
    spec : StudySpec
    """
    if spec.scenario not in SCENARIOS:
        raise ParameterError(f"study.scenario must be one of {', '.join(SCENARIOS)}, got {spec.scenario!r}")
    if spec.plant not in PLANTS:
        raise ParameterError(f"study.plant must be one of {', '.join(PLANTS)}, got {spec.plant!r}")
    if spec.plant == "ancf":
        require_exudyn("study.plant 'ancf'")
    if spec.design not in ("base", "matched"):
        raise ParameterError(f"study.design must be 'base' or 'matched', got {spec.design!r}")
    if not isinstance(spec.settings, dict):
        raise ParameterError("settings must be a table of controller tables")
    if spec.shaping is not None and spec.shaping not in SHAPERS:
        raise ParameterError(f"study.shaping must be one of {', '.join(SHAPERS)}, got {spec.shaping!r}")
    if isinstance(spec.schedule, bool) or not isinstance(spec.schedule, int) \
            or not 1 <= spec.schedule <= MAX_SCHEDULE_POINTS:
        raise ParameterError(f"study.schedule must be an integer >= 1 and <= {MAX_SCHEDULE_POINTS} (spin rates "
                             f"of the design schedule; 1 = a single design), got {spec.schedule!r}"[:300])
    if spec.backend is not None:
        check_backend(spec.backend, "study.backend")
    if spec.tolerances is not None:
        allowed = [f.name for f in dataclasses.fields(Tolerances)]
        if not isinstance(spec.tolerances, dict):
            raise ParameterError(f"study.tolerances must be a table of Tolerances fields, got {spec.tolerances!r}")
        unknown = sorted(set(spec.tolerances) - set(allowed))
        if unknown:
            raise ParameterError(f"study.tolerances: unknown field(s) {', '.join(unknown)}; allowed: "
                                 f"{', '.join(allowed)}")
    for key in ("design_modes", "plant_modes"):
        v = getattr(spec, key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= MAX_MODES):
            raise ParameterError(f"study.{key} must be an integer in 1..{MAX_MODES}, got {v!r}")
    _check_run_budget(spec)                    # before the scenario: its reference spans t_end
    try:
        sc = spec.scenario_for(spec.params)
    except ParameterError as exc:
        raise ParameterError(_as_study_key(str(exc))) from None
    for name, table in spec.settings.items():
        if name not in spec.controllers:
            raise ParameterError(f"settings.{name}: not among study.controllers ({', '.join(spec.controllers)})")
        controller_settings(name, table, sc, spec.horizon, spec.solver)
    for name, values in spec.grid.items():     # each grid value on the base parameters
        for v in values if name not in FACTORS_EXTRA else ():
            try:
                spec.params.replace(**{name: v})
            except ParameterError as exc:
                raise ParameterError(f"grid.{name} = {v!r}: {exc}") from None
    _check_size(spec)
    _check_samples(spec)

def _check_size(spec) -> None:
    """Refuse a plant spread of more than :data:`MAX_CASES` cases, naming the keys."""
    sizes = [(f"grid.{k}", len(v)) for k, v in spec.grid.items()]
    if spec.random:
        sizes.append(("random.n", spec.random["n"]))
    total = math.prod(n for _, n in sizes)
    if total > MAX_CASES:
        parts = " x ".join(f"{k} ({n})" for k, n in sizes)
        raise ParameterError(f"{parts} give {total:.6g} cases, more than the {MAX_CASES} one sweep runs; "
                             "split the study or sample it ([random])")

def _check_run_budget(spec) -> None:
    """Refuse a task whose single run exceeds the closed-loop runs' default memory or
    wall-time limits (what :func:`~hubbeam_ctrl.study.compare.compare` refuses up front)."""
    from hubbeam_ctrl.core.budget import CLOSED_LOOP_SECONDS_PER_SAMPLE, check_budget, mpc_bytes, mpc_seconds
    from hubbeam_ctrl.sim.closedloop import ClosedLoopSettings
    numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0
                  for v in (spec.t_end, spec.dt))
    if not numbers:
        return                                  # the scenario names the bad value
    limits = ClosedLoopSettings()
    p = spec.params
    modes = spec.plant_modes if isinstance(spec.plant_modes, int) else p.n_transverse
    n_q = 1 + p.n_axial + modes
    steps = int(round(min(spec.t_end / spec.dt, 1e15)))      # t_end / dt may overflow to inf
    memory = 16.0 * (steps + 1) * (2 * n_q + 9)
    seconds = steps * CLOSED_LOOP_SECONDS_PER_SAMPLE * (n_q / 11.0) ** 2
    what = f"study.t_end = {spec.t_end:g} s at study.dt = {spec.dt:g} s ({steps + 1:.6g} samples per run)"
    if spec._uses("horizon") and isinstance(spec.horizon, int) and not isinstance(spec.horizon, bool) \
            and 1 <= spec.horizon <= 10**6:
        n_x = 2 * (1 + (spec.design_modes or p.n_transverse))
        memory += mpc_bytes(spec.horizon, n_x)
        seconds += mpc_seconds(spec.horizon, n_x, steps)
        what += f" with study.horizon = {spec.horizon}"
    try:
        check_budget(what, memory_bytes=memory, seconds=seconds, max_memory_mb=limits.max_memory_mb,
                     max_wall_s=limits.max_wall_s)
    except ParameterError as exc:           # a spec cannot lift the limits of one run: say what to lower
        head = str(exc).split(" (raise ")[0]
        lower = "study.horizon or study.t_end" if "horizon" in what else "study.t_end or raise study.dt"
        raise ParameterError(f"{head} (the limit of one closed-loop run of a sweep; lower {lower})") from None

def _check_samples(spec) -> None:
    """Every sampled value must be a valid parameter (a distribution whose samples leave
    the range of its factor is refused, naming it, before any case runs)."""
    if not spec.random:
        return
    for case in spec.cases():
        for name in spec.random["factors"]:
            if name in FACTORS_EXTRA:
                continue
            try:
                spec.params.replace(**{name: case[name]})
            except ParameterError as exc:
                raise ParameterError(f"random.{name}: the sample {case[name]:.6g} is outside its range ({exc}); "
                                     "truncate the distribution with low/high") from None

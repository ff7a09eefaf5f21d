"""The evaluation plant of a closed loop: a richer model than the controller's design model.

A controller designed on an ``m``-mode model and judged on the same ``m`` modes proves
nothing about the real beam: the modes it leaves out are where spillover happens. The
default evaluation plant therefore keeps the design's physical parameters but carries
**every bending mode below the controller's sampling frequency plus the first one above
it**, and at least :data:`EXTRA_MODES` more transverse modes than the design model (at most
:data:`~hubbeam_ctrl.plant.params.MAX_MODES`). The first mode above the sampling frequency
is included because the highest mode of an assumed-mode model is its least accurate (on
the paper's beam the 8-mode model puts mode 8 0.9 % above its converged value, the
10-mode model 0.35 %), so it keeps every mode below the sampling frequency converged.

The modes are counted by :func:`hubbeam_ctrl.plant.modal.converged_bending_hz` (modal
analysis of the plant's physical parameters with 20 transverse modes, hub free, at the
design spin).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_positive
from hubbeam_ctrl.plant.modal import converged_bending_hz
from hubbeam_ctrl.plant.params import MAX_MODES, Params

__all__ = ["EXTRA_MODES", "PLANT_MODELS", "EvaluationPlant", "default_design_modes", "default_plant_modes",
           "evaluation_plant", "modes_to_cover"]

#: The default evaluation plant has at least this many more transverse modes than the design.
EXTRA_MODES = 3
#: Models that can serve as evaluation plant (SFOAM and TLAM are design approximations).
PLANT_MODELS = ("foam", "cfoam", "ancf")


@dataclass(frozen=True, eq=False)
class EvaluationPlant:
    """The plant a closed loop is judged on, and how it was chosen.

    Attributes
    ----------
    model : {"foam", "cfoam"}
    params : Params
        The plant's parameters (``n_transverse`` its transverse modes).
    design_modes : int
        Transverse modes of the controller's design model.
    reason : str
        How the number of modes was chosen (one sentence for reports).
    """

    model: str
    params: Params
    design_modes: int
    reason: str

    @property
    def modes(self) -> int:
        """Transverse modes of the plant."""
        return self.params.n_transverse

    def to_dict(self) -> dict:
        """Plain-data summary (JSON-ready)."""
        return {"plant_model": self.model, "plant_modes": self.modes,
                "plant_axial_modes": self.params.n_axial, "design_modes": self.design_modes,
                "plant_modes_reason": self.reason, "plant_params": self.params.to_dict()}


def _check_modes(name: str, value, lo: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= MAX_MODES:
        raise ParameterError(f"{name} must be an integer in {lo}..{MAX_MODES}, got {value!r}")
    return int(value)


def modes_to_cover(params: Params, f_hz: float, spin: float = 0.0) -> tuple:
    """The plant-mode rule: every bending mode below ``f_hz`` plus the first one above it.

    Parameters
    ----------
    params : Params
        Physical parameters (the mode counts are ignored).
    f_hz : float
        The frequency to cover [Hz], > 0 (a sampling frequency, an excitation band's top).
    spin : float
        Spin rate of the modal analysis [rad/s].

    Returns
    -------
    n : int
        ``(modes below f_hz) + 1``, at most :data:`~hubbeam_ctrl.plant.params.MAX_MODES`.
    below : int
        Modes below ``f_hz``.
    f : ndarray
        The converged free-hub bending frequencies [Hz]
        (:func:`~hubbeam_ctrl.plant.modal.converged_bending_hz`).
    """
    f = converged_bending_hz(params, float(spin))
    below = int(np.sum(f < check_positive("f_hz", f_hz, "Hz")))
    return min(below + 1, MAX_MODES), below, f


def default_plant_modes(params: Params, dt: float, design_modes: int, spin: float = 0.0):
    """Transverse modes of the default evaluation plant, and why.

    Parameters
    ----------
    params : Params
        Physical parameters of the plant (its mode counts are ignored).
    dt : float
        Controller sample time [s]; the sampling frequency is ``1/dt``.
    design_modes : int
        Transverse modes of the design model, 1..20.
    spin : float
        Spin rate of the modal analysis [rad/s] (the design spin).

    Returns
    -------
    n : int
        ``max(design_modes + 3, (modes below 1/dt) + 1)``, at most 20; fewer extra modes (at least
        one more than the design and the first above the sampling frequency) where the integrator
        would need more than 90 % of :data:`~hubbeam_ctrl.sim.step_rule.SUBSTEP_BUDGET` steps a sample
        for them (:func:`default_design_modes` first lowers the design's modes; this is for a
        1-mode design that still does not fit). Found on a random slow boom (5.3 m on a 290 kg m^2
        body at 10 Hz, modes 3.5, 21, 58, 114 Hz): the 1-mode design's 4-mode plant needed 207 steps a
        sample and every default run was refused; its 3-mode plant needs fewer.
    reason : str

    Examples
    --------
    >>> default_plant_modes(Params(), 0.01, 5)[0]      # the paper's beam at 100 Hz
    10
    """
    from hubbeam_ctrl.sim.step_rule import SUBSTEP_BUDGET, substep_rule
    n, reason, f, below = _plant_rule(params, dt, design_modes, spin)
    least = max(_check_modes("design_modes", design_modes, 1) + 1, below + 1)
    budget = int(0.9 * SUBSTEP_BUDGET)
    kept = n
    while n > least:
        try:
            substep_rule(f[:n], dt, tolerance=PLANT_TOLERANCE, max_substeps=budget)
            break
        except ParameterError:
            n -= 1
    if n < kept:
        reason += (f": {kept} would need more than {budget} integration steps per sample of {1e3 * dt:g} ms, "
                   f"so {n}")
    return n, reason + f": {n} transverse modes"


#: The frequency error the closed loop's integrator accepts by default (``ClosedLoopSettings.frequency_tolerance``),
#: with which :func:`default_plant_modes` counts the steps its plant needs.
PLANT_TOLERANCE = 0.01


def _plant_rule(params: Params, dt: float, design_modes: int, spin: float = 0.0) -> tuple:
    """``(n, reason, f, below)``: :func:`default_plant_modes`' rule before the integrator's budget."""
    if not isinstance(params, Params):
        raise ParameterError(f"params must be a Params, got {type(params).__name__}")
    fs = 1.0 / check_positive("dt", dt, "s")
    design_modes = _check_modes("design_modes", design_modes, 1)
    _, below, f = modes_to_cover(params, fs, spin)
    n = max(design_modes + EXTRA_MODES, below + 1)
    count = f"{below}" if below < MAX_MODES else f"at least {below}"
    reason = (f"{count} bending modes lie below the {fs:g} Hz sampling frequency; the plant keeps "
              f"them and the first above it, and at least {EXTRA_MODES} more than the "
              f"{design_modes}-mode design model")
    if n > MAX_MODES:
        n = MAX_MODES
        reason += f" (capped at {MAX_MODES}: modes above {f[MAX_MODES - 1]:.4g} Hz are left out)"
    return n, reason, f, below


def default_design_modes(params: Params, dt: float, spin: float = 0.0, tolerance: float = 0.01) -> tuple:
    """The design model's default modes at the sample time ``dt``, and why when fewer than the beam's.

    ``params.n_transverse``, fewer when the default evaluation plant of that design
    (:func:`default_plant_modes`: at least three more modes) could not be integrated within
    :data:`~hubbeam_ctrl.sim.step_rule.SUBSTEP_BUDGET` steps per sample (with a 10 % margin: the
    plant's own top mode is a little stiffer than the converged one). Found on a random rig: a 0.66 m
    CFRP link sampled at 5 ms (bending modes 12, 72, 223 ... Hz), whose 5-mode design asked an 8-mode
    plant with mode 8 at 2.3 kHz, 210 steps per sample: every default run was refused. Design modes
    that far above the sampling frequency are aliased anyway.

    Parameters
    ----------
    params : Params
        The design's beam (its ``n_transverse``: the most modes).
    dt : float
        Sample time [s].
    spin : float
        Spin rate of the modal analysis [rad/s].
    tolerance : float
        The integrator's accepted frequency error [-] (the closed loop's
        ``ClosedLoopSettings.frequency_tolerance``, 1 %).

    Returns
    -------
    tuple
        ``(modes, note)``: the note is empty when the beam's count is kept.

    Examples
    --------
    >>> default_design_modes(Params(), 0.01)[0]       # the paper's beam at 100 Hz: its 5
    5
    """
    from hubbeam_ctrl.sim.step_rule import SUBSTEP_BUDGET, substep_rule
    dt = check_positive("dt", dt, "s")
    f = modes_to_cover(params, 1.0 / dt, spin)[2]
    m = params.n_transverse
    while m > 1:
        n = _plant_rule(params, dt, m, spin)[0]
        try:
            substep_rule(f[:n], dt, tolerance=tolerance, max_substeps=int(0.9 * SUBSTEP_BUDGET))
            break
        except ParameterError:
            m -= 1
    if m == params.n_transverse:
        return m, ""
    return m, (f"design model: {m} modes, not the beam's {params.n_transverse}: the evaluation plant of a "
               f"{params.n_transverse}-mode design would need more than {SUBSTEP_BUDGET} integration steps per "
               f"sample of {1e3 * dt:g} ms")


def evaluation_plant(model: str = "foam", design_params: Params | None = None, dt: float = 0.01,
                     design_modes: int | None = None, spin: float = 0.0, *,
                     plant_params: Params | None = None, plant_modes: int | None = None) -> EvaluationPlant:
    """Choose the plant a controller is judged on.

    Parameters
    ----------
    model : {"foam", "cfoam"}
        Plant model (default FOAM, which tracks an exact beam closer than CFOAM at large
        deflection).
    design_params : Params, optional
        Parameters of the design model (default Table 1); its ``n_transverse`` is the
        design's mode count unless ``design_modes`` is given.
    dt : float
        Controller sample time [s].
    design_modes : int, optional
        Transverse modes of the design model.
    spin : float
        Design spin rate [rad/s] (for the modal analysis).
    plant_params : Params, optional
        Physical parameters of the plant, when it differs from the design (default: the
        design's). Its ``n_axial`` is kept; its ``n_transverse`` is replaced.
    plant_modes : int, optional
        Transverse modes of the plant, ``design_modes..20`` (default: the rule of
        :func:`default_plant_modes`).

    Returns
    -------
    EvaluationPlant
    """
    if model not in PLANT_MODELS:
        raise ParameterError(f"plant must be one of {', '.join(PLANT_MODELS)}, got {model!r}")
    design_params = design_params if design_params is not None else Params()
    for name, value in (("design_params", design_params), ("plant_params", plant_params)):
        if value is not None and not isinstance(value, Params):
            raise ParameterError(f"{name} must be a Params, got {type(value).__name__}")
    m = design_params.n_transverse if design_modes is None else _check_modes("design_modes", design_modes, 1)
    physical = plant_params if plant_params is not None else design_params
    if plant_modes is None:
        n, reason = default_plant_modes(physical, dt, m, spin)
    else:
        n = _check_modes("plant_modes", plant_modes, m)
        reason = f"{n} transverse modes as requested (design model: {m})"
    return EvaluationPlant(model, physical.replace(n_transverse=n), m, reason)

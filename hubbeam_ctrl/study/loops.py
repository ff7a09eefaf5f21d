"""Loop data and loop figures of the linear controllers (PD, LQR, LQG), for the loop plots.

A linear controller gives its feedback law as matrices
(:meth:`controllers.base.Controller.feedback_matrices`); closed with a sampled linear SFOAM
(:class:`controllers.DesignModel`: the design model itself, or a richer one with the
evaluation plant's modes and parameters, as in :mod:`hubbeam_ctrl.study.spillover`) it
gives the loop broken at the plant input, ``L = -C P``
(:func:`controllers.analysis.loop_matrices`). :func:`loop_response` computes from it the
data :func:`hubbeam_ctrl.plots.loops.plot_loop` draws: frequency response of ``L`` on a
grid dense around every pole (:func:`controllers.analysis.frequency_grid`), closed-loop
responses of the hub angle and the tip deflection to a 1 rad step of the hub-angle reference
and to a 1 N m torque step at the plant input, the closed-loop poles and which of them
belong to modes above the Nyquist frequency (aliased).

Examples
--------
>>> from controllers import DesignModel, PD
>>> lp = loop_response(PD(DesignModel.build(n_modes=2)), t_end=60.0)
>>> round(float(lp.step_theta[-1]), 3)          # a type-1 loop: the hub reaches the reference
1.0
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from controllers import DesignModel
from controllers.analysis import FrequencyResponse, frequency_grid, loop_matrices
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.plant.params import MAX_MODES, Params
from hubbeam_ctrl.plots.loops import LoopResponse, plot_loop, plot_loop_comparison

if TYPE_CHECKING:                  # Matplotlib is imported when a figure is made, not on import
    from matplotlib.figure import Figure

__all__ = ["loop_response", "evaluation_model", "controller_loops", "loop_figure", "comparison_loop_figures",
           "save_comparison_loop_figures", "comparison_loop_figure", "comparison_loop_data",
           "is_linear"]


def is_linear(ctrl) -> bool:
    """Whether ``ctrl`` is a linear time-invariant feedback law (PD, LQR, LQG; not MPC, open loop).

    Parameters
    ----------
    ctrl : Controller
        Any controller.
    """
    try:
        ctrl.feedback_matrices()
    except HubbeamError:
        return False
    return True


def _simulate(A, B, C, n: int) -> np.ndarray:
    """Outputs ``C x[k]`` (rows) for ``k = 0..n-1`` after a unit step of the input at ``k = 0``."""
    x = np.zeros(A.shape[0])
    y = np.empty((C.shape[0], n))
    b = B[:, 0]
    for k in range(n):
        y[:, k] = C @ x
        x = A @ x + b
    return y


def _aliased_hz(plant: DesignModel, poles: np.ndarray) -> np.ndarray:
    """Per closed-loop pole: the true frequency [Hz] of the aliased plant mode it sits at, else NaN.

    A plant mode above the Nyquist frequency ``pi/dt`` is sampled to ``exp(s dt)``, whose
    angle is its frequency folded into ``0..pi/dt``. Feedback hardly moves those modes, so
    each closed-loop pole is matched to the nearest sampled open-loop plant pole.
    """
    s = np.linalg.eigvals(plant.A)
    z_open = np.exp(s * plant.dt)
    out = np.full(len(poles), np.nan)
    high = np.abs(s.imag) > np.pi / plant.dt
    if not np.any(high):
        return out
    for i, p in enumerate(poles):
        j = int(np.argmin(np.abs(z_open - p)))
        if high[j] and abs(z_open[j] - p) < 0.05:
            out[i] = abs(s[j].imag) / (2 * np.pi)
    return out


def loop_response(ctrl, plant: DesignModel | None = None, label: str | None = None, t_end: float = 15.0,
                  n_points: int = 1500) -> LoopResponse:
    """The loop of a linear controller on a sampled linear SFOAM, as data for the loop plots.

    Parameters
    ----------
    ctrl : Controller
        A linear controller (PD, LQR, LQG).
    plant : DesignModel, optional
        The linear plant: same sample time, at least the design model's modes (default: the
        controller's design model; :func:`evaluation_model` for a richer one).
    label : str, optional
        Legend entry (default: ``"design model (N modes)"`` or ``"linear SFOAM, N modes"``).
    t_end : float
        Length of the step and disturbance responses [s], > 0.
    n_points : int
        Points of the logarithmic background frequency grid (dense points are added around
        each pole).

    Returns
    -------
    LoopResponse
        With the balanced disk margin on the grid (0 if the closed loop is unstable).
    """
    if not is_linear(ctrl):
        raise ParameterError(f"ctrl must be a linear controller (PD, LQR, LQG) for the loop plots, got "
                             f"{ctrl.name!r}")
    if not (isinstance(t_end, (int, float)) and 0.0 < t_end <= 3600.0):
        raise ParameterError(f"t_end must be a number of seconds in (0, 3600], got {t_end!r}")
    d = ctrl.design if plant is None else plant
    A, B, C, _ = loop_matrices(ctrl, plant)          # L = -C(zI - A)^-1 B, state [x_plant, x_ctrl]
    dt = ctrl.dt
    Acl = A - B @ C
    poles = np.linalg.eigvals(Acl)
    w = frequency_grid(np.concatenate([np.linalg.eigvals(A), poles]), dt, n_points)
    L = FrequencyResponse(A, B, C)(np.exp(1j * w * dt))
    stable = bool(np.max(np.abs(poles)) < 1.0)
    alpha = float(1.0 / np.max(np.abs(1.0 / (1.0 + L) - 0.5))) if stable else 0.0
    # closed-loop inputs: reference step of theta (enters like the measurement, e = y - r) and torque
    _, Bc, _, Dc, states, inputs = ctrl.feedback_matrices()
    i = list(inputs).index("theta")
    nc = len(states)
    n_p = Acl.shape[0] - nc                          # the plant's states (with the previous command on a rig)
    Bd = B[:n_p]
    B_ref = -np.vstack([Bd @ np.asarray(Dc)[:, [i]], np.asarray(Bc).reshape(nc, len(inputs))[:, [i]]])
    B_dist = np.vstack([Bd, np.zeros((nc, 1))])
    rows = np.zeros((2, n_p))
    rows[0, 0], rows[1, :d.n_x] = 1.0, d.C_tip[0]
    outputs = np.hstack([rows, np.zeros((2, nc))])
    n = int(round(t_end / dt)) + 1
    step = _simulate(Acl, B_ref, outputs, n)
    dist = _simulate(Acl, B_dist, outputs, n)
    if label is None:
        label = f"design model ({d.n_modes} modes)" if plant is None else f"linear SFOAM, {d.n_modes} modes"
    return LoopResponse(label=label, dt=dt, w=w, L=L, t=dt * np.arange(n), step_theta=step[0], step_tip=step[1],
                        dist_theta=dist[0], dist_tip=dist[1], poles=poles, aliased_hz=_aliased_hz(d, poles),
                        disk_margin=alpha)


def evaluation_model(ctrl, params: Params | None = None, modes: int | None = None) -> DesignModel:
    """The sampled linear SFOAM with the evaluation plant's parameters and modes.

    Parameters
    ----------
    ctrl : Controller
        The controller (its design model gives the spin rate and the sample time).
    params : Params, optional
        Physical parameters of the evaluation plant (default: the design model's).
    modes : int, optional
        Transverse modes, the design model's..20 (default: ``params.n_transverse``).

    Returns
    -------
    DesignModel
    """
    design = ctrl.design
    p = design.params if params is None else params
    m = p.n_transverse if modes is None else modes
    if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or not design.n_modes <= m <= MAX_MODES:
        raise ParameterError(f"modes must be an integer in {design.n_modes}..{MAX_MODES}, got {m!r}")
    return DesignModel.build(p, design.spin, design.dt, int(m)).like(design)


def controller_loops(ctrl, evaluation: DesignModel | None = None, t_end: float = 15.0) -> list:
    """The controller's loop on its design model and, if given, on a richer linear model.

    Parameters
    ----------
    ctrl : Controller
        A linear controller.
    evaluation : DesignModel, optional
        The richer linear model (:func:`evaluation_model`).
    t_end : float
        Length of the time responses [s].

    Returns
    -------
    list of LoopResponse
    """
    loops = [loop_response(ctrl, t_end=t_end)]
    if evaluation is not None:
        dp, ep = ctrl.design.params, evaluation.params
        same = {k: v for k, v in ep.to_dict().items() if k != "n_transverse"} == \
            {k: v for k, v in dp.to_dict().items() if k != "n_transverse"}
        label = (f"evaluation: linear SFOAM, {evaluation.n_modes} modes"
                 + ("" if same else ", plant parameters")
                 + (f", damping ratio {ep.damping_ratio:g}" if ep.damping_ratio else ", undamped"))
        loops.append(loop_response(ctrl, evaluation, label=label, t_end=t_end))
    return loops


def loop_figure(ctrl, evaluation: DesignModel | None = None, title: str | None = None,
                t_end: float = 15.0, fig: Figure | None = None) -> Figure:
    """The loop plots of one linear controller (see :func:`hubbeam_ctrl.plots.loops.plot_loop`).

    Parameters
    ----------
    ctrl : Controller
        A linear controller.
    evaluation : DesignModel, optional
        A richer linear model drawn over the design model (:func:`evaluation_model`).
    title : str, optional
        Figure title (default: the controller's name, spin and sample time).
    t_end : float
        Length of the time responses [s].
    fig : Figure, optional
        A loop figure drawn before, to draw into again (see :func:`~hubbeam_ctrl.plots.loops.plot_loop`).

    Returns
    -------
    Figure
    """
    d = ctrl.design
    title = title or (f"{ctrl.name}: loop at the plant input (SFOAM at {d.spin:g} rad/s, "
                      f"dt = {1e3 * d.dt:g} ms)")
    return plot_loop(controller_loops(ctrl, evaluation, t_end=t_end), title, fig=fig)


def comparison_loop_figures(comparison, t_end: float = 15.0) -> dict:
    """One loop figure per linear controller of a comparison (design and evaluation modes).

    Parameters
    ----------
    comparison : Comparison
        From :func:`hubbeam_ctrl.study.compare.compare` (its ``controllers``).
    t_end : float
        Length of the time responses [s].

    Returns
    -------
    dict
        Controller name -> Figure (empty when the comparison has no linear controller).
    """
    return {name: loop_figure(ctrl, evaluation, title=title, t_end=t_end)
            for name, ctrl, evaluation, title in _comparison_loops(comparison)}


def save_comparison_loop_figures(comparison, save, t_end: float = 15.0) -> list:
    """The figures of :func:`comparison_loop_figures`, each handed to ``save`` as soon as it is
    drawn, all in one reused figure (the report's way: the panels and their ticks are made once;
    the images are those of separate figures, pixel for pixel).

    Parameters
    ----------
    comparison : Comparison
        From :func:`hubbeam_ctrl.study.compare.compare`.
    save : callable
        ``save(name, fig)``, called once per linear controller, in order; ``fig`` is redrawn by
        the next call, so write it (e.g. :func:`hubbeam_ctrl.plots.plant.save_figure`) there.
    t_end : float
        Length of the time responses [s].

    Returns
    -------
    list of str
        The controllers drawn, in order.
    """
    fig, names = None, []
    for name, ctrl, evaluation, title in _comparison_loops(comparison):
        fig = loop_figure(ctrl, evaluation, title=title, t_end=t_end, fig=fig)
        save(name, fig)
        names.append(name)
    return names


def comparison_loop_figure(comparison, t_end: float = 15.0) -> Figure | None:
    """Every linear controller of a comparison in one loop figure, overlaid (the report's).

    Each controller's loop is closed on the evaluation plant's linear SFOAM (all of its modes,
    :func:`evaluation_model`; the design model when the comparison has no evaluation plant or
    fewer modes than the design), the loop the linear certificate of the verdict judges; the
    margins table of the report is the design model's. Colours and labels are the
    controllers' registered styles. :func:`comparison_loop_figures` gives one full figure
    per controller (design and evaluation model, phase, ``|T|``, hub angle).

    Parameters
    ----------
    comparison : Comparison
        From :func:`hubbeam_ctrl.study.compare.compare`.
    t_end : float
        Length of the time responses [s].

    Returns
    -------
    Figure or None
        :func:`hubbeam_ctrl.plots.loops.plot_loop_comparison`; None when the comparison has no
        linear controller.
    """
    data = comparison_loop_data(comparison, t_end)
    return None if data is None else plot_loop_comparison(data[0], data[1], colors=data[2])


def comparison_loop_data(comparison, t_end: float = 15.0):
    """The data of :func:`comparison_loop_figure`: each linear controller's loop, the title, the colours.

    Parameters
    ----------
    comparison : Comparison
    t_end : float
        Length of the time responses [s].

    Returns
    -------
    tuple or None
        ``(loops, title, colors)``: :class:`~hubbeam_ctrl.plots.loops.LoopResponse` list, str and
        colour list, the arguments of :func:`~hubbeam_ctrl.plots.loops.plot_loop_comparison`; None
        when the comparison has no linear controller.
    """
    styles = getattr(comparison, "styles", None) or {}
    loops, colors, on = [], [], set()
    for i, (name, ctrl, evaluation, _) in enumerate(_comparison_loops(comparison)):
        label = styles.get(name, {}).get("label") or name
        loops.append(loop_response(ctrl, evaluation, label=label, t_end=t_end))
        colors.append(styles.get(name, {}).get("color") or f"C{i}")
        on.add("design model" if evaluation is None else f"linear SFOAM with the evaluation plant's "
               f"{evaluation.n_modes} modes")
    if not loops:
        return None
    sc, d = comparison.scenario, loops[0]
    title = (f"Loops at the plant input, {sc.name}: each controller on the " + " / ".join(sorted(on))
             + f" (dt = {1e3 * d.dt:g} ms)")
    return loops, title, colors


def _comparison_loops(comparison):
    """``(name, controller, evaluation model or None, title)`` of each linear controller."""
    ctrls = {n: c for n, c in getattr(comparison, "controllers", {}).items() if is_linear(c)}
    ev = comparison.plant
    models = {}
    for name, ctrl in ctrls.items():
        evaluation = None
        if ev is not None and ev.modes >= ctrl.design.n_modes:
            key = (ctrl.design.spin, ctrl.design.dt)
            if key not in models:
                models[key] = evaluation_model(ctrl, ev.params, ev.modes)
            evaluation = models[key]
        yield name, ctrl, evaluation, (f"{name}: loop at the plant input, {comparison.scenario.name} (design SFOAM at "
                                       f"{ctrl.design.spin:g} rad/s, dt = {1e3 * ctrl.dt:g} ms)")

"""Linear controllers as systems, and their loop margins at the plant input.

Every linear controller (PD, LQR, LQG) gives its feedback law as a sampled python-control
system with named signals, :meth:`controllers.base.Controller.to_statespace` (input: what it
measures, output ``tau``). This module closes it with the design model it was made for and
measures the loop broken at the plant input (the hub torque), where model error and actuator
delay enter:

* :func:`design_plant`: the sampled design model with the outputs the controller reads;
* :func:`loop_transfer`: the return ratio ``L = -C P`` (SISO, from torque to torque);
* :func:`closed_loop_poles`: the poles of the closed loop (z-plane);
* :func:`loop_margins`: balanced disk margin, gain and phase margins and the delay margin.

Why not ``control.stability_margins``: the beam's modes are lightly damped (undamped in the
design model), so the loop's frequency response has many sharp gain and phase crossings
between the points of a generic grid. Here the grid is dense around every pole of the loop
and of the closed loop, each crossing is solved for by root finding on the exact frequency
response, and the disk margin's sensitivity peak is refined by a local search. The disk
margin is checked against python-control's :func:`control.disk_margins` on the same grid.

Disk margin (balanced, skew 0): ``alpha = 1 / max_w |S - 1/2|`` with ``S = 1 / (1 + L)``;
the loop stays stable for every simultaneous gain and phase change in the disk, i.e. any
gain in ``[(1 - alpha/2)/(1 + alpha/2), (1 + alpha/2)/(1 - alpha/2)]`` or any phase change up
to ``2 atan(alpha/2)``.

Examples
--------
>>> from controllers import DesignModel, LQR
>>> m = loop_margins(LQR(DesignModel.build(n_modes=2)), check=True)
>>> m.stable, bool(m.disk_margin > 0.5), bool(abs(m.disk_margin / m.disk_margin_control - 1) < 1e-6)
(True, True, True)
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError

from .base import DesignModel
from .frequency import FrequencyResponse, frequency_grid
from .loop_plant import _SENSOR_ROWS, _measurement_matrix, hardware_plant, rig_plant, sampled_rig_plant

__all__ = ["LoopMargins", "FrequencyResponse", "design_plant", "loop_transfer", "loop_matrices", "closed_loop_poles",
           "loop_margins", "margins_of_loop", "grid_disk_margin", "frequency_grid", "hardware_plant", "rig_plant",
           "sampled_rig_plant"]

def design_plant(ctrl):
    """The controller's sampled design model with the outputs the controller reads.

    Parameters
    ----------
    ctrl : Controller
        A linear controller (PD, LQR, LQG).

    Returns
    -------
    control.StateSpace
        Input ``tau`` [N m]; outputs named like the controller's inputs; sample time
        ``ctrl.dt``.
    """
    import control
    d = ctrl.design
    names = list(ctrl.to_statespace().input_labels)
    return control.ss(d.Ad, d.Bd, _measurement_matrix(d, names), np.zeros((len(names), 1)), d.dt,
                      states=list(d.state_names), inputs=["tau"], outputs=names,
                      name=f"{ctrl.name}_design_plant")


def _feedback_arrays(ctrl) -> tuple:
    """``(Ac, Bc, Cc, Dc, inputs)`` of the controller's feedback law as 2-D float arrays, the
    matrices ``ctrl.to_statespace()`` holds, without building the python-control system
    (whose import costs more than the analysis)."""
    Ac, Bc, Cc, Dc, states, inputs = ctrl.feedback_matrices()
    nc, ni = len(states), len(inputs)
    return (np.asarray(Ac, dtype=float).reshape(nc, nc), np.asarray(Bc, dtype=float).reshape(nc, ni),
            np.asarray(Cc, dtype=float).reshape(1, nc), np.asarray(Dc, dtype=float).reshape(1, ni), list(inputs))


def loop_matrices(ctrl, plant=None):
    """State-space matrices ``(A, B, C, D)`` of the return ratio at the plant input.

    ``L = -C(z) P(z)``: plant ``P`` (input tau, outputs the controller's inputs) followed
    by the controller ``C`` and a sign change, so that the loop is ``u = -L u`` (negative
    feedback). State ``[x_plant, x_controller]``.

    Parameters
    ----------
    ctrl : Controller
        A linear controller.
    plant : DesignModel, optional
        The linear plant, with the design model's sample time and at least its modes
        (e.g. another payload, or residual modes); default the controller's design model.
        A plant with fewer modes than a gain with residual modes reads
        (``ctrl.state_modes``) is rebuilt with them (same parameters, spin and sample time).

    Returns
    -------
    tuple of ndarray
    """
    Ac, Bc, Cc, Dc, input_labels = _feedback_arrays(ctrl)
    d = ctrl.design if plant is None else plant
    needed = int(getattr(ctrl, "state_modes", 0) or 0)
    if plant is not None and d.n_modes < needed and d.dt == ctrl.design.dt:
        # a gain on the residual modes (residual_control) reads them: the same plant with them
        d = DesignModel.build(d.params, d.spin, d.dt, needed).like(d)
    hw = getattr(ctrl, "rig_hardware", None)
    if d.sensors is not None or d.delay > 0 or hw is not None:
        Ad, Bd, Cm = rig_plant(d, input_labels, hw, getattr(ctrl, "command", "torque"))
        n, nc = Ad.shape[0], Ac.shape[0]
        A = np.block([[Ad, np.zeros((n, nc))], [Bc @ Cm, Ac]])
        B = np.vstack([Bd, np.zeros((nc, 1))])
        C = -np.hstack([Dc @ Cm, Cc])
        return A, B, C, np.zeros((1, 1))
    missing = [n for n in input_labels if n not in _SENSOR_ROWS and n not in d.state_names]
    if d.dt != ctrl.design.dt or missing:
        raise ParameterError(f"plant must have dt = {ctrl.design.dt:g} s and the signals the controller reads "
                             f"(at least the design model's modes), got dt = {d.dt:g} s and {d.n_modes} modes")
    Cm = _measurement_matrix(d, input_labels)
    n, nc = d.n_x, Ac.shape[0]
    A = np.block([[d.Ad, np.zeros((n, nc))], [Bc @ Cm, Ac]])
    B = np.vstack([d.Bd, np.zeros((nc, 1))])
    C = -np.hstack([Dc @ Cm, Cc])
    return A, B, C, np.zeros((1, 1))


def loop_transfer(ctrl):
    """The return ratio at the plant input ``L = -C P`` as a python-control system.

    Parameters
    ----------
    ctrl : Controller
        A linear controller.

    Returns
    -------
    control.StateSpace
        SISO, input ``tau`` and output ``tau_loop`` [N m], sample time ``ctrl.dt``.
    """
    import control
    return control.ss(*loop_matrices(ctrl), ctrl.dt, inputs=["tau"], outputs=["tau_loop"],
                      name=f"{ctrl.name}_loop")


def closed_loop_poles(ctrl, plant=None) -> np.ndarray:
    """Poles (z-plane) of the controller closed with its design model (or ``plant``).

    Parameters
    ----------
    ctrl : Controller
        A linear controller.
    plant : DesignModel, optional
        A linear plant with the design model's sample time and at least its modes
        (default: the design model).

    Returns
    -------
    ndarray of complex
    """
    A, B, C, _ = loop_matrices(ctrl, plant)
    return np.linalg.eigvals(A - B @ C)


@dataclass(frozen=True)
class LoopMargins:
    """Stability margins of a loop broken at the plant input (see :func:`loop_margins`).

    Attributes
    ----------
    controller : str
        Name of the controller whose loop this is.
    stable : bool
        The closed loop on the design model is stable (every pole inside the unit circle).
    spectral_radius : float
        Largest closed-loop pole magnitude [-].
    disk_margin : float
        Balanced disk margin alpha [-] (0 if unstable).
    disk_margin_frequency_rad_s : float
        Where ``|S - 1/2|`` peaks [rad/s].
    disk_margin_grid : float
        ``1 / max |S - 1/2|`` over the grid points alone, before the peak is refined
        (``>= disk_margin``).
    disk_margin_control : float or None
        python-control's :func:`control.disk_margins` on the same grid (None unless asked for,
        absent or unstable); agrees with ``disk_margin_grid``.
    disk_gain_margin : tuple of float
        Gains ``(low, high)`` [-] the loop tolerates under the disk model.
    disk_phase_margin_deg : float
        Phase change [deg] tolerated under the disk model.
    gain_margin_upper : float
        Smallest gain factor > 1 that destabilises the loop [-] (inf: none).
    gain_margin_lower : float
        Largest gain factor < 1 that destabilises the loop [-] (0: none).
    phase_margin_deg : float
        Smallest phase margin over the gain crossovers [deg] (inf: no crossover).
    crossover_rad_s : float
        Gain crossover of that phase margin [rad/s].
    delay_margin_s : float
        Smallest delay at the plant input that destabilises the loop [s] (inf: none).
    delay_margin_samples : float
        The same in samples [-].
    n_frequencies : int
        Points of the frequency grid.
    """

    controller: str
    stable: bool
    spectral_radius: float
    disk_margin: float
    disk_margin_frequency_rad_s: float
    disk_margin_grid: float
    disk_margin_control: float | None
    disk_gain_margin: tuple
    disk_phase_margin_deg: float
    gain_margin_upper: float
    gain_margin_lower: float
    phase_margin_deg: float
    crossover_rad_s: float
    delay_margin_s: float
    delay_margin_samples: float
    n_frequencies: int

    def to_dict(self) -> dict:
        """Plain dictionary (units in the key names where they have one)."""
        out = asdict(self)
        out["disk_gain_margin"] = list(self.disk_gain_margin)
        return out


def _roots(f, w, values) -> list:
    """Roots of ``f`` between the grid points where ``f`` changes sign (Brent's method).

    ``values`` (``f`` on the grid, possibly less accurate near the roots) says where to look:
    ``f`` itself is evaluated at the ends of every interval where they change sign and of its
    two neighbours, and the intervals where ``f`` changes sign are solved.
    """
    from scipy.optimize import brentq  # here: 0.2 s of import that hubbeam compare makes while its runs go
    idx = np.nonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0)[0]
    near = np.unique(np.clip(np.concatenate([idx - 1, idx, idx + 1]), 0, len(w) - 2))
    at = {int(i): f(w[i]) for i in np.unique(np.concatenate([near, near + 1]))}
    return [brentq(f, w[i], w[i + 1], xtol=1e-14 * w[i + 1], rtol=1e-14) for i in near
            if np.sign(at[int(i)]) * np.sign(at[int(i) + 1]) < 0]


def _disk_peak(S_half, w, values):
    """``(max |S - 1/2|, frequency)``, the grid's few highest local maxima refined (``values``:
    ``S_half`` on the grid ``w``, possibly less accurate; the result is ``S_half``'s)."""
    from scipy.optimize import minimize_scalar  # as in _roots
    i_best = int(np.argmax(values))
    best, w_best = S_half(w[i_best]), w[i_best]
    local = np.nonzero((values[1:-1] >= values[:-2]) & (values[1:-1] >= values[2:]))[0] + 1
    for i in local[np.argsort(values[local])[-5:]]:
        r = minimize_scalar(lambda x: -S_half(x), bounds=(w[i - 1], w[i + 1]), method="bounded",
                            options={"xatol": 1e-12 * w[i]})
        if -r.fun > best:
            best, w_best = -r.fun, r.x
    return best, w_best


def _disk_margin_control(A, B, C, D, dt, w) -> float | None:
    import control
    if not hasattr(control, "disk_margins"):
        return None
    return float(control.disk_margins(control.ss(A, B, C, D, dt), w, skew=0.0)[0])


def loop_margins(ctrl, n_points: int = 3000, plant=None, check: bool = False) -> LoopMargins:
    """Disk, gain, phase and delay margins at the plant input on the design model.

    Parameters
    ----------
    ctrl : Controller
        A linear controller (PD, LQR, LQG; :meth:`~controllers.base.Controller.to_statespace`).
    n_points : int
        Points of the logarithmic background grid (the grid adds points around each pole).
    plant : DesignModel, optional
        A linear plant with the design model's states (e.g. another payload); default the
        design model.
    check : bool
        Also compute python-control's :func:`control.disk_margins` on the same grid
        (``disk_margin_control``; a cross-check that costs another full frequency response,
        about 1-2 s on a 50-state loop); False: None there.

    Returns
    -------
    LoopMargins
    """
    return margins_of_loop(*loop_matrices(ctrl, plant), ctrl.dt, ctrl.name, n_points, check)


def grid_disk_margin(ctrl, n_points: int = 500) -> float:
    """The disk margin at the plant input on the design model, on the frequency grid alone: the
    :attr:`LoopMargins.disk_margin_grid` of :func:`loop_margins` without its refinement, gain, phase
    and delay margins (a cheap comparison of two designs of one loop).

    Parameters
    ----------
    ctrl : Controller
        A linear controller (:meth:`~controllers.base.Controller.feedback_matrices`).
    n_points : int
        Points of the logarithmic background grid (the grid adds points around each pole).

    Returns
    -------
    float
        ``1 / max |S - 1/2|`` over the grid [-]; 0 when the loop is not stable.
    """
    A, B, C, D = loop_matrices(ctrl)
    cl = np.linalg.eigvals(A - B @ C)
    if float(np.max(np.abs(cl))) >= 1.0:
        return 0.0
    w = frequency_grid(np.concatenate([np.linalg.eigvals(A), cl]), ctrl.dt, n_points)
    Lw = FrequencyResponse(A, B, C, D)(np.exp(1j * w * ctrl.dt))
    return float(1.0 / np.max(np.abs(1.0 / (1.0 + Lw) - 0.5)))


def margins_of_loop(A, B, C, D, dt: float, name: str = "", n_points: int = 3000, check: bool = False) -> LoopMargins:
    """Disk, gain, phase and delay margins of a sampled SISO loop ``L = C (zI - A)^-1 B + D``
    closed by ``u = -L u`` (:func:`loop_margins` on any loop, e.g. a plant of an uncertainty set).

    Parameters
    ----------
    A, B, C, D : ndarray
        The broken loop (as :func:`loop_matrices` gives it).
    dt : float
        Sample time [s].
    name : str
        The controller's name (kept in the result).
    n_points, check
        As :func:`loop_margins`.

    Returns
    -------
    LoopMargins
    """
    cl = np.linalg.eigvals(A - B @ C)
    rho = float(np.max(np.abs(cl)))
    w = frequency_grid(np.concatenate([np.linalg.eigvals(A), cl]), dt, n_points)
    response = FrequencyResponse(A, B, C, D)
    Lw = response(np.exp(1j * w * dt))                        # brackets and candidates
    L_at = lambda x: response(np.exp(1j * x * dt), precise=True)[0]      # roots and peaks
    S_half = lambda x: abs(1.0 / (1.0 + L_at(x)) - 0.5)
    on_grid = np.abs(1.0 / (1.0 + Lw) - 0.5)
    peak, w_peak = _disk_peak(S_half, w, on_grid)
    alpha = 1.0 / peak if rho < 1.0 else 0.0
    a = alpha / 2
    disk_gm = (max(0.0, (1 - a) / (1 + a)), (1 + a) / (1 - a) if a < 1 else math.inf)
    # gain crossovers: phase and delay margins
    pm, w_c, delay = math.inf, math.nan, math.inf
    for wc in _roots(lambda x: math.log(abs(L_at(x))), w, np.log(np.abs(Lw))):
        lag = (np.angle(L_at(wc)) + math.pi) % (2 * math.pi)     # phase left before -180 deg
        margin = math.degrees(lag if lag <= math.pi else lag - 2 * math.pi)
        delay = min(delay, lag / wc)
        if abs(margin) < abs(pm):
            pm, w_c = margin, wc
    # phase crossovers (L real and negative): gain margins
    gains = []
    for wp in _roots(lambda x: L_at(x).imag, w, Lw.imag):
        Lp = L_at(wp)
        if Lp.real < 0 and abs(Lp.imag) <= 1e-6 * abs(Lp) and abs(Lp) < 1e9:   # not at a pole
            gains.append(1.0 / abs(Lp))
    L_nyq = L_at(math.pi / dt)
    if L_nyq.real < 0:
        gains.append(1.0 / abs(L_nyq))
    upper = min([g for g in gains if g > 1.0], default=math.inf)
    lower = max([g for g in gains if g < 1.0], default=0.0)
    if rho >= 1.0:
        pm, delay, upper, lower = 0.0, 0.0, math.nan, math.nan
    return LoopMargins(
        controller=name, stable=rho < 1.0, spectral_radius=rho, disk_margin=float(alpha),
        disk_margin_frequency_rad_s=float(w_peak), disk_margin_grid=float(1.0 / np.max(on_grid)),
        disk_margin_control=_disk_margin_control(A, B, C, D, dt, w) if rho < 1.0 and check else None,
        disk_gain_margin=disk_gm, disk_phase_margin_deg=math.degrees(2 * math.atan(a)),
        gain_margin_upper=float(upper), gain_margin_lower=float(lower), phase_margin_deg=float(pm),
        crossover_rad_s=float(w_c), delay_margin_s=float(delay), delay_margin_samples=float(delay / dt),
        n_frequencies=len(w))

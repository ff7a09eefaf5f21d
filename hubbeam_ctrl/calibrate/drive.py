"""What voltage-in records determine of a DC-motor drive (issue 38, item 5).

The drive's hub torque (:func:`~hubbeam_ctrl.sim.hardware.drive_torque`) is
``e N k_t i`` with ``i = clip((V - k_e N thd) / R, +-I_max)`` and the gear factor ``e``
(``eta_forward`` motoring, ``1 / eta_backward`` back-driven). While the current stays below
``I_max`` and the armature's time constant ``L / R`` is far below a sample, the torque is
``e (N k_t / R) (V - k_e N thd)``: the torque constant and the resistance enter only as their
ratio ``k_t / R``, whatever the records. A fit of both is then singular (its Jacobian has a
null direction ``d log k_t = d log R``: singular value 1.8e-7 against 1.1e5 for the servo
link's ``hubbeam excite`` chirp and PRBS, in units of the sensors' noise,
``benchmarks/bench_calibrate.py --fisher``), so
:func:`drive_plan` fixes ``motor.R`` at the given rig's value (its data sheet), fits
``motor.k_t`` in its place and reports what the records did determine: ``motor.k_t /
motor.R``. The back-EMF constant ``k_e`` and the viscous friction ``c_v`` stay fitted: with a
gear whose efficiency differs between driving and back-driven (``eta_forward !=
1 / eta_backward``) the back-EMF damping ``e N^2 k_t k_e / R`` switches with the power's sign
and ``c_v`` does not, which separates them, weakly (the servo link's 0.9 / 0.69 gear: singular
value 65, a 95 % Cramer-Rao half-width of 3 % on ``c_v``, and the estimate rests on the data
sheet's efficiencies); with an ideal gear they enter only as the hub's
linear damping ``N^2 k_t k_e / R + c_v`` and ``friction.viscous`` is fixed at its given value
the same way.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hubbeam_ctrl.plant.rig import Rig

__all__ = ["DrivePlan", "drive_plan", "peak_current"]

#: The armature's time constant ``L / R`` separates ``k_t`` from ``R`` only above this fraction of a sample.
INDUCTANCE_FRACTION = 0.1
#: The current limit separates ``k_t`` from ``R`` only when the records' peak current reaches this fraction of it.
CURRENT_FRACTION = 0.95


@dataclass
class DrivePlan:
    """The drive fields a fit keeps, those it fixes and why, and the combinations it determines.

    Attributes
    ----------
    fixed : dict
        Field path -> ``{"value", "unit", "reason"}``: fields asked for but fixed at the given
        rig's value because the records cannot separate them.
    combinations : dict
        Name (``"motor.k_t / motor.R"``) -> ``{"unit", "meaning"}``; :meth:`evaluate` adds the
        calibrated rig's value.
    peak_current : float
        The records' largest armature current with the given rig [A] (NaN without a DC motor).
    values : dict
        After :meth:`evaluate`: name -> the combination's value and 95 % half-width.
    """

    fixed: dict = field(default_factory=dict)
    combinations: dict = field(default_factory=dict)
    peak_current: float = float("nan")
    values: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-ready."""
        return {"fixed": self.fixed, "combinations": self.values or self.combinations,
                "peak_current_A": self.peak_current if np.isfinite(self.peak_current) else None}

    def lines(self) -> list:
        """Report lines: each fixed field and why, each determined combination."""
        out = [f"fixed {k} = {v['value']:.6g} {v['unit']}: {v['reason']}" for k, v in self.fixed.items()]
        out += [f"determined {k} = {v['value']:.6g} +- {v['ci95_half_width']:.3g} (95 %) {v['unit']}"
                for k, v in self.values.items()]
        return out

    def evaluate(self, rig: Rig, estimate: dict, std: dict) -> dict:
        """The combinations' values on the calibrated rig, with a 95 % half-width from the fitted
        field's (the fixed one is exact).

        Parameters
        ----------
        rig : Rig
            The calibrated rig.
        estimate, std : dict
            Fitted field path -> estimate and standard deviation [its unit].

        Returns
        -------
        dict
            Name -> ``{"value", "ci95_half_width", "unit", "meaning"}``.
        """
        out = {}
        d = rig.drive
        for name, info in self.combinations.items():
            if name == "motor.k_t / motor.R":
                value, rel = d.k_t / d.R, std.get("motor.k_t", np.nan) / estimate.get("motor.k_t", np.nan)
            else:
                continue
            out[name] = {"value": float(value), "ci95_half_width": float(1.96 * abs(rel) * value), **info}
        self.values = out
        return out


def peak_current(rig: Rig, records) -> float:
    """The largest armature current of the records with the rig's drive [A], before the limit.

    ``|V - k_e N thd| / R`` at each sample, the hub rate ``thd`` from the record's encoder
    angle by central differences over 10 ms (an encoder count over one sample would be a
    rate spike); without an angle, ``|V| / R``.

    Parameters
    ----------
    rig : Rig
    records : sequence of Record

    Returns
    -------
    float
    """
    d = rig.drive
    if d.is_ideal:
        return float("nan")
    peak = 0.0
    for r in records:
        V = np.clip(r.input, -d.V_max, d.V_max)
        thd = np.zeros_like(V)
        if "theta" in r.columns and len(r.t) > 2:
            w = int(min(max(1, round(0.01 / r.dt)), (len(r.t) - 1) // 2))
            th = np.pad(r.columns["theta"], w, mode="edge")
            thd = (th[2 * w:] - th[:-2 * w]) / (2 * w * r.dt)
        peak = max(peak, float(np.max(np.abs(V - d.k_e * d.N * thd) / d.R)))
    return peak


def drive_plan(rig: Rig, records, fit_fields) -> tuple:
    """The fitted fields without those the records cannot separate, and the :class:`DrivePlan`.

    See the module docstring: with ``motor.k_t`` and ``motor.R`` both fitted, a resistive
    drive (``L / R`` below :data:`INDUCTANCE_FRACTION` of a sample) whose records stay below
    :data:`CURRENT_FRACTION` of ``I_max`` keeps ``motor.k_t`` and fixes ``motor.R``; with an
    ideal gear (``eta_forward = 1 / eta_backward``, i.e. both 1) and ``motor.k_e`` and
    ``friction.viscous`` both fitted, ``friction.viscous`` is fixed.

    Parameters
    ----------
    rig : Rig
        The start (its values are the data sheet's).
    records : sequence of Record
        Uniform in time.
    fit_fields : sequence of FitField

    Returns
    -------
    (list of FitField, DrivePlan)
    """
    plan = DrivePlan()
    d = rig.drive
    if d.is_ideal:
        return list(fit_fields), plan
    paths = {f.path: f for f in fit_fields}
    plan.peak_current = peak_current(rig, records)
    dt = min(r.dt for r in records)
    if "motor.k_t" in paths and "motor.R" in paths:
        tau_l = d.L / d.R
        if plan.peak_current < CURRENT_FRACTION * d.I_max and tau_l < INDUCTANCE_FRACTION * dt:
            plan.fixed["motor.R"] = {
                "value": float(d.R), "unit": paths["motor.R"].unit,
                "reason": (f"motor.k_t and motor.R enter the drive only as k_t / R while the current stays below "
                           f"I_max ({plan.peak_current:.3g} A at most in these records, I_max {d.I_max:g} A) and "
                           f"L / R ({tau_l:.3g} s) is below {INDUCTANCE_FRACTION:g} of a sample ({dt:g} s): motor.R "
                           f"is fixed at the given {d.R:g} ohm (data sheet) and motor.k_t fitted with it")}
    if "motor.k_t" in paths or "motor.R" in paths:
        plan.combinations["motor.k_t / motor.R"] = {
            "unit": "A^-1 ohm^-1 N m", "meaning": "the drive's torque per volt is eta N k_t / R: what the records "
                                                  "determine of k_t and R"}
    if "motor.k_e" in paths and "friction.viscous" in paths and abs(d.eta_forward * d.eta_backward - 1.0) < 1e-9:
        plan.fixed["friction.viscous"] = {
            "value": float(rig.friction.viscous), "unit": paths["friction.viscous"].unit,
            "reason": ("with an ideal gear (eta_forward = 1 / eta_backward) motor.k_e and friction.viscous enter only "
                       "as the hub's linear damping N^2 k_t k_e / R + c_v: friction.viscous is fixed at the given "
                       f"{rig.friction.viscous:g} N m s/rad")}
    return [f for f in fit_fields if f.path not in plan.fixed], plan

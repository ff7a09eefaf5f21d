"""The NMPC's real-time iteration as C: CasADi's code generation of :attr:`controllers.NMPC.step_function`.

The step (:func:`controllers.nmpc_rti.rti_step_function`: the shooting map and its Jacobians over
the horizon, the condensed QP and its active-set solver, the new plan) is one CasADi function; its
generated C needs no CasADi at run time and is the very function the Python NMPC calls, so the two
agree to rounding (the software-in-the-loop check runs a
whole slew with each, ``tests/test_nmpc_codegen.py``). The caller keeps the plan between samples
(shift by one), the reference window and the saturation, as :meth:`controllers.NMPC.__call__`
does; ``<name>.json`` gives the sizes, weights and limits it needs. With the default QP solver,
DAQP (``NMPCSettings.qp_solver``), the C calls DAQP's library: link the static library that comes
with CasADi's wheel (``<name>.json``, ``"build"``, gives the command on this machine) or build DAQP
(MIT licence, github.com/darnstrom/daqp) for the target.
"""

from __future__ import annotations

import json

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write_text

__all__ = ["nmpc_to_c"]


def nmpc_to_c(controller, out_dir, name: str = "nmpc_rti", *, force: bool = False) -> dict:
    """Write the NMPC's step as C: ``<name>.c``, ``<name>.h`` and ``<name>.json``.

    Parameters
    ----------
    controller : controllers.NMPC
        A built NMPC (any backend: the C is generated from the step's CasADi expression).
    out_dir : str or Path
        The folder (created if missing; its parent must exist).
    name : str
        The C function's name (a C identifier).
    force : bool
        Write into a folder that is not empty.

    Returns
    -------
    dict
        What ``<name>.json`` holds: the function's inputs and outputs with their shapes, the
        horizon, the sample time [s], the command limit [N m], the stage and terminal weights.
    """
    from controllers import NMPC
    from controllers.nmpc import QP_RESIDUAL_TOL
    if not isinstance(controller, NMPC):
        raise ParameterError(f"controller must be an NMPC, got {type(controller).__name__}")
    if not (isinstance(name, str) and name.isidentifier() and len(name) <= 31):
        raise ParameterError(f"name must be a C identifier of at most 31 characters, got {name!r}")
    from .codegen import _check_out
    out = _check_out(out_dir, force)
    out.mkdir(exist_ok=True)
    step = controller.symbolic_step
    args = step.mx_in()
    fn = ca.Function(name, args, step.call(args), step.name_in(), step.name_out())
    gen = ca.CodeGenerator(f"{name}.c", {"with_header": True})
    gen.add(fn)
    gen.generate(str(out) + "/")
    drive = controller.drive
    unit = "N m" if drive is None else "V"
    states = [controller.design.state_names[i] for i in controller.prediction_states]
    info = {"function": name, "horizon": controller.settings.horizon, "dt_s": controller.dt,
            "tau_max_nm": controller.tau_max,
            "command": {"name": "tau" if drive is None else "voltage", "unit": unit, "limit": controller.u_max},
            "states": states,
            "inputs": {fn.name_in(i): list(fn.size_in(i)) for i in range(fn.n_in())},
            "outputs": {fn.name_out(i): list(fn.size_out(i)) for i in range(fn.n_out())},
            "Q": np.asarray(controller._W[0]).tolist(), "P": np.asarray(controller._W[-1]).tolist(),
            "call": "X_next, U_next = f(x, X, U, XR, UR, Q, P): x the measured prediction state, (X, U) "
                    "the previous plan shifted by one sample, (XR, UR) the reference window; the command "
                    "is U_next[0] (plus the residual-mode gain of the Python NMPC), saturated"}
    if drive is not None:
        d = drive.hardware.drive
        info["drive"] = {"V_max_v": d.V_max, "I_max_a": d.I_max, "R_ohm": d.R, "emf_v_s_per_rad": drive.emf,
                         "delay_samples": drive.delay, "viscous_nm_s_per_rad": drive.hardware.friction.viscous,
                         "coulomb": "not in the prediction (the rig's filter estimates it as a disturbance)"}
        info["call"] += ("; with a delay the last input u_prev is the command in flight, the volts applied at "
                         "the previous sample; the command is also kept within k_e N theta_dot +- R I_max")
    info["qp_solver"] = controller.settings.qp_solver
    info["build"] = _build_line(name, (out / f"{name}.c").read_text())
    info["call"] += ("; qp_residual: the QP's optimality residual [command unit]: above "
                     f"{QP_RESIDUAL_TOL:g} x the limit, keep the previous plan shifted instead")
    header = out / f"{name}.h"
    header.write_text(_units_comment(info) + header.read_text())
    atomic_write_text(out / f"{name}.json", json.dumps(info, indent=1) + "\n")
    return info


def _build_line(name: str, source: str) -> str:
    """A compiler command that builds ``<name>.c`` into an object file on this machine, with the QP
    solver's header and library from CasADi's installation."""
    from hubbeam_ctrl.core.linked_solvers import LinkError, solver_link_flags
    try:
        cflags, libs = solver_link_flags(source)
    except LinkError as exc:
        return f"cc -O2 -c {name}.c ({exc})"
    return " ".join(["cc", "-O2", *cflags, "-c", f"{name}.c", "&&", "link", f"{name}.o", *libs, "-lm"])


def _units_comment(info: dict) -> str:
    """The C comment at the top of the header: the call, the command's unit and the limits."""
    c = info["command"]
    lines = [f"NMPC real-time iteration step {info['function']}: horizon {info['horizon']} samples of "
             f"{info['dt_s']:g} s.",
             f"Command U_next[0]: {c['name']} [{c['unit']}], |u| <= {c['limit']:g} {c['unit']}.",
             "Prediction states x: " + ", ".join(info["states"])
             + " (theta [rad], q2 modal [m], their rates [rad/s, m/s])"
             + ("; u_prev: the command in flight [V]." if "u_prev" in info["inputs"] else ".")]
    if "drive" in info:
        d = info["drive"]
        lines.append(f"DC drive in the prediction: |i| <= {d['I_max_a']:g} A, i.e. "
                     f"|V - {d['emf_v_s_per_rad']:.6g} theta_dot| <= {d['R_ohm'] * d['I_max_a']:g} V; "
                     f"delay {d['delay_samples']:g} sample; viscous {d['viscous_nm_s_per_rad']:g} N m s/rad; "
                     "Coulomb friction not in it.")
    lines.append(f"QP solver: {info['qp_solver']}; build: {info['build']}")
    return "/*\n" + "".join(f" * {ln}\n" for ln in lines) + " */\n"

"""The nonlinear plant as an FMI 2.0 co-simulation FMU: :func:`build_fmu`.

The FMU holds the plant of the closed loop, exactly: the free-hub FOAM or CFOAM model of
:mod:`hubbeam_ctrl.plant.models` with the rig's drive and friction
(:class:`~hubbeam_ctrl.sim.hardware.Hardware`), advanced by the fixed-step
generalized-alpha sample of :class:`~hubbeam_ctrl.sim.stepper.PlantStepper` (the same
CasADi step function, the same substep rule, the same iteration-matrix refreshes and
Karnopp sticking), so an FMU run equals the toolbox's fixed-step run.

What goes into the archive:

* ``sources/hb_hot.c``, ``hb_cold.c`` (+ headers): CasADi's generated C of the plant step,
  its iteration matrix, the residual of one substep with its Jacobian (for the full-Newton
  fallback), the mass matrix and bias (initial accelerations), the hardware torques and the
  outputs; every one takes the model's parameter vector ``p`` (and the hardware's numbers)
  as an input, and those are the FMU's parameters;
* ``sources/hubbeam_fmu.c``: the FMI 2.0 functions and the sample logic of
  :class:`PlantStepper` in C99 (written once, shipped with the toolbox);
* ``sources/hubbeam_model.h``: sizes, start values and value references of this plant;
* ``binaries/<platform>/<modelIdentifier>.so`` compiled with the system C compiler, the FMI
  headers taken from the installed FMPy package (``fmpy/c-code``) at build time;
* ``modelDescription.xml`` with units. No Python at run time.

The FMU is a sampled plant: every ``fmi2DoStep`` must cover a whole number of samples of
``dt`` (the closed loop's sample time), and the input is held over each sample (zero-order
hold, as the closed loop holds the controller's command).
"""

from __future__ import annotations

import hashlib
import os
import platform
import sys
import tempfile
import time
import uuid
import zipfile
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from xml.sax.saxutils import escape

import casadi as ca
import numpy as np

from hubbeam_ctrl.core.compiled import (
    OPT_COLD,
    OPT_HOT,
    OPT_HOT_LARGE,
    OPT_HOT_MAX_CHARS,
    CompileError,
    _run_compiler,
    _timeout_s,
    find_compiler,
)
from hubbeam_ctrl.core.errors import HubbeamError, ParameterError
from hubbeam_ctrl.core.fileio import atomic_write, check_writable
from hubbeam_ctrl.core.validation import check_in_range
from hubbeam_ctrl.fmu.description import (
    MODEL_IDENTIFIER,
    SetRanges,
    describe_set,
    model_description,
    set_ranges,
    vendor_annotation,
)
from hubbeam_ctrl.plant.basis import transverse_shapes
from hubbeam_ctrl.plant.modal import modal_analysis
from hubbeam_ctrl.plant.models import build_model
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.plant.rig import Rig, load_rig
from hubbeam_ctrl.plant.robust_certificate import Certificate
from hubbeam_ctrl.plant.uncertainty import Uncertainty
from hubbeam_ctrl.sim.hardware import HW_LAYOUT, Hardware, drive_torque, hub_torque
from hubbeam_ctrl.sim.stepper import (
    StepperSettings,
    _fast_step_function,
    _hold_function,
    _iteration_matrix_function,
    _substep_expressions,
    substep_rule,
)

__all__ = ["FMU_MODELS", "FMI_VERSIONS", "FmuInfo", "build_fmu", "fmi_headers", "fmu_platform"]

#: The plants an FMU can hold (the evaluation plants of the closed loop).
FMU_MODELS = ("foam", "cfoam")
#: FMI versions :func:`build_fmu` writes.
FMI_VERSIONS = ("2.0",)

# units of the parameter vector's blocks (parameter_layout); others are left without a unit
_P_UNITS = {"J_h": "kg.m2", "J": "kg.m2", "V1": "kg.m", "V2": "kg.m", "M1": "kg", "M2": "kg", "R": "kg",
            "D": "kg", "K1": "N/m", "K2": "N/m", "C": "N.s/m", "f1_tip": "1", "f2_tip": "1", "S_tip": "1/m"}
_HW_UNITS = {"R": "ohm", "k_t": "N.m/A", "k_e": "V.s/rad", "N": "1", "eta_forward": "1", "eta_backward": "1",
             "V_max": "V", "I_max": "A", "viscous": "N.m.s/rad", "coulomb": "N.m", "breakaway": "N.m",
             "stribeck_velocity": "rad/s", "v_eps": "rad/s"}
_HW_DOC = {"R": "armature resistance", "k_t": "motor torque constant times the motor efficiency eta_motor",
           "k_e": "back-EMF constant",
           "N": "gear ratio", "eta_forward": "gear efficiency, motor driving", "eta_backward":
           "gear efficiency, load driving", "V_max": "amplifier voltage limit", "I_max": "amplifier current limit",
           "viscous": "viscous friction coefficient", "coulomb": "Coulomb friction torque",
           "breakaway": "breakaway (static) friction torque", "stribeck_velocity": "Stribeck velocity",
           "v_eps": "regularisation velocity of the sliding friction"}
# kinds of value references, as in hubbeam_fmu.c
_K = {"u": 0, "y": 1, "q": 2, "v": 3, "p": 4, "hw": 5, "x0": 6, "misc": 7, "stuck": 8, "const": 9, "enc": 10}


@dataclass(frozen=True)
class FmuInfo:
    """What :func:`build_fmu` wrote.

    Attributes
    ----------
    path : Path
        The ``.fmu`` file.
    fmi_version : str
        ``"2.0"``.
    model : str
        ``"foam"`` or ``"cfoam"``.
    guid : str
    n_q : int
        Generalised coordinates of the plant.
    dt : float
        Sample time [s]: every communication step is a whole number of samples.
    substeps : int
        Integration steps per sample.
    step_reason : str
        Why that many (the substep rule, or "as requested").
    command : str
        The input: ``"torque"`` [N m] or ``"voltage"`` [V].
    inputs, outputs, parameters : tuple of str
        Variable names in the model description.
    binary : str or None
        Path of the shared library inside the archive; None when no C compiler was found
        (the FMU then holds the sources only).
    build_s : float
        Wall time of the build [s].
    ranges : dict
        Parameter name -> ``(min, max)``: the range over the rig's ``[uncertainty]`` set that the
        parameter carries as its FMI ``min``/``max`` (empty without a set).
    certificate : Certificate or None
        The robust certificate in the model description (its ``VendorAnnotations``).
    """

    path: Path
    fmi_version: str
    model: str
    guid: str
    n_q: int
    dt: float
    substeps: int
    step_reason: str
    command: str
    inputs: tuple
    outputs: tuple
    parameters: tuple
    binary: str | None
    build_s: float
    ranges: dict = field(default_factory=dict)
    certificate: Certificate | None = None


def fmi_headers() -> Path:
    """Folder of the FMI 2.0 headers in the installed FMPy package (``fmpy/c-code``).

    Returns
    -------
    Path

    Raises
    ------
    HubbeamError
        If FMPy is not installed (one line: install the ``fmu`` extra).
    """
    try:
        import fmpy
    except ImportError:
        raise HubbeamError("the FMI headers come from FMPy, which is not installed "
                           "(pip install 'hubbeam-ctrl[fmu]' or pip install fmpy)") from None
    folder = Path(fmpy.__file__).parent / "c-code"
    if not (folder / "fmi2Functions.h").is_file():
        raise HubbeamError(f"FMPy {getattr(fmpy, '__version__', '?')} has no fmi2Functions.h in {folder}")
    return folder


def fmu_platform() -> str | None:
    """The FMI 2.0 platform folder of this machine (``linux64``, ``darwin64``, ``win64``), or None."""
    if sys.maxsize <= 2 ** 32:
        return None
    return {"linux": "linux64", "darwin": "darwin64", "win32": "win64"}.get(sys.platform)


def _resolve_plant(rig_or_params):
    """``(params of the plant, hardware or None, rig or None)`` from a Rig, Params, file or preset."""
    if rig_or_params is None:
        rig_or_params = Rig()
    if isinstance(rig_or_params, Params):
        return rig_or_params, None, None
    if isinstance(rig_or_params, (str, os.PathLike)):
        rig_or_params = load_rig(rig_or_params)
    if not isinstance(rig_or_params, Rig):
        raise ParameterError(f"rig_or_params must be a Rig, Params, a rig file or a preset name, got "
                             f"{type(rig_or_params).__name__}")
    rig = rig_or_params
    hw = Hardware.from_rig(rig)
    if hw.inductive:
        raise ParameterError(f"motor.L = {rig.drive.L:g} H: the armature inductance (the current as a state) is not "
                             "in the FMU yet; set motor.L = 0 (the resistive motor)")
    return rig.plant_params, (None if hw.is_ideal else hw), rig


def _named(f: ca.Function, name: str) -> ca.Function:
    """``f`` under another name (a call of ``f``: the same arithmetic in the generated C)."""
    sym = ca.MX
    ins = [sym.sym(f.name_in(i), f.sparsity_in(i)) for i in range(f.n_in())]
    return ca.Function(name, ins, f.call(ins), f.name_in(), f.name_out())


def _functions(model, settings: StepperSettings, hardware: bool, gauges) -> tuple:
    """The hot and the cold CasADi functions of the FMU, and the output names/units."""
    par = model.parametric
    n = model.n_q
    extra = (True,) if hardware else ()
    step = _named(_fast_step_function(par, settings, *extra), "hb_step")
    jac = _named(_iteration_matrix_function(par, settings, *extra), "hb_jac")
    # residual of one substep and its Jacobian in the new accelerations (the full-Newton fallback)
    s, tau, a, p, (q1, v1, p1), residual, *hw = _substep_expressions(par, settings, hardware)
    hw = hw[:1]
    res = ca.Function("hb_res", [a, s, tau, p, *hw], [residual, ca.densify(ca.jacobian(residual, a))],
                      ["a", "s", "tau", "p"] + ["hw"] * len(hw), ["r", "J"], {"cse": True})
    upd = ca.Function("hb_upd", [a, s], [ca.vertcat(q1, v1, a, p1)], ["a", "s"], ["s_next"], {"cse": True})
    sym = par.sym
    q, v, pp = sym.sym("q", n), sym.sym("v", n), sym.sym("p", par.n_p)
    mc = ca.Function("hb_mc", [q, v, pp], [ca.densify(par.mass_matrix(q, pp)), par.bias(q, v, pp)],
                     ["q", "v", "p"], ["M", "c"], {"cse": True})
    # outputs: hub angle and rate, bending moments (root, then each strain gauge), tip deflections
    x = sym.sym("x", 2 * n)
    q2 = x[model.transverse_slice]
    EI, L, n2 = model.params.EI, model.params.L, model.n_transverse
    f2pp = [model.basis.f2pp_root] + [np.ravel(transverse_shapes(np.array([g]), n2, L, 2)) for g in gauges]
    moments = [ca.dot(ca.DM(EI * np.asarray(c, dtype=float)), q2) for c in f2pp]
    v_tip, u_tip = par.tip(x[:n], pp)
    out = ca.Function("hb_out", [x, pp], [ca.vertcat(x[0], x[n], *moments, v_tip, u_tip)], ["x", "p"], ["y"],
                      {"cse": True})
    cold = [jac, res, upd, mc, out]
    if hardware:
        hold = _named(_hold_function(par), "hb_hold")
        uu, thd, hwv = ca.SX.sym("u"), ca.SX.sym("thd"), ca.SX.sym("hw", len(HW_LAYOUT))
        hub = ca.Function("hb_hub", [uu, thd, hwv], [drive_torque(uu, thd, hwv), hub_torque(uu, thd, hwv)],
                          ["u", "thd", "hw"], ["drive", "hub"])
        cold += [hold, hub]
    return [step], cold, len(moments)


def _generate(functions: list, name: str, folder: Path) -> str:
    cg = ca.CodeGenerator(f"{name}.c", {"with_header": True})
    for f in functions:
        cg.add(f)
    cg.generate(str(folder) + os.sep)
    return (folder / f"{name}.c").read_text(encoding="utf-8")


def _c_array(values, ctype="double") -> str:
    vals = [repr(float(v)) if ctype == "double" else str(int(v)) for v in values] or ["0"]
    return "{" + ", ".join(vals) + "}"


def _variables(model, hardware: Hardware | None, rig: Rig | None, n_moments: int, gauges, settings) -> list:
    """Every variable: dicts with name, kind, index, causality, variability, unit, start, description."""
    V = []
    n = model.n_q
    command = "torque" if hardware is None else hardware.command
    V.append(dict(name="u", kind="u", index=0, causality="input", variability="continuous",
                  unit="N.m" if command == "torque" else "V", start=0.0,
                  description=("hub torque command" if command == "torque" else "motor voltage command")
                  + ", held over each sample"))
    ys = [("theta", "rad", "hub angle as the encoder reads it (bias, then the nearest count)"),
          ("theta_dot", "rad/s", "hub rate (plus its bias)"),
          ("root_moment", "N.m", "bending moment at the beam root, E I w''(0) (plus the strain bias)")]
    ys += [(f"strain_gauge_{k + 1}", "N.m", f"bending moment at the strain gauge at x = {g:g} m (plus the bias)")
           for k, g in enumerate(gauges)]
    ys += [("v_tip", "m", "transverse tip deflection in the hub frame"),
           ("u_tip", "m", "axial tip displacement in the hub frame")]
    for k, (name, unit, doc) in enumerate(ys):
        V.append(dict(name=name, kind="y", index=k, causality="output", variability="continuous", unit=unit,
                      description=doc))
    for k, c in enumerate(model.coordinate_names):
        unit = "rad" if k == 0 else "m"
        V.append(dict(name=f"q.{c}", kind="q", index=k, causality="output", variability="continuous",
                      unit=unit, description=f"generalised coordinate {c}"))
    for k, c in enumerate(model.coordinate_names):
        unit = "rad/s" if k == 0 else "m/s"
        V.append(dict(name=f"v.{c}", kind="v", index=k, causality="output", variability="continuous",
                      unit=unit, description=f"rate of {c}"))
    if hardware is not None:
        V.append(dict(name="stuck", kind="stuck", index=0, causality="output", variability="discrete", unit="1",
                      description="1 while friction holds the hub at rest (Karnopp), else 0"))
    k = 0
    for key, (r, c) in model.parametric.layout:
        block = np.asarray(model.p[k:k + r * c]).reshape((r, c), order="F")
        for j in range(c):
            for i in range(r):
                label = f"p.{key}" + ("" if r * c == 1 else f"[{i + 1}]" if c == 1 else f"[{i + 1},{j + 1}]")
                V.append(dict(name=label, kind="p", index=k + i + j * r, causality="parameter", variability="fixed",
                              unit=_P_UNITS.get(key), start=float(block[i, j]),
                              description=f"model parameter {key} (hubbeam_ctrl.plant.models.parameter_layout)"))
        k += r * c
    if hardware is not None:
        values = hardware.values()
        for i, key in enumerate(HW_LAYOUT):
            if key in ("dc_motor", "stick", "L"):       # L: fixed by the build (no inductance in the FMU)
                continue
            if key in ("R", "k_t", "k_e", "N", "eta_forward", "eta_backward", "V_max", "I_max") \
                    and hardware.drive.is_ideal:
                continue
            V.append(dict(name=f"hw.{key}", kind="hw", index=i, causality="parameter", variability="fixed",
                          unit=_HW_UNITS[key], start=float(values[i]), description=_HW_DOC[key]))
        V.append(dict(name="hw.stick_velocity", kind="misc", index=0, causality="parameter", variability="fixed",
                      unit="rad/s", start=float(hardware.friction.stick_velocity),
                      description="Karnopp dead band of the hub rate"))
    sens = rig.sensors if rig is not None else None
    for i, (key, unit, doc) in enumerate((("sensors.angle_bias", "rad", "hub-angle bias"),
                                          ("sensors.rate_bias", "rad/s", "hub-rate bias"),
                                          ("sensors.strain_bias", "N.m", "bending-moment bias"))):
        start = 0.0 if sens is None else float(getattr(sens, key.split(".")[1]))
        V.append(dict(name=key, kind="misc", index=i + 1, causality="parameter", variability="fixed", unit=unit,
                      start=start, description=doc))
    V.append(dict(name="sensors.encoder_counts", kind="enc", index=0, causality="parameter", variability="fixed",
                  type="Integer", start=0 if sens is None else int(sens.encoder_counts),
                  description="hub encoder counts per revolution (0: not quantised)"))
    for k, c in enumerate(model.coordinate_names):
        V.append(dict(name=f"x0.q.{c}", kind="x0", index=k, causality="parameter", variability="fixed",
                      unit="rad" if k == 0 else "m", start=0.0, description=f"initial {c}"))
    for k, c in enumerate(model.coordinate_names):
        V.append(dict(name=f"x0.v.{c}", kind="x0", index=n + k, causality="parameter", variability="fixed",
                      unit="rad/s" if k == 0 else "m/s", start=0.0, description=f"initial rate of {c}"))
    V.append(dict(name="dt", kind="const", index=0, causality="local", variability="constant", unit="s",
                  start=float(settings.dt), description="sample time: each communication step is a whole "
                                                         "number of samples"))
    V.append(dict(name="substeps", kind="const", index=1, causality="local", variability="constant", unit="1",
                  start=float(settings.substeps), description="generalized-alpha steps per sample"))
    V.append(dict(name="rho_inf", kind="const", index=2, causality="local", variability="constant", unit="1",
                  start=float(settings.rho_inf), description="spectral radius at infinity of the integrator"))
    for vr, var in enumerate(V):
        var["vr"] = vr
    return V


def _header(model, V, guid: str, settings, hardware: Hardware | None, n_moments: int, sizes: dict) -> str:
    n = model.n_q
    hw_start = hardware.values() if hardware is not None else np.zeros(len(HW_LAYOUT))
    misc = next((v["start"] for v in V if v["name"] == "hw.stick_velocity"), 1e-3)
    misc_start = [misc] + [next(v["start"] for v in V if v["name"] == k)
                           for k in ("sensors.angle_bias", "sensors.rate_bias", "sensors.strain_bias")]
    enc = next(v["start"] for v in V if v["name"] == "sensors.encoder_counts")
    lines = ["/* generated by hubbeam-ctrl (hubbeam_ctrl.fmu.build): this plant's sizes, start values and",
             "   value references */", "#ifndef HUBBEAM_MODEL_H", "#define HUBBEAM_MODEL_H",
             f'#define HB_GUID "{guid}"', f"#define HB_NQ {n}", f"#define HB_K {settings.substeps}",
             f"#define HB_DT {settings.dt!r}", f"#define HB_NP {model.parametric.n_p}",
             f"#define HB_HARDWARE {0 if hardware is None else 1}", f"#define HB_NHW {len(HW_LAYOUT)}",
             f"#define HB_HW_STATIC {HW_LAYOUT.index('breakaway')}", f"#define HB_NEWTON_TOL {settings.newton_tol!r}",
             f"#define HB_NY {2 + n_moments + 2}", "#define HB_Y_THETA 0", "#define HB_Y_THETA_DOT 1",
             "#define HB_Y_MOMENT0 2", f"#define HB_N_MOMENTS {n_moments}", f"#define HB_ENCODER_COUNTS {int(enc)}",
             f"#define HB_NVR {len(V)}"]
    for key, value in sizes.items():
        lines.append(f"#define HB_SZ_{key} {max(int(value), 1)}")
    lines += [f"static const double HB_P_START[{max(model.parametric.n_p, 1)}] = {_c_array(model.p)};",
              f"static const double HB_HW_START[{len(HW_LAYOUT)}] = {_c_array(hw_start)};",
              f"static const double HB_MISC_START[4] = {_c_array(misc_start)};",
              f"static const double HB_CONST[3] = {_c_array([settings.dt, settings.substeps, settings.rho_inf])};",
              f"static const int HB_VR_KIND[{len(V)}] = {_c_array([_K[v['kind']] for v in V], 'int')};",
              f"static const int HB_VR_INDEX[{len(V)}] = {_c_array([v['index'] for v in V], 'int')};",
              "#endif", ""]
    return "\n".join(lines)


def _starts_at(model: str, hardware: bool, n_moments: int, gauges, settings):
    """``starts_at(rig) -> {name: start}`` of the FMU's Real parameters built for a rig (the set's points)."""
    def starts_at(rig: Rig) -> dict:
        plant = build_model(model, rig.plant_params)
        V = _variables(plant, Hardware.from_rig(rig) if hardware else None, rig, n_moments, gauges, settings)
        return {v["name"]: v["start"] for v in V if v["causality"] == "parameter" and v.get("type", "Real") == "Real"}
    return starts_at


def _check_model(model) -> str:
    if not isinstance(model, str) or model.lower() not in FMU_MODELS:
        raise ParameterError(f"model must be one of {', '.join(FMU_MODELS)}, got {model!r}")
    return model.lower()


def build_fmu(rig_or_params=None, model: str = "foam", out="plant.fmu", *, dt: float | None = None,
              substeps: int | None = None, frequency_tolerance: float = 0.005, rho_inf: float = 0.9,
              spin: float = 0.0, force: bool = False, fmi_version: str = "2.0",
              certificate: Certificate | dict | str | os.PathLike | None = None) -> FmuInfo:
    """Write the nonlinear plant with the rig's hardware as an FMI 2.0 co-simulation FMU.

    Parameters
    ----------
    rig_or_params : Rig, Params, str or Path, optional
        A :class:`~hubbeam_ctrl.plant.rig.Rig` (its ``plant_params``, drive and friction, sensors),
        a rig file or preset name (:func:`~hubbeam_ctrl.plant.rig.load_rig`), or bare
        :class:`~hubbeam_ctrl.plant.params.Params` (ideal torque drive, no friction). Default:
        Table 1 with ideal hardware. The mode counts are the parameters' ``n_axial`` and
        ``n_transverse``.
    model : {"foam", "cfoam"}
        The plant model.
    out : str or Path
        The ``.fmu`` file to write (atomically: a failed build leaves nothing).
    dt : float, optional
        Sample time [s] (every communication step is a whole number of samples); default the
        rig's ``timing.dt``, else 0.01 s.
    substeps : int, optional
        Integration steps per sample, 1..200; default the closed loop's
        :func:`~hubbeam_ctrl.sim.stepper.substep_rule` on the plant's free-hub bending
        frequencies at ``spin``.
    frequency_tolerance : float
        The substep rule's largest relative frequency error [-], (0, 0.1].
    rho_inf : float
        Spectral radius at infinity of the generalized-alpha method [-], 0..1.
    spin : float
        Spin rate of the modal analysis behind the substep rule [rad/s] (the closed loop's is the
        controller's design spin; 0 for a slew).
    force : bool
        Replace an existing file at ``out``.
    fmi_version : {"2.0"}
        FMI 3.0 is not written (see ``docs/fmu.md``).
    certificate : Certificate, dict, str or Path, optional
        A controller's robust certificate over the rig's ``[uncertainty]`` set: ``hubbeam certify
        --json``'s document (or its file), or a ``robust_*`` dict (``GeneratedCode.certificate``).
        Its verdict, worst spectral radius and worst plant go into the model description's
        ``<VendorAnnotations><Tool name="hubbeam_ctrl">`` and one sentence of its ``description``;
        a certificate over another set than the rig's is refused.

    Returns
    -------
    FmuInfo

    Raises
    ------
    ParameterError
        Bad input (one line naming the argument), or ``out`` exists without ``force``.
    HubbeamError
        FMPy (the FMI headers) missing, or the C compiler failed.

    Notes
    -----
    With an ``[uncertainty]`` table on the rig, every parameter the set moves carries its range over
    the set as FMI ``min``/``max`` (:func:`hubbeam_ctrl.fmu.description.set_ranges`), and the set is in
    the description and the vendor annotation; a set that leaves the rig's own value out is refused
    (the FMU's start values are the rig's).

    Without a C compiler the FMU holds the sources only (``FmuInfo.binary`` is None) and one line
    on stderr says so.
    """
    start = time.perf_counter()
    model = _check_model(model)
    if fmi_version not in FMI_VERSIONS:
        raise ParameterError(f"fmi_version must be one of {', '.join(FMI_VERSIONS)}, got {fmi_version!r}")
    if not isinstance(force, bool):
        raise ParameterError(f"force must be True or False, got {force!r}")
    params, hardware, rig = _resolve_plant(rig_or_params)
    uncertainty = rig.uncertainty if rig is not None else Uncertainty()
    if certificate is not None:
        certificate = Certificate.read(certificate)
        certificate.check(uncertainty)
    if dt is None:
        dt = (rig.timing.dt if rig is not None and rig.timing.dt is not None else 0.01)
    dt = check_in_range("dt", dt, "s", 1e-6, 10.0)
    rho_inf = check_in_range("rho_inf", rho_inf, "-", 0.0, 1.0)
    spin = check_in_range("spin", spin, "rad/s", -1e4, 1e4)
    out = check_writable(out, "out")
    if out.exists() and not force:
        raise ParameterError(f"out: {out} exists (use force=True / --force to replace it)")
    headers = fmi_headers()
    plant = build_model(model, params)
    if substeps is None:
        f_hz = modal_analysis(plant, spin, "free").bending_hz
        rule = substep_rule(f_hz, dt, tolerance=frequency_tolerance, rho_inf=rho_inf)
        substeps, reason = rule.substeps, rule.reason
    else:
        if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) or not 1 <= substeps <= 200:
            raise ParameterError(f"substeps must be an integer in [1, 200], got {substeps!r}")
        substeps, reason = int(substeps), f"{substeps} steps per sample as requested"
    settings = StepperSettings(dt=dt, substeps=substeps, rho_inf=rho_inf)
    gauges = tuple(rig.sensors.strain_gauges) if rig is not None else ()
    hot, cold, n_moments = _functions(plant, settings, hardware is not None, gauges)
    sizes = {k: max(getattr(f, f"sz_{k.lower()}")() for f in hot + cold) for k in ("ARG", "RES", "IW", "W")}
    V = _variables(plant, hardware, rig, n_moments, gauges, settings)
    ranges = SetRanges({}, ()) if rig is None else set_ranges(
        rig, _starts_at(model, hardware is not None, n_moments, gauges, settings))
    for var in V:
        if var["name"] in ranges.ranges:
            var["min"], var["max"] = ranges.ranges[var["name"]]
    annotation = vendor_annotation(uncertainty, certificate, ranges.still)
    with tempfile.TemporaryDirectory(prefix="hubbeam-fmu-") as tmp:
        src = Path(tmp) / "sources"
        src.mkdir()
        hot_c = _generate(hot, "hb_hot", src)
        cold_c = _generate(cold, "hb_cold", src)
        template = resources.files("hubbeam_ctrl.fmu").joinpath("hubbeam_fmu.c").read_text(encoding="utf-8")
        (src / "hubbeam_fmu.c").write_text(template, encoding="utf-8")
        digest = hashlib.sha256((hot_c + cold_c + template + repr(V) + "".join(annotation)).encode()).hexdigest()
        guid = "{" + str(uuid.UUID(digest[:32])) + "}"
        (src / "hubbeam_model.h").write_text(_header(plant, V, guid, settings, hardware, n_moments, sizes),
                                             encoding="utf-8")
        sources = ["hubbeam_fmu.c", "hb_hot.c", "hb_cold.c"]
        name = f"hubbeam_{model}_{plant.n_axial}x{plant.n_transverse}"
        what = (f"{model.upper()} with {plant.n_axial} axial and {plant.n_transverse} transverse modes, "
                f"{'ideal torque drive' if hardware is None else hardware.command + ' command'}, "
                f"dt = {dt:g} s, {substeps} generalized-alpha steps per sample (hubbeam-ctrl)")
        robust = describe_set(uncertainty, ranges, certificate)
        description = what + (". " + robust if robust else "")
        (Path(tmp) / "modelDescription.xml").write_text(
            model_description(V, guid, name, description, dt, sources, annotation), encoding="utf-8")
        binary = _compile(src, headers, Path(tmp), hot_c)
        (Path(tmp) / "documentation").mkdir()
        (Path(tmp) / "documentation" / "index.html").write_text(
            f"<html><body><h1>{name}</h1><p>{what}.</p><p>Step reason: {reason}.</p>"
            + (f"<p>{escape(robust)}</p>" if robust else "") + "<p>See hubbeam-ctrl's "
            "docs/fmu.md.</p></body></html>\n", encoding="utf-8")

        def write(path):
            with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
                for f in sorted(Path(tmp).rglob("*")):
                    if f.is_file():
                        z.write(f, f.relative_to(tmp).as_posix())

        atomic_write(out, write)
    names = lambda c: tuple(v["name"] for v in V if v["causality"] == c)     # noqa: E731
    return FmuInfo(path=Path(out), fmi_version="2.0", model=model, guid=guid, n_q=plant.n_q, dt=float(dt),
                   substeps=int(substeps), step_reason=reason,
                   command="torque" if hardware is None else hardware.command, inputs=names("input"),
                   outputs=names("output"), parameters=names("parameter"), binary=binary,
                   build_s=time.perf_counter() - start, ranges=ranges.ranges, certificate=certificate)


def _compile(src: Path, headers: Path, root: Path, hot_c: str) -> str | None:
    """Build ``binaries/<platform>/hubbeam_plant.so`` from the sources; None without a compiler."""
    folder = fmu_platform()
    if folder is None:
        print(f"hubbeam: no FMI 2.0 platform folder for {platform.system()} {platform.machine()}; "
              "the FMU holds the sources only", file=sys.stderr)
        return None
    try:
        compiler = find_compiler()
    except CompileError as exc:
        print(f"hubbeam: {exc}; the FMU holds the sources only (build them with any C99 compiler)",
              file=sys.stderr)
        return None
    suffix = {"win64": ".dll", "darwin64": ".dylib"}.get(folder, ".so")
    timeout = _timeout_s()
    # only the fmi2* functions are exported (FMI2_Export): the CasADi functions stay inside, so two
    # hubbeam FMUs loaded into one process never call each other's plant step
    pic = [] if os.name == "nt" else ["-fPIC", "-fvisibility=hidden", "-DCASADI_SYMBOL_EXPORT="]
    objs = []
    hot_flag = OPT_HOT if len(hot_c) <= OPT_HOT_MAX_CHARS else OPT_HOT_LARGE
    build = root / ".build"
    build.mkdir()
    for name, flags in (("hubbeam_fmu", "-O2"), ("hb_hot", hot_flag), ("hb_cold", OPT_COLD)):
        obj = build / f"{name}.o"
        _run_compiler(compiler + [flags, *pic, "-std=c99", "-I", str(headers), "-I", str(src), "-c",
                                  str(src / f"{name}.c"), "-o", str(obj)], f"FMU {name}.c ({flags})", timeout)
        objs.append(str(obj))
    lib_dir = root / "binaries" / folder
    lib_dir.mkdir(parents=True)
    lib = lib_dir / f"{MODEL_IDENTIFIER}{suffix}"
    _run_compiler(compiler + ["-shared", *objs, "-o", str(lib), "-lm"], f"FMU {lib.name} (link)", timeout)
    for o in objs:
        os.unlink(o)
    build.rmdir()
    return f"binaries/{folder}/{lib.name}"

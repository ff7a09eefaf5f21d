"""Controllers as portable C99: one header and one source per controller.

:func:`to_c` turns a designed controller into C that does at each sample exactly what the
Python controller's call does, operation by operation: the Kalman filter's prediction and
measurement update, the gain, the reference table (extended beyond its end like
:meth:`controllers.Controller._reference_at`), the feedforward, the saturation. The code
has an instance struct holding all its state, ``<name>_init``, ``<name>_reset`` and
``<name>_step(inst, measurements, reference, command)``; no dynamic memory, no I/O, only
``math.h``; gains and tables are ``static const`` arrays printed with 17 significant
digits (``%.17g``), so double precision reproduces the Python numbers.

Kinds (:data:`CODEGEN_KINDS`):

* ``pd``: :class:`controllers.PD` (reads ``theta``, ``theta_dot``);
* ``lqr``: :class:`controllers.LQR` with its observer
  (:class:`controllers.integral.ObservedFeedback`, :class:`ObservedLQR` for a bare LQR): the
  full-state LQR reads modal coordinates no sensor measures, so the exported LQR is its
  gain on a Kalman filter of its model, reading the sensors that model names (the beam
  alone's ``theta``, ``theta_dot``, ``root_moment``, or a rig's own set:
  :meth:`controllers.DesignModel.on_rig`);
* ``lqg``: :class:`controllers.LQG` (the same sensors), and the gain-scheduled
  :class:`controllers.ScheduledLQG` (the same sensors, the beam alone's or a rig's own; gains,
  filter gains and models interpolated on the measured spin rate);
* ``mpc``: :class:`controllers.MPC` with its observer (``ObservedFeedback``,
  :class:`ObservedMPC`): the condensed box-constrained QP solved by a generated primal
  active-set method, on a DC motor with the voltage limit's rows too
  (:mod:`~hubbeam_ctrl.deploy.render_qp`, double precision only; no tip bound);
* ``msmpc``: :class:`controllers.MultiStageMPC` with its observer: the MPC's template with the
  scenario tree's QP (``1 + S (N - 1)`` torques, the first shared; no tip bound, no voltage rows);
* ``hinf``: :class:`controllers.HInf`, the sampled H-infinity law on the hub angle's error, in the
  observer template (its state ``[theta, x_k]``, the reference angle in the prediction);
* ``zv``, ``zvd``, ``ei``, ``openloop`` (profile ``feedforward``): the held torque table
  of an input-shaped or feedforward open loop (reads nothing).

The roles: :mod:`~hubbeam_ctrl.deploy.laws` (the law as arrays),
:mod:`~hubbeam_ctrl.deploy.cfile` (the C text family), :mod:`~hubbeam_ctrl.deploy.render`
and :mod:`~hubbeam_ctrl.deploy.render_mpc` (the templates; :mod:`~hubbeam_ctrl.deploy.render_qp` the
MPC's solver with general rows), this module (files).

The step's interface is double precision whatever ``precision``; with
``precision="single"`` the arithmetic and the stored data are ``float``.
"""


from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from controllers import Controller, KalmanNoise
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import write_folder
from hubbeam_ctrl.plant.robust_certificate import certificate_text

from .cfile import PRECISIONS, command_text
from .laws import CODEGEN_KINDS, SENSOR_UNITS, ControlLaw, control_law, sensor_unit
from .render import render_c

__all__ = ["CODEGEN_KINDS", "SENSOR_UNITS", "ControlLaw", "GeneratedCode", "certificate_comment", "control_law",
           "render_c", "to_c", "command_text", "sensor_unit"]

_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,30}$")




@dataclass(frozen=True, eq=False)
class GeneratedCode:
    """C sources of one controller, as written by :func:`to_c`.

    Attributes
    ----------
    name : str
        C prefix and file stem (``<name>.h``, ``<name>.c``).
    folder : pathlib.Path or None
        Where the files were written (None: in memory only).
    header, source : str
        The files' text.
    precision : {"double", "single"}
    law : ControlLaw
        What the code computes.
    certificate : dict or None
        The robust certificate the code was exported with (``robust_*`` entries of
        :meth:`hubbeam_ctrl.study.worst_case.WorstCase.metrics`), also in the header's first
        comment and the metadata.
    """

    name: str
    folder: Path | None
    header: str
    source: str
    precision: str
    law: ControlLaw
    certificate: dict | None = None

    @property
    def header_path(self) -> Path:
        """``<folder>/<name>.h``."""
        return Path(self.folder) / f"{self.name}.h"

    @property
    def source_path(self) -> Path:
        """``<folder>/<name>.c``."""
        return Path(self.folder) / f"{self.name}.c"

    @property
    def data_bytes(self) -> int:
        """Bytes of the ``static const`` data (gains and tables) [B]."""
        size = 4 if self.precision == "single" else 8
        return int(sum(np.asarray(a).size for a in self.law.arrays.values()) * size)

    def metadata(self) -> dict:
        """What the controller expects and gives: sensors with units, sample time, limits."""
        law = self.law
        return {"name": self.name, "controller": law.controller, "precision": self.precision,
                "dt_s": law.dt, "tau_max_nm": law.tau_max,
                "measurements": [{"name": s, "unit": sensor_unit(s)} for s in law.sensors],
                "reference": law.reference_layout, "n_reference": law.n_reference,
                "command": ({"name": "V", "unit": "V", "V_max": law.scalars["V_max"]} if "V_max" in law.scalars
                            else {"name": "tau", "unit": "N m"}), "data_bytes": self.data_bytes,
                **({"robust_certificate": self.certificate} if self.certificate is not None else {})}


def _check_name(name: str) -> str:
    if not isinstance(name, str) or not _IDENT.match(name):
        raise ParameterError(f"name must be a C identifier of at most 31 characters, got {name!r}")
    return name


def _check_out(out_dir, force: bool) -> Path:
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ParameterError(f"out: {out} exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise ParameterError(f"out: folder {out} exists and is not empty (use --force / force=True to "
                             "write into it)")
    if not out.parent.is_dir():
        raise ParameterError(f"out: folder {out.parent} does not exist")
    return out


def to_c(controller: Controller, out_dir=None, precision: str = "double", *, name: str | None = None,
         force: bool = False, noise: KalmanNoise | None = None, check=None,
         certificate: dict | None = None) -> GeneratedCode:
    """Write ``controller`` as portable C99 (``<name>.h``, ``<name>.c``, ``<name>.json``).

    Parameters
    ----------
    controller : controllers.Controller
        One of :data:`CODEGEN_KINDS` (an LQR is exported with its observer,
        :class:`~hubbeam_ctrl.deploy.observed.ObservedLQR`).
    out_dir : str or Path, optional
        Output folder, written atomically (built beside it, then renamed; a failed build
        leaves nothing). None: return the text without writing.
    precision : {"double", "single"}
        ``double`` (default) reproduces the Python controller to rounding; ``single``
        stores and computes in ``float`` (see docs/deploy.md for its measured error).
    name : str, optional
        C prefix and file stem (default: the controller's kind, e.g. ``"lqg"``).
    force : bool
        Write into an existing, non-empty folder.
    noise : controllers.KalmanNoise, optional
        Noise model of the LQR's observer (default: the simulator's sensors).
    check : callable, optional
        ``check(folder, name)`` run on the written files before they are moved into place
        (e.g. a compile, :func:`hubbeam_ctrl.deploy.sil.compile_c`); if it raises, nothing
        is left.
    certificate : dict, optional
        The robust certificate of the controller over its rig's uncertainty set
        (:meth:`hubbeam_ctrl.study.worst_case.WorstCase.metrics`): its verdict, worst radius
        and worst plant open the header, and the metadata carries it whole.

    Returns
    -------
    GeneratedCode

    Raises
    ------
    ParameterError
        Unknown precision, a controller kind that cannot be generated, a non-finite gain, a
        bad name, or an output folder that is not empty without ``force``.
    """
    if precision not in PRECISIONS:
        raise ParameterError(f"precision must be one of {', '.join(PRECISIONS)}, got {precision!r}")
    law = control_law(controller, noise)
    name = _check_name(law.controller if name is None else name)
    header, source = render_c(law, name, precision)
    if certificate is not None:
        header = certificate_comment(certificate) + header
    code = GeneratedCode(name, None, header, source, precision, law, certificate)
    if out_dir is None:
        return code
    out = _check_out(out_dir, force)
    meta = json.dumps(code.metadata(), indent=1) + "\n"

    def write(folder: Path) -> None:
        (folder / f"{name}.h").write_text(header)
        (folder / f"{name}.c").write_text(source)
        (folder / f"{name}.json").write_text(meta)
        if check is not None:
            check(folder, name)

    write_folder(out, write, "out")
    return GeneratedCode(name, out, header, source, precision, law, certificate)


def certificate_comment(certificate: dict) -> str:
    """The C comment that opens a certified controller's header.

    Parameters
    ----------
    certificate : dict
        ``robust_*`` entries (:meth:`hubbeam_ctrl.study.worst_case.WorstCase.metrics`).

    Returns
    -------
    str
        The two sentences of :func:`hubbeam_ctrl.plant.robust_certificate.certificate_text` as a C
        comment (the FMU's model description says the same).
    """
    verdict, worst = certificate_text(certificate)
    return f"/* {verdict}\n   {worst} */\n\n"

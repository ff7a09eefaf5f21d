"""Take a designed controller to the hardware: portable C and software in the loop.

* :func:`to_c` writes a controller as C99 (one header, one source, a JSON of the sensors
  and units it expects): :mod:`hubbeam_ctrl.deploy.codegen`;
* :func:`compile_c` and :class:`CController` compile it with the system C compiler and run
  it as a controller of the closed-loop simulator: :mod:`hubbeam_ctrl.deploy.sil`;
* :class:`ObservedLQR` and :class:`ObservedMPC` are the full-state designs with their Kalman
  observer, as they are exported.

This layer sits beside :mod:`hubbeam_ctrl.study`: it imports the controllers and the
simulator, and nothing below it imports it. See docs/deploy.md.
"""

from .codegen import CODEGEN_KINDS, SENSOR_UNITS, ControlLaw, GeneratedCode, control_law, render_c, to_c
from .observed import ObservedLQR, ObservedMPC
from .sil import NO_COMPILER, STRICT_FLAGS, CController, compile_c, compiler

__all__ = ["CODEGEN_KINDS", "SENSOR_UNITS", "ControlLaw", "GeneratedCode", "control_law", "render_c", "to_c",
           "ObservedLQR", "ObservedMPC", "NO_COMPILER", "STRICT_FLAGS", "CController", "compile_c", "compiler"]

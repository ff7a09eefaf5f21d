"""The plant as an FMU: the nonlinear hub-beam with the rig's hardware for any FMI importer.

:func:`build_fmu` writes an FMI 2.0 co-simulation FMU built from CasADi's generated C of the
closed loop's plant step (``docs/fmu.md``). Imports the sim, plant and core layers.
"""

import sys as _sys  # noqa: E402

from hubbeam_ctrl.fmu.build import *  # noqa: F401,F403

__all__ = list(_sys.modules["hubbeam_ctrl.fmu.build"].__all__)

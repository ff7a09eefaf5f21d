"""Plots (Matplotlib), apart from computing: plant results, Campbell diagrams, closed-loop runs,
loop plots of linear feedback, calibration fits.
"""

import sys as _sys  # noqa: E402

from hubbeam_ctrl.plots.calibration import *  # noqa: F401,F403
from hubbeam_ctrl.plots.closedloop import *  # noqa: F401,F403
from hubbeam_ctrl.plots.loops import *  # noqa: F401,F403
from hubbeam_ctrl.plots.plant import *  # noqa: F401,F403
from hubbeam_ctrl.plots.shaping import *  # noqa: F401,F403

__all__ = [name for _m in ('plant', 'closedloop', 'shaping', 'loops', 'calibration')
           for name in _sys.modules[f"hubbeam_ctrl.plots.{_m}"].__all__]

"""The physical limit of a task: time-optimal and minimum-vibration slews on the nonlinear
model, checked on the evaluation plant. Imports the sim, plant and core layers.
"""

import sys as _sys  # noqa: E402

from hubbeam_ctrl.limit.bound import *  # noqa: F401,F403
from hubbeam_ctrl.limit.optimal import *  # noqa: F401,F403
from hubbeam_ctrl.limit.replan import *  # noqa: F401,F403
from hubbeam_ctrl.limit.slew import *  # noqa: F401,F403

__all__ = [name for _m in ('slew', 'bound', 'optimal', 'replan')
           for name in _sys.modules[f"hubbeam_ctrl.limit.{_m}"].__all__]

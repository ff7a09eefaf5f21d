"""The simulation layer: IDAS runs of the implicit equations, the fixed-step plant stepper,
the closed loop and the result type. Imports the plant and core layers.
"""

import sys as _sys  # noqa: E402

from hubbeam_ctrl.sim.closedloop import *  # noqa: F401,F403
from hubbeam_ctrl.sim.estimated import *  # noqa: F401,F403
from hubbeam_ctrl.sim.evaluation import *  # noqa: F401,F403
from hubbeam_ctrl.sim.exactbeam import *  # noqa: F401,F403
from hubbeam_ctrl.sim.hardware import *  # noqa: F401,F403
from hubbeam_ctrl.sim.results import *  # noqa: F401,F403
from hubbeam_ctrl.sim.simulate import *  # noqa: F401,F403
from hubbeam_ctrl.sim.stepper import *  # noqa: F401,F403

__all__ = [name for _m in ('results', 'simulate', 'hardware', 'stepper', 'evaluation', 'closedloop',
                           'estimated', 'exactbeam')
           for name in _sys.modules[f"hubbeam_ctrl.sim.{_m}"].__all__]

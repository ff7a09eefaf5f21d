"""The plant layer: parameters, modal basis, the four models defined by their energies, maneuvers,
sensors and modal analysis. Imports only :mod:`hubbeam_ctrl.core`.
"""

import sys as _sys  # noqa: E402

from hubbeam_ctrl.plant.basis import *  # noqa: F401,F403
from hubbeam_ctrl.plant.convergence import *  # noqa: F401,F403
from hubbeam_ctrl.plant.linearization import *  # noqa: F401,F403
from hubbeam_ctrl.plant.maneuvers import *  # noqa: F401,F403
from hubbeam_ctrl.plant.modal import *  # noqa: F401,F403
from hubbeam_ctrl.plant.models import *  # noqa: F401,F403
from hubbeam_ctrl.plant.params import *  # noqa: F401,F403
from hubbeam_ctrl.plant.rig import *  # noqa: F401,F403
from hubbeam_ctrl.plant.sensors import *  # noqa: F401,F403

__all__ = [name for _m in ('params', 'basis', 'models', 'maneuvers', 'sensors', 'linearization', 'modal',
                           'convergence', 'rig')
           for name in _sys.modules[f"hubbeam_ctrl.plant.{_m}"].__all__]

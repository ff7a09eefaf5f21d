"""The linear layer: linearisation about steady spin, state-space models, reduction and export.
Imports the plant and core layers.
"""

import sys as _sys  # noqa: E402

from hubbeam_ctrl.linear.delay import *  # noqa: F401,F403
from hubbeam_ctrl.linear.export import *  # noqa: F401,F403
from hubbeam_ctrl.linear.pole_comparison import *  # noqa: F401,F403
from hubbeam_ctrl.linear.poles import *  # noqa: F401,F403
from hubbeam_ctrl.linear.statespace import *  # noqa: F401,F403
from hubbeam_ctrl.linear.transforms import *  # noqa: F401,F403

__all__ = [name for _m in ('statespace', 'poles', 'transforms', 'pole_comparison', 'export', 'delay')
           for name in _sys.modules[f"hubbeam_ctrl.linear.{_m}"].__all__]

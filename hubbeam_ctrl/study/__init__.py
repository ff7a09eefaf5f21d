"""The study layer: scenarios, closed-loop comparison, metrics, reports, robustness sweeps
and robust tuning. It may import ``controllers`` (at module level); the layers below may not.
"""

import sys as _sys  # noqa: E402

from hubbeam_ctrl.study.compare import *  # noqa: F401,F403
from hubbeam_ctrl.study.loops import *  # noqa: F401,F403
from hubbeam_ctrl.study.metrics import *  # noqa: F401,F403
from hubbeam_ctrl.study.payload import *  # noqa: F401,F403
from hubbeam_ctrl.study.report import *  # noqa: F401,F403
from hubbeam_ctrl.study.scenarios import *  # noqa: F401,F403
from hubbeam_ctrl.study.shaping import *  # noqa: F401,F403
from hubbeam_ctrl.study.spec import *  # noqa: F401,F403
from hubbeam_ctrl.study.spillover import *  # noqa: F401,F403
from hubbeam_ctrl.study.sweep import *  # noqa: F401,F403
from hubbeam_ctrl.study.sweep_report import *  # noqa: F401,F403
from hubbeam_ctrl.study.tasks import *  # noqa: F401,F403
from hubbeam_ctrl.study.tune import *  # noqa: F401,F403

__all__ = [name for _m in ('metrics', 'tasks', 'scenarios', 'compare', 'report', 'shaping', 'payload', 'spec',
                           'spillover', 'sweep', 'sweep_report', 'tune', 'loops')
           for name in _sys.modules[f"hubbeam_ctrl.study.{_m}"].__all__]

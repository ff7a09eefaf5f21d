"""The study layer: scenarios, closed-loop comparison, metrics, reports, robustness sweeps
and robust tuning. It may import ``controllers`` (at module level); the layers below may not.

``hubbeam_ctrl.study.compare`` is the module :mod:`hubbeam_ctrl.study.compare` (``import
hubbeam_ctrl.study.compare`` gives the module, as every other submodule), and calling it
calls its function :func:`~hubbeam_ctrl.study.compare.compare`, so ``from hubbeam_ctrl.study
import compare; compare(...)`` keeps working. The same holds for every submodule with a
function of its own name: ``judge``, ``sweep`` and ``tune``.
"""

import sys as _sys  # noqa: E402
import types as _types

from hubbeam_ctrl.study.certificate import *  # noqa: F401,F403
from hubbeam_ctrl.study.compare import *  # noqa: F401,F403
from hubbeam_ctrl.study.compare_values import *  # noqa: F401,F403
from hubbeam_ctrl.study.judge import *  # noqa: F401,F403
from hubbeam_ctrl.study.ladder import *  # noqa: F401,F403
from hubbeam_ctrl.study.loops import *  # noqa: F401,F403
from hubbeam_ctrl.study.metrics import *  # noqa: F401,F403
from hubbeam_ctrl.study.payload import *  # noqa: F401,F403
from hubbeam_ctrl.study.report import *  # noqa: F401,F403
from hubbeam_ctrl.study.rig_loop import *  # noqa: F401,F403
from hubbeam_ctrl.study.scenarios import *  # noqa: F401,F403
from hubbeam_ctrl.study.settings_table import *  # noqa: F401,F403
from hubbeam_ctrl.study.shaping import *  # noqa: F401,F403
from hubbeam_ctrl.study.spec import *  # noqa: F401,F403
from hubbeam_ctrl.study.spec_files import *  # noqa: F401,F403
from hubbeam_ctrl.study.spillover import *  # noqa: F401,F403
from hubbeam_ctrl.study.spread import *  # noqa: F401,F403
from hubbeam_ctrl.study.sweep import *  # noqa: F401,F403
from hubbeam_ctrl.study.sweep_report import *  # noqa: F401,F403
from hubbeam_ctrl.study.tasks import *  # noqa: F401,F403
from hubbeam_ctrl.study.tune import *  # noqa: F401,F403

__all__ = [name for _m in ('metrics', 'tasks', 'scenarios', 'certificate', 'judge', 'compare', 'report', 'shaping',
                           'compare_values', 'payload', 'spec', 'spec_files', 'spread', 'settings_table', 'spillover',
                           'sweep', 'sweep_report', 'tune',
                           'loops', 'rig_loop', 'ladder')
           for name in _sys.modules[f"hubbeam_ctrl.study.{_m}"].__all__]


class _CallableModule(_types.ModuleType):
    """A module that, called, calls its function of the same name (``study.compare(...)``)."""

    def __call__(self, *args, **kwargs):
        return getattr(self, self.__name__.rsplit(".", 1)[-1])(*args, **kwargs)


def _module_over_function(name: str):
    """Give back the submodule ``name`` its attribute on the package (the star import put its
    function of the same name there), callable as that function."""
    module = _sys.modules[f"{__name__}.{name}"]
    module.__class__ = _CallableModule
    return module


compare = _module_over_function("compare")
judge = _module_over_function("judge")
sweep = _module_over_function("sweep")
tune = _module_over_function("tune")

"""Common ground of every layer: errors, scalar validation, declared settings, reading inputs,
atomic file writing, JSON and NPZ files, progress.
"""

import sys as _sys  # noqa: E402

from hubbeam_ctrl.core.budget import *  # noqa: F401,F403
from hubbeam_ctrl.core.errors import *  # noqa: F401,F403
from hubbeam_ctrl.core.fileio import *  # noqa: F401,F403
from hubbeam_ctrl.core.htmlpage import *  # noqa: F401,F403
from hubbeam_ctrl.core.jsonio import *  # noqa: F401,F403
from hubbeam_ctrl.core.npz import *  # noqa: F401,F403
from hubbeam_ctrl.core.progress import *  # noqa: F401,F403
from hubbeam_ctrl.core.reading import *  # noqa: F401,F403
from hubbeam_ctrl.core.settings import *  # noqa: F401,F403
from hubbeam_ctrl.core.validation import *  # noqa: F401,F403

__all__ = [name for _m in ('errors', 'validation', 'settings', 'fileio', 'reading', 'jsonio', 'npz',
                         'progress', 'budget', 'htmlpage')
           for name in _sys.modules[f"hubbeam_ctrl.core.{_m}"].__all__]

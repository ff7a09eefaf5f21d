"""Calibration of the model to a rig from measured records (issue 25).

``records`` (the record format), ``model`` (a rig's simulated sensors), ``excitation``
(input signals within the drive's and the user's limits), ``modal`` (frequencies and damping
from free-decay records by ERA, forced ones by OKID and ERA), ``design`` (the band records
excite, the fitted plant's modes, the noise floor), ``start`` (a start from the records'
frequency responses), ``fields`` (the fitted rig fields by name), ``drive`` (what voltage-in
records determine of a DC motor), ``fit`` (least squares of
rig fields against records), ``intervals`` (its 95 % intervals, also where stick-slip
friction makes the cost rough) and ``table`` (against a modal table). See ``docs/calibration.md``.
"""

import sys as _sys  # noqa: E402

from hubbeam_ctrl.calibrate.design import *  # noqa: F401,F403,E402
from hubbeam_ctrl.calibrate.drive import *  # noqa: F401,F403,E402
from hubbeam_ctrl.calibrate.excitation import *  # noqa: F401,F403,E402
from hubbeam_ctrl.calibrate.fields import *  # noqa: F401,F403,E402
from hubbeam_ctrl.calibrate.fit import *  # noqa: F401,F403,E402
from hubbeam_ctrl.calibrate.intervals import *  # noqa: F401,F403,E402
from hubbeam_ctrl.calibrate.modal import *  # noqa: F401,F403,E402
from hubbeam_ctrl.calibrate.model import *  # noqa: F401,F403,E402
from hubbeam_ctrl.calibrate.records import *  # noqa: F401,F403,E402
from hubbeam_ctrl.calibrate.start import *  # noqa: F401,F403,E402
from hubbeam_ctrl.calibrate.table import *  # noqa: F401,F403,E402

__all__ = [name for _m in ("records", "model", "excitation", "modal", "fields", "drive", "fit", "intervals", "design",
                          "start", "table")
           for name in _sys.modules[f"hubbeam_ctrl.calibrate.{_m}"].__all__]

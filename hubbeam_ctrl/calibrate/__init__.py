"""Calibration of the model to a rig from measured records (issue 25).

``records`` (the record format), ``model`` (a rig's simulated sensors), ``excitation``
(input signals within the drive's and the user's limits), ``modal`` (frequencies and damping
from free-decay records by ERA) and ``fit`` (least squares of rig fields against records,
and against a modal table). See ``docs/calibration.md``.
"""

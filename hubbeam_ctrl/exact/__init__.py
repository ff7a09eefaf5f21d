"""The exact-beam evaluation plant: a planar geometrically exact ANCF beam (Exudyn) on a rigid hub.

An optional plant (``pip install hubbeam-ctrl[exact]``): the beam of :class:`~hubbeam_ctrl.plant.Params`
as ANCF cable elements of the flexible-multibody code Exudyn, clamped to a rigid hub, stepped
sample by sample with the controller in the loop (:class:`ExactBeamPlant`, the interface of
:class:`~hubbeam_ctrl.sim.stepper.PlantStepper` that :func:`~hubbeam_ctrl.sim.simulate_closed_loop`
uses). Its layer lies between ``sim | linear`` and ``plant``.
"""

from hubbeam_ctrl.exact.beam import (
    EXUDYN_INSTALL,
    MIN_ELEMENTS,
    MIN_STEPS_PER_PERIOD,
    ExactBeamPlant,
    element_rule,
    exudyn_available,
    highest_mode_hz,
    min_substeps,
    require_exudyn,
)

__all__ = ["EXUDYN_INSTALL", "MIN_ELEMENTS", "MIN_STEPS_PER_PERIOD", "ExactBeamPlant", "element_rule",
           "exudyn_available", "highest_mode_hz", "min_substeps", "require_exudyn"]

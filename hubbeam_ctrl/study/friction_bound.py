"""What Coulomb friction and an encoder's count do to a linear loop at rest, predicted before the run.

Coulomb friction and quantisation are bounded nonlinearities: a loop whose linear certificate is
stable stays bounded with them. What they leave at the end follows from the loop's compliance at
rest (:func:`hubbeam_ctrl.study.certificate.hold_gain`, the steady hub-angle offset per N m of
constant hub torque):

* **without integral action** the hub stops wherever the drive's restoring torque is below the
  breakaway torque ``F_s``: a dead band of ``F_s * hold_gain`` on each side of the target, and no
  limit cycle (the loop settles into it);
* **with integral action** friction holds no offset; the command builds up to the breakaway
  torque and the hub slips. When the breakaway torque exceeds the sliding one (a Stribeck drop,
  ``friction.breakaway > friction.coulomb``) the slip overshoots and the hub sticks again on the
  other side: a stick-slip **hunting limit cycle** about the target is predicted (Armstrong-Helouvry,
  Dupont and Canudas de Wit 1994, "A survey of models, analysis tools and compensation methods for
  the control of machines with friction", Automatica 30(7), section 5); with equal breakaway and
  sliding friction none is;
* an encoder of step ``q`` reads the angle to ``+-q/2``: a loop with integral action hunts
  between two counts when the friction lets it; a loop without it whose dead band is narrower than
  half a count can hold the hub only where the encoder reads the target's count: a count off, its
  command at rest (``q / hold_gain``) is past the breakaway torque, so a hub that stops there slips
  again, and stick-slip between counts is predicted until it stops on the target's count. Found on a
  random rig (``benchmarks/fuzz_rigs.py link 41``, rig 7: a 0.33 m steel link with a 146 g payload
  on a geared DC motor, Coulomb friction 0.071 N m, 40 000 counts, a dead band of 0.01 counts while its
  filter's integral leaked, exact since): the prediction said the hub stops in the dead band; the
  default run was "settled", the hub stuck more than a count off while the law's slow states built the
  command up to the breakaway, and the run 4 times longer slipped at 2.3 s and stuck and slipped again
  to its end (tip 0.19 mm against a 0.041 mm band);
* that rounding moves the tip through the loop by at most ``q/2`` times the loop's peak-to-peak
  gain from the angle reading to the tip (:func:`hubbeam_ctrl.study.certificate.angle_error_tip_gain`,
  a bound for every sequence of rounding errors): within the task's tip band the counts cannot
  hold the tip outside it; past it a limit cycle between counts can (:func:`count_prediction`).

The prediction is stated beside the run's verdict (the run judges hunting after the fact:
:attr:`hubbeam_ctrl.study.metrics.Evidence.friction_hunting`).
"""

from __future__ import annotations

import math

from .certificate import angle_error_tip_gain, hold_gain

__all__ = ["friction_prediction", "count_prediction"]

#: A compliance below this [rad per N m] is integral action (the offset-free estimator cancels a
#: constant torque exactly at rest; rounding leaves about 1e-13).
INTEGRAL_COMPLIANCE = 1e-9


def friction_prediction(controller, params, spin: float, rig, angle_band: float) -> dict | None:
    """The dead band or the hunting that the rig's friction predicts for a linear loop at rest.

    Parameters
    ----------
    controller : Controller
        On the rig (its ``rig_hardware``), with a linear form.
    params : Params
        The evaluation plant's parameters.
    spin : float
        Spin rate at the end of the task [rad/s].
    rig : Rig
        Its ``friction`` (``coulomb``, ``breakaway``) and ``sensors.encoder_step``.
    angle_band : float
        The task's settling band on the hub angle [rad].

    Returns
    -------
    dict or None
        ``friction_hold_rad`` (the largest offset friction can hold [rad]; 0 with integral
        action), ``friction_hunting_predicted`` (bool: stick-slip about the target, from a Stribeck
        drop with integral action or from a dead band within half a count) and
        ``friction_prediction`` (one sentence); None without Coulomb friction or for a loop that is
        not stable.
    """
    f = rig.friction
    breakaway = f.coulomb if f.breakaway is None else f.breakaway
    if breakaway <= 0.0:
        return None
    compliance = hold_gain(controller, params, spin)
    if not math.isfinite(compliance):
        return None
    q = rig.sensors.encoder_step
    counts = (lambda x: f" ({x / q:.3g} counts)") if q > 0 else (lambda x: "")
    if compliance > INTEGRAL_COMPLIANCE:
        hold = breakaway * compliance
        where = "inside" if hold <= angle_band else "outside"
        text = (f"no integral action: the loop's compliance at rest is {compliance:.3g} rad/N m, so the breakaway "
                f"torque {breakaway:.3g} N m can hold the hub up to {hold:.3g} rad{counts(hold)} off the target, "
                f"{where} the angle band ({angle_band:.3g} rad)")
        if q > 0 and hold < q / 2:
            # the law sees counts: one count off, its command at rest is q / compliance
            push = q / compliance
            text += (f"; that is within half a count, so the hub can rest only where the encoder reads the target's "
                     f"count: a count off, the law's command at rest is {push:.3g} N m, {push / breakaway:.3g} x the "
                     "breakaway torque, and a hub that stops there slips again once it builds up: stick-slip between "
                     "counts is predicted until the hub stops on the target's count")
            return {"friction_hold_rad": hold, "friction_hunting_predicted": True, "friction_prediction": text}
        text += "; no limit cycle (the hub stops in this dead band)"
        return {"friction_hold_rad": hold, "friction_hunting_predicted": False, "friction_prediction": text}
    hunting = breakaway > f.coulomb
    text = ("integral action: friction holds no offset; the command builds up to the breakaway torque "
            f"{breakaway:.3g} N m and the hub slips")
    text += (f"; the breakaway exceeds the sliding friction ({f.coulomb:.3g} N m), so the slip overshoots and "
             "sticks again: a stick-slip hunting limit cycle about the target is predicted" if hunting else
             "; breakaway and sliding friction are equal, so no hunting is predicted")
    if q > 0:
        text += (f"; the encoder reads the angle to +-{q / 2:.3g} rad (half a count): the hub can rest only where the "
                 "encoder reads the target's count, and on any other the integral action builds the command up until "
                 "the hub slips again")
    return {"friction_hold_rad": 0.0, "friction_hunting_predicted": hunting, "friction_prediction": text}


def count_prediction(controller, params, spin: float, rig, tip_band: float) -> dict | None:
    """What the rig's encoder can leave on the tip at rest: a bound from the linear loop.

    Parameters
    ----------
    controller : Controller
        On the rig, with a linear form that reads the hub angle.
    params : Params
        The evaluation plant's parameters.
    spin : float
        Spin rate at the end of the task [rad/s].
    rig : Rig
        Its ``sensors.encoder_step`` [rad].
    tip_band : float
        The task's settling band on the tip deflection [m].

    Returns
    -------
    dict or None
        ``count_tip_bound_m`` (half a count times
        :func:`~hubbeam_ctrl.study.certificate.angle_error_tip_gain` [m]), ``count_holds_tip``
        (the bound is past the band) and ``count_prediction`` (one sentence, with the encoder
        that would bring the bound within the band); None without an encoder, for a law that
        does not read the angle or a loop that is not stable.
    """
    q = rig.sensors.encoder_step
    if not q:
        return None
    gain = angle_error_tip_gain(controller, params, spin)
    if not (math.isfinite(gain) and gain > 0.0):
        return None
    bound = gain * q / 2.0
    past = bound > tip_band
    text = (f"the encoder reads the angle to +-{q / 2:.3g} rad (half a count), which moves the tip by at most "
            f"{bound:.3g} m through this loop (its peak-to-peak gain from the angle reading to the tip, "
            f"{gain:.3g} m/rad), ")
    if past:
        counts = 2.0 * math.pi * gain / (2.0 * tip_band)
        text += (f"past the tip band ({tip_band:.3g} m): a limit cycle between counts can hold the tip outside it "
                 f"(the bound is within it from about {counts:.3g} counts per revolution with this law, or "
                 "widen --settle-tip)")
    else:
        text += f"within the tip band ({tip_band:.3g} m): the counts cannot hold the tip outside it"
    return {"count_tip_bound_m": bound, "count_holds_tip": past, "count_prediction": text}

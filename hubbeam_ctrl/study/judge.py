"""One verdict for one run: the nonlinear run's metrics with the linear certificate.

:func:`judge` is what :func:`~hubbeam_ctrl.study.compare.compare` and the sweep engine
(:mod:`hubbeam_ctrl.study.sweep`) call for every closed-loop run, so a comparison, a
sweep case and the CLI judge a run the same way: the metrics of
:func:`~hubbeam_ctrl.study.metrics.closed_loop_metrics` (envelope growth of tip, torque and
angle error fitted over the residual window in blocks of half a period of the design's
first bending mode: abs(x) peaks twice a period), decided together with the controller's sampled linear loop on the
evaluation plant's modes (:func:`~hubbeam_ctrl.study.certificate.certify`, at the hub rates
of the start and of the end of the run).
"""

from __future__ import annotations

import math

import numpy as np

from controllers.scaling import first_mode
from hubbeam_ctrl.core.errors import HubbeamError
from hubbeam_ctrl.study.certificate import certify
from hubbeam_ctrl.study.friction_bound import count_prediction, friction_prediction
from hubbeam_ctrl.study.frozen import frozen_check
from hubbeam_ctrl.study.metrics import SATURATION_LIMIT, closed_loop_metrics
from hubbeam_ctrl.study.settling import describe_end
from hubbeam_ctrl.study.yardstick import task_limit, yardstick_metrics

__all__ = ["judge", "residual_modes_for", "margin_cause", "count_cause", "same_laws", "THIN_DISK_MARGIN"]

#: A loop whose disk margin (as it runs: drive, sensors, delay) is below this is called near
#: instability in a verdict's reason [-].
THIN_DISK_MARGIN = 0.1


def judge(result, controller, scenario, plant_params, name: str | None = None, limit: dict | None = None):
    """Metrics and verdict of one closed-loop run, with its linear certificate.

    Parameters
    ----------
    result : Result
        The closed-loop run (with the task's reference).
    controller : Controller
        The controller that ran.
    scenario : Scenario
        The task: maneuver time, torque limit and settling bands.
    plant_params : Params
        The evaluation plant's parameters (all of its transverse modes).
    name : str, optional
        Registry name of the controller (default ``controller.name``).
    limit : dict, optional
        The task's yardstick (:func:`~hubbeam_ctrl.study.yardstick.task_limit`; default the
        rigid body's bound): the metrics get ``limit_s``, ``settling_over_limit`` and
        ``residual_pct_of_L``; with the scenario's ``band_sources``, ``settle_angle_source``
        and ``settle_tip_source`` (where each settling band came from).

    Returns
    -------
    tuple
        ``(metrics, certificate)``: the metrics dictionary (with ``verdict``,
        ``verdict_reason`` and the ``loop_*`` entries) and the
        :class:`~hubbeam_ctrl.study.certificate.Certificate`.
    """
    # the hub rates at the start and the end of the run (a run that diverged past the model's
    # spin range gives no linearisation there: its verdict is the run's)
    spins = tuple(w for w in (float(result.v[0, 0]), float(result.v[-1, 0]))
                  if math.isfinite(w) and abs(w) <= plant_params.max_spin)
    cert = certify(controller, plant_params, spins=spins, name=name)
    block_s = math.pi / first_mode(controller.design)     # half a period of the first bending mode
    metrics = closed_loop_metrics(result, scenario.t_f, tau_max=scenario.tau_max, block_s=block_s,
                                  certificate=cert, **(scenario.bands or {}))
    metrics.update(yardstick_metrics(metrics, scenario, limit or task_limit(scenario)))
    for key, text in (getattr(scenario, "band_sources", None) or {}).items():
        metrics[f"{key}_source"] = text        # where each settling band came from (study.bands)
    return metrics, cert


def residual_modes_for(settings, plant_modes: int):
    """``settings`` with its residual modes set to the evaluation plant's transverse modes.

    A quadratic design with ``residual_control`` (the default of ``for_scenario``) and no
    ``residual_modes`` of its own computes its gain (and the LQG its filter) on the design
    model with the plant's modes; other settings are returned unchanged.

    Parameters
    ----------
    settings : ControllerSettings
    plant_modes : int
        Transverse modes of the evaluation plant.

    Returns
    -------
    ControllerSettings
    """
    if getattr(settings, "residual_control", False) and getattr(settings, "residual_modes", 0) is None:
        return settings.replace(residual_modes=int(plant_modes))
    return settings


def margin_cause(metrics: dict, margins, delay_s: float = 0.0) -> None:
    """Add to a verdict's reason what the loop's margins say about it (in place).

    The margins are of the loop as it runs (:func:`controllers.analysis.loop_margins` on the
    design model with the rig's drive, sensors and computation delay), so the delay margin is the
    delay the loop tolerates beyond the rig's own. A loop that is stable but barely (disk margin
    below :data:`THIN_DISK_MARGIN`, or a delay margin below the rig's own delay: the loop would not
    survive the delay doubling, e.g. a computation that overruns its sample) is named as the cause
    of a run that did not settle: saturation, friction and the evaluation plant's differences tip a
    loop without margin over.

    Parameters
    ----------
    metrics : dict
        One run's metrics (``verdict``, ``verdict_reason``); gets ``delay_s`` [s] and
        ``delay_margin_ok`` when ``margins`` is given.
    margins : LoopMargins or None
    delay_s : float
        The rig's computation delay [s].
    """
    if margins is None:
        return
    metrics["delay_s"] = float(delay_s)
    metrics["delay_margin_ok"] = bool(margins.delay_margin_s > delay_s) if delay_s > 0 else True
    thin = margins.disk_margin < THIN_DISK_MARGIN
    if metrics.get("verdict") in ("settled",) or not (thin or not metrics["delay_margin_ok"]):
        return
    what = (f"the loop as it runs has a disk margin of {margins.disk_margin:.3g} and a delay margin of "
            f"{1e3 * margins.delay_margin_s:.3g} ms")
    if delay_s > 0:
        what += f" (the rig's computation delay: {1e3 * delay_s:.3g} ms)"
    metrics["verdict_reason"] = f"{metrics.get('verdict_reason', '')}; cause: {what}, near instability".lstrip("; ")


def count_cause(metrics: dict, prediction: dict | None) -> None:
    """Add what the encoder's counts can leave on the tip to a run's metrics and, for a run that
    did not settle, name it as the cause when it reaches past the tip band (in place).

    A run called ``"unstable"`` only because the tip's envelope rose in the window (the command off
    its limit, the hub-angle error not growing) in a loop whose linear certificate is stable, with the
    tip within the bound, becomes ``"not settled"``: a stable loop driven by a bounded quantisation
    error stays within that bound. Found on a 0.88 m steel link on 4096 counts without a tachometer
    (``tests/test_friction_bound.py``): its envelope rose at 1.34 1/s against a 0.9 1/s resolution,
    "unstable", while a run 4 times longer shows a steady cycle within the 2.75 mm bound
    (``benchmarks/results/bench_verdict_causes.json``).

    Parameters
    ----------
    metrics : dict
        One run's metrics (``verdict``, ``verdict_reason``).
    prediction : dict or None
        :func:`hubbeam_ctrl.study.friction_bound.count_prediction` of its loop.
    """
    if not prediction:
        return
    metrics.update(prediction)
    verdict, bound = metrics.get("verdict"), prediction["count_tip_bound_m"]
    if not prediction["count_holds_tip"] or verdict not in ("not settled", "unstable"):
        return
    what = (f"the encoder's half count can move the tip by up to {bound:.3g} m through this loop, past the tip band "
            "(a limit cycle between counts)")
    if verdict == "unstable":
        resolution = metrics.get("growth_resolution_per_s") or 0.0
        rates = {k: metrics.get(f"{k}_growth_rate_per_s") or 0.0 for k in ("tip", "angle", "torque")}
        radius = metrics.get("loop_spectral_radius")
        if not (radius is not None and radius < 1.0 and metrics.get("residual_tip_max_m", math.inf) <= bound):
            return
        saturated = (metrics.get("torque_saturated_fraction") or 0.0) > SATURATION_LIMIT
        if all(r <= resolution for r in rates.values()):
            # a command at its limit in a loop whose certificate is stable, nothing growing and the tip within
            # the bound: the counts' limit cycle, bounded
            what = (f"a limit cycle between encoder counts at the command's limit, bounded: nothing grows and the "
                    f"tip stays within the {bound:.3g} m the half count can move it through this loop")
        elif not saturated and rates["angle"] <= resolution:
            # the tip's envelope rises, off the limit, in a stable linear loop, and stays within what the
            # counts can drive through it: a bounded input through a stable loop, not growth
            metrics["verdict"] = "not settled"
            what = (f"the tip's envelope rises at {rates['tip']:.3g} 1/s (resolution {resolution:.3g} 1/s) within the "
                    f"{bound:.3g} m the encoder's half count can move it through this loop, whose linear certificate "
                    f"is stable (radius {radius:.7f}) and whose command stays off its limit: a limit cycle between "
                    "counts, bounded, judged by its bands (not settled), not growth")
            metrics["verdict_reason"] = describe_end(False, metrics.get("inside_bands_at_end_s"),
                                                     metrics.get("settle_hold_s") or 0.0)
        else:
            return
    metrics["verdict_reason"] = f"{metrics.get('verdict_reason', '')}; cause: {what}".lstrip("; ")


def rest_count_cause(metrics: dict, result, rig) -> None:
    """A settled run whose hub rests where the encoder reads a count at which the law's command at rest
    is past the breakaway torque will slip again: "not settled", the cause named (in place).

    Without integral action the law's command at rest is the reading's offset from the target over the
    loop's compliance at rest (:func:`~hubbeam_ctrl.study.friction_bound.friction_prediction`'s
    ``friction_hold_rad`` is the breakaway torque times that compliance). Where the encoder's reading at
    the run's end is further off the target than that hold, the command builds up past the breakaway
    torque (the law's slower states take their time) and the hub slips. With integral action
    (``friction_hold_rad`` 0) nothing is said: a hub resting a count off also slips, but where it goes
    (a count on, inside a band of counts) the run does not tell. Found on a random rig
    (``benchmarks/fuzz_rigs.py link 41`` rig 7, 40 000 counts) while its filter's integral leaked (a dead
    band of 0.01 counts; exact since, :func:`controllers.filter_model.filter_matrices`): "settled" in the
    default window with the hub stuck a count off while the command crept up; the run 4 times longer
    slipped at 2.3 s and stuck and slipped again to its end.

    Parameters
    ----------
    metrics : dict
        One run's metrics (``verdict``, ``verdict_reason``, ``friction_hold_rad``).
    result : Result
        The run (its last hub angle and reference [rad]).
    rig : Rig
        Its ``friction`` and ``sensors.encoder_step``.
    """
    hold, q = metrics.get("friction_hold_rad"), rig.sensors.encoder_step
    if metrics.get("verdict") != "settled" or not hold or not q > 0 or result.theta_ref is None:
        return
    reading = q * math.floor(float(result.theta[-1]) / q + 0.5)
    offset = reading - float(result.theta_ref[-1])
    if abs(offset) <= hold:
        return
    breakaway = rig.friction.coulomb if rig.friction.breakaway is None else rig.friction.breakaway
    push = abs(offset) / hold * breakaway
    law = (f"the law's command at rest is {push:.3g} N m, {push / breakaway:.3g} x the breakaway torque: it slips "
           "again once the command builds up")
    metrics.update(verdict="not settled", settling_time_s=None, settling_over_limit=None,
                   rest_reading_offset_rad=offset)
    metrics["verdict_reason"] = (
        f"{metrics.get('verdict_reason', '')}; cause: the hub rests where the encoder reads {offset / q:+.3g} counts "
        f"off the target, where {law} (stick-slip between counts; a longer run shows it)").lstrip("; ")


#: A run that did not settle names its loop's slowest pole when the residual window is shorter than this
#: many of its decay times (the pole's part of a disturbance falls by e^3, 95 %, in them).
SLOW_POLE_SPANS = 3.0


def slow_pole_cause(metrics: dict, window_s: float) -> None:
    """For a run that did not settle in a loop the certificate calls stable, with the tip's envelope not
    rising in the window, name the loop's slowest pole when the residual window is shorter than
    :data:`SLOW_POLE_SPANS` of its decay times (in place): the run may have ended while that pole's
    part still decays; a longer run tells. A rising tip (a count cycle building up, as on a 2.4 m strip
    whose counts hold it at 5.7 mm against a 0.3 mm band) is not named so.

    Found on a random rig (a 1 m aluminium link, 1024 counts, Coulomb friction, 2 ms): the tip fell
    e-fold every 3.1 s after the slew (the loop's slowest pole, the hub's), from 0.5 mm toward its
    0.13 mm band, and the 4.8 s window ended before it got there: "not settled" with nothing named.

    Parameters
    ----------
    metrics : dict
        One run's metrics (``verdict``, ``verdict_reason``, ``loop_slowest_decay_s``,
        ``loop_certificate``, ``tip_growth_rate_per_s``); ``slow_pole_s`` is added when named.
    window_s : float
        The residual window's length [s].
    """
    tau = metrics.get("loop_slowest_decay_s")
    falling = (metrics.get("tip_growth_rate_per_s") or 0.0) <= 0.0     # a rising tip is not a pole's tail
    if (metrics.get("verdict") != "not settled" or metrics.get("loop_certificate") != "stable" or tau is None
            or not SLOW_POLE_SPANS * tau > window_s or not falling):
        return
    metrics["slow_pole_s"] = tau
    metrics["verdict_reason"] = (f"{metrics.get('verdict_reason', '')}; cause: the loop's slowest pole decays "
                                 f"e-fold in {tau:.3g} s, and the residual window ({window_s:.3g} s) is shorter "
                                 f"than {SLOW_POLE_SPANS:g} of that: a run {SLOW_POLE_SPANS * tau - window_s:.3g} s "
                                 "longer (--t-end) tells whether it settles").lstrip("; ")


def name_causes(metrics: dict, result, controller, margins, sc, ev, rest_rate: float, rig) -> None:
    """What a comparison adds to a run's metrics after its verdict (in place): the loop's margins and
    their cause, on a rig what friction and the encoder's counts leave at rest, the loop frozen at
    the bent beam, and the loop's slowest pole for a run that did not settle.

    Parameters
    ----------
    metrics : dict
        The run's metrics (:func:`judge`).
    result : Result
        The run.
    controller : Controller
        As it ran.
    margins : LoopMargins or None
        Its loop margins (None: no linear form; then only the slowest pole is looked at).
    sc : Scenario
        The comparison's scenario (its ``t_f``, ``t_end``, ``dt`` and bands).
    ev : EvaluationPlant
        The evaluation plant.
    rest_rate : float
        The reference's hub rate at rest [rad/s].
    rig : Rig or None
    """
    if margins is not None:
        metrics.update(disk_margin=margins.disk_margin, gain_margin_upper=margins.gain_margin_upper,
                       gain_margin_lower=margins.gain_margin_lower, phase_margin_deg=margins.phase_margin_deg,
                       delay_margin_s=margins.delay_margin_s)
        margin_cause(metrics, margins, 0.0 if rig is None else rig.timing.delay * sc.dt)
        if rig is not None:                  # what friction leaves at rest, predicted before the run
            metrics.update(friction_prediction(controller, ev.params, rest_rate, rig, sc.bands["settle_angle"]) or {})
            rest_count_cause(metrics, result, rig)
            count_cause(metrics, count_prediction(controller, ev.params, rest_rate, rig, sc.bands["settle_tip"]))
        frozen_check(metrics, result, controller, ev.model, ev.params, sc.t_f)
    slow_pole_cause(metrics, sc.t_end - sc.t_f - sc.bands["residual_delay"])


def same_laws(controllers: dict, metrics: dict) -> list:
    """Notes for controllers that are one law by construction (on a rig the observer-fed LQR is the
    LQG: the same gain on the same Kalman filter); each such row gets ``same_law_as`` (in place).

    Parameters
    ----------
    controllers : dict
        Name -> controller as it ran.
    metrics : dict
        Name -> metrics of its run.

    Returns
    -------
    list of str
        One note per controller whose law (:meth:`~controllers.Controller.feedback_matrices`) equals
        an earlier one's within 1e-9 (MPC, whose plan has constraints, aside).
    """
    laws = {}
    for name, ctrl in controllers.items():
        inner = ctrl
        while hasattr(inner, "inner"):
            inner = inner.inner
        if hasattr(inner, "horizon") or hasattr(getattr(inner, "settings", None), "horizon"):
            continue                     # a constrained plan: its linear form is only its unconstrained law
        try:
            laws[name] = [np.asarray(M, dtype=float) for M in ctrl.feedback_matrices()[:4]]
        except HubbeamError:
            continue
    out, names = [], list(laws)
    for i, a in enumerate(names):
        for b in names[:i]:
            same = all(x.shape == y.shape and np.allclose(x, y, rtol=1e-9,
                                                          atol=1e-12 * max(1.0, np.abs(y).max(initial=0)))
                       for x, y in zip(laws[a], laws[b]))
            if same and "same_law_as" not in metrics[a]:
                metrics[a]["same_law_as"] = b
                out.append(f"{a} is the same linear law as {b} here (the same gain on the same Kalman filter "
                           f"of the rig's sensors): one controller, two rows")
    return out

"""Figures of merit of a closed-loop run (one flat dictionary per run).

Names are snake case with their unit as suffix (``_m``, ``_rad``, ``_s``, ``_nm``,
``_ms``...), the same in ``metrics.csv``, ``metrics.json`` and the printed tables. The one
nested entry is ``plant_params`` (the evaluation plant's :class:`Params` as a dictionary,
in ``metrics.json`` only).

Units are the drive's: the controller's command is a voltage on a DC motor and a hub torque
on a torque source, so the command's own figures (unit ``"command"`` in
:data:`METRIC_UNITS`) are in ``command_unit`` (``"V"`` or ``"N m"``), and the voltage, the
current and the hub torque each have their own metric in their own unit
(:mod:`hubbeam_ctrl.study.drive_figures`); no metric in N m ever holds volts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.validation import check_positive
from hubbeam_ctrl.sim.hardware import Hardware, drive_torque
from hubbeam_ctrl.study.drive_figures import command_limit, drive_metrics, drive_of, friction_of
from hubbeam_ctrl.study.settling import describe_end, settle_hold, settling_time

__all__ = ["closed_loop_metrics", "METRIC_UNITS", "settling_time", "VERDICTS", "verdict", "Evidence",
           "residual_growth", "saturated_fraction", "GROWTH_LIMIT", "SATURATION_LIMIT", "FRICTION_HUNTING_BOUND",
           "GrowthFit", "envelope_growth", "GROWTH_RESOLUTION", "STOP_CAUSES"]

#: The verdicts of a closed-loop run, in the order they are tested (see :func:`verdict`).
VERDICTS = ("failed", "diverged", "unstable", "settled", "not settled")
#: The verdicts whose run reports no settling time (``settling_time_s`` None).
_NOT_SETTLING = ("failed", "diverged", "unstable")
#: Why a run stopped early (``result.stats["stop_cause"]``): ``"diverged"`` is the plant
#: leaving its range; the others are failures of the run, not of the loop's stability.
STOP_CAUSES = ("diverged", "integrator", "controller", "wall_clock")
#: The residual-window envelope growth that the old quarter-ratio rule called unstable; kept
#: as the metric ``residual_growth`` (the verdict uses :func:`envelope_growth`) [-].
GROWTH_LIMIT = 2.0
#: An envelope that grows by less than this factor over the fitted span is not resolved
#: as growth (block maxima of a steady or noisy oscillation scatter by tens of %) [-].
GROWTH_RESOLUTION = 1.5
#: A run whose command sits at its limit (``tau_max``; ``V_max`` on a DC motor) for more than
#: this fraction of the residual window is in a saturation limit cycle, i.e. unstable [-].
SATURATION_LIMIT = 0.25
#: A torque that rises in the residual window but stays within this many breakaway torques of the
#: hub's friction, with a stable certificate and a quiet tip, is friction hunting, not growth [-].
FRICTION_HUNTING_BOUND = 3.0

#: Metric name -> (unit, description), in table order. The unit ``"command"`` is the command's,
#: given per run in ``command_unit``: ``"V"`` on a DC motor, ``"N m"`` on a torque source.
METRIC_UNITS = {
    "peak_tip_m": ("m", "peak |v_tip| over the whole run"),
    "residual_tip_rms_m": ("m", "RMS of v_tip from t_f + delay to the end"),
    "residual_tip_max_m": ("m", "max |v_tip| from t_f + delay to the end"),
    "angle_error_tf_rad": ("rad", "hub angle minus reference at t_f"),
    "final_angle_error_rad": ("rad", "hub angle minus reference at the end"),
    "settling_time_s": ("s", "time after which |angle error| and |v_tip| stay inside their bands "
                             "(None: not within the run)"),
    "limit_s": ("s", "the task's physical limit: the rigid body's shortest time with tau_max, or the "
                     "time-optimal slew (limit_kind says which; hubbeam_ctrl.study.yardstick)"),
    "settling_over_limit": ("-", "settling time over limit_s (1: the physical limit; None: not settled)"),
    "settle_angle_rad": ("rad", "settling band of the hub-angle error (settle_angle_source says where it came from)"),
    "settle_tip_m": ("m", "settling band of |v_tip| (settle_tip_source says where it came from)"),
    "settle_hold_s": ("s", "time a settled run stays inside both bands before its end: a tenth of the residual "
                           "window, at least one period of the first bending mode"),
    "inside_bands_at_end_s": ("s", "time the run has been inside both bands at its end (0: outside at the end)"),
    "residual_pct_of_L": ("%", "residual tip vibration (max |v_tip| in the residual window) in % of L"),
    "peak_command": ("command", "peak |u| of the controller's command (V on a DC motor, N m on a torque source)"),
    "peak_command_step": ("command", "largest change of the command from one sample to the next"),
    "time_at_limit_s": ("s", "time the command sits within 0.1 % of its limit (V_max on a DC motor, tau_max on a "
                             "torque source), over the whole run"),
    "time_at_limit_slew_s": ("s", "the same, up to t_f (during the slew)"),
    "peak_voltage_v": ("V", "peak |V| of the DC motor's voltage, the command clipped to V_max (None: torque source)"),
    "peak_current_a": ("A", "peak |i| of the DC motor's current clip((V - k_e N thd) / R, +-I_max) at the recorded "
                            "hub rate (None: torque source)"),
    "peak_hub_torque_nm": ("N m", "peak |torque| the drive put on the hub, friction aside (the command on a torque "
                                  "source; N eta_motor k_t i times the gear's efficiency on a DC motor)"),
    "peak_torque_nm": ("N m", "peak_hub_torque_nm under its older name: the hub torque, never a voltage"),
    "torque_squared_integral_n2m2s": ("N^2 m^2 s", "integral of the drive's hub torque squared (held command)"),
    "torque_saturated_fraction": ("-", "fraction of the residual window with the command at its limit (tau_max; "
                                       "V_max on a DC motor)"),
    "residual_growth": ("-", "max |v_tip| in the last quarter of the residual window over the first quarter"),
    "tip_growth_rate_per_s": ("1/s", "growth rate of the |v_tip| envelope over the last half of the residual window"),
    "torque_growth_rate_per_s": ("1/s", "growth rate of the envelope of the torque's sample-to-sample ripple"),
    "angle_growth_rate_per_s": ("1/s", "growth rate of the |hub-angle error| envelope"),
    "growth_resolution_per_s": ("1/s", "smallest tip growth rate the window resolves (ln 1.5 over the fitted "
                                       "span, or twice the slope's standard error)"),
    "loop_spectral_radius": ("-", "largest |z| of the sampled linear loop on the evaluation plant's modes"),
    "loop_worst_hz": ("Hz", "frequency of that pole as seen in the samples (aliased into 0..fs/2)"),
    "loop_worst_mode_hz": ("Hz", "true frequency of the plant mode it comes from"),
    "loop_growth_time_s": ("s", "time constant of a growing linear loop (None: it does not grow)"),
    "loop_damping_needed": ("-", "modal damping ratio in every mode that makes a growing loop stable"),
    "loop_design_modes_radius": ("-", "largest |z| of the loop poles of the rigid body and the design modes"),
    "robust_verdict": ("", "robust certificate over the rig's [uncertainty]: certified / not certified"),
    "robust_radius": ("-", "largest spectral radius found over the uncertainty set (searched)"),
    "robust_worst": ("", "the plant of that radius: uncertain parameter -> value (SI)"),
    "robust_worst_spin_rad_s": ("rad/s", "spin rate of the worst radius"),
    "robust_worst_source": ("", "plant mode (or the controller) the worst pole comes from"),
    "robust_nominal_radius": ("-", "spectral radius at the nominal rig"),
    "robust_grid_radius": ("-", "largest spectral radius on the search's grid alone"),
    "robust_bound": ("-", "first-order Bauer-Fike bound on the radius over the grid's cells"),
    "robust_evaluations": ("", "loops the robust certificate evaluated"),
    "robust_undamped_radius": ("-", "the worst plant's radius without structural damping"),
    "robust_disk_margin": ("-", "smallest disk margin found over the set (corners, nominal, worst)"),
    "robust_disk_margin_at": ("", "where that disk margin was found"),
    "robust_settling_time_constant_s": ("s", "-dt / ln(worst radius): the slowest decay over the set"),
    "robust_set": ("", "the uncertainty set: parameter -> [lo, hi] (SI)"),
    "robust_not_covered": ("", "uncertain parameters the linear loop does not see (Coulomb friction)"),
    "robust_plant_modes": ("", "bending modes of the robust certificate's linear plant"),
    "robust_wall_s": ("s", "wall time of the robust certificate"),
    "step_time_median_ms": ("ms", "median wall time of one controller call"),
    "step_time_p99_ms": ("ms", "99th percentile of the controller call time"),
}


#: Entries of the result's settings that describe the plant and its integration step.
_PLANT_KEYS = ("plant_model", "plant_modes", "plant_axial_modes", "design_modes", "plant_modes_reason",
               "substeps", "step_s", "step_mode", "step_mode_hz", "step_mode_frequency_error", "step_reason")


def residual_growth(v_tip) -> float:
    """Envelope growth of a vibration: ``max |v|`` of its last quarter over its first quarter.

    Parameters
    ----------
    v_tip : ndarray
        Tip deflection over the residual window [m].

    Returns
    -------
    float
        [-]; about 1 for a steady oscillation, < 1 for a decaying one, NaN for fewer than
        eight samples.

    Examples
    --------
    >>> t = np.linspace(0, 10, 1001)
    >>> round(residual_growth(np.exp(0.1 * t) * np.sin(20 * t)), 1)     # about e^(0.1 * 7.5 s)
    2.1
    """
    v = np.abs(np.asarray(v_tip, dtype=float))
    if v.size < 8:
        return float("nan")
    q = v.size // 4
    first = np.max(v[:q])
    return float(np.max(v[-q:]) / first) if first > 0 else float("inf") if np.max(v[-q:]) > 0 else 1.0


def saturated_fraction(tau, tau_max: float) -> float:
    """Fraction of torque samples at the limit, ``|tau| >= (1 - 1e-6) tau_max`` [-] (NaN if empty).

    Parameters
    ----------
    tau : array_like
        Torque samples [N m].
    tau_max : float
        Limit [N m].
    """
    tau = np.asarray(tau, dtype=float)
    if not tau.size:
        return float("nan")
    return float(np.mean(np.abs(tau) >= (1 - 1e-6) * tau_max))


@dataclass(frozen=True)
class GrowthFit:
    """The fitted growth of a signal's envelope.

    Attributes
    ----------
    rate_per_s : float
        Least-squares slope of ``ln`` of the block maxima of ``|x|`` [1/s] (NaN: too few
        blocks).
    resolution_per_s : float
        The larger of ``ln(GROWTH_RESOLUTION)`` over the fitted span and twice the standard
        error of the fitted slope (four blocks or more) [1/s]: slower growth is not resolved.
    final : float
        The last block's maximum of ``|x|`` (units of ``x``).
    """

    rate_per_s: float
    resolution_per_s: float
    final: float

    def grows(self, floor: float) -> bool:
        """Resolved growth of an envelope that ends above ``floor`` (units of ``x``).

        Parameters
        ----------
        floor : float
            Level below which growth does not matter (numerical noise).
        """
        return bool(self.rate_per_s > self.resolution_per_s and self.final > floor)


def envelope_growth(t, x, block_s: float) -> GrowthFit:
    """Growth rate of the envelope of ``x`` over the last half of ``t``.

    The last half of the window is cut into blocks of at least ``block_s`` (and at least
    four samples, at most twelve blocks); the block maxima of ``|x|`` are fitted by
    ``ln max = a + rate t`` in the least-squares sense. Fitting the last half, not the
    whole window, lets a growing component show through the decay of the maneuver's
    transient.

    Parameters
    ----------
    t : ndarray
        Times [s] (uniform).
    x : ndarray
        The signal (tip deflection, torque ripple, angle error).
    block_s : float
        Shortest block [s], e.g. one period of the slowest oscillation expected.

    Returns
    -------
    GrowthFit

    Examples
    --------
    >>> t = np.linspace(0, 20, 2001)
    >>> round(envelope_growth(t, 1e-3 * np.exp(0.1 * t) * np.sin(20 * t), 0.5).rate_per_s, 2)
    0.1
    >>> envelope_growth(t, np.sin(20 * t), 0.5).rate_per_s < envelope_growth(t, np.sin(20 * t), 0.5).resolution_per_s
    True
    """
    t = np.asarray(t, dtype=float)
    x = np.abs(np.asarray(x, dtype=float))
    half = t.size // 2
    t, x = t[half:], x[half:]
    nan = float("nan")
    if t.size < 8:
        return GrowthFit(nan, nan, float(np.max(x)) if x.size else nan)
    span = float(t[-1] - t[0])
    dt = span / max(t.size - 1, 1)
    per = max(4, int(math.ceil(block_s / dt)) if block_s > 0 else 4, t.size // 12)
    n_blocks = t.size // per
    if n_blocks < 3:
        return GrowthFit(nan, nan, float(np.max(x)))
    start = t.size - n_blocks * per           # whole blocks, ending at the last sample
    xb = x[start:].reshape(n_blocks, per)
    tb = t[start:].reshape(n_blocks, per).mean(axis=1)
    peaks = np.max(xb, axis=1)
    final = float(peaks[-1])
    tiny = np.finfo(float).tiny
    if not np.all(np.isfinite(peaks)):
        return GrowthFit(math.inf, 0.0, final)
    y = np.log(np.maximum(peaks, tiny))
    (rate, offset) = np.polyfit(tb, y, 1)
    resolution = math.log(GROWTH_RESOLUTION) / max(float(tb[-1] - tb[0]), dt)
    if n_blocks >= 4:          # and twice the slope's standard error: scatter is not growth
        sxx = float(np.sum((tb - tb.mean()) ** 2))
        stderr = math.sqrt(float(np.sum((y - (rate * tb + offset)) ** 2)) / (n_blocks - 2) / sxx)
        resolution = max(resolution, 2.0 * stderr)
    return GrowthFit(float(rate), float(resolution), final)


@dataclass(frozen=True)
class Evidence:
    """What a verdict is decided from.

    Attributes
    ----------
    stop_cause : str or None
        Why the run stopped early (:data:`STOP_CAUSES`), None if it completed.
    growing : tuple of str
        Signals whose envelope grows (``"tip"``, ``"torque"``, ``"angle"``).
    saturated : float
        :func:`saturated_fraction` of the residual window [-] (NaN: no torque limit).
    settled : bool
        Inside the settling bands for the hold before the end (:func:`settle_hold`).
    certificate_grows : bool or None
        The linear certificate's loop grows (None: no certificate).
    friction_bound : float or None
        Largest hub torque of the drive in the residual window over the hub's breakaway torque
        [-] (None: no Coulomb friction); see :attr:`friction_hunting`.
    inside_at_end_s : float or None
        How long the run has been inside both bands at its end [s] (None: not measured).
    hold_s : float
        The hold a settled run needs [s] (:func:`settle_hold`; 0: the last sample decides).
    """

    stop_cause: str | None
    growing: tuple
    saturated: float
    settled: bool
    certificate_grows: bool | None = None
    friction_bound: float | None = None
    inside_at_end_s: float | None = None
    hold_s: float = 0.0

    @property
    def friction_hunting(self) -> bool:
        """Only the torque's ripple (and the hub-angle error) move, within a bound the hub's
        Coulomb friction sets, in a loop whose linear certificate is stable.

        Coulomb friction and an encoder's counts are bounded nonlinearities: a loop that is stable
        without them stays bounded with them, and with integral action it hunts (stick-slip: the
        command builds up to the breakaway torque, the hub slips by a count, sticks again). Its
        torque envelope rises while the command works up to the breakaway torque, which is not
        growth. ``friction_bound`` is the largest hub torque in the residual window over the
        breakaway torque (None: no friction); at most :data:`FRICTION_HUNTING_BOUND` counts.
        """
        return (self.certificate_grows is False and self.friction_bound is not None
                and self.friction_bound <= FRICTION_HUNTING_BOUND and "tip" not in self.growing
                and set(self.growing) <= {"torque", "angle"} and bool(self.growing)
                and not self.saturated > SATURATION_LIMIT)

    @property
    def torque_build_up(self) -> bool:
        """Only the torque's ripple grows, in a settled run whose linear certificate is stable.

        After the slew the loop moves little about rest, where the certificate's linear loop is
        exact; a ripple that rises there while tip and hub stay in their bands and the torque
        stays off its limit is the loop's response to sensor noise, whose envelope over a short
        window scatters and can rise, not growth. Measured: the lab arm's LQG at 1.3 x its
        time-optimal slew, ripple 0.011 N m rms (0.7 % of ``tau_max``) rising at 1.19 1/s over
        the last 0.8 s (resolution 0.77 1/s), certificate stable, settled at 1.08 s; the same run
        without sensor noise has a ripple of 5e-5 N m that decays at 0.61 1/s.
        """
        return (self.certificate_grows is False and self.settled and tuple(self.growing) == ("torque",)
                and not self.saturated > SATURATION_LIMIT)

    @property
    def torque_chatter(self) -> bool:
        """Only the torque's ripple grows, off its limit, in a run whose linear certificate is stable and
        whose tip and hub-angle error do not grow, but that has not settled.

        With the linear loop stable and the command off its limit, a ripple rising while tip and hub do
        not is a bounded nonlinearity's chatter (encoder counts, friction) or sensor noise: the run is
        judged by its bands. Found on a random rig (1 m steel link, 3.8 kg payload, 4096 counts, 2.1 N m
        Coulomb friction, 5 ms): +-1 V between counts after the slew, its envelope rising at 3.5 1/s,
        the tip decaying and the hub within a count; it was judged "unstable".
        """
        return (self.certificate_grows is False and not self.settled and tuple(self.growing) == ("torque",)
                and not self.saturated > SATURATION_LIMIT)


def verdict(evidence: Evidence) -> str:
    """The verdict of a closed-loop run (:data:`VERDICTS`), tested in this order.

    * ``"failed"``: the run stopped because the integrator or the controller failed, or
      the wall-clock limit ended it (the loop's stability is unknown);
    * ``"diverged"``: the run stopped because the plant left its model's range: it passed the
      divergence limit (L), or its mass matrix is no longer positive definite (a first-order
      model past the deflection its kinetic energy holds, e.g. 0.58 L on ``servo_payload``);
    * ``"unstable"``: the linear certificate's loop grows (spectral radius above
      ``1 + RADIUS_TOLERANCE``), or the envelope of the tip deflection, of the torque's
      ripple or of the hub-angle error grows at a resolved rate in the residual window
      (:func:`envelope_growth`), or the command sits at its limit for more than
      :data:`SATURATION_LIMIT` of the window (a saturation limit cycle); except a settled
      run whose certificate is stable and whose torque ripple alone rises
      (:attr:`Evidence.torque_build_up`: sensor noise building up, judged ``"settled"`` and
      said in the reason), and such a run that has not settled (:attr:`Evidence.torque_chatter`:
      ``"not settled"``);
    * ``"settled"``: hub-angle error and tip deflection have stayed inside their settling bands
      for the hold before the end (:func:`~hubbeam_ctrl.study.settling.settle_hold`: a tenth of
      the residual window, at least one period of the first bending mode);
    * ``"not settled"``: anything else (e.g. the undamped open loop, which rings on).

    Parameters
    ----------
    evidence : Evidence

    Returns
    -------
    str

    Examples
    --------
    >>> verdict(Evidence(None, ("torque",), 0.0, True))      # a quiet tip and a growing torque
    'unstable'
    >>> verdict(Evidence(None, ("torque",), 0.0, True, certificate_grows=False))   # noise building up
    'settled'
    >>> verdict(Evidence("integrator", (), 0.0, False))
    'failed'
    """
    if evidence.stop_cause is not None:
        return "diverged" if evidence.stop_cause == "diverged" else "failed"
    if evidence.torque_build_up:
        return "settled"
    if evidence.torque_chatter:
        return "not settled"
    if evidence.friction_hunting:
        return "settled" if evidence.settled else "not settled"
    if evidence.certificate_grows or evidence.growing or evidence.saturated > SATURATION_LIMIT:
        return "unstable"
    return "settled" if evidence.settled else "not settled"


def closed_loop_metrics(result, t_f: float, *, residual_delay: float = 5.0,
                        settle_angle: float = 1e-3, settle_tip: float = 1e-3,
                        tau_max: float | None = None, block_s: float | None = None,
                        certificate=None) -> dict:
    """Metrics of one closed-loop run.

    Parameters
    ----------
    result : Result
        Of kind ``"closed_loop"`` (see :func:`hubbeam_ctrl.sim.closedloop.simulate_closed_loop`),
        with the task's hub reference (``theta_ref``).
    t_f : float
        Maneuver time [s]: the angle error is taken there, and the residual vibration
        window starts at ``t_f + residual_delay``.
    residual_delay : float
        [s], >= 0 (default 5).
    settle_angle : float
        Settling band of the hub-angle error [rad] (default 1 mrad).
    settle_tip : float
        Settling band of the tip deflection [m] (default 1 mm).
    tau_max : float, optional
        Hub-torque limit [N m]; adds ``within_torque_limit`` on a torque source (and the
        saturated fraction). The drive is the run's (``result.settings["hardware"]``, default
        the ideal torque source); on a DC motor the command's limit is ``V_max``.
    block_s : float, optional
        Shortest block of the envelope fits [s] (:func:`envelope_growth`), e.g. one period of
        the first bending mode; default a twelfth of the fitted span.
    certificate : hubbeam_ctrl.study.certificate.Certificate, optional
        The linear certificate of the controller on the evaluation plant: a growing loop is
        ``"unstable"`` whatever the window shows, and its ``loop_*`` entries join the metrics.

    Returns
    -------
    dict
        ``verdict`` (:func:`verdict`), ``verdict_reason`` (one sentence), the
        :data:`METRIC_UNITS` entries plus ``controller``,
        ``plant``, the plant's description (``plant_modes``, ``design_modes``, ``substeps``,
        ``step_s``, ...), ``completed``, ``outside_validated_range``,
        ``outside_range_time_s``, ``message``, ``wall_s``, the controller's own statistics
        (e.g. ``qp_fallbacks``, ``fallback_fraction``), ``command_unit``, ``command_limit``
        and the limit checks ``within_voltage_limit``, ``within_current_limit``,
        ``within_torque_limit`` and ``within_drive_limits`` (each against its own limit;
        :func:`~hubbeam_ctrl.study.drive_figures.drive_metrics`; absent when there is no limit).

    Raises
    ------
    ParameterError
        If the result is not a closed-loop run, has no reference, or was planned to end
        before ``t_f + residual_delay``.
    """
    t_f = check_positive("tf", t_f, "s")
    if not (isinstance(residual_delay, (int, float)) and residual_delay >= 0):
        raise ParameterError(f"residual_delay must be >= 0 [s], got {residual_delay!r}")
    settle_angle = check_positive("settle_angle", settle_angle, "rad")
    settle_tip = check_positive("settle_tip", settle_tip, "m")
    if result.kind != "closed_loop":
        raise ParameterError(f"result must be a closed-loop run (kind 'closed_loop'), got kind {result.kind!r}")
    if result.theta_ref is None:
        raise ParameterError("the result has no hub reference (pass reference= to simulate_closed_loop)")
    t, v_tip, tau = result.t, result.v_tip, result.tau
    err = result.theta - result.theta_ref
    start = t_f + residual_delay
    window = t >= start - 1e-9
    planned_end = float(result.settings.get("t_end", t[-1]))
    out = {"controller": result.controller, "plant": result.plant}
    if planned_end < start:
        raise ParameterError(f"t_end = {planned_end:g} s must exceed tf + {residual_delay:g} s = "
                             f"{start:g} s to measure the residual vibration")
    k_f = int(np.argmin(np.abs(t - t_f)))
    steps = result.step_time_s[np.isfinite(result.step_time_s)]
    res = v_tip[window]
    nan = float("nan")
    growth = residual_growth(res)
    drive = drive_of(result)
    limit = command_limit(drive, tau_max)
    drive_out = drive_metrics(t, tau, result.v[:, 0], t_f, drive, tau_max, friction_of(result))
    saturated = saturated_fraction(tau[window], limit) if limit is not None else nan
    hold = settle_hold(float(t[-1]) - start, 2.0 * block_s if block_s else None)
    entered = settling_time(t, err, v_tip, settle_angle, settle_tip)      # inside from then on, any hold
    inside_at_end = 0.0 if entered is None else float(t[-1]) - entered
    settle = entered if entered is not None and inside_at_end >= hold else None
    t_w = t[window]
    block = float(block_s) if block_s is not None else 0.0
    fits = {"tip": envelope_growth(t_w, res, block),        # the ripple is fast: short blocks
            "torque": envelope_growth(t_w[1:], np.diff(tau[window]), 0.0),
            "angle": envelope_growth(t_w, err[window], block)}
    torque_floor = 1e-6 * (limit if limit is not None else max(1.0, float(np.nanmax(np.abs(tau)))))
    # below its settling band a noise-driven tip or angle envelope cannot be told from growth
    # over a few blocks; the torque's ripple (many short blocks) and the certificate see there
    floors = {"tip": settle_tip, "torque": torque_floor, "angle": settle_angle}
    growing = tuple(k for k, f in fits.items() if f.grows(floors[k]))
    cause = result.stats.get("stop_cause") if result.stopped else None
    if result.stopped and cause is None:     # a run saved before stop causes were recorded
        cause = "diverged" if "left its range" in result.message else "failed"
    cert_grows = certificate.grows if certificate is not None and certificate.available else None
    evidence = Evidence(cause, growing, saturated, settle is not None, cert_grows,
                        _friction_bound(tau[window], result.v[window, 0], drive, friction_of(result)),
                        inside_at_end, hold)
    out["verdict"] = verdict(evidence)
    out["verdict_reason"] = _reason(evidence, fits, certificate, result.message)
    out.update({
        "peak_tip_m": float(np.max(np.abs(v_tip))),
        "residual_tip_rms_m": float(np.sqrt(np.mean(res ** 2))) if res.size else nan,
        "residual_tip_max_m": float(np.max(np.abs(res))) if res.size else nan,
        "angle_error_tf_rad": float(err[k_f]) if t[-1] >= t_f - 1e-9 else nan,
        "final_angle_error_rad": float(err[-1]),
        # a run that grows, diverged or failed has not settled, whatever its window showed
        "settling_time_s": None if out["verdict"] in _NOT_SETTLING else settle,
        "settle_angle_rad": settle_angle,
        "settle_tip_m": settle_tip,
        "settle_hold_s": hold,
        "inside_bands_at_end_s": inside_at_end,
        "peak_torque_nm": drive_out["peak_hub_torque_nm"],
        "torque_squared_integral_n2m2s": drive_out.pop("hub_torque_squared_integral"),
        "torque_saturated_fraction": saturated,
        "residual_growth": growth,
        "tip_growth_rate_per_s": fits["tip"].rate_per_s,
        "torque_growth_rate_per_s": fits["torque"].rate_per_s,
        "angle_growth_rate_per_s": fits["angle"].rate_per_s,
        "growth_resolution_per_s": fits["tip"].resolution_per_s,
        "step_time_median_ms": float(np.median(steps) * 1e3) if steps.size else nan,
        "step_time_p99_ms": float(np.percentile(steps, 99) * 1e3) if steps.size else nan,
    })
    out.update({k: v for k, v in drive_out.items() if v is not None or not k.startswith("within_")})
    for key in METRIC_UNITS:            # the loop_* entries: None without a certificate
        out.setdefault(key, None)
    if certificate is not None:
        out.update(certificate.metrics())
        w = certificate.worst
        if w is not None and w.growth_time_s is not None:
            span = float(t_w[-1] - t_w[0]) / 2 if t_w.size > 1 else 0.0
            # the fitted half-window sees the growth if it spans one growth time constant
            out["window_resolves_loop"] = bool(span >= w.growth_time_s)
    out["completed"] = not result.stopped
    out["stop_cause"] = cause
    out["outside_validated_range"] = bool(getattr(result, "outside_validated_range", False))
    out["outside_range_time_s"] = getattr(result, "outside_range_time_s", None)
    for key in _PLANT_KEYS:
        if key in result.settings:
            out[key] = result.settings[key]
    out["plant_params"] = result.params.to_dict()
    out["message"] = result.message
    out["wall_s"] = float(result.wall_s)
    for key, value in result.controller_stats.items():
        if isinstance(value, (int, float, str, bool)):
            out[key] = value
    return out


def _friction_bound(u, thd, drive, friction) -> float | None:
    """Largest hub torque of the drive in the window over the breakaway torque (None: no friction)."""
    if friction is None or friction.coulomb <= 0 or u.size == 0:
        return None
    ok = np.isfinite(u) & np.isfinite(thd)
    if not np.any(ok):
        return None
    torque = drive_torque(u[ok], thd[ok], Hardware(drive, friction).values())
    breakaway = max(friction.coulomb, friction.breakaway or 0.0)
    return float(np.max(np.abs(torque)) / breakaway)


def _reason(evidence: Evidence, fits: dict, certificate, message: str) -> str:
    """One sentence saying what decided the verdict."""
    end = describe_end(evidence.settled, evidence.inside_at_end_s, evidence.hold_s)
    if evidence.stop_cause is not None:
        return message
    if evidence.friction_hunting:
        return (f"the command works against the hub's Coulomb friction: the hub torque stays within "
                f"{evidence.friction_bound:.2g} x the breakaway torque (stick-slip hunting, bounded) and the "
                "linear certificate says stable; " + end)
    parts = []
    if evidence.certificate_grows:
        parts.append(certificate.describe())
    for name in evidence.growing:
        parts.append(f"the {name} envelope grows at {fits[name].rate_per_s:.3g} 1/s "
                     f"(resolution {fits[name].resolution_per_s:.2g} 1/s)")
    if evidence.saturated > SATURATION_LIMIT:
        parts.append(f"the command sits at its limit {100 * evidence.saturated:.0f} % of the residual window")
    if evidence.torque_build_up:
        return (parts[0] + "; the linear certificate says stable and the tip and hub stay in their "
                "bands: the loop's response to sensor noise building up, not growth")
    if evidence.torque_chatter:
        return (parts[0] + "; the tip and hub do not grow, the command stays off its limit and the linear "
                "certificate says stable: chatter of a bounded nonlinearity (encoder counts, friction) or of "
                "sensor noise, not growth; " + end)
    if parts:
        if evidence.certificate_grows is False:
            parts.append("the linear certificate says stable: the growth is nonlinear (saturation, "
                         "large deflection) or the plant differs from its linear model")
        return "; ".join(parts)
    if evidence.certificate_grows is None:
        lead = "no growth in the run (no linear certificate)"
    else:
        lead = "no growth in the run or in the linear certificate"
    return lead + "; " + end


"""The controllers and the closed loop on a rig: what changes when the hardware is real.

:func:`rig_closed_loop` gives the :class:`~hubbeam_ctrl.sim.hardware.Hardware` the plant carries
(drive, friction, the rig's sensors and computation delay); :func:`on_rig` turns a
designed controller into the one that runs on the rig:

* a controller that reads the plant's modal state (LQR, MPC) is closed through a Kalman
  filter on the rig's sensors (:class:`controllers.integral.ObservedFeedback`): a user gets
  a controller that reads real sensors;
* with ``integral`` (the default when the rig has friction) the filter of LQR, LQG and MPC
  estimates a constant input disturbance that the command cancels (offset-free control,
  :mod:`controllers.integral`); PD and the open loops are left as they are;
* on a DC motor the torque command becomes a voltage (:class:`controllers.drive.VoltageCommand`),
  except the NMPC's, which predicts the drive and commands volts itself (:mod:`controllers.nmpc_drive`).

A rig with ideal hardware changes nothing: the controllers and settings are the beam
alone's, so a comparison on it gives the same numbers bit for bit.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from controllers import LQG, LQGSettings, MPCSettings, Weights
from controllers.drive import VoltageCommand
from controllers.integral import ObservedFeedback
from controllers.sensing import SensorLayout, observability_defect, rig_key
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import Rig
from hubbeam_ctrl.sim.closedloop import ClosedLoopSettings
from hubbeam_ctrl.sim.hardware import Hardware

__all__ = ["rig_closed_loop", "on_rig", "rig_design", "rig_settings", "rig_noise", "task_noise", "integral_default",
           "design_hub_damping", "hub_damping_note", "count_chatter", "noise_chatter", "count_note", "COUNT_SHARE",
           "NOISE_SHARE",
           "DISTURBANCE_FRACTION", "HUB_DAMPING_SHARE"]

#: Random-walk standard deviation per sample of the estimated disturbance, as a fraction of the
#: torque limit (the integral action's speed; measured on ``servo_link``: see docs/rig.md).
DISTURBANCE_FRACTION = 0.01


#: The design model carries the hub's linear damping ``b`` (a DC drive's back-EMF plus the viscous
#: friction) when ``b dt / J_h`` reaches this share: the hub's own speed loses that share of itself
#: to the damping within one sample. Below it a DC drive's command cancels the back-EMF with the hub
#: rate (:class:`controllers.drive.VoltageCommand`); above it that cancellation, one sample late,
#: is a positive rate feedback that grows with ``b``. Measured on a 1.5 m steel link at 10 ms with a
#: full sample of delay (J_h 0.05 kg m^2) on gear ratios 30, 60 and 100 (``b dt / J_h`` 0.10,
#: 0.41 and 1.12): with the cancellation LQR, LQG and MPC settled, banged between +-24 V, and
#: were unstable (loop radius 1.205); see tests/test_drive_damping.py. The presets sit at 0.05 or less.
HUB_DAMPING_SHARE = 0.1


def design_hub_damping(rig: Rig) -> float:
    """The hub damping [N m s/rad] the design model carries on ``rig`` (:meth:`controllers.DesignModel.on_rig`):
    the drive's back-EMF plus the viscous friction when ``b dt / J_h`` reaches :data:`HUB_DAMPING_SHARE`,
    else 0 (and a DC drive's command cancels the back-EMF instead).

    Parameters
    ----------
    rig : Rig

    Returns
    -------
    float
        ``b`` [N m s/rad] or 0.
    """
    if rig.is_ideal:
        return 0.0
    b = Hardware.from_rig(rig).hub_damping()
    j_h = rig.beam.J_h + rig.drive.reflected_inertia      # the hub's own inertia, rotor included
    if b <= 0.0:
        return 0.0
    return b if (j_h <= 0.0 or b * rig.timing.dt / j_h >= HUB_DAMPING_SHARE) else 0.0


def _torque_at_rest_bound(rig: Rig, tau_max: float) -> float:
    """The bound [N m] of a design that carries the back-EMF (:func:`design_hub_damping`): its input is the
    torque at rest ``g V``, bounded by the voltage, ``g V_max``, not by a stall torque that a current limit
    sets lower (the drive clips the current itself); at least ``tau_max`` (a rig file's rounding of it)."""
    return max(tau_max, Hardware.from_rig(rig).torque_per_volt() * rig.drive.V_max)


def hub_damping_note(design, rig: Rig) -> str:
    """The report's line on a design that carries the hub's damping (:func:`design_hub_damping`).

    Parameters
    ----------
    design : DesignModel
        On ``rig`` (:func:`rig_design`).
    rig : Rig
    """
    j_h = rig.beam.J_h + rig.drive.reflected_inertia
    b = design.hub_damping
    return (f"the design model carries the hub's damping b = {b:.4g} N m s/rad (back-EMF and viscous "
            f"friction; b dt / J_h = {b * design.dt / j_h:.3g} >= {HUB_DAMPING_SHARE:g}): the command is the voltage "
            "of the torque at rest, without back-EMF compensation")


def integral_default(rig: Rig) -> bool:
    """Integral action by default: on rigs with friction or a DC motor (whose torque is not exactly
    the one commanded).

    Parameters
    ----------
    rig : Rig
    """
    return not (rig.friction.is_ideal and rig.drive.is_ideal)


def rig_closed_loop(rig: Rig, settings: ClosedLoopSettings) -> tuple:
    """The closed loop's settings and hardware on ``rig``.

    Parameters
    ----------
    rig : Rig
    settings : ClosedLoopSettings
        The task's default settings (sample time, sensor noise scaled to its signals; a rig with
        its own sensors is measured through them instead, see
        :func:`~hubbeam_ctrl.sim.closedloop.simulate_closed_loop`).

    Returns
    -------
    settings : ClosedLoopSettings
        ``settings`` (the rig's sample time is the task's: compare builds the task with it).
    hardware : Hardware or None
        The rig's drive, friction, sensors and timing; None for a rig with ideal hardware (the
        plant and the measurement are then the beam alone's).
    """
    if not isinstance(rig, Rig):
        raise ParameterError(f"rig must be a Rig (hubbeam_ctrl.plant.rig.load_rig), got {type(rig).__name__}")
    return settings, (None if rig.is_ideal else Hardware.from_rig(rig))


def rig_design(design, rig: Rig):
    """The design model on ``rig``: its estimators read the rig's sensors and its laws act
    where the rig's computation delay puts the command (:meth:`controllers.DesignModel.on_rig`).

    A sensor set that cannot observe the design model is refused in one line naming the rig keys.

    Parameters
    ----------
    design : DesignModel
    rig : Rig

    Returns
    -------
    DesignModel
        ``design`` itself on a rig with the beam alone's sensors and no delay.
    """
    if not isinstance(rig, Rig):
        raise ParameterError(f"rig must be a Rig (hubbeam_ctrl.plant.rig.load_rig), got {type(rig).__name__}")
    layout = SensorLayout.from_rig(rig.sensors)
    out = design.on_rig(layout, rig.timing.delay, design_hub_damping(rig))
    if out.hub_damping and not rig.drive.is_ideal:
        bound = _torque_at_rest_bound(rig, out.params.tau_max)
        out = dataclasses.replace(out, params=out.params.replace(tau_max=bound))
    missing = observability_defect(out.Ad, out.C_sensors, out.state_names)
    if missing is not None:
        keys = ", ".join(dict.fromkeys(rig_key(s) for s in layout.signals))
        raise ParameterError(f"the rig's sensors ({keys}) cannot observe the design model's {missing}: add "
                             "sensors.strain_gauges, sensors.tip_accelerometer or sensors.rate")
    return out


def rig_settings(name: str, settings, rig: Rig, integral: bool | None = None):
    """A controller's settings on ``rig``: LQG's integral action switched on where it applies, MPC's
    voltage limit through back-EMF on a DC motor (:attr:`controllers.MPCSettings.emf_torque_limit`).

    Parameters
    ----------
    name : str
        Registered controller name.
    settings : ControllerSettings
    rig : Rig
    integral : bool, optional
        Integral action; default :func:`integral_default`.

    Returns
    -------
    ControllerSettings
    """
    integral = integral_default(rig) if integral is None else bool(integral)
    if design_hub_damping(rig) and not rig.drive.is_ideal and getattr(settings, "tau_max", None) is not None:
        settings = dataclasses.replace(settings, tau_max=_torque_at_rest_bound(rig, settings.tau_max))
    if isinstance(settings, LQGSettings) and not rig.is_ideal:
        return dataclasses.replace(rig_noise(settings, rig), integral=integral)
    if isinstance(settings, MPCSettings) and not rig.drive.is_ideal and settings.emf_torque_limit is None:
        # the plan keeps the voltage within V_max through the back-EMF at every step (a design that
        # carries the back-EMF, design_hub_damping, commands the torque at rest: its bound is g V_max)
        hw = Hardware.from_rig(rig)
        g = hw.torque_per_volt()
        emf = 0.0 if design_hub_damping(rig) else g * hw.back_emf_constant()
        return dataclasses.replace(settings, emf_torque_limit=g * rig.drive.V_max, emf_damping=emf)
    return settings


def rig_noise(noise, rig: Rig):
    """The filter's noise model with the rig's sensors: their stated noise and the encoder's
    quantisation as angle noise.

    Each assumed standard deviation is at least the rig's (``sensors.angle_noise``, ``rate_noise``,
    ``strain_noise``, ``accel_noise``): a filter that trusts a sensor more than it deserves passes
    its noise on to the command (measured on ``space_boom``: the command banged between the
    wheels' limits).

    An encoder of step ``q`` reads the angle with an error spread uniformly over ``+-q/2``,
    of standard deviation ``q / sqrt(12)``; a filter that assumed less would trust the counts
    more than they deserve and pass the quantisation on to the command as chatter (measured on
    ``servo_link``: the tip rang at 0.6-0.8 mm instead of 0.013 mm).

    Parameters
    ----------
    noise : KalmanNoise
        E.g. an :class:`~controllers.lqg.LQGSettings`.
    rig : Rig

    A rate sensor with a stated bias (``sensors.rate_bias`` or a drifting one,
    ``sensors.rate_bias_walk``) gets a bias state in the filter
    (:attr:`~controllers.filter_model.KalmanNoise.rate_bias_walk`): measured on ``space_boom`` (gyro
    bias 4.8e-7 rad/s drifting 1e-7 rad/s/sqrt(s)), LQR, LQG and MPC through a filter that trusted
    the gyro ended 9.6e-5 rad off (4 standard deviations of the star tracker); with the bias state
    1.4e-5 rad, as without any bias (1.1e-5 rad), and a residual tip of 3.4e-4 m against 1.7e-4 m.

    Returns
    -------
    KalmanNoise
        The same type, ``angle_noise_rad`` raised to ``sqrt(noise^2 + q^2 / 12)``.
    """
    q = rig.sensors.encoder_step
    sn = rig.sensors
    # the filter never assumes less noise than the rig's sensors state (a star tracker, a gyro)
    stated = {"angle_noise_rad": sn.angle_noise, "rate_noise_rad_s": sn.rate_noise,
              "moment_noise_nm": sn.strain_noise, "accel_noise_m_s2": sn.accel_noise}
    raised = {k: max(getattr(noise, k), v) for k, v in stated.items() if hasattr(noise, k) and v > getattr(noise, k)}
    if (sn.rate_bias or sn.rate_bias_walk) and hasattr(noise, "rate_bias_walk") and noise.rate_bias_walk is None:
        raised["rate_bias_walk"] = sn.rate_bias_walk
    if raised:
        noise = dataclasses.replace(noise, **raised)
    return dataclasses.replace(noise, angle_noise_rad=math.hypot(noise.angle_noise_rad, q / math.sqrt(12.0)))


def on_rig(controller, rig: Rig, noise, hardware: Hardware | None, integral: bool | None = None):
    """The controller that runs on ``rig``: observer for state feedback, integral action, voltage.

    Parameters
    ----------
    controller : Controller
        A designed controller (its ``measurement``, ``tau_max``).
    rig : Rig
    noise : KalmanNoise
        The filter's noise model for state-feedback controllers (the task's LQG settings).
    hardware : Hardware or None
        From :func:`rig_closed_loop`.
    integral : bool, optional
        Integral action; default :func:`integral_default`.

    Returns
    -------
    object
        ``controller`` itself on an ideal rig.
    """
    if rig.is_ideal:
        return controller
    integral = integral_default(rig) if integral is None else bool(integral)
    ctrl = controller
    tracks = hasattr(controller, "feedback_matrices") and getattr(controller, "measurement", None) == "state"
    if (hardware is not None and hardware.command == "voltage" and hasattr(controller, "built_on")
            and not controller.settings.learn_payload):
        # the NMPC predicts the drive, friction and delay itself: it commands volts (controllers.nmpc_drive);
        # one that learns the payload keeps the beam alone's prediction behind the rig's volts stage
        from controllers.nmpc_drive import nmpc_on_drive
        d = DISTURBANCE_FRACTION * controller.tau_max if integral else None
        ctrl = nmpc_on_drive(controller, hardware, noise, d)
        ctrl.rig_hardware = hardware
        return ctrl
    if tracks and _has_gain(controller):
        d = DISTURBANCE_FRACTION * controller.tau_max if integral else None

        def observed(factor):
            law = controller if factor == 1.0 else type(controller)(
                controller.design, _softer(controller.settings, factor), controller.reference)
            return lambda n: ObservedFeedback(law, n, d)

        softens = isinstance(getattr(controller.settings, "weights", None), Weights)
        ctrl = _quiet_or_softer(observed, noise, rig, softens)
    elif type(controller) is LQG:
        def filtered(factor):
            return lambda n: (controller if factor == 1.0 and n is controller.settings else
                              LQG(controller.design, _softer(n, factor), controller.reference))

        ctrl = _quiet_or_softer(filtered, controller.settings, rig, True)
    if hardware is not None and hardware.command == "voltage":
        ctrl = VoltageCommand(ctrl, hardware)
    if hardware is not None:
        ctrl.rig_hardware = hardware        # the certificate closes the loop through the rig's drive and delay
    return ctrl


#: The most one encoder count may move a rig's default law's command, as a share of its torque limit,
#: at the highest frequency (a count that toggles each sample: ``|H_theta(z = -1)| q``). Found on a random
#: rig (a 0.49 m aluminium strip on a 0.063 N m torque source, 4096 counts, 10 ms, no rate sensor): one
#: count moved LQR's, LQG's and MPC's command by 3.0 times the limit, and all three sat at the limit 49 %
#: of the residual window ("unstable"; a 2^20-count encoder settled). Lowered from 0.5 on another (a 1.26 m
#: aluminium link on a geared DC motor, 2000 counts, a root gauge, no tachometer, 5 ms and a sample of
#: delay; tests/test_fuzzed_rigs.py): at 0.5 the filter kept its angle noise (a count moved the command by
#: 33 %) and LQR, LQG and MPC rang at the first mode for ever, the reading toggling between two counts, a
#: 1.5 mm RMS tip (1.6 times the open loop's residual) against a 0.16 mm band; with the noise raised 4x
#: (7 %) all three settle to 1.1 um. On accel_link the rule now raises its filter's noise 4x (18 % -> 6 %):
#: LQR settles in 1.7 s instead of 2.4 s, MPC in 4.1 s instead of 2.5 s; the other presets are below 0.1 %.
COUNT_SHARE = 0.1


#: Factors on the torque weight of a law whose filter cannot quieten one encoder count to
#: :data:`COUNT_SHARE` (:func:`on_rig`): the gains are lowered until the encoder carries them. Found on a
#: random rig (a 0.41 m aluminium link on a 0.71 N m torque source, 2000 counts, a root gauge and no
#: tachometer, 5 ms, half a sample of delay): with the filter's angle noise raised 64x a count still moved
#: LQR's command by 98 % of its limit; it stepped by 80 % of the limit a sample, sat 0.12 s at the limit and
#: settled in 4.45 s with a disk margin of 0.08. At 1000x the torque weight: a count moves it by 27 %,
#: the disk margin is 0.34 and it settles in 1.7 s.
#: 10^5 and 10^6 since a random slow boom (5.3 m on 290 kg m^2 at 10 Hz, a 21 urad star tracker and a
#: 28 urad/s gyro): at 10^4 its sensors still moved the command by 15 % of the limit RMS and it sat at
#: the limit 11.6 s of the slew; at 10^5 (5 %) 0.1 s, with a disk margin of 1.5.
SOFTER_LADDER = (10.0, 100.0, 1000.0, 1e4, 1e5, 1e6)


def _softer(settings, factor: float):
    """``settings`` with its torque weight times ``factor`` (lower gains; itself at 1)."""
    if factor == 1.0:
        return settings
    w = settings.weights
    return dataclasses.replace(settings, weights=dataclasses.replace(w, torque=w.torque * factor))


#: The largest standard deviation of a rig's law's command that its sensors' stated noise may cause in the
#: loop at rest, as a share of its torque limit (:func:`noise_chatter`; :func:`on_rig` raises the filter's
#: angle noise, then the torque weight, until it holds). Found on random slow space structures (session 24:
#: an 8.8 m CFRP boom on a 36 kg m^2 body, a 16 mN m actuator, a star tracker of 90 urad and a gyro of
#: 21 urad/s at 20 Hz): the laws designed from the task's weights turned the star tracker's noise into a
#: command of 4 times the limit (RMS); LQR, LQG and MPC banged between +-tau_max every sample ("unstable",
#: tests/test_fuzzed_rigs.py).
NOISE_SHARE = 0.1


def _loud(law) -> float:
    """How far ``law`` is from quiet: the larger of its count share over :data:`COUNT_SHARE` and its noise
    share over :data:`NOISE_SHARE` (<= 1: quiet)."""
    return max(law.count_share / COUNT_SHARE, law.noise_share / NOISE_SHARE)


def _quiet_or_softer(make, noise, rig: Rig, softens: bool):
    """:func:`_quiet_to_a_count` of ``make(1.0)``; where no filter brings one count within
    :data:`COUNT_SHARE` (and ``softens``), of ``make(factor)`` along :data:`SOFTER_LADDER` until one
    does. ``make(factor)`` gives the ``build(noise)`` of the law with its torque weight times
    ``factor``; the law keeps the factor in ``count_softened``."""
    law = _quiet_to_a_count(make(1.0), noise, rig)
    for factor in SOFTER_LADDER if softens and _loud(law) > 1.0 else ():
        law = _quiet_to_a_count(make(factor), noise, rig)
        law.count_softened = factor
        if _loud(law) <= 1.0:
            break
    return law


def count_chatter(law, rig: Rig) -> float:
    """How far one count of the rig's encoder moves ``law``'s command at the highest frequency, as a share
    of its torque limit: ``|H_theta(z = -1)| q / tau_max`` with ``H_theta`` the law's response to the hub
    angle (:meth:`~controllers.Controller.feedback_matrices`); 0 without an encoder.

    Parameters
    ----------
    law : Controller
        A law that reads the rig's sensors (an LQG, an observer-fed LQR or MPC), in torque.
    rig : Rig

    Returns
    -------
    float
        [-]
    """
    q = rig.sensors.encoder_step
    Ak, Bk, Ck, Dk, _, inputs = law.feedback_matrices()
    if not q or "theta" not in inputs:
        return 0.0
    j = list(inputs).index("theta")
    h = np.atleast_2d(Ck) @ np.linalg.solve(-np.eye(Ak.shape[0]) - Ak, Bk[:, j]) + np.atleast_2d(Dk)[0, j]
    return abs(float(np.squeeze(h))) * q / law.tau_max


def noise_chatter(law, rig: Rig) -> float:
    """The standard deviation of ``law``'s command that the rig's stated sensor noise causes in the loop at
    rest, as a share of its torque limit (0 when the rig states none for the signals it reads).

    Each signal the law reads carries white noise of the rig's stated standard deviation
    (``sensors.angle_noise`` on ``theta``, ``rate_noise`` on ``theta_dot``, ``strain_noise`` on the
    gauges, ``accel_noise`` on the accelerometer; an encoder's counts are :func:`count_chatter`'s); the
    command's variance is the sum over the signals of the certificate's sampled loop's H2 gain from each
    to the command (:func:`~hubbeam_ctrl.study.certificate.loop_matrix`, the law's design plant with its
    delay), squared, times the noise's variance.

    Parameters
    ----------
    law, rig
        As :func:`count_chatter`.

    Returns
    -------
    float
        [-]; inf when the loop is not stable.
    """
    import scipy.linalg

    from hubbeam_ctrl.study.sampled_loop import AS_DESIGNED, closed_loop_matrix, loop_parts
    sn = rig.sensors
    Ak, Bk, Ck, Dk, _, inputs = law.feedback_matrices()

    def sigma(name: str) -> float:
        return {"theta": sn.angle_noise, "theta_dot": sn.rate_noise}.get(
            name, sn.strain_noise if "moment" in name else sn.accel_noise if name.startswith("accel") else 0.0)

    sig = np.array([sigma(str(n)) for n in inputs], dtype=float)
    if not np.any(sig > 0.0):
        return 0.0
    Ad, Bd, Cm, laws, _ = loop_parts(law, law.design.params, 0.0, 0.0, AS_DESIGNED)
    A_loop = closed_loop_matrix(Ad, Bd, Cm, laws)
    if np.max(np.abs(np.linalg.eigvals(A_loop))) >= 1.0:
        return math.inf
    Ak, Bk, Ck, Dk = laws
    B = Bd @ Dk if not Ak.size else np.vstack([Bd @ Dk, Bk])          # the noise enters where the readings do
    c = Dk @ Cm if not Ak.size else np.hstack([Dk @ Cm, Ck])         # the command
    Bs = B * sig
    P = scipy.linalg.solve_discrete_lyapunov(A_loop, Bs @ Bs.T)
    var = float((c @ P @ c.T)[0, 0] + np.sum((Dk[0] * sig) ** 2))
    return math.sqrt(max(var, 0.0)) / law.tau_max


def _quiet_to_a_count(build, noise, rig: Rig):
    """``build(noise)``, with the filter's angle noise doubled (up to 2^6) while one encoder count moves the
    command by more than :data:`COUNT_SHARE` of its limit (:func:`count_chatter`) or the sensors' stated
    noise moves it by more than :data:`NOISE_SHARE` (:func:`noise_chatter`); the quietest law when none is
    within. The law keeps the factor in ``count_noise_factor`` and both shares for the report."""
    best = None
    for k in range(7):
        law = build(noise if k == 0 else dataclasses.replace(noise, angle_noise_rad=noise.angle_noise_rad * 2 ** k))
        law.count_noise_factor, law.count_share = 2 ** k, count_chatter(law, rig)
        law.noise_share = noise_chatter(law, rig)
        if _loud(law) <= 1.0:
            return law
        if best is None or _loud(law) < _loud(best):
            best = law
    return best


def count_note(name: str, controller) -> list:
    """The report's line on a law whose filter trusts the encoder less than its counts
    (:func:`_quiet_to_a_count`): ``[]`` when it trusts them as they are.

    Parameters
    ----------
    name : str
        The controller's name in the report.
    controller : object
        As :func:`on_rig` returns it.
    """
    law = controller
    while not hasattr(law, "count_noise_factor") and hasattr(law, "inner"):
        law = law.inner
    factor = getattr(law, "count_noise_factor", 1)
    softened = getattr(law, "count_softened", None)
    if factor == 1 and not softened:
        return []
    what = []
    if factor > 1:
        what.append(f"the filter's angle noise is raised {factor}x")
    # the noise's share is named where it binds (no encoder, or its counts quieter than the noise)
    noisy = getattr(law, "noise_share", 0.0) / NOISE_SHARE >= law.count_share / COUNT_SHARE
    if softened:
        also = " or the sensors' noise" if noisy else ""
        what.append(f"the torque weight is raised {softened:g}x (lower gains: the filter alone could not quieten "
                    f"the counts{also})")
    share = law.count_share
    quiet = _loud(law) <= 1.0
    if not noisy:
        outcome = ("so that one encoder count moves the command by" if quiet else
                   "the most the rule tries; one encoder count still moves the command by")
        return [f"{name}: {' and '.join(what)}, {outcome} {100 * share:.0f} % of its limit at most "
                f"(COUNT_SHARE {100 * COUNT_SHARE:.0f} %)"]
    outcome = "so that" if quiet else "the most the rule tries; still"
    count = (f"one encoder count moves the command by {100 * share:.0f} % of its limit at most and " if share > 0.0
             else "")
    return [f"{name}: {' and '.join(what)}, {outcome} {count}the sensors' stated noise moves it by "
            f"{100 * law.noise_share:.0f} % of its limit RMS (NOISE_SHARE {100 * NOISE_SHARE:.0f} %)"]


def _has_gain(controller) -> bool:
    """A linear state feedback (LQR, MPC's unconstrained law) that an observer can feed."""
    try:
        controller.feedback_matrices()
    except Exception:      # noqa: BLE001 - the open loops and shaped profiles have none
        return False
    return True


def task_noise(scenario, rig: Rig) -> LQGSettings:
    """The filter's noise model of the task on the rig (its LQG defaults, :func:`rig_noise`) for
    observer-fed controllers.

    Parameters
    ----------
    scenario : Scenario
    rig : Rig
    """
    return rig_noise(LQGSettings.for_scenario(scenario), rig)

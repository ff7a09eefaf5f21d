"""H-infinity control of the hub angle over a payload range (python-control's ``hinfsyn``, slycot).

The robust alternative to the multi-model Riccati designs of :mod:`controllers.robust`: one
loop shaped in the frequency domain, with the payload range entering through a weight measured
from the range's own plants. The plant of the synthesis is the continuous design model from hub
torque to hub angle, ``G(s) = theta / tau`` (SFOAM at the design payload, its design modes); the
controller reads the hub angle alone (collocated with the torque) and adds its torque to the
reference's feedforward. ``control.hinfsyn`` (slycot's ``sb10ad``) minimises the H-infinity
norm ``gamma`` from the reference ``r`` and an input disturbance ``d`` (the torque the
feedforward gets wrong, scaled by ``disturbance tau_max``) to

* ``W1 e``, ``W1 = (s / M + wb) / (s + wb A)``: tracking below the crossover ``wb``
  (:attr:`HInfSettings.bandwidth`, the scenario's rigid-body bandwidth by default), ``M = 2``
  (a peak of ``|S|`` below 2), ``A = 1e-2`` (the error left at low frequency);
* ``W2 u``, ``W2 = (1 / tau_max) (s / (roll_off wb) + 1) / (s / (100 roll_off wb) + 1)``: the
  torque within the limit for a unit error, and a gain that falls off above ``roll_off wb``;
* ``W3 y``, ``W3 = k``: the robustness weight of the payload range, ``k`` the
  ``spread_margin`` times the largest relative error ``|G_m / G - 1|`` of the range's plants
  below the crossover (:func:`payload_spread`: the rigid inertia's spread and the first mode's approach;
  W3 = 0.23 on Table 1 over 0-0.5 kg).

The input disturbance is what keeps the synthesis from cancelling the lightly damped modes
with controller zeros (a mixed-sensitivity S/KS/T design notches them and the notch's phase
destabilises the mode when the payload moves it). The weight on ``T`` is held flat: the plant
spread near the bending modes exceeds 1, and a ``W3`` that covers it forces a roll-off below
the first mode, whose phase lag pumps that collocated mode (measured on Table 1: worst radius
1.0001-1.0010 at mode 1 with such a ``W3``); above the crossover the controller keeps phase
lead through the first mode instead, and rolls off at ``roll_off wb``.

The synthesis needs a plant without poles on the imaginary axis (the rigid body's double
integrator, the undamped modes): it sees the modes damped to ``synthesis_damping`` and every
pole moved left by ``synthesis_shift wb``. The continuous controller is sampled by the bilinear
(Tustin) map at the design's ``dt``; the certificate judges that sampled law with the evaluation
plant's modes, the zero-order hold and, on a rig, the drive and delay
(:meth:`HInf.feedback_matrices`).

Needs slycot (the ``robust`` extra: ``pip install 'hubbeam-ctrl[robust]'``); without it the
design refuses in one line.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import setting

from .base import Controller, DesignModel, Reference, TrackingSettings, saturate

__all__ = ["HInfSettings", "HInf", "payload_spread", "spread_weight", "synthesis_plant", "have_slycot"]

#: Peak of |S| the performance weight allows (``M`` of W1) [-].
S_PEAK = 2.0
#: Low-frequency error W1 allows (``A`` of W1) [-].
S_FLOOR = 1e-2
#: Ratio of the high- to the low-frequency level of W2 [-].
WEIGHT_SPAN = 100.0


def have_slycot() -> bool:
    """Whether slycot (python-control's SLICOT wrapper, needed by ``hinfsyn``) can be imported."""
    try:
        import slycot  # noqa: F401
    except ImportError:
        return False
    return True


@dataclass(frozen=True)
class HInfSettings(TrackingSettings):
    """Settings of :class:`HInf` (module docstring gives the weights)."""

    bandwidth: float = setting(1.0, unit="rad/s", lo=0.0, lo_open=True,
                               doc="Crossover wb of the performance weight W1 (the scenario's rigid-body "
                                   "bandwidth by default: 1 rad/s on the paper's 10 s slew).")
    payloads: tuple | None = setting(None, kind=tuple, unit="kg",
                                     doc="Tip payloads whose plants' spread sets the robustness weight W3 (the "
                                         "range's ends and the nominal payload); None: the design payload alone "
                                         "(no W3).")
    roll_off: float = setting(20.0, lo=0.0, lo_open=True, hi=1e3,
                              doc="Corner of the effort weight W2 as a multiple of the bandwidth.")
    disturbance: float = setting(0.1, lo=0.0, lo_open=True, hi=10.0,
                                 doc="Input disturbance of the synthesis as a share of tau_max [-] (keeps "
                                     "the synthesis from cancelling the lightly damped modes).")
    spread_margin: float = setting(1.5, lo=1.0, hi=100.0,
                                   doc="W3 over the largest payload spread below the crossover [-].")
    synthesis_damping: float = setting(0.1, lo=0.0, hi=0.9,
                                       doc="Damping ratio the synthesis gives every bending mode [-].")
    synthesis_shift: float = setting(0.05, lo=0.0, lo_open=True, hi=1.0,
                                     doc="Left shift of the plant's poles for the synthesis, times the bandwidth "
                                         "(the rigid body sits on the imaginary axis).")


def _angle_plant(design: DesignModel, shift: float, zeta: float = 0.0):
    """``theta / tau`` of ``design`` (continuous) as the synthesis sees it: every mode ``w`` given the
    damping ratio ``zeta`` [-] (the damping ``Phi diag(2 zeta w) Phi^-1`` in the coordinates of the
    stiffness block's eigenvectors ``Phi``), then every pole moved left by ``shift`` [1/s]."""
    import control
    n = design.n_x
    h = n // 2
    A = np.array(design.A, dtype=float)
    if zeta > 0.0:
        lam, Phi = np.linalg.eig(A[h:, :h])                  # -w^2 of each mode (0: the rigid body)
        w = np.sqrt(np.maximum(0.0, -lam.real))
        A[h:, h:] -= np.real(Phi @ np.diag(2.0 * zeta * w) @ np.linalg.inv(Phi))
    C = np.zeros((1, n))
    C[0, 0] = 1.0
    return control.ss(A - shift * np.eye(n), design.B[:, :1], C, 0.0)


def payload_spread(design: DesignModel, payloads, omega, shift: float, zeta: float = 0.0) -> np.ndarray:
    """Largest relative plant error ``max_m |G_m(jw) / G0(jw) - 1|`` over the payloads [-].

    Parameters
    ----------
    design : DesignModel
        The nominal design model (``G0``: torque to hub angle).
    payloads : sequence of float
        Tip masses [kg] (the design's own adds nothing).
    omega : array_like
        Frequencies [rad/s].
    shift : float
        Left shift of every pole [1/s] (as the synthesis sees the plants).
    zeta : float
        Damping ratio given every mode [-] (as the synthesis sees the plants).

    Returns
    -------
    ndarray
        One value per frequency.
    """
    from .msmpc import scenario_models
    w = np.asarray(omega, dtype=float)
    g0 = _angle_plant(design, shift, zeta)(1j * w)
    out = np.zeros_like(w)
    for d in scenario_models(design, payloads):
        if d is design:
            continue
        out = np.maximum(out, np.abs(np.asarray(_angle_plant(d, shift, zeta)(1j * w)).ravel() / np.ravel(g0) - 1.0))
    return out


def spread_weight(design: DesignModel, payloads, bandwidth: float, shift: float, margin: float,
                  zeta: float = 0.0) -> float:
    """``k`` of the flat robustness weight ``W3 = k``: ``margin`` times the largest :func:`payload_spread`
    below the crossover [-] (0 when the payloads spread nothing).

    Parameters
    ----------
    design : DesignModel
    payloads : sequence of float
        Tip masses [kg].
    bandwidth : float
        Crossover [rad/s].
    shift : float
        Pole shift of the synthesis [1/s].
    margin : float
        ``k`` over the largest spread below the crossover [-].
    zeta : float
        Damping ratio of the synthesis's modes [-].

    Returns
    -------
    float
    """
    w = np.logspace(np.log10(bandwidth) - 3, np.log10(bandwidth), 400)
    return margin * float(np.max(payload_spread(design, payloads, w, shift, zeta)))


def _named(sys_, inputs, outputs):
    """``sys_`` as a state-space system with named signals."""
    import control
    ss = control.ss(sys_)
    return control.ss(ss.A, ss.B, ss.C, ss.D, inputs=inputs, outputs=outputs)


def synthesis_plant(design: DesignModel, settings: "HInfSettings", tau_max: float):
    """The generalised plant of the synthesis: inputs ``r, d, u``, outputs ``z1, z2, [z3,] e``.

    Parameters
    ----------
    design : DesignModel
    settings : HInfSettings
    tau_max : float
        Torque limit [N m] (scales W2 and the disturbance).

    Returns
    -------
    tuple
        ``(P, weights)``: the plant (control.StateSpace) and the weights' parameters.
    """
    import control
    wb = float(settings.bandwidth)
    shift, zeta = float(settings.synthesis_shift) * wb, float(settings.synthesis_damping)
    payloads = () if settings.payloads is None else tuple(float(m) for m in settings.payloads)
    s = control.tf("s")
    corner = float(settings.roll_off) * wb
    blocks = [_named(_angle_plant(design, shift, zeta), ["ug"], ["y"]),
              _named((s / S_PEAK + wb) / (s + wb * S_FLOOR), ["e"], ["z1"]),
              _named((1.0 / tau_max) * (s / corner + 1) / (s / (WEIGHT_SPAN * corner) + 1), ["u"], ["z2"]),
              _named(control.tf(float(settings.disturbance) * tau_max, 1), ["d"], ["dw"]),
              control.summing_junction(inputs=["u", "dw"], output="ug"),
              control.summing_junction(inputs=["r", "-y"], output="e")]
    k = spread_weight(design, payloads, wb, shift, float(settings.spread_margin), zeta) if payloads else 0.0
    outputs = ["z1", "z2"]
    if k > 0.0:
        blocks.append(_named(control.tf(k, 1), ["y"], ["z3"]))
        outputs.append("z3")
    P = control.interconnect(blocks, inplist=["r", "d", "u"], outlist=outputs + ["e"])
    weights = {"bandwidth_rad_s": wb, "w2_corner_rad_s": corner,
               "disturbance_nm": float(settings.disturbance) * tau_max, "w3": k}
    return control.ss(P.A, P.B, P.C, P.D), weights


class HInf(Controller):
    """Mixed-sensitivity H-infinity control of the hub angle (module docstring).

    ``tau = sat(tau_ff + K(theta_ref - theta))`` with ``K`` the sampled (Tustin) hinfsyn controller.

    Parameters
    ----------
    design : DesignModel
        The design model (its continuous ``A``, ``B``; ``dt``).
    settings : HInfSettings, optional
    reference : Reference, optional

    Attributes
    ----------
    gamma : float
        The closed-loop H-infinity norm hinfsyn reached [-] (below 1: every weight's bound holds).
    weights : dict
        The weights' parameters (``wb``, W2's corner, the disturbance, W3's level).
    continuous : control.StateSpace
        The continuous controller from the angle error to the torque.

    Examples
    --------
    >>> from controllers import DesignModel                                  # doctest: +SKIP
    >>> h = HInf(DesignModel.build(n_modes=3), HInfSettings(payloads=(0.0, 0.5)))   # doctest: +SKIP
    >>> h.gamma < 2                                                          # doctest: +SKIP
    True
    """

    measurement = "sensors"

    @property
    def signals(self):
        """The hub angle (None on the beam alone: the closed loop's default sensors)."""
        return None if self.design.sensors is None else ("theta",)

    def __init__(self, design: DesignModel, settings: HInfSettings | None = None,
                 reference: Reference | None = None):
        settings = settings or HInfSettings()
        if not isinstance(settings, HInfSettings):
            raise ParameterError(f"settings must be a HInfSettings, got {type(settings).__name__}")
        if not have_slycot():
            raise ParameterError("controller hinf needs slycot (python-control's hinfsyn): pip install "
                                 "'hubbeam-ctrl[robust]' or slycot==0.7.0")
        super().__init__(design, settings, reference)
        import control
        if settings.payloads is not None and not all(np.isfinite(float(m)) and float(m) >= 0.0
                                                     for m in settings.payloads):
            raise ParameterError(f"payloads must be finite numbers >= 0 [kg], got {settings.payloads!r}")
        P, self.weights = synthesis_plant(design, settings, self.tau_max)
        try:
            K, _, gamma, _ = control.hinfsyn(P, 1, 1)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            raise ParameterError(f"hinf: hinfsyn found no controller for these weights (bandwidth = "
                                 f"{settings.bandwidth:g} rad/s, roll_off = {settings.roll_off:g}): "
                                 f"{str(exc).strip()[:120]}") from None
        self.gamma = float(gamma)
        self.continuous = K
        Kd = control.c2d(K, self.dt, "tustin")
        self._Ak, self._Bk, self._Ck, self._Dk = (np.atleast_2d(np.asarray(M, dtype=float))
                                                  for M in (Kd.A, Kd.B, Kd.C, Kd.D))
        self._ff = 1.0 if settings.feedforward else 0.0
        self.reset()

    @property
    def order(self) -> int:
        """The controller's states."""
        return self._Ak.shape[0]

    def reset(self) -> None:
        """Zero the controller's state."""
        self._x = np.zeros(self._Ak.shape[0])

    def feedback_matrices(self) -> tuple:
        """The sampled law on the angle measurement's deviation ``theta - theta_ref`` (the synthesised
        controller reads ``theta_ref - theta``: its input matrices change sign)."""
        names = [f"k{i + 1}" for i in range(self.order)]
        return self._Ak, -self._Bk, self._Ck, -self._Dk, names, ["theta"]

    def __call__(self, t: float, y) -> float:
        """Hub torque [N m] at time ``t`` [s] from the measurement ``y`` (its first entry the hub angle)."""
        ref = self.reference
        k = int(round(t / self.dt))
        if k < len(ref.theta):
            th, tff = ref.theta[k], ref.torque[k]
        else:
            (th,), _, (tff,) = ref.window(k, 1)
        e = np.array([th - float(y[0])])
        u = float((self._Ck @ self._x + self._Dk @ e)[0])
        self._x = self._Ak @ self._x + self._Bk @ e
        return saturate(self._ff * tff + u, self.tau_max)

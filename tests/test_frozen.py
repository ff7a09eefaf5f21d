"""The loop frozen along a run (hubbeam_ctrl.study.frozen, issue 36): the evaluation model
linearised about the bent beam by CasADi's derivatives of its inverse dynamics."""

from __future__ import annotations

import numpy as np
import pytest

from hubbeam_ctrl import Params
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import rig_from_dict
from hubbeam_ctrl.study.certificate import loop_matrix
from hubbeam_ctrl.study.compare import compare
from hubbeam_ctrl.study.frozen import frozen_loop, frozen_scan


def test_at_rest_the_frozen_foam_loop_is_the_certificates_sfoam_loop(fast_backend):
    """Straight and at rest, FOAM's linearisation is SFOAM's with the axial modes apart: with the
    axial modes damped (Params.damping_ratio), the frozen loop's radius is the certificate's.
    Two derivations meet: CasADi's derivatives of FOAM's inverse dynamics, and SFOAM's linear
    model (hubbeam_ctrl.linear)."""
    cmp = compare(Params(), "slew", ["lqr"])
    ctrl = cmp.controllers["lqr"]
    params = cmp.plant.params.replace(damping_ratio=0.01)
    n_q = 1 + params.n_axial + params.n_transverse
    frozen = frozen_loop(ctrl, "foam", params, np.zeros(n_q), np.zeros(n_q), 0.0)
    A, _ = loop_matrix(ctrl, params, 0.0, 0.01)
    radius = float(np.max(np.abs(np.linalg.eigvals(A))))
    assert frozen["radius"] == pytest.approx(radius, abs=1e-9)
    assert radius < 1.0
    _every_pole_is_there(np.linalg.eigvals(A), frozen["poles"], params.n_axial)
    # bent by a tenth of L in its first mode, the loop moves (the coupling the certificate lacks)
    q = np.zeros(n_q)
    q[1 + params.n_axial] = 0.1 * params.L / 2
    bent = frozen_loop(ctrl, "foam", params, q, np.zeros(n_q), 0.0)
    assert bent["radius"] != pytest.approx(radius, abs=1e-9)
    with pytest.raises(ParameterError, match="q must hold the model's 16 coordinates"):
        frozen_loop(ctrl, "foam", params, np.zeros(n_q - 1), np.zeros(n_q - 1), 0.0)


#: A random rig of the session-22 fuzzing (a 2.53 m steel strip, E 200 GPa, rho 7850 kg/m^3, on a
#: 493 N m torque source with Coulomb friction, 10000 counts, a root gauge, 1 kHz and one sample of
#: computation delay). Its first axial mode (498 Hz) sits at the 500 Hz Nyquist frequency; the
#: default slew bends the tip by 0.62 m and the command alternates between +-tau_max for 0.5 s
#: of it, while the straight-beam certificate says stable (0.99905).
AXIAL_RIG = {
    "beam": {"L": 2.533, "rho": 7850, "A": 0.00018433, "E": 2e11, "I": 7.8502e-10, "J_h": 3.3703, "r": 0.0,
             "m_t": 0, "tau_max": 493.19},
    "friction": {"viscous": 0.007359, "coulomb": 29.8},
    "damping": {"ratios": [0.004275]},
    "sensors": {"encoder_counts": 10000, "strain_gauges": [0.0]},
    "timing": {"dt": 0.001, "delay": 1.0},
}


@pytest.mark.slow
def test_a_bent_beam_that_couples_its_axial_mode_into_the_delayed_loop_is_named(fast_backend):
    rig = rig_from_dict(AXIAL_RIG)
    cmp = compare(rig, "slew", ["openloop", "lqr"])
    m, res, ctrl = cmp.metrics["lqr"], cmp.results["lqr"], cmp.controllers["lqr"]
    assert m["time_at_limit_slew_s"] > 0.2 and m["loop_spectral_radius"] < 1.0
    # the command alternates between the limits: an oscillation at the Nyquist frequency
    u = np.asarray(res.tau)
    at = np.abs(u) >= 0.999 * rig.beam.tau_max
    assert np.sum((u[1:] * u[:-1] < 0) & at[1:] & at[:-1]) > 100
    assert m["frozen_radius"] > 1.1 and m["frozen_hz"] == pytest.approx(500.0, abs=5.0)
    assert m["frozen_tip_m"] == pytest.approx(0.62, abs=0.01) and "axial mode" in m["frozen_mode"]   # docs/rig.md
    assert "the loop frozen at the bent beam" in m["verdict_reason"] and "anti_alias_hz" in m["verdict_reason"]
    # straight, the same loop is neutral at most (the undamped axial modes), as the certificate says
    t = np.asarray(res.t)
    end = frozen_loop(ctrl, "foam", cmp.plant.params, res.q[-1], res.v[-1], float(res.tau[-1]))
    assert end["radius"] < 1.0 + 1e-4
    assert frozen_scan(res, ctrl, "ancf", cmp.plant.params, float(t[-1])) is None


def test_at_rest_the_frozen_loop_reads_the_rigs_accelerometer_as_the_certificate_does(fast_backend):
    """The rig-signal path (the sensor layout's rows, the accelerometer's feedthrough of the command):
    on accel_link (encoder and tip accelerometer, 1 kHz) the frozen FOAM loop at rest is the
    certificate's loop with the rig's damping."""
    from hubbeam_ctrl.plant.rig import load_rig
    rig = load_rig("accel_link")
    cmp = compare(rig, "slew", ["lqr"])
    ctrl = cmp.controllers["lqr"]
    assert "accel" in " ".join(ctrl.feedback_matrices()[5])
    params = cmp.plant.params.replace(damping_ratio=0.01)
    n_q = 1 + params.n_axial + params.n_transverse
    frozen = frozen_loop(ctrl, cmp.plant.model, params, np.zeros(n_q), np.zeros(n_q), 0.0)
    A, _ = loop_matrix(ctrl, params, 0.0, rig.damping.ratios[0])
    assert frozen["radius"] == pytest.approx(float(np.max(np.abs(np.linalg.eigvals(A)))), abs=1e-9)
    _every_pole_is_there(np.linalg.eigvals(A), frozen["poles"], params.n_axial)


def _every_pole_is_there(certificate, frozen, n_axial):
    """Each pole of the certificate's loop is a pole of the frozen one, which has the axial modes' too."""
    gaps = [float(np.min(np.abs(frozen - z))) for z in certificate]
    # the axial modes' poles, and without a rig one held command (delay_augmented's state, a pole at 0)
    assert len(frozen) - len(certificate) - 2 * n_axial in (0, 1)
    assert max(gaps) < 1e-6, max(gaps)



@pytest.mark.slow
def test_an_anti_alias_filter_the_design_models_removes_the_cycle(fast_backend):
    """The hint the reason gives, on the same strip: a first-order 100 Hz filter on the gauge (a tenth
    of the sampling frequency), modelled by the design, and the command never reaches its limit."""
    import copy
    d = copy.deepcopy(AXIAL_RIG)
    d["sensors"]["anti_alias_hz"] = 100.0
    rig = rig_from_dict(d)
    m = compare(rig, "slew", ["openloop", "lqr"]).metrics["lqr"]
    assert m["verdict"] == "settled" and m["time_at_limit_slew_s"] == 0.0
    assert m["peak_command_step"] < 0.02 * rig.beam.tau_max and "frozen_radius" not in m


def test_the_reason_names_growth_not_round_off():
    """frozen_cause: a neutral mode's round-off (1 + 1e-13, the undamped axial modes at rest) is
    recorded but not named; a growth past FROZEN_MARGIN is, with the anti-alias hint only near Nyquist,
    as the cause of a run that did not settle and as a remark on one that did, unless held over one span
    of the scan it would grow less than FROZEN_GROWTH."""
    from hubbeam_ctrl.study.frozen import FROZEN_MARGIN, frozen_cause
    scan = {"radius": 1.0 + 1e-13, "hz": 484.0, "mode": "axial mode 5 (4484 Hz, folded to 484 Hz)", "t_s": 0.0,
            "tip_m": 0.0, "nyquist_hz": 500.0, "span_samples": 1000.0}
    m = {"verdict": "settled", "verdict_reason": "inside the settling bands"}
    frozen_cause(m, scan)
    assert m["frozen_radius"] == 1.0 + 1e-13 and m["verdict_reason"] == "inside the settling bands"
    m = {"verdict": "not settled", "verdict_reason": "outside the bands"}
    frozen_cause(m, dict(scan, radius=1.0 + 2 * FROZEN_MARGIN, hz=100.0))
    assert m["verdict_reason"].startswith("outside the bands; cause: the loop frozen at the bent beam")
    assert "anti_alias_hz" not in m["verdict_reason"]
    m = {"verdict": "settled", "verdict_reason": "", "time_at_limit_slew_s": 0.5}
    frozen_cause(m, dict(scan, radius=1.11, hz=500.0))
    assert m["verdict_reason"].startswith("the command at its limit 0.5 s of the slew: the loop frozen")
    assert "anti_alias_hz" in m["verdict_reason"]
    frozen_cause(m, None)                                  # nothing frozen: nothing added
    assert m["frozen_radius"] == 1.11
    # past the margin but brief: random rig s34/2 (1.14 m steel link, 200 Hz), 1.0018 over a 50-sample span
    m = {"verdict": "not settled", "verdict_reason": "outside the bands"}
    frozen_cause(m, dict(scan, radius=1.00175, hz=1.246, span_samples=50.0))
    assert m["verdict_reason"] == "outside the bands" and m["frozen_growth"] == pytest.approx(1.0914, abs=1e-4)

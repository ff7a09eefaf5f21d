"""Linear state-space models about steady spin (issue 3, items 1-4).

Figures measured with Table 1's data (m_t = 0.1 kg at the tip, n = 5), hub free:

* Omega = 0: SFOAM, FOAM, TLAM (and CFOAM) bending poles agree to ~2e-15 relative.
* FOAM minus SFOAM, relative, lowest bending mode: -1.52e-6 (1 rad/s), -6.11e-6 (2 rad/s),
  -1.38e-5 (3 rad/s), i.e. -1.53e-6 Omega^2; higher modes differ less. The difference is
  the Coriolis (gyroscopic) coupling of bending to the axial modes that SFOAM drops
  (the prescribed-hub difference is of the same size, -1.93e-6 at 1 rad/s).
* TLAM critical speed 2.6043 rad/s: there the lowest bending pole is 8.9e-8 rad/s
  (3e-8 of its non-rotating value), and a real pair appears above it.
* tau -> theta: s^2 G(s) -> 1 / J_total = 4.0234e-3 1/(kg m^2) at Omega = 0.
* Hub held (J_h = 1e9): SFOAM frequencies equal the prescribed-hub ones to 2e-8 and
  lie 0.05-0.06 % below the printed Table 2 (which is 0.05 % high, see docs/physics.md).
"""

from __future__ import annotations

import control
import numpy as np
import pytest
import scipy.linalg as sla

from hubbeam_ctrl import Params, critical_speed, natural_frequencies
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.linear.pole_comparison import compare_poles
from hubbeam_ctrl.linear.poles import continuous_poles, poles_hz
from hubbeam_ctrl.linear.statespace import OUTPUTS, LinearModel, linearize
from hubbeam_ctrl.linear.transforms import discretize, reduce

P = Params()
TABLE2 = {0.0: [0.4635, 2.9047, 8.1332, 15.9377, 26.3462],
          1.0: [0.4714, 2.9308, 8.1618, 15.9682, 26.3776]}


# -- item 1: SFOAM model, names, outputs -------------------------------------------
def test_sfoam_names_and_defaults():
    lm = linearize()
    assert isinstance(lm, LinearModel) and isinstance(lm.sys, control.StateSpace)
    assert lm.model == "sfoam" and lm.spin == 0.0 and lm.params == P and lm.reduction == "none"
    assert lm.state_names == (["theta"] + [f"q2_{i}" for i in range(1, 6)] + ["theta_dot"]
                              + [f"q2_dot_{i}" for i in range(1, 6)])
    assert lm.input_names == ["tau"] and lm.output_names == ["theta", "tip_deflection"]
    assert lm.state_units[:2] == ["rad", "m"] and lm.state_units[6:8] == ["rad/s", "m/s"]
    assert lm.dt == 0.0 and not lm.is_discrete
    assert np.all(lm.D == 0)


def test_output_rows():
    lm = linearize("sfoam", 1.0, outputs=list(OUTPUTS), n_modes=3, tip_mass=0.2,
                   tip_position=6.0, damping=0.01)
    assert lm.params.n_transverse == 3 and lm.params.m_t == 0.2 and lm.params.l == 6.0
    assert lm.params.damping_ratio == 0.01
    C = lm.C
    b = __import__("hubbeam_ctrl").build_model("sfoam", lm.params).basis
    assert np.array_equal(C[0], np.eye(8)[0]) and np.array_equal(C[1], np.eye(8)[4])
    np.testing.assert_array_equal(C[2, 1:4], b.f2_tip)
    np.testing.assert_array_equal(C[3, 5:8], b.f2_tip)
    np.testing.assert_allclose(np.abs(b.f2_tip), 2.0, rtol=1e-12)   # |f2(L)| = 2
    np.testing.assert_array_equal(C[4, 1:4], lm.params.EI * b.f2pp_root)
    assert lm.output_units == ["rad", "rad/s", "m", "m/s", "N m"]


def test_foam_state_names_include_axial():
    lm = linearize("foam", 2.0, P.replace(n_axial=2, n_transverse=3))
    assert lm.state_names == ["theta", "q1_1", "q1_2", "q2_1", "q2_2", "q2_3", "theta_dot",
                              "q1_dot_1", "q1_dot_2", "q2_dot_1", "q2_dot_2", "q2_dot_3"]


@pytest.mark.parametrize("kwargs, word", [
    ({"model": "abc"}, "model"), ({"outputs": "theta,foo"}, "outputs"),
    ({"outputs": ""}, "outputs"), ({"outputs": "theta,theta"}, "outputs"),
    ({"spin": float("nan")}, "spin"), ({"n_modes": 0}, "n_transverse"),
    ({"damping": 1.0}, "damping_ratio"), ({"tip_position": 9.0}, "l"),
    ({"name": "a.b"}, "name"),
])
def test_bad_input(kwargs, word):
    with pytest.raises(ParameterError, match=word):
        linearize(**kwargs)


# -- item 3: checks ------------------------------------------------------------------
def test_spin_zero_bending_poles_coincide():
    ref = linearize("sfoam", 0.0, P).poles_hz()
    assert len(ref) == 5
    for model in ("foam", "tlam", "cfoam"):
        c = compare_poles("sfoam", model, 0.0, P)
        np.testing.assert_allclose(c.bending_a_hz, ref, rtol=1e-12)
        assert np.abs(c.bending_rel_diff).max() < 1e-6          # issue: within 1e-6
        assert np.abs(c.bending_rel_diff).max() < 1e-13         # measured ~2e-15
        # the linear model's own lowest poles are the bending ones (axial > 100 Hz)
        np.testing.assert_allclose(linearize(model, 0.0, P).poles_hz()[:5], ref, rtol=1e-12)


@pytest.mark.parametrize("spin, first", [(1.0, -1.52e-6), (2.0, -6.11e-6), (3.0, -1.38e-5)])
def test_foam_vs_sfoam_axial_coupling(spin, first):
    c = compare_poles("sfoam", "foam", spin, P)
    rel = c.bending_rel_diff
    assert len(c.axial_a_hz) == 0 and len(c.axial_b_hz) == 5
    np.testing.assert_allclose(rel[0], first, rtol=0.01)        # measured figure
    assert np.all(rel < 0)                                      # coupling lowers them
    assert np.all(np.abs(rel) <= 1.6e-6 * spin ** 2)            # bound stated in docs
    assert np.all(np.diff(np.abs(rel)) < 0)                     # higher modes differ less
    assert "(absent)" in c.table()


def test_tlam_lowest_pole_reaches_zero_at_critical_speed():
    wc = critical_speed("tlam", P)
    assert wc == pytest.approx(2.6043, abs=1e-4)
    lam0 = np.sort(np.abs(continuous_poles(linearize("tlam", 0.0, P))))[2]
    lam = continuous_poles(linearize("tlam", wc, P))
    lowest = np.sort(np.abs(lam))[2]                 # after the rigid double pole
    assert lowest < 1e-6 * lam0                      # measured 3e-8 of the value at rest
    below = linearize("tlam", 0.99 * wc, P)
    assert below.poles_hz()[0] < 0.15 * lam0 / (2 * np.pi)
    assert np.abs(continuous_poles(below).real).max() < 1e-9     # still oscillatory
    above = continuous_poles(linearize("tlam", 1.01 * wc, P))
    assert (above.real > 1e-2).sum() == 1            # one divergent real pole
    c = compare_poles("tlam", "foam", 1.01 * wc, P)
    assert c.unstable_a and np.isnan(c.bending_a_hz[0]) and "(lost)" in c.table()


@pytest.mark.parametrize("model", ["sfoam", "foam", "tlam", "cfoam"])
def test_single_double_integrator_tau_to_theta(model):
    for spin in (0.0, 1.0, 2.0, 3.0):
        lm = linearize(model, spin, P, outputs="theta")
        A, B, C = lm.A, lm.B, lm.C
        n = A.shape[0]
        # two poles at zero, geometric multiplicity 1: one Jordan block of size 2
        assert n - np.linalg.matrix_rank(A, tol=1e-9 * np.linalg.norm(A)) == 1
        G = lambda s: (C @ np.linalg.solve(s * np.eye(n) - A, B))[0, 0]
        g1, g2 = 1e-3 ** 2 * G(1e-3), 2e-3 ** 2 * G(2e-3)
        assert g1 > 0 and abs(g2 / g1 - 1) < 1e-5   # s^2 G(s) has a finite nonzero limit
        assert g1 == pytest.approx(1 / P.total_inertia, rel=1e-4 if spin else 1e-7)
        others = np.sort(np.abs(np.linalg.eigvals(A)))[2:]
        assert others.min() > 0.05                   # no other pole near the origin


def test_hub_held_tends_to_table2():
    p0 = Params(m_t=0.0)
    for spin in (0.0, 1.0):
        prescribed = natural_frequencies("sfoam", spin, "prescribed", p0)
        errs = []
        for J_h in (1e4, 1e6, 1e9):
            f = linearize("sfoam", spin, p0.replace(J_h=J_h)).poles_hz()
            errs.append(np.abs(f / prescribed - 1).max())
        assert errs[0] > 10 * errs[1] > 100 * errs[2] and errs[2] < 1e-7
        rel = f / np.array(TABLE2[spin]) - 1
        assert np.all(np.abs(rel) < 7e-4) and np.all(rel < 0)   # Table 2 is ~0.05 % high


def test_damping_ratio_appears_in_poles():
    lm = linearize("sfoam", 0.0, Params(m_t=0.0, J_h=1e9), damping=0.02)
    lam = continuous_poles(lm)
    osc = lam[lam.imag > 1e-6]
    np.testing.assert_allclose(-osc.real / np.abs(osc), 0.02, rtol=1e-6)


# -- item 4: discretisation and reduction ------------------------------------------
def test_discretize_zoh():
    lm = linearize("foam", 1.0, P.replace(n_axial=2, n_transverse=3), damping=0.01,
                   outputs="theta,root_moment")
    dt = 0.005
    d = discretize(lm, dt)
    assert d.dt == dt and d.sys.dt == dt and d.is_discrete
    assert d.state_names == lm.state_names and d.output_names == lm.output_names
    assert d.input_names == ["tau"] and d.model == "foam" and d.spin == 1.0
    n = lm.n_states
    E = sla.expm(np.block([[lm.A, lm.B], [np.zeros((1, n + 1))]]) * dt)
    np.testing.assert_allclose(d.A, E[:n, :n], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(d.B, E[:n, n:], rtol=1e-9, atol=1e-15)
    np.testing.assert_array_equal(d.C, lm.C)
    # below Nyquist the frequencies come back through log(z)/dt
    np.testing.assert_allclose(d.poles_hz()[:3], lm.poles_hz()[:3], rtol=1e-8)
    with pytest.raises(ParameterError, match="dt"):
        discretize(lm, 0.0)
    with pytest.raises(ParameterError, match="continuous"):
        discretize(d, dt)


def test_reduce_modal_keeps_poles_and_low_frequency_response():
    lm = linearize("foam", 2.0, P, outputs="theta,tip_deflection", damping=0.01)
    r = reduce(lm, 3)
    assert r.reduction == "modal:3" and r.n_states == 8
    assert r.state_names == ["rigid", "mode_1", "mode_2", "mode_3",
                             "rigid_dot", "mode_dot_1", "mode_dot_2", "mode_dot_3"]
    assert r.state_units[0] == "rad" and r.output_names == lm.output_names
    np.testing.assert_allclose(r.poles_hz(), lm.poles_hz()[:3], rtol=1e-10)
    w = 2 * np.pi * np.array([0.05, 0.2, 1.0, 3.0])
    H = np.array([lm.sys(1j * x)[:, 0] for x in w])
    Hr = np.array([r.sys(1j * x)[:, 0] for x in w])
    err = np.abs(Hr / H - 1)
    assert err[:3].max() < 1e-4          # measured 6.6e-5 up to 1 Hz
    assert err[3].max() < 1e-2           # 7.2e-3 on the tip at 3 Hz (left-out modes)
    with pytest.raises(ParameterError, match="n_modes"):
        reduce(lm, 16)          # 5 bending + 5 axial flexible modes


def test_reduce_balanced():
    lm = linearize("sfoam", 0.0, P, outputs="theta,tip_deflection", damping=0.02)
    r = reduce(lm, 2, method="balanced")
    assert r.reduction == "balanced:2" and r.state_names[:3] == ["rigid", "rigid_dot", "xb_1"]
    assert r.n_states == 6
    w = 2 * np.pi * np.array([0.05, 0.2, 1.0])
    H = np.array([lm.sys(1j * x)[:, 0] for x in w])
    Hr = np.array([r.sys(1j * x)[:, 0] for x in w])
    assert np.abs(Hr / H - 1).max() < 1e-2
    with pytest.raises(ParameterError, match="damping_ratio"):
        reduce(linearize("sfoam"), 2, method="balanced")
    with pytest.raises(ParameterError, match="method"):
        reduce(lm, 2, method="foo")


def test_poles_hz_of_plain_statespace():
    lm = linearize("sfoam", 0.0, P)
    np.testing.assert_allclose(poles_hz(lm.sys), lm.poles_hz(), rtol=1e-12)
    assert np.all(np.diff(lm.poles_hz()) > 0)


def test_poles_hz_is_damp_without_the_rigid_poles():
    """python-control's damp() gives the same frequencies, but it divides by |s| and so warns
    (0/0) on the free hub's rigid-body poles at s = 0: why poles_hz keeps its own selection."""
    import warnings
    lm = linearize("sfoam", 1.0, Params(n_transverse=3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(RuntimeWarning):
            lm.sys.damp()
        f = poles_hz(lm)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        wn, zeta, p = lm.sys.damp()
    expect = np.sort(wn[(p.imag > 0) & (wn > 1e-6)]) / (2 * np.pi)
    assert np.allclose(f, expect, rtol=1e-12) and len(f) == 3

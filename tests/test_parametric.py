"""Parameters as inputs: one set of functions per model family and mode counts."""

import numpy as np
import pytest

from hubbeam_ctrl import Params, build_model
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.basis import modal_basis
from hubbeam_ctrl.plant.models import pair_map, parameter_layout, parametric_model, reduced_foreshortening
from hubbeam_ctrl.sim.stepper import StepperSettings, step_functions

P_A = Params(n_axial=3, n_transverse=3, m_t=0.1)
P_B = Params(n_axial=3, n_transverse=3, m_t=0.45, l=0.6, damping_ratio=0.02)


@pytest.mark.parametrize("name", ["cfoam", "foam", "tlam", "sfoam"])
def test_functions_are_shared_across_parameters(name):
    a, b = build_model(name, P_A), build_model(name, P_B)
    assert a.parametric is b.parametric is parametric_model(name, a.n_axial, a.n_transverse)
    assert a.p.shape == (a.parametric.n_p,) and not np.array_equal(a.p, b.p)
    step_a, jac_a, _ = step_functions(a, StepperSettings(), "vm")
    step_b, jac_b, _ = step_functions(b, StepperSettings(), "vm")
    assert step_a is step_b and jac_a is jac_b


@pytest.mark.parametrize("name", ["cfoam", "foam", "tlam", "sfoam"])
def test_parameter_vector_carries_the_moments(name):
    m = build_model(name, P_B)
    tot = m.basis.total
    M0 = m.mass_matrix(np.zeros(m.n_q))
    assert M0[0, 0] == pytest.approx(P_B.J_h + tot.J, rel=1e-14)              # J_h + int s^2 dmu
    sl2 = m.transverse_slice
    np.testing.assert_allclose(M0[sl2, sl2], tot.M2, rtol=1e-13)
    np.testing.assert_allclose(M0[0, sl2], tot.V2, rtol=1e-13)
    # at rest with the hub still: c(q, 0) = K q (stiffness only)
    q = np.zeros(m.n_q)
    q[sl2] = [1e-3, -2e-3, 5e-4]
    c = m.bias(q, np.zeros(m.n_q))
    K2 = m.basis.K2
    np.testing.assert_allclose(c[sl2], K2 @ q[sl2], rtol=1e-9, atol=1e-12 * np.abs(K2).max())
    # the damping: c(0, v) elastic part = C v
    v = np.zeros(m.n_q)
    v[sl2] = 1.0
    zeta = P_B.damping_ratio
    expected = 2 * zeta * np.sqrt(np.diag(m.basis.K2) * np.diag(m.basis.beam.M2))
    assert np.all(expected > 0)
    c_v = m.bias(np.zeros(m.n_q), v)[sl2]
    np.testing.assert_allclose(c_v, expected, rtol=1e-12)


def test_bound_function_equals_parametric_evaluation():
    m = build_model("cfoam", P_B)
    rng = np.random.default_rng(3)
    q, v, a = (0.05 * rng.standard_normal(m.n_q) for _ in range(3))
    bound = np.array(m.inverse_dynamics_function(q, v, a)).ravel()
    direct = np.array(m.parametric.inverse_dynamics(q, v, a, m.p)).ravel()
    np.testing.assert_allclose(bound, direct, rtol=1e-12, atol=1e-12 * np.abs(direct).max())


def test_reduced_foreshortening_is_exact():
    n2 = 4
    mom = modal_basis(Params(n_axial=2, n_transverse=n2, m_t=0.2)).total
    red = reduced_foreshortening(mom)
    rng = np.random.default_rng(7)
    q, qd = rng.standard_normal(n2), rng.standard_normal(n2)
    pairs = [(i, j) for i in range(n2) for j in range(i, n2)]
    y = np.array([q[i] * q[j] for i, j in pairs])
    yd = np.array([0.5 * (q[i] * qd[j] + q[j] * qd[i]) for i, j in pairs])
    Fm = mom.F.reshape(n2 * n2, n2 * n2)
    qq, qqd = np.outer(q, q).ravel(), np.outer(q, qd).ravel()
    assert y @ red["F_r"] @ y == pytest.approx(qq @ Fm @ qq, rel=1e-12)
    assert yd @ red["F_r"] @ yd == pytest.approx(qqd @ Fm @ qqd, rel=1e-12)
    np.testing.assert_allclose(red["E_r"] @ yd, mom.E.reshape(2, -1) @ qqd, rtol=1e-12)
    np.testing.assert_allclose(y @ red["G_r"], qq @ mom.G.reshape(n2 * n2, n2), rtol=1e-12)
    W = pair_map(n2)
    assert W.shape == (16, 10) and W.sum() == 16


def test_parameter_layout_and_bad_values():
    layout = parameter_layout("cfoam", 2, 3)
    names = [k for k, _ in layout]
    assert names[:2] == ["J_h", "J"] and names[-3:] == ["E_r", "G_r", "F_r"]
    assert dict(layout)["F_r"] == (6, 6)
    assert "F_r" not in dict(parameter_layout("foam", 2, 3))
    pm = parametric_model("foam", 2, 3)
    fields = build_model("foam", Params(n_axial=2, n_transverse=3))._parameter_fields()
    fields["M2"] = np.zeros((2, 2))
    with pytest.raises(ParameterError, match=r"parameter M2 must have shape \(3, 3\)"):
        pm.values(fields)


def test_functions_are_built_on_first_use():
    """A family's functions are built when first used, once; an unknown name is an AttributeError."""
    from hubbeam_ctrl.plant.models import ParametricModel
    pm = ParametricModel("foam", 1, 2)
    assert not any(name in pm.__dict__ for name in ParametricModel.FUNCTIONS)
    f = pm.energy
    assert f is pm.energy and f.name() == "energy" and "energy" in pm.__dict__ and "bias" not in pm.__dict__
    with pytest.raises(AttributeError, match="no attribute 'energi'"):
        pm.energi

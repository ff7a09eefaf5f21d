"""H-infinity control of the hub angle over a payload range (controllers.hinf, issue 39 item 3)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from controllers import DesignModel, HInfSettings, make_controller, slew_reference
from controllers.hinf import have_slycot, payload_spread, spread_weight
from hubbeam_ctrl import Params
from hubbeam_ctrl.core.errors import ParameterError

needs_slycot = pytest.mark.skipif(not have_slycot(), reason="slycot (the robust extra) is not installed")

P = Params(n_axial=2, n_transverse=3)


@pytest.fixture(scope="module")
def design():
    return DesignModel.build(P, 0.0, 0.01, 3)


@pytest.fixture(scope="module")
def hinf(design):
    ref = slew_reference(0.5, 3.0, P.total_inertia, 200.0, 0.01, 5.0)
    return make_controller("hinf", design, HInfSettings(payloads=(0.0, 0.1, 0.5), tau_max=200.0), ref)


@needs_slycot
def test_the_spread_weight_is_the_rigid_inertias_spread(design):
    """Below the crossover the plants differ by their rigid inertia: |G_m / G - 1| = J / J_m - 1 at
    the lightest and heaviest payloads (to the synthesis's pole shift), and W3 is 1.5 times the larger."""
    w = np.array([1e-2])
    J = {m: design.params.replace(m_t=m).total_inertia for m in (0.0, 0.5)}
    expected = max(abs(design.inertia / J[0.0] - 1), abs(design.inertia / J[0.5] - 1))
    assert payload_spread(design, (0.0, 0.5), w, 0.0)[0] == pytest.approx(expected, rel=1e-3)
    assert spread_weight(design, (0.0, 0.5), 0.05, 0.0, 1.5) == pytest.approx(1.5 * expected, rel=1e-3)
    assert spread_weight(design, (0.0, 0.5), 1.0, 0.0, 1.5) > 1.5 * expected     # the first mode nears


@needs_slycot
def test_the_law_it_runs_is_the_law_the_certificate_judges(hinf):
    """feedback_matrices (input theta - theta_ref) reproduce the torques of __call__ beyond the feedforward."""
    Ak, Bk, Ck, Dk, states, inputs = hinf.feedback_matrices()
    assert inputs == ["theta"] and len(states) == hinf.order == Ak.shape[0]
    assert np.isfinite(hinf.gamma) and hinf.gamma > 0
    rng = np.random.default_rng(3)
    hinf.reset()
    x = np.zeros(hinf.order)
    ref = hinf.reference
    for k in range(40):
        theta = ref.theta[k] + 1e-4 * rng.standard_normal()
        tau = hinf(k * hinf.dt, [theta, 0.0, 0.0])
        e = np.array([theta - ref.theta[k]])
        u = float((Ck @ x + Dk @ e)[0])
        x = Ak @ x + Bk @ e
        assert tau == pytest.approx(ref.torque[k] + u, rel=1e-9, abs=1e-9)


@needs_slycot
def test_certified_over_the_payload_range_with_the_damping_floor(hinf):
    """The certificate of the sampled law with a 6-mode plant over 0-0.5 kg and a 0.05 % floor."""
    from hubbeam_ctrl.plant.rig import Rig
    from hubbeam_ctrl.plant.uncertainty import Uncertainty
    from hubbeam_ctrl.study.worst_case import RADIUS_MARGIN, certify_set
    u = Uncertainty.from_table({"m_t": (0.0, 0.5), "damping": (0.0005, 0.0005)})
    wc = certify_set(hinf, Rig(beam=P.replace(n_transverse=6)), u, plant_modes=6, margins=False)
    assert 0.99 < wc.worst.radius <= 1 - RADIUS_MARGIN


@needs_slycot
@pytest.mark.parametrize("kwargs, message", [
    ({"bandwidth": 0.0}, "bandwidth"), ({"roll_off": -1.0}, "roll_off"), ({"payloads": (0.0, -0.1)}, "payloads"),
])
def test_bad_settings_name_the_setting(design, kwargs, message):
    with pytest.raises(ParameterError, match=message):
        make_controller("hinf", design, HInfSettings(**kwargs))



def test_the_docs_table_is_the_benchmarks_json():
    """docs/robust.md's H-infinity table is benchmarks/results/bench_robust.json's hinf entry."""
    from tests.conftest import ROOT, bench_module
    module, _ = bench_module("bench_robust")
    doc = json.loads((ROOT / "benchmarks" / "results" / "bench_robust.json").read_text())
    text = (ROOT / "docs" / "robust.md").read_text()
    table = text.split("<!-- hinf table: from benchmarks/results/bench_robust.json -->")[1].strip().split("\n\n")[0]
    assert table.splitlines() == module.hinf_lines(doc)
    assert set(doc["hinf"]["controllers"]) == {"lqr", "hinf"}

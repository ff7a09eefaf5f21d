"""The NMPC that learns the payload (issue 40, item 2): the momentum balance, the payload table,
the re-planned reference and a slew on a plant heavier than the design's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers import NMPCSettings
from controllers.payload_estimate import PayloadMomentum, payload_table
from controllers.planning import planned_slew_reference, replanned
from hubbeam_ctrl import Params
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.models import build_model

LAB = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.1, tau_max=1.5)


def test_the_payload_table_is_each_payloads_own_model_at_its_points():
    table = payload_table(LAB, 2, 0.0, 0.2, points=5)
    for m, vec in zip(table.masses, table.vectors):
        p, _ = table.at(m)
        np.testing.assert_array_equal(p, vec)
        np.testing.assert_allclose(vec, build_model("foam", LAB.replace(m_t=float(m), n_transverse=2),
                                                    axial="quasi-static").p, rtol=0, atol=0)
    # between points: the chord, and its slope
    p, dp = table.at(0.025)
    np.testing.assert_allclose(p, 0.5 * (table.vectors[0] + table.vectors[1]), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(dp, (table.vectors[1] - table.vectors[0]) / 0.05, rtol=1e-12, atol=1e-9)
    with pytest.raises(ParameterError, match="payload range"):
        payload_table(LAB, 2, 0.2, 0.1)


def _zoh_motion(params: Params, commands, dt: float, modes: int):
    """The 5-mode FOAM (quasi-static axial) driven by held commands: its states at the samples,
    integrated by SciPy at tight tolerance (a reference independent of the closed loop's integrator)."""
    from scipy.integrate import solve_ivp
    model = build_model("foam", params.replace(n_transverse=modes), axial="quasi-static")
    n = model.n_q
    Mf, cf = model.mass_matrix_function, model.bias_function
    B = np.zeros(n)
    B[0] = 1.0
    x = np.zeros(2 * n)
    states = [x]
    for u in commands:
        def f(_t, z, u=u):
            q, v = z[:n], z[n:]
            return np.r_[v, np.linalg.solve(np.asarray(Mf(q, v)), B * u - np.asarray(cf(q, v)).ravel())]
        x = solve_ivp(f, (0.0, dt), x, rtol=1e-10, atol=1e-13, method="DOP853").y[:, -1]
        states.append(x)
    return np.array(states)


def test_the_momentum_balance_finds_the_payload_from_the_first_tenth_of_a_second():
    """The hub's momentum changes by the torque's impulse alone: from a 0.1 kg prior over 0-0.2 kg,
    the lab arm's true 0.17 kg is found to 0.1 % of the range within 0.1 s of a torque ramp."""
    dt, modes, truth = 0.005, 4, 0.17
    commands = np.linspace(0.05, 1.0, 20)                   # 0.1 s of a rising torque [N m]
    states = _zoh_motion(LAB.replace(m_t=truth), commands, dt, modes)
    model = build_model("foam", LAB.replace(n_transverse=modes), axial="quasi-static")
    for prior in (0.1, 0.0):              # the estimate is the record's, not the prior's
        est = PayloadMomentum(model.parametric.momentum, payload_table(LAB, modes, 0.0, 0.2, points=2), prior,
                              dt, 1e-7 * LAB.total_inertia)
        est.update(states[0], None)
        for u, x in zip(commands, states[1:]):
            est.update(x, u)
        assert abs(est.mass - truth) <= 1e-3 * 0.2, prior
        assert abs(est.lag_s) < 1e-3 * dt                   # an exact hold: no lag to explain


def test_a_plan_planned_again_is_the_other_beams_own_plan():
    ref = planned_slew_reference(LAB, math.pi / 2, 1.2, 1.0, 0.01, 2.0)
    heavy = LAB.replace(m_t=0.2)
    again = replanned(ref, heavy)
    own = planned_slew_reference(heavy, math.pi / 2, 1.2, 1.0, 0.01, 2.0)
    for field in ("theta", "theta_dot", "torque", "elastic"):
        np.testing.assert_array_equal(getattr(again, field), getattr(own, field))
    assert not np.allclose(again.torque, ref.torque)     # the heavier tip needs another torque
    with pytest.raises(ParameterError, match="Reference.plan"):
        from controllers import Reference
        replanned(Reference.rest(0.01), heavy)


def test_learning_settings_are_checked():
    with pytest.raises(ParameterError, match="payload_max_kg"):
        NMPCSettings(learn_payload=True, payload_min_kg=0.3, payload_max_kg=0.2)
    from controllers import NMPC, DesignModel
    design = DesignModel.build(LAB.replace(n_transverse=3), 0.0, 0.01, 3)
    with pytest.raises(ParameterError, match="must hold the design's payload"):
        NMPC(design, NMPCSettings(learn_payload=True, payload_min_kg=0.15, payload_max_kg=0.2))


@pytest.mark.slow
def test_the_learning_nmpc_settles_the_lab_arm_with_twice_the_design_payload(fast_backend):
    """The 1 m lab arm designed for 0.1 kg carries 0.2 kg: the NMPC that learns it settles within one
    first-mode period after t_f with the residual within 0.1 % of L and within the torque limit (its
    step times are benchmarks/bench_nmpc_payload.py's; the same NMPC with the design's payload does
    not settle in the window, benchmarks/results/bench_nmpc_payload.json)."""
    from controllers.scaling import first_mode
    from hubbeam_ctrl.limit import time_optimal_slew
    from hubbeam_ctrl.study import Slew, compare
    from hubbeam_ctrl.study.compare_values import CompareSettings, DesignChoice, PlantChoice
    from hubbeam_ctrl.study.scenarios import make_scenario
    task = Slew(math.pi / 2, 1.5 * time_optimal_slew(LAB.replace(m_t=0.2), math.pi / 2).duration_s)
    s = NMPCSettings.for_scenario(make_scenario(task, params=LAB, t_end=None)).replace(
        learn_payload=True, payload_max_kg=0.2)
    c = compare(LAB, task, ["nmpc"], CompareSettings(plant=PlantChoice(plant_params=LAB.replace(m_t=0.2)),
                                                     design=DesignChoice(settings={"nmpc": s})))
    m, ctrl = c.metrics["nmpc"], c.controllers["nmpc"]
    period = 2 * math.pi / first_mode(ctrl.design)     # the design's (0.1 kg): shorter than the plant's
    assert m["verdict"] == "settled"
    assert m["settling_time_s"] <= task.duration + period
    assert m["residual_pct_of_L"] <= 0.1
    assert abs(ctrl.payload.mass - 0.2) <= 0.002
    assert ctrl.payload.history[int(round(0.1 / c.scenario.dt))] == pytest.approx(0.2, abs=0.004)
    assert max(abs(float(t)) for t in c.results["nmpc"].tau) <= LAB.tau_max * (1 + 1e-9)


def test_compare_payload_learning_turns_the_nmpcs_own_learning_on():
    """``PayloadChoice(payload_learning=...)`` (the CLI's --learn-payload) wraps LQR, LQG and MPC in the
    re-planning learner; the NMPC's settings get learn_payload over the same range instead."""
    from controllers.payload_learning import PayloadLearningSettings
    from hubbeam_ctrl.study.compare import _learning
    from hubbeam_ctrl.study.scenarios import make_scenario
    from hubbeam_ctrl.study.tasks import Slew
    sc = make_scenario(Slew(1.0, 4.6), params=Params(), t_end=None)
    own = _learning(NMPCSettings(), PayloadLearningSettings(payload_min_kg=0.0, payload_max_kg=0.5), sc, None)
    assert own.learn_payload and (own.payload_min_kg, own.payload_max_kg) == (0.0, 0.5)
    with pytest.raises(ParameterError, match="without a rig"):
        _learning(NMPCSettings(), PayloadLearningSettings(payload_max_kg=0.5), sc, object())


@pytest.mark.parametrize("name", ["bench_nmpc_payload.json", "bench_nmpc_payload_compiled.json"])
def test_docs_quote_the_learning_nmpc_benchmark(name):
    """docs/limit.md's tables of the learning NMPC are the benchmark's JSON (the step on CasADi's virtual
    machine, and as its generated C); in those runs the NMPC that learns meets more targets than the same
    NMPC with the design's payload on every beam, and every learning run settles within the torque limit
    with at most 0.1 % of L of residual vibration."""
    import json

    from conftest import bench_module
    bench, root = bench_module("bench_nmpc_payload")
    doc = json.loads((root / "benchmarks" / "results" / name).read_text())
    text = (root / "docs" / "limit.md").read_text()
    assert f"<!-- bench_nmpc_payload table: generated from benchmarks/results/{name} -->" in text
    for line in bench.table_lines(doc):
        assert line in text, line
    for beam, b in doc["beams"].items():
        assert b["learning"]["met"] > b["nominal"]["met"], beam
        for m, r in b["learning"]["runs"].items():
            assert r["verdict"] == "settled" and r["residual_pct_of_L"] <= 0.1, (beam, m)
            assert all(v for k, v in r["met"].items() if k != "real_time"), (beam, m)
            if doc.get("backend") == "compiled":         # as C: every step of every run within its sample
                assert r["met"]["real_time"] and r["steps_late"] == 0, (beam, m)


def test_docs_prose_on_the_learning_nmpc_is_the_benchmark():
    """docs/limit.md's sentence on the learning NMPC's step on the virtual machine quotes the JSON, and
    every learning run there is real-time (12 of 12)."""
    import json

    from conftest import bench_module
    bench, root = bench_module("bench_nmpc_payload")
    vm = json.loads((root / "benchmarks" / "results" / "bench_nmpc_payload.json").read_text())
    n = bench.prose_numbers(vm)
    text = " ".join((root / "docs" / "limit.md").read_text().split())
    assert (f"runs' median steps are {n['PAYLOAD_VM_MED']} ms and the longest {n['PAYLOAD_VM_MAX']} ms: every "
            "run meets the real-time target there too") in text
    assert all(r["met"]["real_time"] and r["steps_late"] == 0
               for b in vm["beams"].values() for r in b["learning"]["runs"].values())

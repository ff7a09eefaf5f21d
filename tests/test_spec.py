"""Study specs: TOML loading, case generation (grid, Latin hypercube), validation."""

import numpy as np
import pytest
import tomllib
from scipy.stats import norm

from controllers import LQRSettings
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.study.settings_table import controller_settings, settings_to_toml
from hubbeam_ctrl.study.spec import StudySpec
from hubbeam_ctrl.study.spec_files import load_spec

SMALL = {"study": {"controllers": ["openloop", "lqr"], "t_f": 1.0, "t_end": 6.5},
         "params": {"n_axial": 2, "n_transverse": 2}}


def test_toml_and_dict_give_the_same_spec(tmp_path):
    text = """
[study]
controllers = ["openloop", "lqr"]
t_f = 1.0
t_end = 6.5
[params]
n_axial = 2
n_transverse = 2
[grid]
m_t = [0.0, 0.2]
l = [4.0, 8.0]
[random]
n = 4
seed = 3
E = {dist = "uniform", low = 6.5e10, high = 7.0e10}
"""
    path = tmp_path / "s.toml"
    path.write_text(text)
    a, b = load_spec(path), load_spec(tomllib.loads(text))
    assert a == b and a.hash() == b.hash()
    assert StudySpec.from_dict(a.to_dict()).hash() == a.hash()
    assert a.factors == ("m_t", "l", "E")
    cases = a.cases()
    assert len(cases) == 2 * 2 * 4
    # grid in order (last factor fastest), the same random samples at every grid point
    assert [(c["m_t"], c["l"]) for c in cases[::4]] == [(0.0, 4.0), (0.0, 8.0), (0.2, 4.0), (0.2, 8.0)]
    assert [c["E"] for c in cases[:4]] == [c["E"] for c in cases[4:8]]
    assert a.plant_params(cases[5]).m_t == 0.0 and a.plant_params(cases[5]).l == 8.0
    assert a.plant_params(cases[5]).E == cases[5]["E"]
    assert a.design_params(cases[5]) == a.params          # design stays at the base


def test_latin_hypercube_is_stratified_and_seeded():
    spec = StudySpec.from_dict({**SMALL, "random": {"n": 8, "seed": 1,
                                                    "m_t": {"dist": "uniform", "low": 0.0, "high": 0.4},
                                                    "E": {"dist": "normal", "mean": 7e10, "std": 2e9,
                                                          "low": 6.6e10}}})
    m = np.array([c["m_t"] for c in spec.cases()])
    # one sample in each of the 8 equal strata of [0, 0.4)
    assert sorted(np.floor(m / 0.05).astype(int)) == list(range(8))
    e = np.array([c["E"] for c in spec.cases()])
    assert e.min() >= 6.6e10
    # truncated normal: the strata are equal in probability between Phi(-2) and 1
    u = (norm.cdf((e - 7e10) / 2e9) - norm.cdf(-2.0)) / (1 - norm.cdf(-2.0))
    assert sorted(np.floor(u * 8).astype(int)) == list(range(8))
    again = StudySpec.from_dict({**SMALL, "random": {**spec.to_dict()["random"]}})
    assert [c["E"] for c in again.cases()] == list(e)
    other = StudySpec.from_dict({**SMALL, "random": {**spec.to_dict()["random"], "seed": 2}})
    assert [c["E"] for c in other.cases()] != list(e) and other.hash() != spec.hash()


def test_lognormal_median_and_plain_monte_carlo():
    spec = StudySpec.from_dict({**SMALL, "random": {"n": 400, "seed": 0, "method": "random",
                                                    "damping_ratio": {"dist": "lognormal", "median": 0.01,
                                                                      "sigma": 0.5}}})
    z = np.log(np.array([c["damping_ratio"] for c in spec.cases()]) / 0.01) / 0.5
    assert abs(np.median(z)) < 0.15 and abs(np.std(z) - 1) < 0.1


def test_controller_settings_replace_the_defaults():
    spec = StudySpec.from_dict({**SMALL, "study": {**SMALL["study"], "tau_max": 150.0},
                                "settings": {"lqr": {"weights": {"tip": 5e3}}}})
    sc = spec.scenario_for(spec.params)
    st = controller_settings("lqr", spec.settings["lqr"], sc)
    assert st == LQRSettings(weights=st.weights, tau_max=150.0, residual_control=True)   # for_scenario's
    # the other weights are the scenario's scaled defaults (controllers.scaling)
    assert (st.weights.tip, st.weights.angle) == (5e3, sc.defaults["weights"].angle)


def test_settings_toml_round_trip(tmp_path):
    table = {"lqr": {"tau_max": 120.0, "weights": {"angle": 1.5e4, "tip": 3.25e-3, "torque": 2.5e-5}}}
    text = settings_to_toml(table)
    assert tomllib.loads(text)["settings"] == table
    spec = load_spec({**SMALL, **tomllib.loads(text)})
    assert spec.settings == table


@pytest.mark.parametrize("data, words", [
    ({"grid": {"mt": [0.1]}}, ["unknown factor 'mt'", "m_t"]),
    ({"grid": {"m_t": []}}, ["grid.m_t", "non-empty"]),
    ({"grid": {"m_t": [0.1, 0.1]}}, ["grid.m_t", "repeats"]),
    ({"grid": {"m_t": [-0.1]}}, ["grid.m_t", "m_t must be in [0, "]),
    ({"grid": {"w_f": [1.0]}}, ["w_f", "spinup"]),
    ({"grid": {"n_axial": [1.5]}}, ["grid.n_axial", "integers"]),
    ({"random": {"n": 0, "m_t": {"dist": "uniform", "low": 0, "high": 1}}}, ["random.n", "1..100000"]),
    ({"random": {"n": 2}}, ["random", "names no factor"]),
    ({"random": {"n": 2, "m_t": {"dist": "uniform", "low": 1, "high": 0}}}, ["random.m_t", "low < high"]),
    ({"random": {"n": 2, "E": {"dist": "normal", "mean": 7e10, "std": 0}}}, ["random.E", "std > 0"]),
    ({"random": {"n": 2, "E": {"dist": "lognormal", "median": -1, "sigma": 1}}}, ["random.E", "median > 0"]),
    ({"random": {"n": 2, "E": {"dist": "normal", "mean": 7e10, "std": 1e9, "high": 1e9}}},
     ["random.E", "no probability"]),
    ({"random": {"n": 2, "E": {"dist": "beta", "a": 1}}}, ["random.E", "uniform, normal, lognormal"]),
    ({"random": {"n": 2, "method": "grid", "E": {"dist": "uniform", "low": 1, "high": 2}}}, ["random.method"]),
    ({"grid": {"m_t": [0.1]}, "random": {"n": 2, "m_t": {"dist": "uniform", "low": 0, "high": 1}}},
     ["random.m_t", "already a [grid] factor"]),
    ({"study": {"controllers": ["lqr", "h2opt"]}}, ["controllers", "h2opt"]),
    ({"study": {"design": "robust"}}, ["study.design"]),
    ({"study": {"t_end": 12.0}}, ["study", "t_end"]),
    ({"study": {"speed": 1}}, ["study", "speed"]),
    ({"study": {"controllers": ["lqr"]}, "settings": {"lqr": {"weights": {"tipp": 1.0}}}},
     ["settings.lqr.weights", "tipp"]),
    ({"study": {"controllers": ["lqr"]}, "settings": {"mpc": {"horizon": 10}}}, ["settings.mpc", "not among"]),
    ({"sweep": {}}, ["unknown table", "sweep"]),
    ({"study": {"shaping": "zz"}}, ["study.shaping must be one of zv, zvd, ei", "'zz'"]),
    ({"study": {"schedule": 0}}, ["study.schedule must be an integer >= 1"]),
    ({"study": {"schedule": True}}, ["study.schedule must be an integer >= 1"]),
    ({"study": {"backend": "gpu"}}, ["study.backend must be one of auto, compiled, vm"]),
    ({"study": {"tolerances": {"angel_error": 1e-3}}}, ["study.tolerances: unknown field(s) angel_error",
                                                        "angle_error"]),
    ({"study": {"tolerances": {"angle_error": -1.0}}}, ["study.tolerances", "angle_error must be > 0"]),
    ({"study": {"tolerances": 3}}, ["study.tolerances must be a table"]),
    ({"study": {"slew_angle": 0.0}}, ["study", "slew_angle must be a finite number != 0 [rad]"]),
])
def test_bad_specs_are_one_line_errors(data, words):
    with pytest.raises(ParameterError) as info:
        load_spec(data)
    msg = str(info.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_missing_and_broken_files(tmp_path):
    with pytest.raises(ParameterError, match="does not exist"):
        load_spec(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[grid\nm_t = 1")
    with pytest.raises(ParameterError, match="not valid TOML"):
        load_spec(bad)


def test_task_keys_round_trip_and_change_the_hash():
    """slew_angle, shaping, schedule, tolerances and backend survive to_dict/from_dict, and each
    changes the spec's hash (an output folder of one is not resumed with another)."""
    base = StudySpec.from_dict({"study": {"controllers": ["lqr"]}})
    keys = {"slew_angle": 1.5, "shaping": "zvd", "schedule": 3, "tolerances": {"angle_error": 5e-4},
            "backend": "vm"}
    hashes = {base.hash()}
    for key, value in keys.items():
        spec = StudySpec.from_dict({"study": {"controllers": ["lqr"], key: value}})
        assert getattr(spec, key) == value
        assert StudySpec.from_dict(spec.to_dict()) == spec and spec.to_dict()["study"][key] == value
        hashes.add(spec.hash())
    assert len(hashes) == 1 + len(keys)
    tol = StudySpec.from_dict({"study": {"tolerances": {"angle_error": 5e-4}}}).scenario_for(Params()).tolerances
    assert tol.angle_error == 5e-4 and tol.rate_time == base.scenario_for(Params()).tolerances.rate_time

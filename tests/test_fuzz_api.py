"""Fuzzing the Python API with Hypothesis (issue 14): every input gives a valid result or one
clean error, never another exception, a hang or a silent NaN.

Derandomized (the same examples on every run) and kept small; the simulation properties run
tiny models under a short wall-time limit. Test names carry the issue's class (``c1``: user
functions, ``c2``: budgets, ``c4``: NaN models, ``c5``: huge finite values, ``c6``: outputs,
``c7``: parameter files, ``c8``: nonsense results, ``c10``: loaders, ``sm``: the "Smaller"
list).
"""

import json
import math
import os
import tempfile
from dataclasses import fields
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from hubbeam_ctrl import (
    ConstantSpin,
    ParameterError,
    Params,
    SimulationSettings,
    SpinUp,
    TorquePulse,
    UserManeuver,
    discretize,
    linearize,
    load_model,
    load_params,
    load_result,
    save_model,
    simulate,
)
from hubbeam_ctrl.cli.args import OPTION_NAMES, rename_options
from hubbeam_ctrl.core.budget import check_budget
from hubbeam_ctrl.core.errors import HubbeamError, UserFunctionError
from hubbeam_ctrl.core.fileio import check_writable
from hubbeam_ctrl.core.jsonio import strict_json
from hubbeam_ctrl.core.settings import _in_range
from hubbeam_ctrl.plant.params import RELATIONS
from hubbeam_ctrl.plant.sensors import SensorSettings
from hubbeam_ctrl.sim.closedloop import ClosedLoopSettings, simulate_closed_loop
from hubbeam_ctrl.sim.stepper import StepperSettings

FUZZ = settings(max_examples=60, derandomize=True, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
FUZZ_SLOW = settings(FUZZ, max_examples=25)

# -- strategies ----------------------------------------------------------------------------
finite = st.floats(allow_nan=False, allow_infinity=False)
plausible = st.floats(min_value=-1e4, max_value=1e4, allow_nan=False)
log_spread = st.builds(lambda e, s: s * 10.0 ** e, st.floats(-330, 308), st.sampled_from([1.0, -1.0]))
junk = st.one_of(st.none(), st.booleans(), st.text(max_size=12), st.lists(finite, max_size=3),
                 st.dictionaries(st.text(max_size=3), finite, max_size=2), st.just(object()),
                 st.just(b"8"), st.just(1j))
numbers = st.one_of(finite, log_spread, st.floats(), st.integers(-10**6, 10**6),
                    st.integers(min_value=10**300, max_value=10**500),
                    st.builds(np.float32, st.floats(width=32)), st.builds(np.int64, st.integers(-2**62, 2**62)),
                    st.builds(np.array, finite))
anything = st.one_of(numbers, junk)


def mostly(good, bad, tenths: int = 8):
    """``good`` in ``tenths`` of the examples, ``bad`` in the rest (one_of would draw evenly)."""
    return st.integers(0, 9).flatmap(lambda i: good if i < tenths else bad)


def one_line(exc) -> bool:
    text = str(exc)
    return "\n" not in text and 0 < len(text) < 600


def params_kwargs():
    names = [f.name for f in fields(Params)]
    return st.dictionaries(st.sampled_from(names), anything, max_size=4)


# -- class 5 and "Smaller": Params --------------------------------------------------------
@FUZZ
@given(kwargs=params_kwargs())
def test_c5_params_valid_and_in_range_or_one_line_error(kwargs):
    try:
        p = Params(**kwargs)
    except ParameterError as exc:
        assert one_line(exc) and str(exc).split(" ")[0].rstrip(":") in {f.name for f in fields(Params)}
        return
    for f in fields(p):
        value = getattr(p, f.name)
        if value is None:
            continue
        if f.metadata["kind"] is tuple:          # damping_ratios: floats in [0, 1)
            assert type(value) is tuple and all(type(z) is float and 0 <= z < 1 for z in value)
            continue
        assert not isinstance(value, bool) and type(value) in (int, float)
        assert _in_range(value, f.metadata, p), (f.name, value)
    for rel in RELATIONS:
        rel.check(p)
    for derived in (p.total_inertia, p.max_spin, p.beam_inertia, p.slenderness, p.EI, p.EA):
        assert math.isfinite(derived) and derived > 0


@FUZZ
@given(value=st.floats(0.5, 20.0), n=st.integers(1, 20))
def test_sm_params_take_numpy_scalars_and_integer_valued_floats(value, n):
    ref = Params(L=float(np.float32(value)), n_transverse=n)
    assert Params(L=np.float32(value), n_transverse=np.int64(n)) == ref
    assert Params(L=float(np.float32(value)), n_transverse=float(n)) == ref
    assert type(Params(n_axial=np.int64(n)).n_axial) is int


@pytest.mark.parametrize("kwargs", [{"L": 10**400}, {"L": True}, {"n_axial": True}, {"m_t": -10**400},
                                    {"l": float("nan")}, {"damping_ratio": np.bool_(True)}],
                         ids=lambda k: repr(k)[:30])
def test_sm_params_refuse_bool_and_huge_ints_cleanly(kwargs):
    with pytest.raises(ParameterError) as err:
        Params(**kwargs)
    assert one_line(err.value) and len(str(err.value)) < 200


# -- class 7 and 5: parameter files ---------------------------------------------------------
toml_values = st.one_of(st.sampled_from(["1e300", "1e-300", "-1", "0", "nan", "inf", "-inf", "true", '"x"',
                                         "[1, 2]", "{a = 1}", "1979-05-27", "0x10", "8", "8.0", "5", "0.5"]),
                        finite.map(repr), st.integers(-10**30, 10**30).map(str))
toml_keys = st.one_of(st.sampled_from([f.name for f in fields(Params)]), st.from_regex(r"[a-z_]{1,8}", fullmatch=True))


@FUZZ
@given(lines=st.lists(st.tuples(toml_keys, toml_values), max_size=6, unique_by=lambda kv: kv[0]),
       table=st.booleans())
def test_c7_load_params_from_fuzzed_toml(lines, table):
    text = ("[params]\n" if table else "") + "".join(f"{k} = {v}\n" for k, v in lines)
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "p.toml"
        path.write_text(text)
        try:
            p = load_params(path)
        except ParameterError as exc:
            assert one_line(exc) and str(exc).startswith(f"params file {path}")
            return
    assert isinstance(p, Params) and math.isfinite(p.max_spin)


@FUZZ
@given(data=st.one_of(st.binary(max_size=300), st.text(max_size=300).map(str.encode)))
def test_c7_load_params_from_arbitrary_bytes(data):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "p.toml"
        path.write_bytes(data)
        try:
            assert isinstance(load_params(path), Params)
        except ParameterError as exc:
            assert one_line(exc)


# -- class 5: settings --------------------------------------------------------------------------
SETTINGS = [SimulationSettings, StepperSettings, ClosedLoopSettings, SensorSettings, SpinUp,
            TorquePulse, ConstantSpin]


@FUZZ
@given(data=st.data(), cls=st.sampled_from(SETTINGS))
def test_c5_settings_valid_or_one_line_error(data, cls):
    names = [f.name for f in fields(cls) if f.metadata["kind"] in (int, float)]
    kwargs = data.draw(st.dictionaries(st.sampled_from(names), anything, max_size=3))
    try:
        s = cls(**kwargs)
    except ParameterError as exc:
        assert one_line(exc)
        return
    for f in fields(s):
        value = getattr(s, f.name)
        if f.metadata["kind"] in (int, float) and not (value is None and f.metadata["optional"]):
            assert _in_range(value, f.metadata, s)


@pytest.mark.parametrize("seed", [-1, 1.5, 2**70, "0", None, True])
def test_sm_invalid_sensor_seed_is_a_parameter_error(seed):
    with pytest.raises(ParameterError, match="^seed must be"):
        SensorSettings(seed=seed)


# -- class 1: user functions ------------------------------------------------------------------
def _good_constant(value) -> bool:
    if isinstance(value, (bool, np.bool_, list, tuple, dict, str, bytes, complex)):
        return False
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        return False
    return arr.size == 1 and bool(np.isfinite(arr).all())


@FUZZ
@given(value=anything, t=st.floats(0.0, 100.0))
def test_c1_constant_functions_numeric_and_symbolic(value, t):
    m = UserManeuver(lambda _t: value, name="const")
    if _good_constant(value):
        assert float(m(t)) == float(np.asarray(value, dtype=float))
        sym = m(ca.MX.sym("t"))
        assert isinstance(sym, ca.MX) and float(ca.evalf(sym)) == float(np.asarray(value, dtype=float))
    else:
        for arg in (t, ca.MX.sym("t")):
            with pytest.raises(UserFunctionError) as err:
                m(arg)
            assert one_line(err.value) and "torque function const" in str(err.value)


@FUZZ
@given(bad_after=st.floats(0.05, 0.5), kind=st.sampled_from(["raise", "nan", "inf"]))
def test_c1_failing_later_is_found_at_its_time(bad_after, kind):
    def f(t):
        if t < bad_after:
            return 1.0
        if kind == "raise":
            raise ValueError("out of table")
        return float(kind)
    values, err = UserManeuver(f, name="f").evaluate(np.arange(0.0, 1.0, 0.01))
    assert isinstance(err, UserFunctionError) and "torque function f" in str(err)
    assert np.all(values == 1.0) and err.t == pytest.approx(0.01 * values.shape[1])
    assert err.t >= bad_after - 1e-12 and err.t - 0.01 < bad_after


# -- classes 1, 2, 5, 8: simulate inputs --------------------------------------------------------
TINY = Params(n_axial=1, n_transverse=1)
maneuvers = st.one_of(st.none(), st.builds(TorquePulse, st.floats(1.0, 500.0), st.floats(0.01, 2.0)),
                      st.builds(SpinUp, st.floats(-5, 5), st.floats(0.01, 2.0)),
                      st.builds(ConstantSpin, st.floats(-5, 5)),
                      anything.map(lambda v: UserManeuver(lambda t: v, name="u")),
                      plausible.map(lambda v: (lambda t: v)), junk)


@pytest.mark.slow
@FUZZ_SLOW
@given(model=mostly(st.sampled_from(["sfoam", "foam", "tlam"]), st.sampled_from(["bogus", 3, None])),
       maneuver=maneuvers, t_end=mostly(st.floats(0.0, 0.3), st.one_of(numbers, junk)),
       hub=mostly(st.none(), st.sampled_from(["free", "prescribed", "x", 1])),
       dt=mostly(st.sampled_from([0.01, 0.005, 0.02]), st.one_of(st.floats(1e-7, 20.0), junk)))
def test_c2_c5_c8_simulate_inputs(model, maneuver, t_end, hub, dt):
    try:
        res = simulate(model, maneuver, t_end, params=TINY, hub=hub, dt=dt, max_wall_s=0.05)
    except (ParameterError, UserFunctionError) as exc:
        assert one_line(exc)
        event("refused: " + str(exc).split(" ")[0])
        return
    event("ran, diverged" if res.diverged else "ran, completed")
    assert len(res.t) >= 2 and res.t[-1] <= t_end + 0.5 * dt + 1e-9     # the grid rounds t_end to k dt
    for name in ("q", "v", "a", "tau", "v_tip", "energy"):
        assert np.all(np.isfinite(getattr(res, name))), name
    assert isinstance(res.message, str) and res.message.startswith("completed") != res.diverged


@pytest.mark.parametrize("x0", [[np.nan] * 6, [0.0] * 5, "zero", [np.inf] + [0.0] * 5])
def test_sm_nan_initial_state_is_refused_not_blamed_on_the_controller(x0):
    class Hold:
        def __call__(self, t, y):
            return 0.0

        def reset(self):
            pass
    with pytest.raises(ParameterError, match=r"^x0 must hold 6 finite numbers"):
        simulate_closed_loop("sfoam", Hold(), 0.1, params=Params(n_axial=1, n_transverse=2), x0=x0)


# -- classes 4, 5 and "Smaller": linear models ----------------------------------------------
LIN = Params(n_axial=1, n_transverse=2)


@FUZZ
@given(model=mostly(st.sampled_from(["sfoam", "foam", "tlam", "cfoam", "SFOAM"]), st.sampled_from(["beam", 7, None])),
       spin=mostly(st.floats(-90.0, 90.0), st.one_of(numbers, junk, st.just("3"), st.just(True))),
       outputs=mostly(st.lists(st.sampled_from(["theta", "theta_dot", "tip_deflection", "tip_rate", "root_moment"]),
                               min_size=1, max_size=3, unique=True).map(",".join),
                      st.one_of(st.text(max_size=20), st.lists(st.text(max_size=8), max_size=3))))
def test_c4_c5_linearize_valid_finite_or_one_line_error(model, spin, outputs):
    try:
        lm = linearize(model, spin, LIN, outputs=outputs)
    except ParameterError as exc:
        assert one_line(exc)
        event("refused")
        return
    event("linearised")
    assert not isinstance(spin, (str, bool)) and abs(spin) <= LIN.max_spin
    assert all(np.all(np.isfinite(M)) for M in (lm.A, lm.B, lm.C, lm.D))


@pytest.fixture(scope="module")
def tlam_near_max_spin():
    return linearize("tlam", 70.0, LIN)


@FUZZ
@given(dt=st.one_of(finite, numbers, junk))
def test_c4_discretize_never_returns_nan(tlam_near_max_spin, dt):
    try:
        d = discretize(tlam_near_max_spin, dt)
    except ParameterError as exc:
        assert one_line(exc)
        return
    assert all(np.all(np.isfinite(M)) for M in (d.A, d.B, d.C, d.D)) and d.unstable


# -- class 10: loaders ---------------------------------------------------------------------------
@FUZZ
@given(data=st.binary(max_size=400), suffix=st.sampled_from([".npz", ".mat", ".json"]))
def test_c10_load_model_of_arbitrary_bytes(data, suffix):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"m{suffix}"
        path.write_bytes(data)
        with pytest.raises(ParameterError) as err:
            load_model(path)
        assert one_line(err.value)


@FUZZ
@given(data=st.one_of(st.binary(max_size=400), st.just(b"PK\x03\x04" + b"\x00" * 40)))
def test_c10_load_result_of_arbitrary_bytes(data):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "r.npz"
        path.write_bytes(data)
        with pytest.raises(ParameterError) as err:
            load_result(path)
        assert one_line(err.value)


@pytest.fixture(scope="module")
def model_json(tmp_path_factory):
    path = tmp_path_factory.mktemp("lm") / "m.json"
    save_model(linearize("sfoam", 1.0, LIN), path)
    return json.loads(path.read_text())


@FUZZ
@given(key=st.sampled_from(["A", "B", "C", "D", "state_names", "output_names", "input_names", "model",
                            "spin_rad_s", "dt", "name", "reduction", "params", "format"]),
       value=st.one_of(anything, st.lists(st.lists(st.one_of(finite, st.floats()), max_size=3), max_size=3)))
def test_c10_load_model_with_a_fuzzed_entry(model_json, key, value):
    doc = dict(model_json)
    doc[key] = value.tolist() if isinstance(value, np.ndarray) else value
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "m.json"
        try:
            path.write_text(json.dumps(doc, default=str))
        except (TypeError, ValueError):
            return
        try:
            lm = load_model(path)
        except ParameterError as exc:
            assert one_line(exc)
            return
    assert all(np.all(np.isfinite(M)) for M in (lm.A, lm.B, lm.C, lm.D))
    assert lm.model in ("sfoam", "foam", "tlam", "cfoam") and abs(lm.spin) <= lm.params.max_spin


# -- class 8: strict JSON --------------------------------------------------------------------------
json_leaves = st.one_of(st.floats(), st.integers(-10**6, 10**6), st.text(max_size=5), st.none(), st.booleans())
json_trees = st.recursive(json_leaves, lambda kids: st.one_of(st.lists(kids, max_size=3),
                                                               st.dictionaries(st.text(max_size=4), kids, max_size=3)),
                          max_leaves=12)


@FUZZ
@given(tree=json_trees)
def test_c8_strict_json_is_valid_json_and_flags_nulls(tree):
    text = strict_json(tree)
    back = json.loads(text, parse_constant=lambda c: pytest.fail(f"bare {c} in JSON"))
    if isinstance(tree, dict):
        bad = [k for k, v in tree.items() if isinstance(v, float) and not math.isfinite(v)]
        assert back.get("non_finite", []) == bad or (not bad and "non_finite" not in back or
                                                      "non_finite" in tree)


# -- classes 2 and 6: budgets, option names, outputs ------------------------------------------------
@FUZZ
@given(memory=st.floats(0, 1e15), seconds=st.floats(0, 1e9), mb=st.floats(1, 1e9), wall=st.floats(1e-3, 1e7))
def test_c2_budget_refuses_exactly_above_its_limits(memory, seconds, mb, wall):
    over = memory > mb * 1e6 or seconds > wall
    try:
        check_budget("t_end = 1 s", memory_bytes=memory, seconds=seconds, max_memory_mb=mb, max_wall_s=wall)
    except ParameterError as exc:
        assert over and one_line(exc) and ("--allow-large" in str(exc) or "--max-wall" in str(exc))
        return
    assert not over


@FUZZ
@given(name=st.sampled_from(sorted(OPTION_NAMES)), rest=st.text(max_size=30).filter(lambda s: "\n" not in s))
def test_c2_errors_name_the_option_as_typed(name, rest):
    message = rename_options(f"{name} must be {rest}", set(OPTION_NAMES.values()))
    assert message.startswith(OPTION_NAMES[name])
    assert rename_options(f"{name} must be {rest}", set()) == f"{name} must be {rest}"


@FUZZ
@given(name=st.one_of(st.text(max_size=300), st.text(alphabet="ab/.\x00 ", max_size=40)))
def test_c6_check_writable_path_or_one_line_error_and_nothing_left(name):
    with tempfile.TemporaryDirectory() as d:
        try:
            check_writable(os.path.join(d, name) if name else name, "--out")
        except ParameterError as exc:
            assert one_line(exc)
        assert os.listdir(d) == []


def test_every_fuzzed_error_is_a_toolbox_error():
    """The exceptions the properties accept are the toolbox's own (one except clause suffices)."""
    assert issubclass(ParameterError, HubbeamError) and issubclass(UserFunctionError, HubbeamError)

"""The compiled backend: fallbacks without a compiler, the build cache, agreement with the VM.

The first group needs no compiler. The second (marked by ``needs_cc``) is skipped on a
machine where the toolbox finds no C compiler ($CC, cc, gcc, clang); it compiles small models
(2 + 2 modes) into a private cache.
"""

import json
import os
import shutil
import subprocess
import sys
import textwrap

import casadi as ca
import numpy as np
import pytest

from hubbeam_ctrl import Params, TorquePulse, build_model, simulate
from hubbeam_ctrl.cli import main
from hubbeam_ctrl.core import compiled, recipes
from hubbeam_ctrl.core.compiled import (
    cache_info,
    check_backend,
    clear_cache,
    compile_function,
    resolve_backend,
)
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.models import MX_FROM_TRANSVERSE
from hubbeam_ctrl.sim.closedloop import simulate_closed_loop
from hubbeam_ctrl.sim.stepper import PlantStepper


def _has_compiler() -> bool:
    """Whether the toolbox finds a C compiler here ($CC, else cc/gcc/clang on the PATH)."""
    try:
        return bool(compiled.find_compiler())
    except compiled.CompileError:
        return False


needs_cc = pytest.mark.skipif(not _has_compiler(), reason="no C compiler ($CC, cc, gcc or clang) on this machine")
posix_only = pytest.mark.skipif(os.name != "posix", reason="fake compilers are shell scripts")

SMALL = Params(n_axial=2, n_transverse=2)


def _function(name="twice_sin", n=3):
    x = ca.SX.sym("x", n)
    return ca.Function(name, [x], [2 * ca.sin(x) * x[0]])


@pytest.fixture
def fresh(monkeypatch, tmp_path):
    """A private cache folder and a process with nothing loaded or printed yet."""
    monkeypatch.setenv("HUBBEAM_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(compiled, "_LOADED", {})
    monkeypatch.setattr(compiled, "_NOTICES", set())
    return tmp_path / "cache"


def _fake_compiler(tmp_path, body: str) -> str:
    path = tmp_path / "fakecc"
    path.write_text("#!/bin/sh\n" + 'if [ "$1" = "--version" ]; then echo "fakecc 1.0"; exit 0; fi\n' + body)
    path.chmod(0o755)
    return str(path)


# -- without a compiler ------------------------------------------------------------------------------
def test_backend_names_are_checked(monkeypatch):
    assert check_backend("vm") == "vm"
    with pytest.raises(ParameterError, match="backend must be one of auto, compiled, vm, got 'fast'"):
        check_backend("fast")
    monkeypatch.setenv("HUBBEAM_BACKEND", "gpu")
    with pytest.raises(ParameterError, match="HUBBEAM_BACKEND must be one of"):
        resolve_backend(None)
    monkeypatch.setenv("HUBBEAM_BACKEND", "compiled")
    assert resolve_backend(None) == "compiled"
    assert resolve_backend("vm") == "vm"


def test_bad_backend_is_one_line_error_everywhere(capsys):
    model = build_model("foam", SMALL)
    with pytest.raises(ParameterError, match="backend must be one of"):
        PlantStepper(model, backend="fast")
    with pytest.raises(ParameterError, match="backend must be one of"):
        simulate(model, TorquePulse(200.0, 10.0), 1.0, backend="C")
    assert main(["simulate", "--model", "foam", "--maneuver", "torque", "--t-end", "1",
                 "--backend", "fast"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--backend" in err[0] and "Traceback" not in err[0]


def test_vm_backend_returns_the_function_itself(fresh):
    f = _function()
    assert compile_function(f, "vm") is f
    assert not fresh.exists()                  # nothing built, no folder made


def test_missing_compiler_falls_back_with_one_line(fresh, monkeypatch, capsys):
    monkeypatch.setenv("CC", "/nonexistent/cc")
    f = _function()
    assert compile_function(f, "auto") is f
    assert compile_function(f, "compiled") is f
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["hubbeam: C compiler CC='/nonexistent/cc' not found; using the CasADi VM"]
    stepper = PlantStepper(build_model("foam", SMALL), backend="auto")
    assert stepper.backend == "vm"


@posix_only
def test_failing_compiler_falls_back_naming_the_reason(fresh, monkeypatch, capsys, tmp_path):
    monkeypatch.setenv("CC", _fake_compiler(tmp_path, 'echo "fatal: no space left on device" >&2\nexit 1\n'))
    f = _function()
    assert compile_function(f, "compiled") is f
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert f"C compiler fakecc failed on twice_sin ({compiled.OPT_HOT}): fatal: no space left on device" in err[0]
    assert err[0].endswith("using the CasADi VM")
    assert not list(fresh.glob("*.so"))        # nothing half-built left in the cache


@posix_only
def test_compiler_that_hangs_times_out(fresh, monkeypatch, capsys, tmp_path):
    monkeypatch.setenv("CC", _fake_compiler(tmp_path, "sleep 30\n"))
    monkeypatch.setenv("HUBBEAM_CC_TIMEOUT", "0.5")
    f = _function()
    assert compile_function(f, "auto") is f
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"timed out after 0.5 s on twice_sin ({compiled.OPT_HOT})" in err[0]
    monkeypatch.setenv("HUBBEAM_CC_TIMEOUT", "-3")
    with pytest.raises(ParameterError, match="HUBBEAM_CC_TIMEOUT must be a number of seconds > 0"):
        compile_function(_function("other"), "auto")


def test_unwritable_cache_folder_uses_a_temporary_one(fresh, monkeypatch, capsys, tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("HUBBEAM_CACHE_DIR", str(blocker / "cache"))
    compiled._temporary_cache.cache_clear()
    folder = compiled._writable_cache_dir()
    assert folder.is_dir() and folder != blocker / "cache"
    assert os.access(folder, os.W_OK)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is not writable" in err[0] and str(folder) in err[0]


def test_cache_cli_on_an_empty_cache(fresh, capsys):
    assert main(["cache", "info", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["folder"] == str(fresh) and info["libraries"] == 0 and info["bytes"] == 0
    assert main(["cache", "clear"]) == 0
    assert "removed 0 files" in capsys.readouterr().out


# -- with a compiler ---------------------------------------------------------------------------------
@needs_cc
def test_large_sources_get_the_cheaper_flag(fresh, monkeypatch):
    """A hot function whose C is longer than OPT_HOT_MAX_CHARS is compiled with OPT_HOT_LARGE;
    another flag asked for explicitly is kept."""
    assert compiled.OPT_HOT == "-O3" and compiled.OPT_HOT_LARGE == "-O1"
    monkeypatch.setattr(compiled, "OPT_HOT_MAX_CHARS", 10)
    f = _function("large")
    compile_function(f, "compiled", opt=compiled.OPT_HOT, jacobian="-O2")
    meta = json.loads(next(fresh.glob("large-*.so")).with_suffix(".json").read_text())
    assert meta["flags"] == ["-O1", "-O2"]


@needs_cc
def test_compiled_function_is_cached_and_reloaded(fresh, capsys):
    f = _function()
    g = compile_function(f, "compiled", jacobian="-O0")
    assert g is not f and g.name() == f.name()
    x = [0.3, -1.2, 2.5]
    np.testing.assert_array_equal(np.array(g(x)), np.array(f(x)))
    X = ca.MX.sym("x", 3)                     # derivatives come from the compiled jac_twice_sin
    jg = ca.Function("jg", [X], [ca.jacobian(g(X), X)])(x)
    np.testing.assert_allclose(np.array(jg), np.array(ca.Function("jf", [X], [ca.jacobian(f(X), X)])(x)),
                               rtol=1e-15, atol=1e-15)
    libs = list(fresh.glob("twice_sin-*.so"))
    assert len(libs) == 1
    meta = json.loads(libs[0].with_suffix(".json").read_text())
    assert meta["functions"] == ["twice_sin", "jac_twice_sin"] and meta["flags"] == [compiled.OPT_HOT, "-O0"]
    stamp = libs[0].stat().st_mtime_ns
    # another process loads the library instead of compiling it
    code = textwrap.dedent("""
        import casadi as ca
        from hubbeam_ctrl.core import compiled, recipes
        x = ca.SX.sym("x", 3)
        f = ca.Function("twice_sin", [x], [2 * ca.sin(x) * x[0]])
        compiled._build = None                 # any build would fail
        g = compiled.compile_function(f, "compiled", jacobian="-O0")
        print(float(g([0.3, -1.2, 2.5])[1]))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=dict(os.environ),
                         check=True)
    assert float(out.stdout) == pytest.approx(float(f(x)[1]), rel=1e-15)
    assert libs[0].stat().st_mtime_ns == stamp
    assert cache_info()["libraries"] == 1


@needs_cc
@pytest.mark.parametrize("damage", ["corrupt", "foreign"])
def test_corrupt_or_foreign_library_is_rebuilt(fresh, damage):
    f = _function()
    compile_function(f, "compiled")
    lib = next(fresh.glob("twice_sin-*.so"))
    good = lib.read_bytes()
    lib.unlink()                               # a new file: the loaded one stays mapped intact
    if damage == "corrupt":
        lib.write_bytes(good[: len(good) // 2])
    else:                                      # a valid library of another function, same name
        other = compile_function(_function("twice_sin", n=4), "compiled")
        assert other.size_in(0) == (4, 1)
        foreign = [p for p in fresh.glob("twice_sin-*.so") if p != lib][0]
        shutil.copyfile(foreign, lib)
    compiled._LOADED.clear()
    g = compile_function(f, "compiled")
    assert g is not f
    assert lib.read_bytes() == good            # rebuilt (same compiler, same bytes)
    np.testing.assert_array_equal(np.array(g([1.0, 2.0, 3.0])), np.array(f([1.0, 2.0, 3.0])))


@needs_cc
def test_two_processes_building_the_same_entry(fresh):
    code = textwrap.dedent("""
        import casadi as ca
        from hubbeam_ctrl.core import compiled, recipes
        builds = []
        real = compiled._build
        compiled._build = lambda *a: (builds.append(1), real(*a))
        x = ca.SX.sym("x", 40)
        y = x
        for k in range(60):                    # a few thousand operations: ~1 s of gcc
            y = ca.sin(y) * ca.cos(ca.vertcat(y[1:], y[0])) + 0.1 * k
        f = ca.Function("busy", [x], [y])
        g = compiled.compile_function(f, "compiled")
        assert g is not f
        print(len(builds), float(g(range(40))[7]))
    """)
    env = dict(os.environ)
    procs = [subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True, env=env) for _ in range(2)]
    outs = [p.communicate(timeout=300) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1] for o in outs]
    results = [o[0].split() for o in outs]
    assert sum(int(r[0]) for r in results) == 1          # compiled once, loaded by the other
    assert results[0][1] == results[1][1]
    assert len(list(fresh.glob("busy-*.so"))) == 1
    assert not list(fresh.glob(".build-*"))
    assert clear_cache() == 3                            # library, side file, lock
    assert cache_info()["libraries"] == 0


#: CFOAM on MX symbols (MX_FROM_TRANSVERSE transverse modes): compact generated code
LARGE_CFOAM = Params(n_axial=2, n_transverse=MX_FROM_TRANSVERSE)


@needs_cc
@pytest.mark.parametrize("name, params", [("foam", SMALL), ("cfoam", SMALL), ("cfoam", LARGE_CFOAM)])
def test_stepper_backends_agree(fresh, name, params):
    model = build_model(name, params)
    taus = 200.0 * np.sin(np.linspace(0.0, np.pi, 150)) ** 2
    runs = {}
    for backend in ("vm", "compiled"):
        st = PlantStepper(model, backend=backend)
        assert st.backend == backend
        s = st.initial_state()
        traj = []
        for tau in taus:
            s = st.step(s, tau)
            traj.append(s)
        runs[backend] = np.array(traj)
    scale = np.max(np.abs(runs["vm"]), axis=0) + 1e-300
    assert np.max(np.abs(runs["compiled"] - runs["vm"]) / scale) <= 1e-9
    assert np.max(np.abs(runs["vm"][:, model.n_q])) > 0.01     # the hub moved


@needs_cc
@pytest.mark.parametrize("name, params", [("foam", SMALL), ("cfoam", SMALL), ("cfoam", LARGE_CFOAM)])
def test_idas_backends_agree(fresh, name, params):
    model = build_model(name, params)
    pulse = TorquePulse(200.0, 2.0)
    res = {b: simulate(model, pulse, 3.0, backend=b) for b in ("vm", "compiled")}
    assert res["compiled"].settings["backend"] == "compiled"
    peak = np.max(np.abs(res["vm"].v_tip))
    assert peak > 1e-3
    assert np.max(np.abs(res["compiled"].v_tip - res["vm"].v_tip)) <= 1e-9 * peak
    np.testing.assert_allclose(res["compiled"].q, res["vm"].q, rtol=1e-9, atol=1e-9 * np.max(np.abs(res["vm"].q)))


@needs_cc
def test_closed_loop_runs_compiled(fresh):
    class Hold:
        measurement = "state"

        def reset(self):
            pass

        def __call__(self, t, y):
            return 50.0 if t < 0.5 else 0.0

    out = {b: simulate_closed_loop(build_model("foam", SMALL), Hold(), 1.0, backend=b) for b in ("vm", "compiled")}
    assert out["compiled"].settings["backend"] == "compiled"
    scale = np.max(np.abs(out["vm"].v_tip))
    assert np.max(np.abs(out["compiled"].v_tip - out["vm"].v_tip)) <= 1e-9 * scale


@needs_cc
def test_new_tip_mass_loads_the_same_libraries(fresh):
    runs = {}
    for m_t in (0.1, 0.4):
        model = build_model("cfoam", SMALL.replace(m_t=m_t))
        before = cache_info()["libraries"]
        st = PlantStepper(model, backend="compiled")
        if m_t == 0.4:
            assert cache_info()["libraries"] == before            # nothing compiled for the new mass
        s = st.initial_state()
        for _ in range(100):
            s = st.step(s, 150.0)
        vm = PlantStepper(model, backend="vm")
        r = vm.initial_state()
        for _ in range(100):
            r = vm.step(r, 150.0)
        np.testing.assert_allclose(s, r, rtol=1e-9, atol=1e-12)
        runs[m_t] = s
    assert abs(runs[0.1][0] - runs[0.4][0]) > 1e-4 * abs(runs[0.1][0])  # the mass does change the run


@needs_cc
def test_the_hot_flag_can_be_set_for_the_run(fresh, monkeypatch):
    """``$HUBBEAM_CC_OPT`` sets the flag of the functions called every step (a large step builds
    several times faster at -O0); the cache keeps the two builds apart, and both give the same numbers."""
    f = _function()
    fast = compile_function(f, "compiled")
    monkeypatch.setenv("HUBBEAM_CC_OPT", "-O0")
    quick = compile_function(_function("twice_sin_o0"), "compiled")
    flags = sorted(json.loads(p.read_text())["flags"][0] for p in fresh.glob("*.json"))
    assert flags == ["-O0", compiled.OPT_HOT]
    x = [0.3, -0.2, 0.7]
    np.testing.assert_allclose(np.asarray(quick(x)), np.asarray(fast(x)), rtol=1e-15)
    monkeypatch.setenv("HUBBEAM_CC_OPT", "-O9")
    with pytest.raises(ParameterError, match=r"HUBBEAM_CC_OPT must be one of -O0, -O1, -O2, -O3, -Os, got '-O9'"):
        compile_function(_function("other"), "compiled")


@needs_cc
def test_recipe_loads_the_library_without_building(fresh):
    """compile_recipe builds and compiles once; a later process (here: nothing loaded) finds the
    library by its recipe without calling build, and it gives the same numbers; another recipe
    or another opt level builds again."""
    built = []

    def build(name="twice_sin"):
        built.append(name)
        return _function(name)

    g = recipes.compile_recipe(("twice", 3), build, "compiled")
    assert built == ["twice_sin"] and g.is_a("External")
    x = np.array([0.3, -1.2, 2.5])
    expected = np.array(_function()(x)).ravel()
    assert np.array_equal(np.array(g(x)).ravel(), expected)
    compiled._LOADED.clear()                              # as in a new process
    again = recipes.compile_recipe(("twice", 3), build, "compiled")
    assert built == ["twice_sin"]                         # not built again
    assert np.array_equal(np.array(again(x)).ravel(), expected)
    recipes.compile_recipe(("twice", 4), lambda: build("twice_sin"), "compiled")
    recipes.compile_recipe(("twice", 3), build, "compiled", opt=compiled.OPT_COLD)
    assert len(built) == 3
    assert recipes.compile_recipe(("twice", 3), build, "vm").is_a("SXFunction") and len(built) == 4


@needs_cc
def test_recipe_with_a_damaged_library_builds_again(fresh):
    """A library that no longer matches its side file is not loaded by its recipe: built and compiled again."""
    built = []

    def build():
        built.append(1)
        return _function("twice_sin_damaged")

    recipes.compile_recipe(("damaged",), build, "compiled")
    for lib in fresh.glob("twice_sin_damaged-*.so"):
        lib.unlink()                                      # a new file: the loaded one stays mapped
        lib.write_bytes(b"not a library")
    compiled._LOADED.clear()
    g = recipes.compile_recipe(("damaged",), build, "compiled")
    assert len(built) == 2 and g.is_a("External")
    x = np.array([0.1, 0.2, 0.3])
    assert np.array_equal(np.array(g(x)).ravel(), np.array(_function()(x)).ravel())


@needs_cc
@pytest.mark.parametrize("name", ["foam", "cfoam"])
def test_stepper_initial_accelerations_are_the_models_bit_for_bit(name):
    """The stepper's initial accelerations (M and c compiled by their recipes) equal
    HubBeamModel.accelerations (CasADi's VM) bit for bit, at rest and in motion."""
    model = build_model(name, SMALL)
    st = PlantStepper(model, backend="compiled")
    rng = np.random.default_rng(3)
    for k in range(5):
        q = np.zeros(model.n_q) if k == 0 else 1e-2 * rng.standard_normal(model.n_q)
        v = np.zeros(model.n_q) if k == 0 else rng.standard_normal(model.n_q)
        assert st._accelerations(q, v, 7.5).tobytes() == model.accelerations(q, v, 7.5).tobytes()

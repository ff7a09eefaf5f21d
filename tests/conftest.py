"""Shared fixtures: non-GUI plotting, common parameter sets."""

import os

os.environ.setdefault("MPLBACKEND", "Agg")
# The normal suite runs on CasADi's VM (no compiler needed, nothing compiled per parameter
# set); tests/test_compiled.py runs the compiled backend where a compiler exists.
os.environ.setdefault("HUBBEAM_BACKEND", "vm")
# compiled functions of the tests that use them go to build/, not to the user's cache folder
os.environ.setdefault("HUBBEAM_CACHE_DIR", os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(
    __file__))), "build", "hubbeam-cache"))

from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from hubbeam_ctrl import Params  # noqa: E402

#: The project root (this checkout).
ROOT = Path(__file__).resolve().parents[1]
#: Environment of a ``python -m hubbeam_ctrl`` subprocess: this checkout first, no display.
ENV = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""), "MPLBACKEND": "Agg"}


def sweep_spec(controllers, t_end: float, masses) -> str:
    """The TOML text of a small sweep: 2+2 modes evaluated on 2, a 1 s slew of ``t_end`` [s],
    a grid of tip masses ``masses`` [kg]."""
    return (f"[study]\ncontrollers = {list(controllers)!r}\nt_f = 1.0\nt_end = {t_end!r}\nplant_modes = 2\n"
            f"[params]\nn_axial = 2\nn_transverse = 2\n[grid]\nm_t = {list(masses)!r}\n").replace("'", '"')


@pytest.fixture(scope="session")
def no_tip():
    """Table 1 without the tip mass (the paper's Sections 4.1-4.3)."""
    return Params(m_t=0.0)


@pytest.fixture(scope="session")
def table1():
    """Table 1 with 0.1 kg at the tip."""
    return Params()


#: Backend of the long closed-loop target tests on FOAM: compiled where a C compiler works,
#: else the VM (``auto`` falls back with one line). The two agree to 1e-9 relative
#: (tests/test_compiled.py), and compiling FOAM's plant step takes a few seconds, so these
#: tests run 3-4x faster with a compiler and still run without one. CFOAM stays on the VM
#: (its 10-mode functions take minutes to compile).
FAST_BACKEND = "auto"


@pytest.fixture
def fast_backend(monkeypatch):
    """Run the test (and the processes it starts) on :data:`FAST_BACKEND`."""
    monkeypatch.setenv("HUBBEAM_BACKEND", FAST_BACKEND)
    return FAST_BACKEND


@pytest.fixture(scope="module")
def fast_backend_module():
    """:func:`fast_backend` for module-scoped fixtures."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("HUBBEAM_BACKEND", FAST_BACKEND)
        yield FAST_BACKEND


def bench_module(name: str):
    """``(module, root)``: the benchmark ``benchmarks/<name>.py`` loaded as a module (its table
    functions keep the docs equal to its JSON) and the project root."""
    import importlib.util
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(root / "benchmarks"))
    spec = importlib.util.spec_from_file_location(name, root / "benchmarks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module, root



def assert_refused_in_one_line(argv, words: str, folder, capsys, max_len: int | None = None) -> None:
    """``hubbeam ARGV`` run in ``folder``: exit 2, one line on stderr naming ``words``, nothing on
    stdout and no file created or removed (the fault tests' refusal check)."""
    from hubbeam_ctrl.cli.main import main
    before = sorted(os.listdir(folder))
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err and out == "", err
    assert max_len is None or len(err) < max_len, err
    assert words in err, err
    assert sorted(os.listdir(folder)) == before


def until_first_stick(result, t_f: float, rig) -> np.ndarray:
    """Samples up to the first one after ``t_f`` [s] where the hub's rate is within the rig's stick
    velocity (every sample on a rig without Coulomb friction)."""
    t = np.asarray(result.t)
    if rig.friction.coulomb == 0.0:
        return np.ones(len(t), dtype=bool)
    thd = np.asarray(result.v)[:, 0] if np.ndim(result.v) == 2 else np.asarray(result.v)
    stuck = np.nonzero((t > t_f) & (np.abs(thd) < rig.friction.stick_velocity))[0]
    end = stuck[0] if stuck.size else len(t)
    return np.arange(len(t)) < end

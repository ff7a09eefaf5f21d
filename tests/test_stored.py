"""Arrays kept in the build cache (hubbeam_ctrl.core.stored): computed once, then read bit for bit."""

import numpy as np
import pytest

from hubbeam_ctrl.core import compiled
from hubbeam_ctrl.core.stored import stored_array
from hubbeam_ctrl.plant.modal import _converged_bending_hz, modal_analysis
from hubbeam_ctrl.plant.params import MAX_MODES, Params


@pytest.fixture
def cache(monkeypatch, tmp_path):
    monkeypatch.setenv("HUBBEAM_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def test_computed_once_then_read_bit_for_bit(cache):
    calls = []

    def compute():
        calls.append(1)
        return np.array([1.0 / 3.0, np.pi, -2.5e-300])

    first = stored_array(("thirds", 3, Params()), compute)
    again = stored_array(("thirds", 3, Params()), compute)
    assert len(calls) == 1 and again.tobytes() == first.tobytes() and not again.flags.writeable
    stored_array(("thirds", 4, Params()), compute)                     # another key: computed
    stored_array(("thirds", 3, Params(m_t=1.0)), compute)
    assert len(calls) == 3
    assert compiled.clear_cache() == 3 and not list((cache / "results").glob("*.npz"))


def test_a_damaged_file_is_computed_again(cache):
    stored_array(("damaged",), lambda: np.arange(3.0))
    for f in (cache / "results").glob("damaged-*.npz"):
        f.write_bytes(b"not an array")
    out = stored_array(("damaged",), lambda: np.arange(4.0))
    assert np.array_equal(out, np.arange(4.0))
    assert np.array_equal(stored_array(("damaged",), lambda: np.zeros(1)), np.arange(4.0))   # rewritten


def test_converged_frequencies_are_the_modal_analysis(cache):
    p = Params(m_t=2.0)
    _converged_bending_hz.cache_clear()
    first = _converged_bending_hz(p, 0.5)
    _converged_bending_hz.cache_clear()
    read = _converged_bending_hz(p, 0.5)                               # from the file
    direct = modal_analysis("sfoam", 0.5, "free", p.replace(n_transverse=MAX_MODES, n_axial=1)).bending_hz
    assert read.tobytes() == first.tobytes() == direct.tobytes()
    assert len(list((cache / "results").glob("converged_bending_hz-*.npz"))) == 1


def test_planned_slew_is_read_bit_for_bit(cache):
    """The comparison's planned slew (study.scenarios._planned) read from the cache: the planner's
    reference, every array, the description and the plan equal."""
    from controllers import planned_slew_reference
    from hubbeam_ctrl.study.scenarios import _planned
    p = Params(n_axial=2, n_transverse=3)
    direct = planned_slew_reference(p, 1.5, 4.0, 120.0, 0.02, 6.0)
    for _ in range(2):                                               # computed, then read
        r = _planned(p, 1.5, 4.0, 120.0, 0.02, 6.0)
        for k in ("theta", "theta_dot", "theta_ddot", "torque", "elastic"):
            assert getattr(r, k).tobytes() == getattr(direct, k).tobytes() and getattr(r, k).flags.writeable
        assert (r.dt, r.description, r.plan, r.planned_on_design) == (direct.dt, direct.description, direct.plan,
                                                                       True)
    assert len(list((cache / "results").glob("planned_slew-*.npz"))) == 1

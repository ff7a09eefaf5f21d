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
    assert compiled.clear_cache() == 3 and not list((cache / "results").glob("*.npy"))


def test_a_damaged_file_is_computed_again(cache):
    stored_array(("damaged",), lambda: np.arange(3.0))
    for f in (cache / "results").glob("damaged-*.npy"):
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
    assert len(list((cache / "results").glob("converged_bending_hz-*.npy"))) == 1

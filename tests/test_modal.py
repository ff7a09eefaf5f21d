"""Modal analysis against the paper's Table 2 and Fig. 9 critical speeds."""

import numpy as np
import pytest

from hubbeam_ctrl import Params, campbell, critical_speed, critical_speed_map, modal_analysis

TABLE2 = {
    ("foam", 0.0): [0.4635, 2.9047, 8.1332, 15.9377, 26.3462],
    ("tlam", 1.0): [0.4353, 2.9003, 8.1316, 15.9369, 26.3457],
    ("foam", 1.0): [0.4714, 2.9308, 8.1618, 15.9682, 26.3776],
}


@pytest.mark.parametrize("model,spin", list(TABLE2))
def test_table2_frequencies(model, spin, no_tip):
    """All 15 frequencies of Table 2 (prescribed hub, no tip mass) within 0.15 %."""
    f = modal_analysis(model, spin, "prescribed", no_tip).bending_hz
    np.testing.assert_allclose(f, TABLE2[(model, spin)], rtol=1.5e-3)


def test_cfoam_and_sfoam_match_foam_frequencies(no_tip):
    ref = modal_analysis("foam", 1.0, "prescribed", no_tip).bending_hz
    for name in ("cfoam", "sfoam"):
        np.testing.assert_allclose(modal_analysis(name, 1.0, "prescribed", no_tip).bending_hz, ref, rtol=1e-5)


def test_free_hub_has_one_rigid_mode_and_stiffer_first_mode(no_tip):
    free = modal_analysis("foam", 0.0, "free", no_tip)
    held = modal_analysis("foam", 0.0, "prescribed", no_tip)
    assert free.n_rigid == 2                     # one double zero eigenvalue: the rotation
    assert free.bending_hz[0] > held.bending_hz[0]   # free-hub (pinned) frequency is higher


@pytest.mark.parametrize("m_t,expected,tol", [(0.0, 2.91, 0.01), (0.1, 2.60, 0.01), (0.5, 1.91, 0.03)])
def test_tlam_critical_speed(m_t, expected, tol):
    assert critical_speed("tlam", Params(m_t=m_t)) == pytest.approx(expected, rel=tol)


def test_critical_speed_is_where_stiffness_is_lost(table1):
    w = critical_speed("tlam", table1)
    assert not modal_analysis("tlam", 0.99 * w, "prescribed", table1).unstable
    assert modal_analysis("tlam", 1.01 * w, "prescribed", table1).unstable


def test_foam_has_no_critical_speed(table1):
    assert critical_speed("foam", table1) is None
    assert critical_speed("foam", Params(m_t=0.5)) is None
    assert not modal_analysis("foam", 10.0, "prescribed", table1).unstable


def test_fig9_map_tip_mass_softens_tlam():
    """Tip mass at the hub changes nothing; further out and heavier lowers the critical speed."""
    speeds = critical_speed_map([0.0, 0.1, 0.5], [0.0, 4.0, 8.0])
    assert np.allclose(speeds[:, 0], speeds[0, 0], rtol=1e-12)
    assert np.all(np.diff(speeds[:, 2]) < 0)
    assert np.all(np.diff(speeds[2, :]) < 0)


def test_campbell_foam_stiffens_tlam_softens(no_tip):
    spins = [0.0, 1.0, 2.0]
    foam = campbell("foam", spins, params=no_tip)
    tlam = campbell("tlam", spins, params=no_tip)
    assert np.all(np.diff(foam[:, 0]) > 0) and np.all(np.diff(tlam[:, 0]) < 0)

"""Parameters: defaults, validation messages, TOML round trip."""

import math

import pytest

from hubbeam_ctrl import ParameterError, Params, load_params, save_params


def test_defaults_are_table_1():
    p = Params()
    assert (p.L, p.rho, p.A, p.E, p.I, p.J_h, p.r, p.m_t) == (
        8.0, 2.7667e3, 7.2968e-5, 6.8952e10, 8.2189e-9, 200.0, 0.5, 0.1)
    assert p.tip_position == 8.0 and p.n_axial == 5 and p.n_transverse == 5
    assert p.damping_ratio == 0.0
    # rigid inertia: J_h + rho A ((r+L)^3 - r^3)/3 + m_t (r+L)^2
    assert math.isclose(p.total_inertia, 200 + 2766.7 * 7.2968e-5 * (8.5 ** 3 - 0.5 ** 3) / 3 + 0.1 * 8.5 ** 2)


@pytest.mark.parametrize("field,lo", [("L", "0.01"), ("E", "100000"), ("rho", "1"), ("A", "1e-10"),
                                      ("I", "1e-20"), ("J_h", "1e-09")])
@pytest.mark.parametrize("value", [0.0, -1.0])
def test_non_positive_rejected(field, lo, value):
    with pytest.raises(ParameterError, match=rf"^{field} must be in \[{lo}, "):
        Params(**{field: value})


@pytest.mark.parametrize("field,value,pattern", [
    ("r", -0.1, r"^r must be in \[0, 1000\] \[m\]"),
    ("m_t", -0.1, r"^m_t must be in \[0, 1e\+06\] \[kg\]"),
    ("l", -0.5, r"^l must be in \[0, L\]"),
    ("l", 8.5, r"^l must be in \[0, L\]"),
    ("n_axial", 0, r"^n_axial must be an integer in 1\.\.20"),
    ("n_transverse", 21, r"^n_transverse must be an integer in 1\.\.20"),
    ("n_transverse", 2.5, r"^n_transverse must be an integer in 1\.\.20"),
    ("damping_ratio", 1.0, r"^damping_ratio must be in \[0, 1\)"),
    ("E", float("nan"), r"^E must be finite"),
    ("J_h", float("inf"), r"^J_h must be finite"),
    ("rho", "heavy", r"^rho must be a number"),
])
def test_out_of_range_rejected(field, value, pattern):
    with pytest.raises(ParameterError, match=pattern):
        Params(**{field: value})


def test_error_is_one_line():
    with pytest.raises(ParameterError) as info:
        Params(l=99.0)
    assert "\n" not in str(info.value)


def test_toml_round_trip(tmp_path):
    p = Params(m_t=0.5, l=4.0, n_transverse=7, damping_ratio=0.01)
    path = tmp_path / "p.toml"
    save_params(p, path)
    assert load_params(path) == p


def test_toml_table_and_unknown_keys(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text("[params]\nm_t = 0.5\n")
    assert load_params(path).m_t == 0.5
    path.write_text("m_t = 0.5\nmass = 3\n")
    with pytest.raises(ParameterError, match="unknown parameter.*mass"):
        load_params(path)
    path.write_text("m_t = -2\n")
    with pytest.raises(ParameterError, match=r"m_t must be in \[0, "):
        load_params(path)
    path.write_text("m_t = = 2\n")
    with pytest.raises(ParameterError, match="not valid TOML"):
        load_params(path)

"""Input shapers: closed forms, defining equations, residual vibration, multi-mode, bad input."""

import math

import numpy as np
import pytest

from controllers.shaping import (
    Shaper,
    ei_shaper,
    ei_side_frequencies,
    make_shaper,
    residual_vibration,
    zv_shaper,
    zvd_shaper,
)
from hubbeam_ctrl.core.errors import ParameterError

MODES = [(2 * math.pi * 0.46, 0.0), (3.0, 0.02), (17.0, 0.1), (0.7, 0.3)]


def _closed_form(w, zeta):
    """``(T_d, K)`` written out independently of the module."""
    wd = w * math.sqrt(1 - zeta ** 2)
    return 2 * math.pi / wd, math.exp(-zeta * math.pi / math.sqrt(1 - zeta ** 2))


@pytest.mark.parametrize("w, zeta", MODES)
def test_zv_and_zvd_match_the_closed_forms(w, zeta):
    Td, K = _closed_form(w, zeta)
    zv, zvd = zv_shaper(w, zeta), zvd_shaper(w, zeta)
    assert np.allclose(zv.times, [0.0, Td / 2], rtol=0, atol=1e-12)
    assert np.allclose(zv.amplitudes, [1 / (1 + K), K / (1 + K)], rtol=0, atol=1e-12)
    assert np.allclose(zvd.times, [0.0, Td / 2, Td], rtol=0, atol=1e-12)
    assert np.allclose(zvd.amplitudes, [1 / (1 + K) ** 2, 2 * K / (1 + K) ** 2, K ** 2 / (1 + K) ** 2],
                       rtol=0, atol=1e-12)
    # both leave nothing at their own mode
    assert zv.residual(w, zeta) < 1e-12 and zvd.residual(w, zeta) < 1e-12


@pytest.mark.parametrize("tol", [0.02, 0.05, 0.1])
def test_ei_undamped_closed_form(tol):
    w = 2.0
    s = ei_shaper(w, 0.0, tol)
    Td = 2 * math.pi / w
    assert np.allclose(s.times, [0, Td / 2, Td], rtol=0, atol=1e-12)
    assert np.allclose(s.amplitudes, [(1 + tol) / 4, (1 - tol) / 2, (1 + tol) / 4], rtol=0, atol=1e-12)
    # the side frequencies of the closed form: cos(pi r) = -(1 - V)/(1 + V)
    r_lo = math.acos(-(1 - tol) / (1 + tol)) / math.pi
    assert np.allclose(ei_side_frequencies(w, 0.0, tol), [w * r_lo, w * (2 - r_lo)], rtol=1e-12)


@pytest.mark.parametrize("zeta", [0.0, 0.03, 0.1, 0.2])
@pytest.mark.parametrize("tol", [0.05, 0.1])
def test_ei_defining_conditions(zeta, tol):
    w = 3.0
    s = ei_shaper(w, zeta, tol)
    lo, hi = ei_side_frequencies(w, zeta, tol)
    assert lo < w < hi
    assert s.residual(w, zeta) == pytest.approx(tol, abs=1e-10)          # V_tol at nominal
    assert np.all(s.residual([lo, hi], zeta) < 1e-10)                     # zero either side
    h = 1e-5 * w
    slope = (s.residual(w + h, zeta) - s.residual(w - h, zeta)) / (2 * h)
    assert abs(slope) * w < 1e-7                                          # top of the hump
    band = np.linspace(lo, hi, 4001)
    assert np.max(s.residual(band, zeta)) <= tol * (1 + 1e-9)             # insensitivity band
    assert np.all(s.amplitudes > 0) and s.amplitudes.sum() == pytest.approx(1.0, abs=1e-14)


@pytest.mark.parametrize("zeta", [0.05, 0.1, 0.2])
def test_ei_agrees_with_singhoses_published_fit(zeta):
    """Singhose's curve fit of damped EI shapers (t3 = T_d, no derivative condition)."""
    V = 0.05
    Td, _ = _closed_form(1.0, zeta)
    A1 = 0.24968 + 0.24961 * V + 0.80008 * zeta + 1.23328 * V * zeta + 0.49599 * zeta ** 2 \
        + 3.17316 * V * zeta ** 2
    A3 = 0.25149 + 0.21474 * V - 0.83249 * zeta + 1.41498 * V * zeta + 0.85181 * zeta ** 2 \
        - 4.90094 * V * zeta ** 2
    t2 = 0.49990 + 0.46159 * V * zeta + 4.26169 * V * zeta ** 2 + 1.75601 * V * zeta ** 3 \
        + 8.57843 * V ** 2 * zeta - 108.644 * V ** 2 * zeta ** 2 + 336.989 * V ** 2 * zeta ** 3
    s = ei_shaper(1.0, zeta, V)
    assert np.allclose(s.amplitudes, [A1, 1 - A1 - A3, A3], atol=1.5e-3)
    assert np.allclose(s.times / Td, [0.0, t2, 1.0], atol=0.012)


def _step_response(shaper, w, zeta, t):
    """Exact response and rate of ``x'' + 2 zeta w x' + w^2 x = w^2 u`` to the shaped unit step."""
    wd = w * math.sqrt(1 - zeta ** 2)
    x = np.zeros_like(t)
    v = np.zeros_like(t)
    for ti, a in zip(shaper.times, shaper.amplitudes):
        s = np.maximum(t - ti, 0.0)
        e = np.exp(-zeta * w * s)
        x += a * (1 - e * (np.cos(wd * s) + zeta * w / wd * np.sin(wd * s))) * (t >= ti)
        v += a * e * (w ** 2 / wd) * np.sin(wd * s) * (t >= ti)
    return x, v


def test_zv_shaped_step_leaves_an_undamped_mode_at_rest():
    w = 2 * math.pi * 0.46
    zv = zv_shaper(w)
    t = zv.duration + np.linspace(0.0, 20 * 2 * math.pi / w, 20001)
    x, v = _step_response(zv, w, 0.0, t)
    assert np.max(np.abs(x - 1)) < 1e-9 and np.max(np.abs(v)) / w < 1e-9
    # the unshaped step swings by 1 (the check can fail)
    x0, _ = _step_response(Shaper([0.0], [1.0]), w, 0.0, t)
    assert np.max(np.abs(x0 - 1)) == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("kind", ["zv", "zvd", "ei"])
@pytest.mark.parametrize("zeta", [0.0, 0.05])
def test_residual_vibration_is_the_simulated_amplitude_ratio(kind, zeta):
    """V(omega) is the shaped step's residual amplitude over that of an unshaped step of the
    same age (applied at the shaper's last impulse), off the nominal frequency too."""
    w0 = 2.0
    s = make_shaper(kind, w0, zeta, 0.05)
    for w in (0.8 * w0, w0 * 1.13, 1.3 * w0):
        wd = w * math.sqrt(1 - zeta ** 2)
        t = s.duration + np.linspace(0, 2 * math.pi / wd, 2001)
        x, v = _step_response(s, w, zeta, t)
        x0, v0 = _step_response(Shaper([0.0], [1.0]), w, zeta, t - s.duration)   # same age
        # amplitude of a damped oscillation from displacement and rate, at each instant
        amp = np.hypot(x - 1, (v + zeta * w * (x - 1)) / wd)
        amp0 = np.hypot(x0 - 1, (v0 + zeta * w * (x0 - 1)) / wd)
        assert np.allclose(amp / amp0, s.residual(w, zeta), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("zeta", [0.0, 0.07])
def test_zv_convolved_with_itself_is_zvd(zeta):
    zv, zvd = zv_shaper(4.0, zeta), zvd_shaper(4.0, zeta)
    c = zv.convolve(zv)
    assert len(c.times) == 3
    assert np.allclose(c.times, zvd.times, atol=1e-12) and np.allclose(c.amplitudes, zvd.amplitudes, atol=1e-12)


def test_multi_mode_convolution_cancels_both_modes():
    w1, w2 = 2.9, 16.7
    s = zvd_shaper(w1, 0.01).convolve(ei_shaper(w2, 0.0, 0.05))
    assert s.name == "zvd*ei" and len(s.times) == 9
    assert s.duration == pytest.approx(zvd_shaper(w1, 0.01).duration + ei_shaper(w2).duration, abs=1e-12)
    assert s.amplitudes.sum() == pytest.approx(1.0, abs=1e-14)
    assert s.residual(w1, 0.01) < 1e-12
    assert s.residual(w2, 0.0) == pytest.approx(0.05 * float(zvd_shaper(w1, 0.01).residual(w2, 0.0)),
                                                rel=1e-9)
    # shaping a function of time: the sum of delayed copies
    f = lambda t: np.where(t >= 0, np.sin(t), 0.0)
    t = np.array([0.3, 1.7, 4.0])
    expect = sum(a * f(t - ti) for ti, a in zip(s.times, s.amplitudes))
    assert np.allclose(s.apply(f, t), expect, atol=1e-15)


@pytest.mark.parametrize("call, match", [
    (lambda: zv_shaper(1.0, 1.0), "damping must be a finite number in \\[0, 1\\)"),
    (lambda: zvd_shaper(1.0, 1.5), "damping"),
    (lambda: zv_shaper(float("nan")), "frequency must be a finite number > 0"),
    (lambda: zvd_shaper(-2.0), "frequency must be a finite number > 0"),
    (lambda: ei_shaper(1.0, float("nan")), "damping"),
    (lambda: ei_shaper(1.0, 0.0, 0.7), "tolerance must be a finite number in \\(0, 0.5\\)"),
    (lambda: ei_shaper(1.0, 0.0, float("nan")), "tolerance"),
    (lambda: make_shaper("zvdd", 1.0), "shaper must be one of zv, zvd, ei"),
    (lambda: residual_vibration(zv_shaper(1.0), [1.0, float("nan")]), "frequency"),
    (lambda: Shaper([0.0, 1.0], [0.5, 0.6]), "sum to 1"),
    (lambda: Shaper([0.5, 1.0], [0.5, 0.5]), "ascending from 0"),
    (lambda: zv_shaper(1.0).convolve([1.0]), "other must be a Shaper"),
])
def test_bad_input_is_one_line(call, match):
    with pytest.raises(ParameterError, match=match) as exc:
        call()
    assert "\n" not in str(exc.value)

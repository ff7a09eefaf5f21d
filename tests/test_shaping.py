"""Input shapers: closed forms, defining equations, residual vibration, multi-mode, bad input;
shapers for the design model, the open-loop shaped slew and the reference filter; on FOAM."""

import math

import numpy as np
import pytest

from controllers import (
    CONTROLLERS,
    DesignModel,
    EIOpenLoop,
    OpenLoop,
    ShapedOpenLoop,
    ShapedSettings,
    ZVDOpenLoop,
    ZVOpenLoop,
    eq44_reference,
    make_controller,
    slew_reference,
    spinup_reference,
)
from controllers.shaping import (
    Shaper,
    design_modes,
    design_shaper,
    ei_shaper,
    ei_side_frequencies,
    make_shaper,
    residual_vibration,
    shape_reference,
    shaper_sensitivity,
    zv_shaper,
    zvd_shaper,
)
from hubbeam_ctrl import Params
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.modal import modal_analysis
from hubbeam_ctrl.plant.models import build_model
from hubbeam_ctrl.sim import simulate_closed_loop
from hubbeam_ctrl.study.compare import compare
from hubbeam_ctrl.study.compare_values import (
    CompareSettings,
    DesignChoice,
    PlantChoice,
    RunChoice,
    ScenarioChoice,
    compare_arguments,
)
from hubbeam_ctrl.study.scenarios import make_scenario
from hubbeam_ctrl.study.shaping import plant_sensitivity, plant_variant, residual_after

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


# == shapers for the design model, the open-loop shaped slew, the reference filter ===========
P3 = Params(n_axial=3, n_transverse=3)


@pytest.fixture(scope="module")
def design3():
    return DesignModel.build(P3, 0.0, 0.01)


def test_design_modes_are_the_free_hub_modes(design3):
    w, z = design_modes(design3)
    assert np.allclose(w / (2 * math.pi), modal_analysis("sfoam", 0.0, "free", P3).bending_hz, rtol=1e-9)
    assert np.all(z == 0)
    damped = DesignModel.build(P3.replace(damping_ratio=0.02), 0.0, 0.01)
    wd, zd = design_modes(damped)
    ref = modal_analysis("sfoam", 0.0, "free", P3.replace(damping_ratio=0.02))
    assert np.allclose(zd, ref.damping_ratios, rtol=1e-6) and np.all(zd > 0.005)
    s = design_shaper(damped, "zv")
    assert s.duration == pytest.approx(math.pi / (wd[0] * math.sqrt(1 - zd[0] ** 2)), rel=1e-12)


def test_design_shaper_convolves_the_modes(design3):
    w, z = design_modes(design3)
    s = design_shaper(design3, "zvd", (1, 3))
    expect = zvd_shaper(w[0], z[0]).convolve(zvd_shaper(w[2], z[2]))
    assert np.allclose(s.times, expect.times, atol=1e-12) and np.allclose(s.amplitudes, expect.amplitudes)
    assert np.all(s.residual(w[[0, 2]], 0.0) < 1e-12)


def _rigid_motion(torques, dt, J):
    """Exact rigid-body angle and rate under held torques."""
    th = om = 0.0
    for u in torques:
        th += om * dt + 0.5 * u / J * dt ** 2
        om += u / J * dt
    return th, om


@pytest.mark.parametrize("profile", ["bangbang", "smooth"])
@pytest.mark.parametrize("cls", [ZVOpenLoop, ZVDOpenLoop, EIOpenLoop])
def test_shaped_slew_turns_by_the_angle_within_tau_max(design3, profile, cls):
    J = design3.inertia
    angle = 200.0 * 100 / (2 * math.pi * J)          # the default paper slew
    ctrl = cls(design3, ShapedSettings(profile=profile, angle=angle, tau_max=200.0))
    th, om = _rigid_motion(ctrl.torques, ctrl.dt, J)
    assert th == pytest.approx(angle, rel=1e-6) and abs(om) < 1e-9
    assert np.max(np.abs(ctrl.torques)) <= 200.0 * (1 + 1e-9)
    # the shortest duration uses the whole budget: the base profile peaks at tau_max
    assert ctrl.profile.base_peak == pytest.approx(200.0, rel=1e-6)
    assert ctrl(ctrl.profile.duration + 1.0, None) == 0.0
    # a duration below the shortest is refused, naming the shortest
    quoted = math.ceil(ctrl.profile.duration * 1e4) / 1e4          # rounded up: the quoted value runs
    with pytest.raises(ParameterError, match=f"shortest feasible duration {quoted:.4f} s"):
        cls(design3, ShapedSettings(profile=profile, angle=angle, duration=0.99 * ctrl.profile.duration))


def test_shaped_slew_leaves_the_linear_design_model_at_rest(design3):
    """The held torques on the exact ZOH model: the shaped slew leaves ~no vibration, the unshaped a lot."""
    def residual(ctrl):
        x = np.zeros(design3.n_x)
        for u in ctrl.torques:
            x = design3.Ad @ x + design3.Bd[:, 0] * u
        n = design3.n_x // 2
        return np.hypot(x[1:n] * design_modes(design3)[0], x[n + 1:]).max()
    settings = ShapedSettings(profile="bangbang", angle=1.0, duration=12.0, modes=(1, 2, 3))
    unshaped = ShapedOpenLoop(design3, ShapedSettings(profile="bangbang", angle=1.0, duration=7.0),
                              shaper=Shaper([0.0], [1.0]))
    assert residual(ZVDOpenLoop(design3, settings)) < 1e-3 * residual(unshaped)
    assert residual(ZVOpenLoop(design3, settings)) < 1e-3 * residual(unshaped)


def test_shaped_feedforward_of_the_spinup(design3):
    J = design3.inertia
    ref = spinup_reference(3.0, 10.0, J, 0.01, 20.0)
    ctrl = ZVDOpenLoop(design3, ShapedSettings(profile="feedforward"), ref)
    _, om = _rigid_motion(ctrl.torques, 0.01, J)
    assert om == pytest.approx(3.0, rel=1e-9)
    assert np.max(np.abs(ctrl.torques)) <= np.max(ref.torque) + 1e-9
    with pytest.raises(ParameterError, match="does not end at rest"):
        ZVDOpenLoop(design3, ShapedSettings(profile="bangbang"), ref)


def test_shape_reference_delays_and_keeps_the_end_state(design3):
    J = design3.inertia
    ref = slew_reference(2.0, 8.0, J, 200.0, 0.01, 20.0)
    s = design_shaper(design3, "zvd")
    sh = shape_reference(ref, s)
    assert len(sh.theta) == len(ref.theta) + math.ceil(s.duration / 0.01)
    assert sh.theta[-1] == pytest.approx(2.0, abs=1e-12) and abs(sh.theta_dot[-1]) < 1e-12
    assert np.max(np.abs(sh.torque)) <= np.max(np.abs(ref.torque)) + 1e-9
    # on the sample grid: the sum of delayed, linearly interpolated copies
    k = 500
    expect = sum(a * np.interp(0.01 * k - ti, ref.t, ref.theta) for ti, a in zip(s.times, s.amplitudes))
    assert sh.theta[k] == pytest.approx(expect, abs=1e-14)
    # the feedback controllers take it through make_controller(shaping=...)
    ctrl = make_controller("lqr", design3, None, ref, shaping="zvd")
    assert "shaped by zvd" in ctrl.reference.description and len(ctrl.reference.theta) == len(sh.theta)
    assert np.allclose(ctrl.reference.torque, sh.torque)


def test_registered_and_sensitivity_arrays(design3):
    specs = {k: CONTROLLERS[k] for k in ("zv", "zvd", "ei")}
    assert {k: s.controller for k, s in specs.items()} == {"zv": ZVOpenLoop, "zvd": ZVDOpenLoop, "ei": EIOpenLoop}
    assert all(s.settings is ShapedSettings and not s.default and not s.tracks_reference and s.scheduled is None
               for s in specs.values())
    out = shaper_sensitivity(design3, errors=[-0.2, 0.0, 0.2])
    assert np.allclose(out["zv"], [abs(math.cos(0.4 * math.pi)), 0.0, abs(math.cos(0.6 * math.pi))], atol=1e-12)
    assert np.allclose(out["zvd"], np.cos([0.4 * math.pi, 0.5 * math.pi, 0.6 * math.pi]) ** 2, atol=1e-12)
    assert out["ei"][1] == pytest.approx(0.05, abs=1e-12)


def test_shaped_settings_for_a_scenario():
    """A rest-to-rest scenario gets a smooth slew, any other its feedforward shaped; both its budget."""
    slew = make_scenario("slew", plant="foam", tau_max=150.0, t_f=8.0, t_end=14.0)
    spin = make_scenario("spinup", plant="foam", tau_max=150.0, t_f=8.0, t_end=14.0, w_f=2.0)
    assert ShapedSettings.for_scenario(slew, horizon=50) == ShapedSettings(profile="smooth", tau_max=150.0,
                                                                           duration=8.0)
    assert ShapedSettings.for_scenario(spin) == ShapedSettings(profile="feedforward", tau_max=150.0)
    assert ShapedSettings(modes=[2, 1]).modes == (2, 1)


@pytest.mark.parametrize("call, match", [
    (lambda d: design_shaper(d, "zvd", (4,)), "modes must be distinct mode numbers in 1..3"),
    (lambda d: design_shaper(d, "zvd", (0, 1)), "modes must be distinct mode numbers in 1..3"),
    (lambda d: design_shaper(d, "zvd", (1, 1)), "modes must be distinct"),
    (lambda d: shaper_sensitivity(d, mode=7), "modes must be distinct mode numbers in 1..3"),
    (lambda d: shaper_sensitivity(d, errors=[float("nan")]), "errors must be finite"),
    (lambda d: ZVOpenLoop(d, ShapedSettings(angle=1.0, modes=(5,))), "modes must be distinct mode numbers in 1..3"),
    (lambda d: ShapedSettings(profile="sine"), "profile must be one of 'bangbang', 'smooth', 'feedforward'"),
    (lambda d: ShapedSettings(duration=-1.0), r"duration must be > 0 \[s\], got -1"),
    (lambda d: ShapedSettings(angle=float("nan")), r"angle must be finite \[rad\]"),
    (lambda d: ShapedSettings(tolerance=0.6), r"tolerance must be in \(0, 0.5\), got 0.6"),
    (lambda d: ShapedSettings(modes=()), "modes must be distinct"),
    (lambda d: ZVOpenLoop(d, ShapedSettings(profile="feedforward")), "needs a reference"),
    (lambda d: ZVOpenLoop(d, ShapedSettings(profile="feedforward", tau_max=10.0),
                          eq44_reference(200.0, 10.0, d.inertia, 0.01, 12.0)), "more than tau_max = 10 N m"),
    (lambda d: make_controller("lqr", d, shaping="zvdd"), "shaper must be one of zv, zvd, ei"),
    (lambda d: make_controller("openloop", d, shaping="zv"), "'openloop' does not track a reference"),
    (lambda d: compare(None, "slew", "lqr",
                       CompareSettings(design=DesignChoice(shaping="zvdd"))), "shaper must be one of zv, zvd, ei"),
    (lambda d: shape_reference([0.0], zv_shaper(1.0)), "reference must be a Reference"),
])
def test_bad_design_level_input_is_one_line(design3, call, match):
    with pytest.raises(ParameterError, match=match) as exc:
        call(design3)
    assert "\n" not in str(exc.value)


# == on the nonlinear plant (slow) ==============================================================
@pytest.mark.slow
def test_target_zvd_open_loop_on_the_paper_slew():
    """ZVD-shaped open loop, default paper slew on FOAM: within tau_max, <= 2 % of Eq. 44's residual."""
    m = compare(None, "slew", "openloop,zvd").metrics["zvd"]
    assert m["completed"] and m["within_torque_limit"]
    assert m["residual_pct_of_openloop"] <= 2.0          # measured 0.94 %
    assert abs(m["final_angle_error_rad"]) < 0.01         # open loop: FOAM's inertia is not J_total


@pytest.mark.slow
def test_nonlinear_plant_follows_the_linear_sensitivity_at_three_points():
    """E scaled to move every frequency by -20 %, 0, +20 %; bang-bang at 50 N m (FOAM nearly linear).

    The measured ratio must lie within the linear curve's values over the error +- 3 %
    (the stiffening during the slew shifts the frequency by about 1.5 %) plus 1 % residual.
    """
    d = DesignModel.build(Params(), 0.0, 0.01)
    out = plant_sensitivity(d, errors=(-0.2, 0.0, 0.2))
    for kind in ("zv", "zvd", "ei"):
        lin = shaper_sensitivity(d, (kind,), np.linspace(-0.5, 0.5, 1001))
        shaper = design_shaper(d, kind, (1, 2, 3, 4, 5))
        w1 = lin["frequency"]
        for e, v in zip(out["errors"], out[kind]):
            band = shaper.residual(w1 * (1 + e + np.linspace(-0.03, 0.03, 61)), 0.0)
            assert band.min() - 0.01 <= v <= band.max() + 0.01, (kind, e, v, band.min(), band.max())
    assert np.all(out["ei"] <= 0.055) and out["zv"][0] > 0.25 and out["zv"][2] > 0.25


@pytest.mark.slow
def test_target_ei_robust_to_a_heavier_tip_where_zv_is_not():
    """Design at m_t = 0.1 kg; plant with the tip mass that lowers the first frequency by 20 %."""
    p = Params()
    d = DesignModel.build(p, 0.0, 0.01)
    heavy = plant_variant(p, -0.2, "tip_mass")
    f = [modal_analysis("foam", 0.0, "free", q).bending_hz[0] for q in (p, heavy)]
    assert f[1] / f[0] == pytest.approx(0.8, abs=1e-9) and 0.4 < heavy.m_t < 0.5
    # percentage residual vibration (shaped / unshaped base profile) at 50 N m
    out = plant_sensitivity(d, errors=(-0.2,), kinds=("zv", "ei"), how="tip_mass")
    assert out["ei"][0] <= 0.05 and out["zv"][0] > 0.25          # measured 4.3 %, 29 %
    # the default paper slew (200 N m), against the heavy plant's own Eq. 44 residual
    sc = make_scenario("slew", plant="foam", params=p)
    model = build_model("foam", heavy)
    res = {}
    for name, ctrl in (("eq44", OpenLoop(d)), ("zv", make_controller("zv", d, ShapedSettings(profile="smooth"),
                                                                   sc.reference)),
                       ("ei", make_controller("ei", d, ShapedSettings(profile="smooth"), sc.reference))):
        res[name] = residual_after(simulate_closed_loop(model, ctrl, sc.t_end), sc.t_f + 5.0)
    assert res["ei"] <= 0.05 * res["eq44"] < res["zv"]             # measured 2.1 %, 197 %


def test_shaped_slew_honours_the_tasks_duration_or_refuses_it(capsys, tmp_path):
    """Issue 22: a shaped slew takes the task's t_f (its torque ends there, the angle is reached), a t_f
    its budget cannot do is refused before any run naming t_f and the shortest feasible duration (which
    then runs), and on the Eq. 44 task, which no shaped profile can do in t_f, the report says so."""
    from hubbeam_ctrl.cli.main import main
    from hubbeam_ctrl.study.report import _report
    kw = dict(slew_angle=0.5, t_end=9.0, design_modes=2, plant_modes=3)
    c = compare(**compare_arguments("foam", "slew", "zvd", t_f=4.0, **kw))
    r = c.results["zvd"]
    moving = r.t[np.abs(r.tau) > 1e-9]
    assert 3.9 < moving[-1] <= 4.0 + 1e-9                    # the last torque sample is inside t_f
    assert c.notes == [] and abs(r.theta[-1] - 0.5) < 0.01    # FOAM's inertia is not J_total
    with pytest.raises(ParameterError, match=r"^t_f = 2 s is too short for zvd: .*shortest feasible "
                                             r"duration (\d+\.\d+) s$") as exc:
        compare(**compare_arguments("foam", "slew", "zvd", t_f=2.0, **kw))
    shortest = float(str(exc.value).rsplit(" ", 2)[-2])
    assert 2.0 < shortest < 4.0
    compare(**compare_arguments("foam", "slew", "zvd", t_f=shortest, **kw))      # the value quoted (rounded up) runs
    assert main(["compare", "--controllers", "zvd", "--tf", "2", "--slew-angle", "0.5", "--out",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--tf" in err[0] and "shortest feasible duration" in err[0], err
    assert not (tmp_path / "o").exists()
    # the Eq. 44 task at the full budget: the shortest shaped slew, said in the report
    eq44 = compare(None, "slew", "zvd",
                   CompareSettings(plant=PlantChoice(plant_modes=3), design=DesignChoice(design_modes=2),
                                   run=RunChoice(t_end=9.0), scenario=ScenarioChoice(t_f=4.0)))
    assert len(eq44.notes) == 1 and eq44.notes[0].startswith("zvd: its shaped slew takes")
    assert f"- {eq44.notes[0]}" in _report(eq44).splitlines()

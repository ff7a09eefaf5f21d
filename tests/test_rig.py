"""The rig description: validation, TOML files, presets (issue 21, Build 1)."""

import math

import pytest

from hubbeam_ctrl import Params, save_params
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import (
    PRESETS,
    RIG_TABLES,
    Damping,
    Drive,
    Friction,
    Rig,
    Sensors,
    Timing,
    load_rig,
    save_rig,
)


def test_servo_link_preset_has_the_published_numbers():
    rig = load_rig("servo_link")
    b, d, f = rig.beam, rig.drive, rig.friction
    assert (b.L, b.rho, b.A, b.E, b.I, b.r, b.J_h, b.m_t) == (0.381, 7900.0, 2.1596e-5, 193e9, 5.352e-13, 0.0,
                                                              2.087e-3, 0.0)
    assert b.beam_mass == pytest.approx(0.065, rel=1e-3)          # 65 g of steel
    assert b.EI == pytest.approx(0.1033, rel=1e-3)
    # first clamped mode of a uniform Euler-Bernoulli cantilever: (1.8751^2 / L^2) sqrt(EI / rho A)
    f1 = 1.875104 ** 2 / b.L ** 2 * math.sqrt(b.EI / b.rhoA) / (2 * math.pi)
    assert f1 == pytest.approx(3.0, abs=0.06)                    # "3.0 Hz clamped", measured 2.94-3.0
    assert (d.kind, d.R, d.k_t, d.k_e, d.N, d.eta_forward, d.eta_backward, d.V_max) == \
        ("dc_motor", 2.6, 7.68e-3, 7.68e-3, 70.0, 0.9, 0.69, 10.0)
    assert (f.viscous, f.coulomb) == (4e-3, 10e-3)
    assert rig.damping.ratios == (0.034,)
    assert rig.sensors.encoder_counts == 4096 and rig.sensors.strain_gauges == (0.0,)
    assert (rig.timing.dt, rig.timing.delay) == (1e-3, 0.5)
    assert b.tau_max == pytest.approx(d.stall_torque, rel=1e-3)
    assert not rig.is_ideal


def test_paper_preset_is_table_1_with_ideal_hardware():
    rig = load_rig("paper")
    assert rig.beam == Params()
    assert rig.is_ideal and rig == Rig()
    assert rig.plant_params is rig.beam


def test_presets_ship_and_every_one_loads():
    assert set(PRESETS) == {"servo_link", "paper", "accel_link", "servo_payload", "space_boom"}
    for name in PRESETS:
        assert isinstance(load_rig(name), Rig)


def test_round_trip_through_toml(tmp_path):
    rig = load_rig("servo_link").replace(
        damping=Damping(ratios=(0.034, 0.02), alpha=0.1, beta=1e-5),
        sensors=Sensors(encoder_counts=1024, strain_gauges=(0.0, 0.2), tip_accelerometer=True,
                        angle_noise=1e-4, accel_bias=0.3, anti_alias_hz=200.0),
        friction=Friction(viscous=1e-3, coulomb=1e-2, breakaway=1.5e-2))
    path = tmp_path / "rig.toml"
    save_rig(rig, path)
    assert load_rig(path) == rig
    save_rig(Rig(), path)
    assert load_rig(path) == Rig()


def test_flat_params_file_is_the_beam_with_ideal_hardware(tmp_path):
    path = tmp_path / "p.toml"
    p = Params(m_t=0.5, n_transverse=3)
    save_params(p, path)
    rig = load_rig(path)
    assert rig.beam == p and rig.is_ideal
    path.write_text("[params]\nm_t = 0.5\n")
    assert load_rig(path).beam == Params(m_t=0.5)


def test_reflected_rotor_inertia_adds_to_the_hub():
    rig = Rig(beam=Params(J_h=1.0), drive=Drive(kind="dc_motor", N=10.0, J_r=1e-3))
    assert rig.plant_params.J_h == pytest.approx(1.0 + 100 * 1e-3)
    # the torque drive has no rotor
    assert Rig(beam=Params(J_h=1.0), drive=Drive(N=10.0, J_r=1e-3)).plant_params.J_h == 1.0


def test_damping_ratio_per_mode_and_rayleigh():
    d = Damping(ratios=(0.03, 0.01), alpha=0.2, beta=1e-4)
    assert d.ratio(1, 10.0) == pytest.approx(0.03 + 0.2 / 20 + 0.5e-4 * 10)
    assert d.ratio(2, 100.0) == pytest.approx(0.01 + 0.2 / 200 + 0.5e-4 * 100)
    assert d.ratio(5, 100.0) == pytest.approx(0.01 + 0.2 / 200 + 0.5e-4 * 100)   # last value beyond
    assert Damping().ratio(3, 50.0) == 0.0 and not Damping().is_set


@pytest.mark.parametrize("make, message", [
    (lambda: Drive(kind="dc_motor", R=-1), r"^motor\.R must be in \(0, 10000\] \[ohm\], got -1$"),
    (lambda: Drive(kind="dc_motor", N=0), r"^motor\.N must be in \(0, 10000\], got 0$"),
    (lambda: Drive(kind="dc_motor", eta_backward=1.2), r"^motor\.eta_backward must be in \(0, 1\]"),
    (lambda: Drive(kind="servo"), r"^motor\.kind must be one of 'torque', 'dc_motor', got 'servo'$"),
    (lambda: Timing(delay=1.5), r"^timing\.delay must be in \[0, 1\], got 1.5$"),
    (lambda: Timing(dt=0.0), r"^timing\.dt must be in \[1e-06, 10\] \[s\], got 0"),
    (lambda: Friction(coulomb=-0.1), r"^friction\.coulomb must be in \[0, 1e\+09\] \[N m\], got -0.1$"),
    (lambda: Friction(coulomb=0.1, breakaway=0.05), r"^friction\.breakaway must be >= friction\.coulomb"),
    (lambda: Damping(ratios=(0.03, 1.0)), r"^damping\.ratios\[1\] must be in \[0, 1\) \[-\], got 1.0$"),
    (lambda: Sensors(encoder_counts=-5),
     r"^sensors\.encoder_counts must be an integer in 0\.\.1e\+09 \[counts/rev\], got -5$"),
    (lambda: Sensors(strain_gauges=(0.0, -0.1)), r"^sensors\.strain_gauges\[1\] must be in \[0, inf\]"),
    (lambda: Rig(beam=Params(L=0.4, I=5e-13, A=2e-5, rho=7900, E=2e11, J_h=2e-3),
                 sensors=Sensors(strain_gauges=(0.0, 0.5))),
     r"^sensors\.strain_gauges\[1\] must be in \[0, L\] = \[0, 0\.4\] \[m\] \(on the beam\), got 0\.5$"),
    (lambda: Rig(drive=Drive(kind="dc_motor", N=70, k_t=7.68e-3, I_max=0.01), friction=Friction(coulomb=0.01)),
     r"^motor\.I_max must be >= 0\.0186 \[A\] .*breakaway friction 0\.01 N m\), got 0\.01$"),
    (lambda: Rig(beam=Params(damping_ratio=0.01), damping=Damping(ratios=(0.02,))),
     r"^beam\.damping_ratio must be 0 when \[damping\] is given"),
])
def test_bad_input_is_one_line_naming_the_key(make, message):
    with pytest.raises(ParameterError, match=message) as info:
        make()
    assert "\n" not in str(info.value)


def test_current_limit_holding_the_rig_is_accepted():
    """The same motor with a current limit just above the holding current is a valid rig."""
    rig = Rig(drive=Drive(kind="dc_motor", N=70, k_t=7.68e-3, I_max=0.021), friction=Friction(coulomb=0.01))
    assert rig.drive.eta_forward * 70 * 7.68e-3 * 0.021 >= 0.01
    # a torque drive has no current limit to check
    Rig(drive=Drive(I_max=1e-6), friction=Friction(coulomb=10.0))


@pytest.mark.parametrize("text, message", [
    ("[beam]\nL = 8.0\n[motr]\nR = 1.0\n", r"unknown table \[motr\]; allowed tables: \[beam\], \[motor\]"),
    ("[motor]\nkind = 'dc_motor'\nresistance = 2.6\n", r"unknown key motor\.resistance; allowed in \[motor\]: "),
    ("[beam]\nL = -1.0\n", r"beam\.L must be in \[0\.01, 1000\] \[m\], got -1"),
    ("[beam]\nlength = 1.0\n", r"\[beam\]: unknown parameter\(s\) length"),
    ("[motor]\nkind = 'dc_motor'\nR = -1\n", r"motor\.R must be in \(0, 10000\] \[ohm\], got -1$"),
    ("[motor]\nkind = 'dc_motor'\nN = 0\n", r"motor\.N must be in \(0, 10000\], got 0$"),
    ("[timing]\ndelay = 2.0\n", r"timing\.delay must be in \[0, 1\], got 2"),
    ("[sensors]\nstrain_gauges = [0.0, 9.0]\n", r"sensors\.strain_gauges\[1\] must be in \[0, L\] = \[0, 8\]"),
    ("[sensors]\nstrain_gauges = 'root'\n", r"sensors\.strain_gauges must be a tuple"),
    ("[motor]\nkind = 'dc_motor'\nN = 1\nI_max = 0.1\n[friction]\ncoulomb = 1.0\n",
     r"motor\.I_max must be >= 130\.2 \[A\]"),
    ("beam = 3\n[motor]\nR = 1.0\n", r"\[beam\] must be a table of keys, got int"),
    ("colour = 'red'\n[motor]\nR = 1.0\n", r"unknown key colour; allowed tables"),
])
def test_bad_rig_files_name_the_table_or_key(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ParameterError, match=message) as info:
        load_rig(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)


def test_unknown_preset_or_missing_file():
    with pytest.raises(ParameterError, match=r"^rig 'servo_lnk' is neither a file nor a preset \(servo_link, paper, "):
        load_rig("servo_lnk")
    with pytest.raises(ParameterError, match=r"does not exist"):
        load_rig("no/such/rig.toml")


def test_every_rig_field_is_in_the_ranges_doc():
    from pathlib import Path
    text = (Path(__file__).parent.parent / "docs" / "ranges.md").read_text()
    for table, cls in RIG_TABLES.items():
        assert f"`{cls.__name__}`" in text, table
        from dataclasses import fields
        for f in fields(cls):
            assert f"| `{f.name}` | {f.metadata['unit']} |" in text, (table, f.name)


def test_rig_damping_reaches_the_plant_modes():
    """Per-mode ratios and Rayleigh terms become the damping ratios of the plant's clamped modes
    (modal analysis of the prescribed-hub FOAM plant, 6 modes): 0.034 on mode 1, 0.02 beyond, plus
    beta w_i / 2; and the servo link's first clamped mode is at 3.0 Hz."""
    from hubbeam_ctrl import build_model
    from hubbeam_ctrl.plant.modal import modal_analysis
    rig = load_rig("servo_link").replace(damping=Damping(ratios=(0.034, 0.02), beta=1e-5))
    P = rig.plant_params.replace(n_axial=2, n_transverse=6)
    ma = modal_analysis(build_model("foam", P), 0.0, "prescribed")
    w = 2 * math.pi * ma.bending_hz
    want = [0.034 if i == 0 else 0.02 for i in range(6)] + 0.5e-5 * w
    assert ma.damping_ratios == pytest.approx(want, rel=1e-6)
    assert ma.bending_hz[0] == pytest.approx(3.0, rel=1e-3)
    assert len(rig.plant_params.damping_ratios) == 20 and rig.plant_params.damping_ratio == 0.0
    # no [damping]: the beam's own uniform ratio, unchanged
    assert load_rig("paper").plant_params.damping_ratios == ()


def test_params_per_mode_damping_validation_and_toml(tmp_path):
    from hubbeam_ctrl import load_params
    p = Params(damping_ratios=[0.03, 0.01])
    assert p.damping_ratios == (0.03, 0.01)
    assert list(p.transverse_damping(4)) == [0.03, 0.01, 0.01, 0.01]
    assert list(Params(damping_ratio=0.02).transverse_damping(2)) == [0.02, 0.02]
    with pytest.raises(ParameterError, match=r"^damping_ratios must hold numbers in \[0, 1\), got 1.5 at index 1$"):
        Params(damping_ratios=(0.1, 1.5))
    path = tmp_path / "p.toml"
    save_params(p, path)
    assert load_params(path) == p


def test_sensors_give_the_closed_loop_sensor_settings():
    s = Sensors(encoder_counts=4096, angle_noise=1e-5, rate_noise=1e-3, strain_noise=0.01)
    ss = s.sensor_settings(seed=3)
    assert (ss.encoder_counts, ss.angle_noise_rad, ss.rate_noise_rad_s, ss.moment_noise_nm, ss.seed) == \
        (4096, 1e-5, 1e-3, 0.01, 3)
    assert ss.encoder_step == pytest.approx(2 * math.pi / 4096) == s.encoder_step
    assert Sensors().sensor_settings().encoder_step == 0.0


# -- the drive's limit is the beam's tau_max (issue 36, Build 4) ----------------------------

def _servo_file(tmp_path, beam_tau=None, motor_extra=""):
    """servo_link's motor and friction in a file, with ``beam.tau_max`` stated or not."""
    beam = "[beam]\nL = 0.381\nrho = 7900.0\nA = 2.1596e-5\nE = 193e9\nI = 5.352e-13\nJ_h = 2.087e-3\nr = 0.0\n"
    if beam_tau is not None:
        beam += f"tau_max = {beam_tau!r}\n"
    motor = ("[motor]\nkind = 'dc_motor'\nR = 2.6\nk_t = 7.68e-3\nk_e = 7.68e-3\nN = 70.0\neta_forward = 0.9\n"
             "eta_backward = 0.69\nV_max = 10.0\nI_max = 4.0\n" + motor_extra)
    path = tmp_path / "servo.toml"
    path.write_text(beam + motor)
    return path


def test_beam_tau_max_follows_from_the_dc_drive(tmp_path):
    stall = 0.9 * 70 * 7.68e-3 * 10.0 / 2.6                      # V_max / R = 3.85 A < I_max = 4 A
    assert load_rig(_servo_file(tmp_path)).beam.tau_max == pytest.approx(stall, rel=1e-12)
    assert load_rig("servo_link").beam.tau_max == 1.86            # the preset's rounded value, 0.05 % off
    for ok in (stall * 0.991, stall * 1.009):
        assert load_rig(_servo_file(tmp_path, ok)).beam.tau_max == ok
    for bad in (stall * 0.989, stall * 1.011, 200.0):
        with pytest.raises(ParameterError, match=rf"beam\.tau_max must be within 1 % of 1\.861 N m \(the DC "
                                                 rf"motor's stall torque .*got {bad:g}$") as info:
            load_rig(_servo_file(tmp_path, bad))
        assert "\n" not in str(info.value)
    # a Rig built in Python takes the drive's limit (a calibrated drive keeps the rig consistent)
    rig = Rig(beam=Params(J_h=1.0), drive=Drive(kind="dc_motor", N=10.0))
    assert rig.beam.tau_max == pytest.approx(10 * 7.68e-3 * 10.0 / 2.6, rel=1e-12)
    again = load_rig("servo_link").replace(drive=load_rig("servo_link").drive.replace(V_max=5.0))
    assert again.beam.tau_max == pytest.approx(0.9 * 70 * 7.68e-3 * 5.0 / 2.6, rel=1e-12)


def test_motor_efficiency_scales_the_torque_and_the_stall_torque(tmp_path):
    from hubbeam_ctrl.sim.hardware import Hardware
    rig = load_rig(_servo_file(tmp_path, motor_extra="eta_motor = 0.69\n"))
    d = rig.drive
    assert d.k_torque == pytest.approx(0.69 * 7.68e-3, rel=1e-15)
    assert rig.beam.tau_max == pytest.approx(0.9 * 70 * 0.69 * 7.68e-3 * 10 / 2.6, rel=1e-12)
    hw, hw1 = Hardware.from_rig(rig), Hardware.from_rig(rig.replace(drive=d.replace(eta_motor=1.0),
                                                                       beam=rig.beam.replace(tau_max=1.86)))
    for u, thd in ((10.0, 0.0), (4.0, 1.5), (-3.0, 0.2)):
        # the current is the same (back-EMF unchanged); the torque is eta_motor times
        assert float(hw.hub_torque(u, thd)) == pytest.approx(0.69 * float(hw1.hub_torque(u, thd)), rel=1e-12)
    assert float(hw.voltage_for_torque(0.5, 0.0)) == pytest.approx(2.6 * 0.5 / (70 * 0.9 * 0.69 * 7.68e-3), rel=1e-12)


def test_a_torque_source_takes_its_own_limit(tmp_path):
    path = tmp_path / "boom.toml"
    path.write_text("[motor]\nkind = 'torque'\ntau_max = 50.0\n")
    assert load_rig(path).beam.tau_max == 50.0
    path.write_text("[beam]\ntau_max = 50.4\n[motor]\nkind = 'torque'\ntau_max = 50.0\n")
    assert load_rig(path).beam.tau_max == 50.4
    path.write_text("[beam]\ntau_max = 200.0\n[motor]\nkind = 'torque'\ntau_max = 50.0\n")
    with pytest.raises(ParameterError, match=r"beam\.tau_max must be within 1 % of 50 N m \(the torque source's "
                                             r"motor\.tau_max; .*got 200$"):
        load_rig(path)
    path.write_text("[motor]\nkind = 'dc_motor'\ntau_max = 5.0\n")
    with pytest.raises(ParameterError, match=r"motor\.tau_max is the limit of a torque source .* "
                                             r"remove motor\.tau_max, "
                                             r"got 5$"):
        load_rig(path)
    assert Rig().beam.tau_max == 200.0 and Rig().drive.torque_limit is None     # no own limit: the beam's

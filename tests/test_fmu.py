"""The plant as an FMU (hubbeam_ctrl.fmu), checked by an independent client: FMPy.

The FMU runs the closed loop's plant step as generated C; FMPy loads it with no Python of
ours in between. References are the toolbox's own runs on the same plant: the fixed-step
run of the Eq. 44 pulse, a PD closed loop, and the servo_link rig's DC motor with friction.
"""

import dataclasses
import shutil
import subprocess
import sys
import zipfile

import numpy as np
import pytest

from controllers import PD, DesignModel, PDSettings
from controllers.reference import eq44_reference
from hubbeam_ctrl.core.compiled import CompileError, find_compiler
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.maneuvers import TorquePulse
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.plant.rig import load_rig
from hubbeam_ctrl.plant.sensors import SensorSettings
from hubbeam_ctrl.sim import ClosedLoopSettings, StepperSettings, simulate_closed_loop, simulate_fixed_step
from hubbeam_ctrl.sim.hardware import Hardware

fmpy = pytest.importorskip("fmpy", reason="FMPy is not installed (pip install 'hubbeam-ctrl[fmu]')")
from fmpy.validation import validate_fmu  # noqa: E402

from hubbeam_ctrl.fmu import build_fmu  # noqa: E402


def _compiler_or_skip():
    try:
        find_compiler()
    except CompileError as exc:
        pytest.skip(f"the FMU's binary needs a C compiler: {exc}")


#: A small plant keeps the tests cheap: FOAM with 2 axial and 3 transverse modes.
SMALL = Params(n_axial=2, n_transverse=3)
T_END = 3.0          # [s] the first 3 s of the Eq. 44 slew (the tip's first large swing)


@pytest.fixture(scope="module")
def plant_fmu(tmp_path_factory):
    _compiler_or_skip()
    path = tmp_path_factory.mktemp("fmu") / "plant.fmu"
    return build_fmu(SMALL, "foam", path)


@pytest.fixture(scope="module")
def rig_fmu(tmp_path_factory):
    """servo_link (DC motor, gear, viscous and Coulomb friction, 4096-count encoder), 3 modes."""
    _compiler_or_skip()
    rig = load_rig("servo_link")
    rig = dataclasses.replace(rig, beam=rig.beam.replace(n_axial=2, n_transverse=3))
    return rig, build_fmu(rig, "foam", tmp_path_factory.mktemp("fmu") / "servo.fmu")


def _zoh(signal, dt, substeps):
    """``signal`` held over each sample, as the toolbox's fixed-step run evaluates it at substep ends."""
    return lambda t: signal(dt * np.maximum(np.floor(np.asarray(t, dtype=float) / dt - 0.5 / substeps), 0))


def _table(signal, dt, t_end):
    t = dt * np.arange(int(round(t_end / dt)) + 1)
    return np.array(list(zip(t, signal(t))), dtype=[("time", float), ("u", float)])


def test_fmu_validates_and_describes_the_plant(plant_fmu, rig_fmu):
    for info in (plant_fmu, rig_fmu[1]):
        assert validate_fmu(str(info.path)) == []
    md = fmpy.read_model_description(str(plant_fmu.path))
    units = {v.name: v.unit for v in md.modelVariables}
    assert (units["u"], units["v_tip"], units["theta_dot"], units["root_moment"]) == ("N.m", "m", "rad/s", "N.m")
    assert md.coSimulation.modelIdentifier == "hubbeam_plant"
    assert float(md.defaultExperiment.stepSize) == plant_fmu.dt
    rig_md = fmpy.read_model_description(str(rig_fmu[1].path))
    rig_units = {v.name: v.unit for v in rig_md.modelVariables}
    assert rig_units["u"] == "V" and rig_units["hw.R"] == "ohm" and rig_fmu[1].command == "voltage"
    with zipfile.ZipFile(plant_fmu.path) as z:
        files = set(z.namelist())
    assert {"sources/hubbeam_fmu.c", "sources/hb_hot.c", "sources/hb_cold.c", "sources/hubbeam_model.h",
            "binaries/linux64/hubbeam_plant.so" if sys.platform == "linux" else plant_fmu.binary} <= files
    assert not any(f.endswith(".py") for f in files)          # no Python at run time


def test_pulse_in_fmpy_equals_fixed_step_run(plant_fmu):
    """simulate_fmu of the Eq. 44 pulse (held over each 10 ms sample) against simulate_fixed_step."""
    dt, k = plant_fmu.dt, plant_fmu.substeps
    pulse = TorquePulse(200.0, 10.0)
    ref = simulate_fixed_step("foam", _zoh(pulse, dt, k), T_END, params=SMALL,
                              settings=StepperSettings(dt=dt, substeps=k))
    res = fmpy.simulate_fmu(str(plant_fmu.path), stop_time=T_END, output_interval=dt,
                            input=_table(pulse, dt, T_END), output=["v_tip", "theta", "u_tip"])
    assert np.array_equal(res["time"], ref.t)
    peak = np.max(np.abs(ref.v_tip))
    assert peak > 0.5                                       # the slew bends the beam (1.30 m here)
    err = np.max(np.abs(res["v_tip"] - ref.v_tip)) / peak
    print(f"FMU pulse: max tip difference {err:.2e} of the peak {peak:.4f} m")
    assert err < 1e-6                                       # measured 3e-16 (same arithmetic)
    assert np.max(np.abs(res["theta"] - ref.q[:, 0])) < 1e-6 * np.max(np.abs(ref.q[:, 0]))
    assert np.max(np.abs(res["u_tip"] - ref.u_tip)) < 1e-6 * np.max(np.abs(ref.u_tip))


def test_pd_loop_through_fmu2slave_equals_simulate_closed_loop(plant_fmu, tmp_path):
    """A PD controller (Python) reading the FMU's sensors through FMPy's FMU2Slave, one doStep
    per sample, against simulate_closed_loop on the same plant with noise-free sensors."""
    dt = plant_fmu.dt
    design = DesignModel.build(SMALL, 0.0, dt, n_modes=3)
    ref_traj = eq44_reference(200.0, 10.0, SMALL.total_inertia, dt, T_END)
    ctrl = PD(design, PDSettings(bandwidth=2.0), reference=ref_traj)
    ref = _quiet_closed_loop(plant_fmu, ctrl)
    err, err_tau = _fmu_loop_errors(plant_fmu, tmp_path / "unzipped", "pd_loop", ctrl, ref, "FMU PD loop")
    assert err < 1e-6
    assert err_tau < 1e-6


def test_rig_with_dc_motor_and_friction_equals_fixed_step_run(rig_fmu):
    """servo_link: voltage in, DC motor, gear efficiencies, friction with Karnopp sticking (the
    hub stops and sticks while the voltage is zero), against simulate_fixed_step(hardware=...)."""
    rig, info = rig_fmu
    dt, k, t_end = info.dt, info.substeps, 1.5

    def volt(t):
        t = np.asarray(t, dtype=float)
        late = np.where(t < 1.0, 0.0, 0.2 * np.sin(2 * np.pi * t / 0.3))
        return np.where(t < 0.5, 3.0 * np.sin(2 * np.pi * t / 0.5), late)

    ref = simulate_fixed_step("foam", _zoh(volt, dt, k), t_end, params=rig.plant_params,
                              settings=StepperSettings(dt=dt, substeps=k), hardware=Hardware.from_rig(rig))
    res = fmpy.simulate_fmu(str(info.path), stop_time=t_end, output_interval=dt, input=_table(volt, dt, t_end),
                            output=["v_tip", "q.theta", "theta", "stuck"])
    peak = np.max(np.abs(ref.v_tip))
    err = np.max(np.abs(res["v_tip"] - ref.v_tip)) / peak
    print(f"FMU servo_link: max tip difference {err:.2e} of the peak {peak:.4f} m, "
          f"{int(res['stuck'].sum())} held samples of {len(res)}")
    assert err < 1e-6                                   # measured 1e-14
    assert np.max(np.abs(res["q.theta"] - ref.q[:, 0])) < 1e-9
    assert res["stuck"].sum() > 50                       # the hub did stick (141 of 1501 samples)
    step = 2 * np.pi / rig.sensors.encoder_counts        # the encoder's nearest count
    assert np.allclose(res["theta"], step * np.floor(res["q.theta"] / step + 0.5), rtol=0, atol=1e-12)
    assert np.max(np.abs(res["theta"] - res["q.theta"])) <= step / 2 + 1e-12


def test_bad_input_is_one_line(tmp_path, plant_fmu):
    with pytest.raises(ParameterError, match="model must be one of foam, cfoam"):
        build_fmu(SMALL, "tlam", tmp_path / "x.fmu")
    with pytest.raises(ParameterError, match="exists"):
        build_fmu(SMALL, "foam", plant_fmu.path)
    with pytest.raises(ParameterError, match=r"substeps must be an integer in \[1, 200\]"):
        build_fmu(SMALL, "foam", tmp_path / "x.fmu", substeps=0)
    with pytest.raises(ParameterError, match="fmi_version must be one of 2.0"):
        build_fmu(SMALL, "foam", tmp_path / "x.fmu", fmi_version="3.0")
    with pytest.raises(ParameterError, match="dt must be"):
        build_fmu(SMALL, "foam", tmp_path / "x.fmu", dt=-1.0)
    assert list(tmp_path.iterdir()) == []                  # nothing written


def test_doStep_refuses_a_partial_sample(plant_fmu, tmp_path):
    from fmpy.fmi2 import FMU2Slave
    md = fmpy.read_model_description(str(plant_fmu.path))
    folder = fmpy.extract(str(plant_fmu.path), unzipdir=str(tmp_path / "u"))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier)
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    with pytest.raises(Exception, match=r"fmi2DoStep failed with status 3"):
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.5 * plant_fmu.dt)
    fmu.freeInstance()
    if sys.platform == "linux":         # only the FMI functions are exported, not CasADi's
        import ctypes
        lib = ctypes.CDLL(str(tmp_path / "u" / plant_fmu.binary))
        assert hasattr(lib, "fmi2DoStep") and not hasattr(lib, "hb_step")


def test_cli_writes_the_fmu_and_refuses_bad_input(tmp_path, plant_fmu):
    params = tmp_path / "p.toml"
    params.write_text("n_axial = 2\nn_transverse = 3\n", encoding="utf-8")
    out = tmp_path / "cli.fmu"
    cmd = [sys.executable, "-m", "hubbeam_ctrl.cli", "fmu", "--params", str(params), "--model", "foam",
           "--out", str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert validate_fmu(str(out)) == []
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert again.returncode == 2 and "--force" in again.stderr and "Traceback" not in again.stderr
    assert len(again.stderr.strip().splitlines()) == 1
    bad = subprocess.run(cmd[:-4] + ["--model", "sfoam", "--out", str(tmp_path / "y.fmu")],
                         capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert not (tmp_path / "y.fmu").exists()
    shutil.rmtree(tmp_path, ignore_errors=True)


def test_failed_compiler_leaves_nothing_and_no_compiler_gives_sources(tmp_path, monkeypatch, plant_fmu):
    monkeypatch.setenv("CC", "false")                       # a compiler that fails
    with pytest.raises(CompileError, match="failed"):
        build_fmu(SMALL, "foam", tmp_path / "failed.fmu")
    assert list(tmp_path.iterdir()) == []
    monkeypatch.setenv("CC", "no-such-compiler-hubbeam")    # none at all: the sources only
    info = build_fmu(SMALL, "foam", tmp_path / "sources.fmu")
    assert info.binary is None
    with zipfile.ZipFile(info.path) as z:
        names = z.namelist()
    assert "sources/hubbeam_fmu.c" in names and not any(n.startswith("binaries/") for n in names)
    assert validate_fmu(str(info.path)) == []


def test_generated_c_controller_and_fmu_in_fmpy_equal_the_toolbox_loop(plant_fmu, tmp_path):
    """Issue 26 item 4: the generated C LQG (hubbeam_ctrl.deploy) reading the FMU's sensors through
    FMPy's FMU2Slave, one doStep per sample, against simulate_closed_loop of the Python LQG on the
    same plant with noise-free sensors: the tip within 1e-6 of its peak, the torque likewise."""

    from controllers import LQG, LQGSettings, slew_reference
    from hubbeam_ctrl.deploy import CController, compile_c, compiler, to_c
    if compiler() is None:
        pytest.skip("the generated controller needs a C compiler")
    dt = plant_fmu.dt
    design = DesignModel.build(SMALL, 0.0, dt, n_modes=2)
    ref_traj = slew_reference(0.3, 2.0, SMALL.total_inertia, 200.0, dt, T_END)
    lqg = LQG(design, LQGSettings(residual_control=True, residual_modes=3), reference=ref_traj)
    ref = _quiet_closed_loop(plant_fmu, lqg)
    code = to_c(lqg, tmp_path / "lqg")
    cctrl = CController(compile_c(code, "-O2", tmp_path), code, lqg)
    err, err_tau = _fmu_loop_errors(plant_fmu, tmp_path / "u", "c_loop", cctrl, ref, "C LQG + FMU in FMPy")
    assert err < 1e-6 and err_tau < 1e-6


def _quiet_closed_loop(plant_fmu, ctrl):
    """simulate_closed_loop of ``ctrl`` on the FMU's plant (FOAM, its substeps) with noise-free sensors."""
    quiet = SensorSettings(angle_noise_rad=0.0, rate_noise_rad_s=0.0, moment_noise_nm=0.0)
    return simulate_closed_loop("foam", ctrl, T_END, params=SMALL, settings=ClosedLoopSettings(
        dt=plant_fmu.dt, substeps=plant_fmu.substeps, sensors=quiet))


def _fmu_loop_errors(plant_fmu, unzip, instance: str, ctrl, ref, label: str) -> tuple:
    """``ctrl`` reading the FMU's sensors through FMPy's FMU2Slave, one doStep per sample: the largest
    tip and torque differences from ``ref``, relative to their peaks (the tip's peak must be > 1 mm)."""
    from fmpy.fmi2 import FMU2Slave
    md = fmpy.read_model_description(str(plant_fmu.path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(plant_fmu.path), unzipdir=str(unzip)),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName=instance)
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    ctrl.reset()
    outputs = [vr["theta"], vr["theta_dot"], vr["root_moment"], vr["v_tip"]]
    v_tip, taus = [], []
    try:
        for k in range(len(ref.t)):
            y = np.array(fmu.getReal(outputs))
            v_tip.append(y[3])
            taus.append(float(ctrl(ref.t[k], y[:3])))
            if k < len(ref.t) - 1:
                fmu.setReal([vr["u"]], [taus[-1]])
                fmu.doStep(currentCommunicationPoint=ref.t[k], communicationStepSize=plant_fmu.dt)
    finally:
        fmu.terminate()
        fmu.freeInstance()
    peak = np.max(np.abs(ref.v_tip))
    err = np.max(np.abs(np.array(v_tip) - ref.v_tip)) / peak
    err_tau = np.max(np.abs(np.array(taus) - ref.tau)) / np.max(np.abs(ref.tau))
    print(f"{label}: max tip difference {err:.2e} of the peak {peak:.4f} m, torque {err_tau:.2e} of its peak")
    assert peak > 1e-3
    return err, err_tau


def test_generated_c_nmpc_through_its_filter_and_fmu_in_fmpy_equal_the_toolbox_loop(plant_fmu, tmp_path,
                                                                                      monkeypatch):
    """Issue 40 item 3: the NMPC's step as generated C (``backend="compiled"``), closed through a Kalman
    filter on the FMU's three sensors read by FMPy's FMU2Slave, one doStep per sample, against
    simulate_closed_loop of the same controller on the same plant with noise-free sensors: the tip
    and the torque within 1e-6 of their peaks. The step is built at -O0 (the same C)."""
    from controllers import NMPC, LQGSettings, NMPCSettings, slew_reference
    from controllers.integral import ObservedFeedback
    monkeypatch.setenv("HUBBEAM_CC_OPT", "-O0")
    dt = plant_fmu.dt
    design = DesignModel.build(SMALL, 0.0, dt, n_modes=2)
    ref_traj = slew_reference(0.3, 2.0, SMALL.total_inertia, 200.0, dt, T_END)
    nmpc = NMPC(design, NMPCSettings(horizon=10, backend="compiled"), reference=ref_traj)
    assert "External" in str(nmpc.step_function) or nmpc.step_function is not nmpc.symbolic_step
    ctrl = ObservedFeedback(nmpc, LQGSettings())
    ref = _quiet_closed_loop(plant_fmu, ctrl)
    err, err_tau = _fmu_loop_errors(plant_fmu, tmp_path / "u", "nmpc_loop", ctrl, ref, "C NMPC + FMU in FMPy")
    assert err < 1e-6 and err_tau < 1e-6
    assert nmpc.stats()["qp_fallbacks"] == 0 and np.max(np.abs(ref.tau)) > 10.0      # a slew, every QP solved

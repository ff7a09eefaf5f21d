"""The registries: a new controller is one class plus one registry entry, and then runs through
``compare`` and ``hubbeam compare`` like the built-ins; scenarios and models feed the CLI."""

import json
from dataclasses import dataclass

import numpy as np
import pytest

from controllers import (
    CONTROLLERS,
    Controller,
    DesignModel,
    MPCSettings,
    OpenLoopSettings,
    PDSettings,
    TrackingSettings,
    controller_names,
    make_controller,
    register_controller,
    unregister_controller,
)
from hubbeam_ctrl import Params
from hubbeam_ctrl.cli.main import main
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import setting
from hubbeam_ctrl.plant.sensors import SensorSettings
from hubbeam_ctrl.sim import ClosedLoopSettings
from hubbeam_ctrl.study import DEFAULT_CONTROLLERS, compare, make_scenario
from hubbeam_ctrl.study.compare_values import compare_arguments
from hubbeam_ctrl.study.scenarios import SCENARIOS, register_scenario

P2 = Params(n_axial=2, n_transverse=2)
#: A 4 s slew with a 50 N m budget, simulated for 9.5 s on 2 + 2 modes.
SHORT = dict(params=P2, tau_max=50.0, t_f=4.0, t_end=9.5)
NOISE_FREE = ClosedLoopSettings(sensors=SensorSettings(0.0, 0.0, 0.0))


# -- a new controller: these two classes and the register_controller call are all it takes ------
@dataclass(frozen=True)
class ToySettings(TrackingSettings):
    """Settings of :class:`ToyPD`."""

    kp: float = setting(300.0, unit="N m/rad", lo=0.0, doc="Angle gain.")
    kd: float = setting(600.0, unit="N m s/rad", lo=0.0, doc="Rate gain.")


class ToyPD(Controller):
    """Constant-gain hub PD on the plant's state: ``sat(tau_ff + kp e_theta + kd e_theta_dot)``."""

    measurement = "state"

    def __call__(self, t, y):
        th, thd, tff = self.reference.at(t)
        s, n = self.settings, len(y) // 2
        tau = s.feedforward * tff + s.kp * (th - y[0]) + s.kd * (thd - y[n])
        return float(np.clip(tau, -s.tau_max, s.tau_max))


@pytest.fixture(scope="module")
def toy():
    register_controller("toy", ToySettings, controller=ToyPD, color="tab:purple", label="toy PD",
                        default=False)
    try:
        yield CONTROLLERS["toy"]
    finally:
        unregister_controller("toy")


@pytest.fixture(scope="module")
def runs(toy):
    """The toy and the built-in PD with the same gains, on noise-free sensors (same loop)."""
    return compare(**compare_arguments("foam", "slew", "pd,toy",
                                       settings={"pd": PDSettings(kp=300.0, kd=600.0, tau_max=50.0)},
                                       sim_settings=NOISE_FREE, **SHORT))


def test_registration_fills_the_registry(toy):
    assert ToyPD.name == "toy"
    assert (toy.controller, toy.settings, toy.color, toy.label, toy.target) == \
        (ToyPD, ToySettings, "tab:purple", "toy PD", False)
    assert "toy" in controller_names() and "toy" not in controller_names(default=True)
    assert controller_names(default=True) == DEFAULT_CONTROLLERS       # the built-ins only
    ctrl = make_controller("toy", DesignModel.build(P2, 0.0, 0.01))
    assert isinstance(ctrl, ToyPD) and ctrl.settings == ToySettings()


def test_toy_runs_through_compare_like_the_builtin_pd(runs):
    """Same gains, same reference, exact hub measurements: the toy's loop is the PD's, bit for bit."""
    pd, toy = runs.results["pd"], runs.results["toy"]
    assert toy.controller == "toy" and not toy.stopped
    assert len(toy.tau) == 951 and np.array_equal(toy.tau, pd.tau)
    assert np.array_equal(toy.v_tip, pd.v_tip)
    assert ToySettings.for_scenario(runs.scenario, horizon=50) == ToySettings(tau_max=50.0)
    assert runs.metrics["toy"]["residual_tip_max_m"] == runs.metrics["pd"]["residual_tip_max_m"]
    assert runs.styles["toy"] == {"color": "tab:purple", "label": "toy PD"}
    assert runs.targets == ()


def test_toy_runs_through_the_cli(runs, tmp_path, capsys):
    out = tmp_path / "cli"
    rc = main(["compare", "--plant", "foam", "--controllers", "toy", "--n-modes", "2", "--tau-max", "50",
               "--tf", "4", "--t-end", "9.5", "--out", str(out), "--json"])
    assert rc == 0
    (m,) = json.loads(capsys.readouterr().out)
    ref = runs.metrics["toy"]                        # the CLI's sensor noise does not reach the toy
    assert m["controller"] == "toy"
    for key in ("residual_tip_max_m", "peak_tip_m", "peak_torque_nm", "final_angle_error_rad"):
        assert m[key] == ref[key], key
    assert (out / "torque.png").stat().st_size > 1000
    with pytest.raises(SystemExit):
        main(["compare", "--help"])
    assert "toy (toy PD)" in capsys.readouterr().out


def test_unregistered_controller_is_gone():
    register_controller("toy2", ToySettings, controller=ToyPD, default=False)
    assert CONTROLLERS["toy2"].label == "toy2"
    unregister_controller("toy2")
    with pytest.raises(ParameterError, match="unknown 'toy2'"):
        compare(**compare_arguments("foam", "slew", "toy2", **SHORT))
    with pytest.raises(ParameterError, match="not registered"):
        unregister_controller("toy2")


@pytest.mark.parametrize("call, match", [
    (lambda: register_controller("Toy", ToySettings, controller=ToyPD), "lower-case"),
    (lambda: register_controller("a,b", ToySettings, controller=ToyPD), "without commas"),
    (lambda: register_controller("toy3", dict, controller=ToyPD), "ControllerSettings"),
    (lambda: register_controller("toy3", ToySettings, controller=object), "Controller subclass"),
    (lambda: register_controller("lqr", ToySettings, controller=ToyPD), "already registered"),
])
def test_bad_registrations_are_refused(call, match):
    with pytest.raises(ParameterError, match=match):
        call()
    assert "toy3" not in CONTROLLERS and CONTROLLERS["lqr"].controller.__name__ == "LQR"


def test_default_settings_come_from_the_settings_classes():
    slew = make_scenario("slew", plant="foam", params=P2, tau_max=150.0, t_f=8.0, t_end=14.0)
    spin = make_scenario("spinup", plant="foam", params=P2, tau_max=150.0, t_f=8.0, t_end=14.0, w_f=2.0)
    assert OpenLoopSettings.for_scenario(slew) == OpenLoopSettings("eq44", 150.0, 8.0)
    assert OpenLoopSettings.for_scenario(spin).profile == "feedforward"
    mpc = MPCSettings.for_scenario(slew, horizon=20, solver="qrqp", unknown_option=1)
    assert (mpc.tau_max, mpc.horizon, mpc.solver) == (150.0, 20, "qrqp")
    # the PD bandwidth scales with the task (controllers.scaling: pd_bandwidth / t_f = 10 / 8 rad/s)
    assert PDSettings.for_scenario(slew, horizon=20) == PDSettings(tau_max=150.0, bandwidth=10.0 / 8.0)


def test_scenario_registry_feeds_make_scenario_and_the_cli(tmp_path, capsys):
    @register_scenario("slew-copy")
    def _copy(**kwargs):
        return SCENARIOS["slew"](**kwargs)

    try:
        sc = make_scenario("slew-copy", plant="foam", **SHORT)
        assert sc.name == "slew-copy" and sc.baseline == "eq44"
        assert sc.target == pytest.approx(50 * 4.0 ** 2 / (2 * np.pi * P2.total_inertia))
        with pytest.raises(SystemExit):
            main(["compare", "--help"])
        assert "slew-copy" in capsys.readouterr().out
    finally:
        SCENARIOS.pop("slew-copy")
    rc = main(["compare", "--plant", "foam", "--scenario", "slew-copy", "--out", str(tmp_path / "x")])
    assert rc == 2 and "slew-copy" in capsys.readouterr().err


def test_cli_model_choices_come_from_model_specs(capsys):
    from hubbeam_ctrl.plant.models import MODEL_SPECS
    with pytest.raises(SystemExit):
        main(["modes", "--help"])
    assert "{" + ",".join(MODEL_SPECS) + "}" in capsys.readouterr().out
    rc = main(["critical-speed", "--model", "cfoam"])
    assert rc == 2 and "--model" in capsys.readouterr().err

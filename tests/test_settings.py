"""Declared settings: every settings dataclass states each field's unit and range in metadata,
and the one validator of hubbeam_ctrl.core.settings enforces them with the caller's names."""

import inspect
import math
from dataclasses import dataclass, fields

import pytest

from controllers import (
    LQGSettings,
    LQRSettings,
    LQSettings,
    MPCSettings,
    OpenLoopSettings,
    PDSettings,
    ShapedSettings,
    Weights,
)
from controllers.estimator import KalmanNoise
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.settings import Settings, range_text, setting
from hubbeam_ctrl.plant.maneuvers import ConstantSpin, SpinUp, TorquePulse
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.plant.sensors import SensorSettings
from hubbeam_ctrl.sim import ClosedLoopSettings, StepperSettings

SETTINGS = [Params, Weights, OpenLoopSettings, PDSettings, LQRSettings, LQGSettings, MPCSettings,
            ShapedSettings, KalmanNoise, StepperSettings, ClosedLoopSettings, SensorSettings, SpinUp, TorquePulse,
            ConstantSpin]


def _bounds_cases():
    """(class, field, bad value) just outside every declared numeric bound."""
    for cls in SETTINGS:
        owner = cls()
        for f in fields(cls):
            m = f.metadata
            if m["kind"] not in (int, float):
                continue
            step = 1 if m["kind"] is int else 1e-3 * max(1.0, abs(getattr(owner, f.name) or 1.0))
            for bound, open_, sign in ((m["lo"], m["lo_open"], -1), (m["hi"], m["hi_open"], +1)):
                if bound is None:
                    continue
                b = getattr(owner, bound) if isinstance(bound, str) else bound
                yield pytest.param(cls, f.name, b if open_ else b + sign * step,
                                   id=f"{cls.__name__}.{f.name}{'<' if sign < 0 else '>'}")


@pytest.mark.parametrize("cls", SETTINGS, ids=lambda c: c.__name__)
def test_every_field_declares_unit_range_and_doc(cls):
    doc = inspect.getdoc(cls)
    assert "Parameters\n----------" in doc
    for f in fields(cls):
        assert {"unit", "doc", "lo", "hi", "kind"} <= set(f.metadata), f.name
        assert f.metadata["doc"], f.name
        assert f"\n{f.name} : " in doc, f.name
        if f.metadata["kind"] is float and f.metadata["unit"] not in ("-", ""):
            entry = " ".join(doc.split(f"\n{f.name} : ")[1].split())
            assert f"[{f.metadata['unit']}" in entry, f.name


@pytest.mark.parametrize("cls, name, value", list(_bounds_cases()))
def test_declared_bounds_are_enforced_naming_the_field(cls, name, value):
    prefix = getattr(cls, "_setting_prefix", "")
    with pytest.raises(ParameterError, match=rf"^{prefix}{name} must be"):
        cls(**{name: value})


def test_messages_name_the_argument_as_written():
    with pytest.raises(ParameterError) as info:
        TorquePulse(tau_m=-1)
    assert str(info.value) == "tau_m must be in (0, 1e+09] [N m], got -1"
    with pytest.raises(ParameterError, match=r"^t_f must be in \[0.001, 1e\+06\] \[s\], got 0"):
        SpinUp(3.0, 0.0)
    with pytest.raises(ParameterError, match=r"^spin must be finite \[rad/s\], got nan"):
        ConstantSpin(math.nan)
    with pytest.raises(ParameterError, match=r"^horizon must be an integer in 1\.\.5000 \[samples\], got 2.5"):
        MPCSettings(horizon=2.5)
    with pytest.raises(ParameterError, match=r"^solver must be one of 'daqp', "):
        MPCSettings(solver="cplex")
    with pytest.raises(ParameterError, match=r"^feedforward must be True or False, got 'yes'"):
        LQRSettings(feedforward="yes")
    with pytest.raises(ParameterError, match=r"^weights must be a Weights, got dict"):
        LQRSettings(weights={})
    with pytest.raises(ParameterError, match=r"^weights\.modal must be >= 0"):
        Weights(modal=-1.0)
    with pytest.raises(ParameterError, match=r"^sensors must be a SensorSettings"):
        ClosedLoopSettings(sensors=None)
    with pytest.raises(ParameterError, match=r"^l must be in \[0, L\] = \[0, 4\] \[m\], got 5"):
        Params(L=4.0, l=5.0)


def test_values_are_normalised():
    p = Params(n_axial=3.0, L=8, damping_ratio=0)
    assert type(p.n_axial) is int and type(p.L) is float and type(p.damping_ratio) is float
    assert p == Params(n_axial=3)
    assert StepperSettings(substeps=4.0).substeps == 4
    assert PDSettings(kp=None).kp is None and PDSettings(kp=2).kp == 2.0


def test_shared_fields_are_declared_once():
    """LQR, LQG and MPC share tau_max, feedforward, weights, elastic_reference and the residual
    modes (issue 27); LQG adds the
    Kalman filter's noise model, whose sensor noise defaults are the sensors' own."""
    base = {f.name: f for f in fields(LQSettings)}
    assert set(base) == {"tau_max", "feedforward", "weights", "elastic_reference", "residual_control",
                         "residual_modes"}
    for cls in (LQRSettings, LQGSettings, MPCSettings):
        own = {f.name: f for f in fields(cls)}
        assert all(own[name] is field for name, field in base.items()), cls.__name__
    sensors, lqg = SensorSettings(), LQGSettings()
    assert (lqg.angle_noise_rad, lqg.rate_noise_rad_s, lqg.moment_noise_nm) == \
        (sensors.angle_noise_rad, sensors.rate_noise_rad_s, sensors.moment_noise_nm)
    assert isinstance(lqg, KalmanNoise)


def test_closed_loop_settings_extend_the_stepper_settings():
    cl = ClosedLoopSettings(dt=0.02, substeps=3, rho_inf=0.8, newton_tol=1e-7)
    assert cl.stepper == StepperSettings(dt=0.02, substeps=3, rho_inf=0.8, newton_tol=1e-7)
    assert type(cl.stepper) is StepperSettings


def test_a_field_without_setting_is_a_programming_error():
    @dataclass(frozen=True)
    class Loose(Settings):
        gain: float = 1.0

    with pytest.raises(TypeError, match="Loose.gain is not declared with setting"):
        Loose()


def test_range_text_and_generated_doc():
    @dataclass(frozen=True)
    class Box(Settings):
        """A box.

        Examples
        --------
        >>> Box().width
        1.0
        """

        width: float = setting(1.0, unit="m", lo=0.0, lo_open=True, hi=10.0, doc="Width.")
        count: int = setting(2, lo=1, hi=9, doc="Count.")
        ratio: float = setting(0.5, lo=0.0, hi=1.0, hi_open=True, doc="Ratio.")

    meta = {f.name: f.metadata for f in fields(Box)}
    assert [range_text(meta[n]) for n in ("width", "count", "ratio")] == ["in (0, 10]", "in 1..9", "in [0, 1)"]
    doc = inspect.getdoc(Box)
    assert doc.index("Parameters") < doc.index("Examples")
    assert "width : float, default 1.0\n    Width. [m, in (0, 10]]" in doc
    assert Box.units() == {"width": "m", "count": "-", "ratio": "-"}
    assert Box(count=3).replace(ratio=0.25).to_dict() == {"width": 1.0, "count": 3, "ratio": 0.25}
    with pytest.raises(ParameterError, match=r"^count must be an integer in 1\.\.9, got 10"):
        Box().replace(count=10)

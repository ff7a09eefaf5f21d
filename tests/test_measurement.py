"""The rig's measurement chain: bias, seeded noise, anti-alias filter, encoder, chosen signals
(issue 21, Build 5)."""

import numpy as np
import pytest

from hubbeam_ctrl import Params, build_model
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import Drive, Friction, Rig, Sensors, rig_from_dict
from hubbeam_ctrl.sim import ClosedLoopSettings, simulate_closed_loop
from hubbeam_ctrl.sim.hardware import Hardware
from hubbeam_ctrl.sim.measurement import AntiAliasFilter, MeasurementChain

P = Params(n_axial=1, n_transverse=2)


def test_anti_alias_filter_is_exact_on_a_ramp_and_has_the_first_order_response():
    """y_f' = w_c (y - y_f): on a ramp from rest y_f = t - (1 - e^(-w_c t)) / w_c exactly; a sine
    of frequency f comes out with gain 1 / sqrt(1 + (f / f_c)^2) and phase -atan(f / f_c)."""
    fc, dt = 20.0, 1e-3
    wc = 2 * np.pi * fc
    t = dt * np.arange(200)
    filt = AntiAliasFilter(fc, dt)
    out = np.array([filt(np.array([x]))[0] for x in t])
    assert out == pytest.approx(t - (1 - np.exp(-wc * t)) / wc, abs=1e-15)
    f = 10.0
    filt = AntiAliasFilter(fc, dt)
    t = dt * np.arange(3000)
    out = np.array([filt(np.array([np.sin(2 * np.pi * f * x)]))[0] for x in t])
    gain, phase = 1 / np.sqrt(1 + (f / fc) ** 2), -np.arctan(f / fc)
    late = t > 1.0                                  # the start's transient decays as e^(-w_c t)
    want = gain * np.sin(2 * np.pi * f * t[late] + phase)
    # the straight line between samples errs by O((w dt)^2): measured 2.9e-4, (w dt)^2 / 8 = 4.9e-4
    assert np.max(np.abs(out[late] - want)) < (2 * np.pi * f * dt) ** 2 / 8
    with pytest.raises(ParameterError, match=r"^sensors.anti_alias_hz must be in \(0, 1e\+06\] \[Hz\], got -5"):
        Sensors(anti_alias_hz=-5.0)


def test_chain_adds_bias_and_seeded_noise_per_sensor_and_counts_the_encoder():
    model = build_model("foam", P)
    s = Sensors(encoder_counts=4096, strain_gauges=(0.0, 4.0), tip_accelerometer=True, angle_bias=0.01,
                rate_noise=0.02, rate_bias=-0.1, strain_noise=0.5, strain_bias=2.0, accel_noise=0.3, accel_bias=1.0)
    n_samples = 4000
    chain = MeasurementChain(s, model, 0.01, n_samples, seed=7)
    assert chain.names == ("theta", "theta_dot", "moment_1", "moment_2", "accel_radial", "accel_tangential")
    state = np.zeros(3 * model.n_q)
    state[0] = 0.3
    exact = chain.exact(state)
    y = np.array([chain.measure(k, state) for k in range(n_samples)])
    step = 2 * np.pi / 4096
    assert np.all(y[:, 0] == step * round((0.3 + 0.01) / step))    # bias, then the count
    err = y[:, 1:] - exact[1:]
    std = np.array([0.02, 0.5, 0.5, 0.3, 0.3])
    assert np.all(np.abs(np.mean(err, axis=0) - [-0.1, 2.0, 2.0, 1.0, 1.0]) < 4 * std / np.sqrt(n_samples))
    assert np.std(err, axis=0) == pytest.approx(std, rel=0.05)
    assert abs(np.corrcoef(err[:, 1], err[:, 2])[0, 1]) < 0.06          # independent per sensor
    again = MeasurementChain(s, model, 0.01, n_samples, seed=7)
    assert np.array_equal(again.measure(5, state), y[5])                 # seeded
    assert not np.array_equal(MeasurementChain(s, model, 0.01, n_samples, seed=8).measure(5, state), y[5])


def test_chain_filters_each_analog_signal_as_the_filter_and_not_the_encoder_count():
    """The compiled chain's filter is AntiAliasFilter's update, per analog channel; with an encoder the
    angle is counted, unfiltered."""
    model = build_model("foam", P)
    n = model.n_q
    t = 0.002 * np.arange(50)
    states = np.zeros((50, 3 * n))
    states[:, 0], states[:, n], states[:, 2] = 0.4 * t ** 2, 0.8 * t, 1e-3 * np.sin(40 * t)
    for counts in (0, 2048):
        s = Sensors(encoder_counts=counts, strain_gauges=(1.0,), anti_alias_hz=25.0, rate_bias=0.1)
        chain = MeasurementChain(s, model, 0.002, 50)
        got = np.array([chain.measure(k, x) for k, x in enumerate(states)])
        raw = np.array([chain.exact(x) + [0.0, 0.1, 0.0] for x in states])
        ref = AntiAliasFilter(25.0, 0.002)
        want = np.array([ref(y) for y in raw])
        first = 1 if counts else 0
        assert np.allclose(got[:, first:], want[:, first:], rtol=1e-12, atol=1e-15)
        if counts:
            assert np.array_equal(got[:, 0], 2 * np.pi / counts * np.floor(raw[:, 0] / (2 * np.pi / counts) + 0.5))
        assert np.max(np.abs(got[:, 1] - raw[:, 1])) > 1e-3                    # the filter lags


class Reader:
    """A controller that records what it reads and turns the hub with a fixed torque."""

    name, dt, n_modes = "reader", 0.01, 2

    def __init__(self, measurement="sensors", signals=None):
        self.measurement = measurement
        if signals is not None:
            self.signals = signals

    def reset(self):
        self.seen = []

    def __call__(self, t, y):
        self.seen.append(np.array(y))
        return 20.0 if t < 0.3 else -20.0


def test_controller_reads_the_signals_it_names_and_an_ideal_rig_is_the_beam_alone():
    settings = ClosedLoopSettings(dt=0.01, substeps=4)
    rig = rig_from_dict({"beam": P.to_dict(), "sensors": {"strain_gauges": [0.0, 2.0], "tip_accelerometer": True}})
    ctrl = Reader(signals=("accel_tangential", "moment_2", "theta"))
    res = simulate_closed_loop("foam", ctrl, 0.5, params=P, settings=settings, hardware=Hardware.from_rig(rig))
    seen = np.array(ctrl.seen)
    assert res.settings["rig_sensors"]["read"] == ["accel_tangential", "moment_2", "theta"]
    assert np.array_equal(seen[:, 2], res.q[:, 0])                      # ideal sensors: exact
    model = build_model("foam", P)
    chain = MeasurementChain(rig.sensors, model, 0.01, 1)
    mid = chain.exact(np.r_[res.q[20], res.v[20], np.zeros(model.n_q)])
    assert seen[20, 1] == pytest.approx(mid[3], rel=1e-12)              # moment at 2 m
    # the tangential tip acceleration at t = 0 is the hub's alpha (r + L) under the torque before t = 0 (none)
    assert seen[0, 0] == 0.0 and abs(seen[1, 0]) > 0
    with pytest.raises(ParameterError, match=r"reads 'moment_3' \(sensors.strain_gauges\), which the rig does "
                                             r"not have; its sensors give theta, theta_dot"):
        simulate_closed_loop("foam", Reader(signals=("moment_3",)), 0.1, params=P, settings=settings,
                             hardware=Hardware.from_rig(rig))
    # the invariant: a rig with ideal hardware is the beam alone, bit for bit, for either measurement
    for kind in ("sensors", "state"):
        runs = [simulate_closed_loop("foam", Reader(kind), 0.5, params=P, settings=settings, hardware=hw)
                for hw in (None, Hardware.from_rig(Rig(beam=P)))]
        assert np.array_equal(runs[0].q, runs[1].q) and np.array_equal(runs[0].tau, runs[1].tau)


def test_state_feedback_gets_the_measured_hub_angle_and_rate():
    s = Sensors(angle_bias=0.02, rate_bias=0.5, encoder_counts=1024)
    ctrl = Reader("state")
    res = simulate_closed_loop("foam", ctrl, 0.3, params=P, settings=ClosedLoopSettings(dt=0.01, substeps=4),
                               hardware=Hardware(Drive(), Friction(), sensors=s))
    seen = np.array(ctrl.seen)
    step = 2 * np.pi / 1024
    assert np.allclose(seen[:, 0], step * np.round((res.q[:, 0] + 0.02) / step), rtol=0, atol=1e-15)
    assert np.array_equal(seen[:, 3], res.v[:, 0] + 0.5)
    assert np.array_equal(seen[:, 1:3], res.q[:, 2:4]) and np.array_equal(seen[:, 4:], res.v[:, 2:4])


@pytest.mark.parametrize("tables, message", [
    ({"beam": {"L": 0.381}, "sensors": {"strain_gauges": [0.0, 0.5]}},
     r"sensors.strain_gauges\[1\] must be in \[0, L\] = \[0, 0.381\] \[m\] \(on the beam\), got 0.5"),
    ({"sensors": {"anti_alias_hz": -5}}, r"sensors.anti_alias_hz must be in \(0, 1e\+06\] \[Hz\], got -5"),
    ({"timing": {"delay": 1.5}}, r"timing.delay must be in \[0, 1\], got 1.5"),
])
def test_bad_sensors_and_timing_in_a_rig_file_are_one_line_naming_the_key(tables, message):
    with pytest.raises(ParameterError, match=rf"^rig file rig.toml: {message}$"):
        rig_from_dict(tables, path="rig.toml")


def test_state_feedback_reads_the_filtered_rate_and_the_unfiltered_count():
    step = 2 * np.pi / 1024
    s = Sensors(rate_bias=0.5, encoder_counts=1024, anti_alias_hz=15.0)
    ctrl = Reader("state")
    res = simulate_closed_loop("foam", ctrl, 0.3, params=P, settings=ClosedLoopSettings(dt=0.01, substeps=4),
                               hardware=Hardware(Drive(), Friction(), sensors=s))
    seen = np.array(ctrl.seen)
    ref = AntiAliasFilter(15.0, 0.01)
    assert np.allclose(seen[:, 3], [ref(np.array([v]))[0] for v in res.v[:, 0] + 0.5], rtol=1e-12, atol=1e-15)
    assert np.allclose(seen[:, 0], step * np.round(res.q[:, 0] / step), rtol=0, atol=1e-15)

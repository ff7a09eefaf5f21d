"""The rig's hardware against the ideal plant, in the same run (issue 21, Speed). Prints one JSON object.

Run: ``.venv/bin/python benchmarks/bench_rig.py [--repeats 3] [--t-end 5] [--backend compiled] [--out F.json]``.

The plant is the ``servo_link`` preset's beam (FOAM, 5 + 5 modes, its hub inertia), sampled
at its 1 ms, with the integration step of the substep rule. The same LQR (designed on 2
modes) slews the hub by 90 degrees from rest, its torque sent through
``Hardware.voltage_for_torque`` (the identity for the ideal drive) so that the controller side
is the same code in every variant. Measured, median over ``--repeats`` runs, warm cache:

1. ``closed_loop``: :func:`simulate_closed_loop` CPU time per sample [us] (a ``--t-end`` run less
   a 0.1 s one: the loop without the set-up) with no hardware
   (the ideal torque source), the DC motor alone, the DC motor with its armature inductance
   (the current a state), friction alone, the rig's sensors (encoder, two strain gauges, the tip
   accelerometer, noise on each, a 200 Hz anti-alias filter), half a sample of computation delay,
   the preset's drive and friction (``drive_friction``), the ``servo_link`` preset as it ships
   (``rig``: DC motor, friction, 4096-count encoder, root gauge, half a sample of delay) and all
   of the above at once (``everything``), and each one's ratio to the ideal plant (the issue's
   target: at most 1.3).
2. ``plant_step``: :meth:`PlantStepper.step` alone per sample [us CPU] on each variant's own command
   sequence from 1., and the ratios.
3. ``measurement_chain``: :meth:`MeasurementChain.measure` alone per sample [us CPU], reading the hub
   angle and rate (what the state-feedback LQR of 1. reads) and every signal of the sensors (the
   accelerometer's kinematics included).

The variants run interleaved, ``--repeats`` rounds; the headline numbers are the fastest round
of each (the least disturbed by other processes), the ``_median`` ones beside them.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time

import numpy as np
from benchjson import emit

from controllers import LQR, DesignModel
from hubbeam_ctrl import build_model
from hubbeam_ctrl.plant.modal import modal_analysis
from hubbeam_ctrl.plant.rig import Drive, Friction, Sensors, Timing, load_rig
from hubbeam_ctrl.sim import ClosedLoopSettings, simulate_closed_loop, substep_rule
from hubbeam_ctrl.sim.hardware import Hardware
from hubbeam_ctrl.sim.measurement import MeasurementChain
from hubbeam_ctrl.sim.stepper import PlantStepper, StepperSettings


class _Commanded:
    """The LQR with its torque turned into the drive's command (volts for the DC motor)."""

    def __init__(self, lqr, hardware: Hardware, m: int):
        self.lqr, self.hw, self.m = lqr, hardware, m
        self.name, self.measurement, self.dt, self.n_modes = "lqr", "state", lqr.dt, m

    def reset(self):
        self.lqr.reset()

    def __call__(self, t, y):
        return float(self.hw.voltage_for_torque(self.lqr(t, y), y[1 + self.m]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--t-end", type=float, default=5.0)
    ap.add_argument("--backend", default="compiled")
    ap.add_argument("--out")
    a = ap.parse_args(argv)
    rig = load_rig("servo_link")
    P = rig.plant_params.replace(n_axial=5, n_transverse=5, damping_ratio=0.034)
    dt = rig.timing.dt
    model = build_model("foam", P)
    rule = substep_rule(modal_analysis(model, 0.0, "free").bending_hz, dt)
    design = DesignModel.build(P.replace(n_transverse=2), 0.0, dt)
    x0 = np.zeros(2 * model.n_q)
    x0[0] = np.pi / 2
    inductive = Drive(**{**rig.drive.to_dict(), "L": 1.8e-4})       # the SRV02's 0.18 mH
    sensors = Sensors(encoder_counts=4096, strain_gauges=(0.0, 0.19), tip_accelerometer=True, rate_noise=1e-3,
                      strain_noise=1e-3, accel_noise=0.01, anti_alias_hz=200.0)
    delay = Timing(dt=dt, delay=0.5)
    variants = {"ideal": Hardware(Drive(), Friction()),
                "dc_motor": Hardware(rig.drive, Friction()),
                "inductance": Hardware(inductive, Friction()),
                "friction": Hardware(Drive(), rig.friction),
                "sensors": Hardware(Drive(), Friction(), sensors=sensors),
                "delay": Hardware(Drive(), Friction(), timing=delay),
                "drive_friction": Hardware(rig.drive, rig.friction),
                "rig": Hardware.from_rig(rig),
                "everything": Hardware(inductive, rig.friction, sensors, delay)}
    settings = ClosedLoopSettings(dt=dt, substeps=rule.substeps)
    closed, closed_median, plant, plant_median, info, results = {}, {}, {}, {}, {}, {}
    for name, hw in variants.items():       # first pass: compile and warm up
        simulate_closed_loop(model, _Commanded(LQR(design), hw, 2), 0.1, settings=settings, x0=x0,
                             hardware=hw, backend=a.backend)
    times = {name: [] for name in variants}
    for _ in range(a.repeats):                  # interleaved, so a change of load hits every variant
        for name, hw in variants.items():
            cpu = []
            for t_end in (a.t_end, 0.1):         # the difference: the loop's CPU time without the set-up
                start = time.process_time()
                res = simulate_closed_loop(model, _Commanded(LQR(design), hw, 2), t_end, settings=settings, x0=x0,
                                           hardware=hw, backend=a.backend)
                cpu.append(time.process_time() - start)
                if t_end == a.t_end:
                    results[name] = res
            times[name].append((cpu[0] - cpu[1]) / round((a.t_end - 0.1) / dt))
    for name, res in results.items():
        closed[name] = 1e6 * min(times[name])
        closed_median[name] = 1e6 * statistics.median(times[name])
        info[name] = {"final_angle_rad": float(res.q[-1, 0]), "peak_command": float(np.max(np.abs(res.tau))),
                      "plant_fallbacks": res.stats["plant_fallbacks"],
                      "jacobian_updates": res.stats["jacobian_updates"], "backend": res.settings["backend"],
                      "stick_events": res.settings.get("hardware", {}).get("stick_events", 0)}
    steppers = {name: PlantStepper(model, StepperSettings(dt=dt, substeps=rule.substeps), a.backend, hardware=hw)
                for name, hw in variants.items()}
    times = {name: [] for name in variants}
    for _ in range(a.repeats):
        for name, stepper in steppers.items():
            u = results[name].tau[:-1]           # each variant's own command sequence
            s = stepper.initial_state(x0, u[0])
            start = time.process_time()
            for v in u:
                s = stepper.step(s, v)
            times[name].append((time.process_time() - start) / len(u))
    for name in variants:
        plant[name] = 1e6 * min(times[name])
        plant_median[name] = 1e6 * statistics.median(times[name])
    # the measurement chain alone, per sample: what a state feedback reads (angle, rate) and every signal
    chain_us = {}
    for label, read in (("angle_and_rate", ("theta", "theta_dot")), ("all_signals", None)):
        chain = MeasurementChain(sensors, model, dt, 5000, read=read, backend=a.backend)
        s = PlantStepper(model, StepperSettings(dt=dt, substeps=rule.substeps)).initial_state(x0, 0.1)
        best = []
        for _ in range(a.repeats):
            chain.reset()
            start = time.process_time()
            for k in range(5000):
                chain.measure(k, s)
            best.append((time.process_time() - start) / 5000)
        chain_us[label] = 1e6 * min(best)
    ratio = {k: closed[k] / closed["ideal"] for k in closed}
    out = {
        "machine": {"python": sys.version.split()[0], "platform": platform.platform(),
                    "load_avg": os.getloadavg() if hasattr(os, "getloadavg") else None},
        "plant": {"model": "foam", "n_axial": 5, "n_transverse": 5, "dt_s": dt, "substeps": rule.substeps,
                  "t_end_s": a.t_end, "repeats": a.repeats, "backend": a.backend},
        "closed_loop_us_per_sample": closed, "closed_loop_ratio": ratio,
        "closed_loop_us_per_sample_median": closed_median,
        "closed_loop_ratio_median": {k: closed_median[k] / closed_median["ideal"] for k in closed},
        "measurement_chain_us_per_sample": chain_us,
        "plant_step_us": plant, "plant_step_ratio": {k: plant[k] / plant["ideal"] for k in plant},
        "plant_step_ratio_median": {k: plant_median[k] / plant_median["ideal"] for k in plant},
        "runs": info,
        "targets": {"closed_loop_ratio_max": 1.3, "met": all(r <= 1.3 for r in ratio.values())},
    }
    emit(out, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The plant FMU against the toolbox's own fixed-step run, in the same run (issue 26). Prints one JSON object.

Run: ``.venv/bin/python benchmarks/bench_fmu.py [--model foam] [--n-modes 5] [--rig servo_link]
[--t-end 10] [--repeats 3] [--out benchmarks/results/bench_fmu_DATE.json]``.

The plant is Table 1's beam (or ``--rig``'s, with its drive and friction) with ``--n-modes``
axial and transverse modes, sampled at the rig's ``dt`` (0.01 s for Table 1) with the substep
rule's step, driven by the Eq. 44 pulse (200 N m, 10 s; for a DC-motor rig a 3 V sine of 0.5 s)
held over each sample. Measured, best of ``--repeats`` (median beside it), wall time per
sample [us]:

1. ``toolbox``: :func:`simulate_fixed_step` on the compiled backend (the named alternative);
2. ``fmu_one_step``: the FMU through FMPy's ``FMU2Slave``, one ``doStep`` of one sample each,
   with ``setReal``/``getReal`` per sample (what a Python co-simulation master pays);
3. ``fmu_simulate``: ``fmpy.simulate_fmu`` with the input table (FMPy's own loop and recorder);
4. ``fmu_c_only``: one ``doStep`` over the whole run at zero input after the pulse: the C
   integrator alone, no Python per sample (the horizon ``--t-end``).

Also: the largest difference of the tip deflection between FMU and toolbox relative to the
peak (``max_rel_tip_difference``), and the FMU's build time and size.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from benchjson import emit

from hubbeam_ctrl.fmu import build_fmu
from hubbeam_ctrl.plant.maneuvers import TorquePulse
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.plant.rig import load_rig
from hubbeam_ctrl.sim.hardware import Hardware
from hubbeam_ctrl.sim.stepper import StepperSettings, simulate_fixed_step


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="foam", choices=["foam", "cfoam"])
    ap.add_argument("--n-modes", type=int, default=5)
    ap.add_argument("--rig", default=None)
    ap.add_argument("--t-end", type=float, default=10.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out")
    a = ap.parse_args(argv)
    import fmpy
    from fmpy.fmi2 import FMU2Slave

    if a.rig:
        rig = load_rig(a.rig)
        rig = dataclasses.replace(rig, beam=rig.beam.replace(n_axial=a.n_modes, n_transverse=a.n_modes))
        source, params = rig, rig.plant_params
        hw = Hardware.from_rig(rig)
        hardware = None if hw.is_ideal else hw
    else:
        rig, hardware = None, None
        params = Params(n_axial=a.n_modes, n_transverse=a.n_modes)
        source = params
    if hardware is not None and hardware.command == "voltage":
        def signal(t):
            t = np.asarray(t, dtype=float)
            return np.where(t <= 0.5, 3.0 * np.sin(2 * np.pi * t / 0.5), 0.0 * t)
    else:
        signal = TorquePulse(200.0, 10.0)
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        info = build_fmu(source, a.model, Path(tmp) / "plant.fmu")
        build_s = time.perf_counter() - start
        size = info.path.stat().st_size
        dt, k = info.dt, info.substeps
        n = int(round(a.t_end / dt))
        tg = dt * np.arange(n + 1)
        u = np.asarray(signal(tg), dtype=float) * np.ones_like(tg)

        def zoh(t):
            return signal(dt * np.maximum(np.floor(np.asarray(t, dtype=float) / dt - 0.5 / k), 0))

        settings = StepperSettings(dt=dt, substeps=k)
        table = np.array(list(zip(tg, u)), dtype=[("time", float), ("u", float)])
        md = fmpy.read_model_description(str(info.path))
        vr = {v.name: v.valueReference for v in md.modelVariables}
        folder = fmpy.extract(str(info.path), unzipdir=str(Path(tmp) / "unzipped"))

        def slave():
            fmu = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier)
            fmu.instantiate()
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
            fmu.exitInitializationMode()
            return fmu

        def run_toolbox():
            return simulate_fixed_step(a.model, zoh, a.t_end, params=params, settings=settings, backend="compiled",
                                       hardware=hardware).v_tip

        def run_slave():
            fmu = slave()
            out = np.empty(n + 1)
            out[0] = fmu.getReal([vr["v_tip"]])[0]
            for i in range(n):
                fmu.setReal([vr["u"]], [u[i]])
                fmu.doStep(currentCommunicationPoint=tg[i], communicationStepSize=dt)
                out[i + 1] = fmu.getReal([vr["v_tip"]])[0]
            fmu.terminate()
            fmu.freeInstance()
            return out

        def run_simulate():
            return fmpy.simulate_fmu(str(info.path), stop_time=a.t_end, output_interval=dt, input=table,
                                     output=["v_tip"])["v_tip"]

        def run_c_only():
            fmu = slave()
            fmu.setReal([vr["u"]], [0.0])
            fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=n * dt)
            fmu.terminate()
            fmu.freeInstance()

        variants = {"toolbox": run_toolbox, "fmu_one_step": run_slave, "fmu_simulate": run_simulate,
                    "fmu_c_only": run_c_only}
        outputs = {name: f() for name, f in variants.items()}      # warm-up (compiles the toolbox's step)
        times = {name: [] for name in variants}
        for _ in range(a.repeats):
            for name, f in variants.items():
                start = time.perf_counter()
                f()
                times[name].append((time.perf_counter() - start) / n)
        ref = outputs["toolbox"]
        peak = float(np.max(np.abs(ref)))
        diff = {name: float(np.max(np.abs(outputs[name] - ref)) / peak) for name in ("fmu_one_step", "fmu_simulate")}
    best = {name: 1e6 * min(t) for name, t in times.items()}
    out = {
        "machine": {"python": sys.version.split()[0], "platform": platform.platform(),
                    "load_avg": os.getloadavg() if hasattr(os, "getloadavg") else None},
        "plant": {"model": a.model, "n_axial": a.n_modes, "n_transverse": a.n_modes, "rig": a.rig,
                  "command": info.command, "dt_s": dt, "substeps": k, "t_end_s": a.t_end, "repeats": a.repeats},
        "us_per_sample": best,
        "us_per_sample_median": {name: 1e6 * statistics.median(t) for name, t in times.items()},
        "ratio_to_toolbox": {name: best[name] / best["toolbox"] for name in best},
        "max_rel_tip_difference": diff, "peak_tip_m": peak,
        "fmu_build_s": build_s, "fmu_bytes": size,
    }
    emit(out, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

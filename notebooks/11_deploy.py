# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # 11 · Take the design to the hardware: the controller as C, run in the loop
#
# `hubbeam_ctrl.deploy.to_c` writes a designed controller as portable C99: one header and one
# source, an instance struct that holds all the state, `init`, `reset` and `step`; no dynamic
# memory, no I/O, only `math.h`. This notebook generates an LQG, compiles it with the system C
# compiler under `-std=c99 -Wall -Wextra -pedantic -Werror`, loads it with `ctypes` and runs it
# as the controller of the closed-loop simulator on the evaluation plant, next to the Python
# LQG it came from. The two torques must agree to rounding. See docs/deploy.md.
#
# A small beam model keeps it quick: one design mode at 20 Hz (the evaluation plant then has
# five modes).

# %%
# %matplotlib inline
import tempfile
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from controllers import LQG, DesignModel, LQGSettings, slew_reference
from hubbeam_ctrl import Params
from hubbeam_ctrl.deploy import NO_COMPILER, CController, compile_c, compiler, to_c
from hubbeam_ctrl.sim import simulate_closed_loop
from hubbeam_ctrl.sim.closedloop import ClosedLoopSettings

T0 = time.perf_counter()
plt.rcParams.update({"figure.figsize": (9, 3.4), "axes.grid": True})
OUT = Path(tempfile.mkdtemp(prefix="hubbeam_deploy_"))   # change to keep the files
DT = 0.05
p = Params(n_axial=1, n_transverse=1)
design = DesignModel.build(p, 0.0, DT)
ref = slew_reference(0.5, 8.0, p.total_inertia, 200.0, DT, 16.0)
lqg = LQG(design, LQGSettings(residual_control=True), reference=ref)
print("filter states:", lqg.filter_model.n_x, "| torque limit:", lqg.tau_max, "N m")

# %% [markdown]
# ## Generate
#
# The folder is written atomically: built beside `OUT / "lqg"` and renamed into place. The
# JSON file says which sensors, in which units, the step reads.

# %%
code = to_c(lqg, OUT / "lqg")
print(sorted(f.name for f in code.folder.iterdir()))
print(code.header[:900])
print(code.metadata()["measurements"], code.data_bytes, "bytes of gains and tables")

# %% [markdown]
# ## Compile and run in the loop
#
# Without a C compiler the sources are still written; the software-in-the-loop part needs one.

# %%
settings = ClosedLoopSettings(dt=DT)
py = simulate_closed_loop("foam", lqg, 16.0, settings=settings)
if compiler() is None:
    print(NO_COMPILER)
    c = None
else:
    lib = compile_c(code, "-O2", OUT)
    c = simulate_closed_loop("foam", CController(lib, code, lqg), 16.0, settings=settings)
    err = np.max(np.abs(c.tau - py.tau)) / lqg.tau_max
    print(f"largest |tau_C - tau_Python| / tau_max = {err:.2e}")
    assert err < 1e-9

# %%
fig, ax = plt.subplots(1, 2)
ax[0].plot(py.t, py.tau, label="Python LQG")
if c is not None:
    ax[0].plot(c.t, c.tau, "--", label="generated C")
    ax[1].semilogy(c.t, np.abs(c.tau - py.tau) + 1e-18)
ax[0].set(xlabel="t [s]", ylabel="tau [N m]")
ax[0].legend()
ax[1].set(xlabel="t [s]", ylabel="|tau_C - tau_Python| [N m]")
fig.tight_layout()

# %% [markdown]
# ## The plant as an FMU, the controller as C, and an independent client in between
#
# `hubbeam fmu` (`hubbeam_ctrl.fmu.build_fmu`) writes the nonlinear evaluation plant as an FMI 2.0
# co-simulation FMU: CasADi's generated C of the closed loop's own plant step, no Python at run
# time. FMPy (not the toolbox) steps it one sample at a time while the generated C LQG reads its
# sensors and sets its torque. The loop must equal the toolbox's own closed loop (noise-free
# sensors here: an FMU is deterministic). See docs/fmu.md.

# %%
from hubbeam_ctrl.plant.sensors import SensorSettings  # noqa: E402

try:
    import fmpy
    from fmpy.fmi2 import FMU2Slave

    from hubbeam_ctrl.fmu import build_fmu
except ImportError:
    fmpy = None
if fmpy is None or c is None:
    print("the FMU part needs FMPy (pip install 'hubbeam-ctrl[fmu]') and a C compiler")
else:
    quiet = ClosedLoopSettings(dt=DT, sensors=SensorSettings(angle_noise_rad=0.0, rate_noise_rad_s=0.0,
                                                            moment_noise_nm=0.0))
    toolbox = simulate_closed_loop("foam", lqg, 16.0, settings=quiet)
    info = build_fmu(toolbox.params, "foam", OUT / "plant.fmu", dt=DT, substeps=toolbox.settings["substeps"])
    md = fmpy.read_model_description(str(info.path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(info.path), unzipdir=str(OUT / "fmu")),
                    modelIdentifier=md.coSimulation.modelIdentifier)
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    cc = CController(lib, code, lqg)
    cc.reset()
    tip = []
    for k, t in enumerate(toolbox.t):
        y = fmu.getReal([vr["theta"], vr["theta_dot"], vr["root_moment"], vr["v_tip"]])
        tip.append(y[3])
        u = cc(t, y[:3])
        if k < len(toolbox.t) - 1:
            fmu.setReal([vr["u"]], [u])
            fmu.doStep(currentCommunicationPoint=t, communicationStepSize=DT)
    fmu.terminate()
    fmu.freeInstance()
    err = np.max(np.abs(np.array(tip) - toolbox.v_tip)) / np.max(np.abs(toolbox.v_tip))
    print(f"{info.path.name}: {info.n_q} coordinates, {info.substeps} substeps per sample; C LQG + FMU in FMPy "
          f"vs the toolbox's loop: largest tip difference {err:.1e} of the peak")
    assert err < 1e-6

# %%
print(f"notebook ran in {time.perf_counter() - T0:.1f} s")

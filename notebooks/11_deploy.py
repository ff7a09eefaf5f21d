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
# ## The plant as an FMU
#
# The nonlinear plant as an FMI co-simulation unit lives in `hubbeam fmu` (issue 26, items 3
# and 4, added separately); a closed loop of this generated controller and that FMU, driven by
# FMPy, belongs here once it is there.

# %%
print(f"notebook ran in {time.perf_counter() - T0:.1f} s")

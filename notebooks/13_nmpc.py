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
# # 13 · Nonlinear MPC at the physical limit, learning the payload, as C
#
# The time-optimal slew (`hubbeam optimal`) is the physical limit: the shortest time in which
# the torque budget can turn the hub and leave the beam at rest. Linear designs track a plan
# about one spin rate; the **NMPC** (`controllers.nmpc.NMPC`, registered as `nmpc`) predicts
# with FOAM itself (the stiffening with the hub rate and the tip mass's coupling included), one
# real-time iteration per sample: the shooting map's Jacobians, a condensed QP and DAQP's dual
# active-set solver, all in **one CasADi function** whose generated C is the same step.
#
# 1. the limit and the NMPC at 1.1 T* on the paper's beam (Table 1), 90 degrees (the LQR and the linear MPC
#    beside it: docs/limit.md, `benchmarks/bench_nmpc.py`);
# 2. a payload the design does not know, learnt by the NMPC from the hub's momentum during the
#    slew (the 1 m lab arm designed for 0.1 kg carries 0.2 kg);
# 3. the step as C.

# %%
# %matplotlib inline
import math
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from controllers import NMPCSettings
from controllers.scaling import first_mode
from hubbeam_ctrl import Params
from hubbeam_ctrl.deploy.nmpc_c import nmpc_to_c
from hubbeam_ctrl.limit import time_optimal_slew
from hubbeam_ctrl.study import Slew, compare
from hubbeam_ctrl.study.compare_values import CompareSettings, DesignChoice, PlantChoice, RunChoice
from hubbeam_ctrl.study.scenarios import make_scenario

# %% [markdown]
# ## 1. The limit, and the NMPC at 1.1 T*
#
# Table 1's beam turns 90 degrees in 1.1 times its time-optimal slew T*. The NMPC tracks the
# beam's minimum-vibration slew in that time, planned on the nonlinear model
# (`reference="optimal"`): a slew this close to the limit bends the beam far enough that a plan
# on the linear design model is not a motion of the real beam (docs/limit.md).

# %%
paper = Params()
limit = time_optimal_slew(paper, math.pi / 2)
print(f"T* = {limit.duration_s:.3f} s for 90 degrees within {paper.tau_max:g} N m")
task = Slew(math.pi / 2, 1.1 * limit.duration_s)
fast = compare(paper, task, ["nmpc"], CompareSettings(design=DesignChoice(reference="optimal"),
                                                      run=RunChoice(t_end=12.0)))   # 12 s: the slew and 3 periods
period = 2 * math.pi / first_mode(fast.controllers["nmpc"].design)
for name in ("nmpc",):
    m = fast.metrics[name]
    print(f"{name:5s} {m['verdict']:12s} settled {(m['settling_time_s'] - task.duration) / period:.2f} first-mode "
          f"periods after t_f, residual {m['residual_pct_of_L']:.3f} % of L, peak {m['peak_torque_nm']:.0f} N m")
steps = np.asarray(fast.controllers["nmpc"].step_times_s)
print(f"NMPC step: median {1e3 * np.median(steps):.1f} ms, 99th percentile {1e3 * np.percentile(steps, 99):.1f} ms "
      f"of the {1e3 * fast.scenario.dt:g} ms sample (CasADi's virtual machine, this machine)")

# %%
fig, ax = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
r = fast.results["nmpc"]
ax[0].plot(r.t, 1e3 * np.asarray(r.v_tip), label="NMPC")
ax[1].plot(r.t, r.tau, label="NMPC")
ax[0].set_ylabel("tip deflection [mm]")
ax[1].set_ylabel("hub torque [N m]")
ax[1].set_xlabel("time [s]")
ax[0].axvline(task.duration, color="k", lw=0.5)
ax[0].legend()
ax[0].set_title(f"Table 1, 90 degrees in 1.1 T* = {task.duration:.2f} s")

# %% [markdown]
# ## 2. A payload the design does not know
#
# The lab arm is designed for 0.1 kg and carries 0.2 kg. With `learn_payload` the NMPC fits the
# payload every sample to the hub's momentum balance (the torque's impulse against the momentum
# of the measured state, exact whatever modes the prediction leaves out), predicts with that
# payload's model and follows the task planned again for it. The same NMPC without learning is
# the baseline.

# %%
lab = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.1, tau_max=1.5)
heavy = lab.replace(m_t=0.2)
slew = Slew(math.pi / 2, 1.5 * time_optimal_slew(heavy, math.pi / 2).duration_s)
own = NMPCSettings.for_scenario(make_scenario(slew, params=lab, t_end=None))
runs = {}
for label, settings in (("nominal", own), ("learning", own.replace(learn_payload=True, payload_max_kg=0.2))):
    c = compare(lab, slew, ["nmpc"], CompareSettings(plant=PlantChoice(plant_params=heavy),
                                                     design=DesignChoice(settings={"nmpc": settings})))
    runs[label] = c
    m = c.metrics["nmpc"]
    settle = "-" if m["settling_time_s"] is None else f"{m['settling_time_s']:.2f} s"
    print(f"{label:9s} {m['verdict']:12s} settled {settle} (t_f {slew.duration:.2f} s), "
          f"residual {m['residual_pct_of_L']:.4f} % of L")
learner = runs["learning"].controllers["nmpc"]
print(f"payload learnt: {learner.payload.mass:.4f} kg (truth 0.2 kg); torque lag {1e3 * learner.payload.lag_s:.3f} ms")

# %%
fig, ax = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
dt = runs["learning"].scenario.dt
ax[0].plot(dt * np.arange(len(learner.payload.history)), learner.payload.history)
ax[0].axhline(0.2, color="k", lw=0.5, ls="--")
ax[0].set_ylabel("payload estimate [kg]")
for label, c in runs.items():
    r = c.results["nmpc"]
    ax[1].plot(r.t, 1e3 * np.asarray(r.v_tip), label=label)
ax[1].set_ylabel("tip deflection [mm]")
ax[1].set_xlabel("time [s]")
ax[1].set_xlim(0, 3 * slew.duration)
ax[1].legend()

# %% [markdown]
# ## 3. The step as C
#
# `nmpc_to_c` writes the step's generated C (the QP solver inside, no CasADi at run time), its
# header and a JSON of sizes, weights and limits. `NMPCSettings(backend="compiled")` runs the
# Python NMPC on that same C; `tests/test_nmpc_codegen.py` checks a whole slew with it against
# the virtual machine's.

# %%
out = Path(tempfile.mkdtemp())
info = nmpc_to_c(learner, out, name="arm_nmpc")
print(sorted(p.name for p in out.iterdir()))
print({k: info[k] for k in ("horizon", "dt_s", "tau_max_nm", "inputs")})

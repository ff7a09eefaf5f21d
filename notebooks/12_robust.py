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
# # 12 · Robust by certificate: from what you do not know to a certified controller in C
#
# A controller designed for the nominal rig is tested, by the comparison, on the nominal rig.
# The payload you will carry, the stiffness the datasheet rounds, the damping nobody measured:
# each moves the beam's modes, and a loop that decays at the nominal point can grow elsewhere.
# This notebook states what is not known as an **uncertainty set**, asks the **robust
# certificate** (`hubbeam_ctrl.study.worst_case`) for the worst plant of the set, lets the
# **design search** (`hubbeam_ctrl.study.robust_design`) find a design the certificate accepts,
# checks it by nonlinear runs at the worst plant and the corners of the set, and writes it as C
# with the verdict in its header. The command line does the same: `hubbeam certify lqg
# --design robust --uncertainty m_t=0:0.5,damping=0.0005:0.0005 --c-out DIR --out DIR`.
#
# The beam is the paper's (Table 1) with its default slew; the payload at the tip is anywhere
# between 0 and 0.5 kg (nominal 0.1 kg), and the structure has at least 0.05 % damping in
# every mode.

# %%
# %matplotlib inline
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from hubbeam_ctrl import Params
from hubbeam_ctrl.deploy import compiler, to_c
from hubbeam_ctrl.plant.rig import Rig, rig_to_toml
from hubbeam_ctrl.plant.uncertainty import Uncertainty
from hubbeam_ctrl.study.certificate import loop_matrix
from hubbeam_ctrl.study.compare import compare
from hubbeam_ctrl.study.robust_check import check_points, residual_score, run_at
from hubbeam_ctrl.study.robust_design import design_for_set

# %% [markdown]
# ## 1. The set, as a value and as the rig file's `[uncertainty]` table

# %%
payload = Uncertainty.from_table({"m_t": (0.0, 0.5), "damping": (0.0005, 0.0005)})
rig = Rig(beam=Params(), uncertainty=payload)
print(rig_to_toml(rig).split("[uncertainty]")[1])

# %% [markdown]
# ## 2. The nominal LQG, certified over the set
#
# `compare` designs the LQG for the nominal rig and, because the rig carries an uncertainty
# table, certifies it over the set: the sampled loop as it runs, on the evaluation plant's
# linear model at every point the search visits.

# %%
cmp = compare(rig, "slew", ["openloop", "lqg"])
nominal = cmp.robust["lqg"]
print(nominal.describe())

# %% [markdown]
# The certificate names the plant where the loop grows. A nonlinear run there agrees:

# %%
bare = rig.replace(uncertainty=Uncertainty())
at_worst = run_at(cmp, "lqg", bare, nominal.worst.values, payload)
print(f"nominal LQG at {nominal.worst.values}: {at_worst['verdict']}")

# %% [markdown]
# ## 3. A design the certificate accepts
#
# The search changes the design's own choices (the design point, the modes the gain and the
# filter act on, the filter's trust in its model, the weights) and keeps the candidate with
# the best worst-case residual among those the certificate accepts.

# %%
robust = design_for_set(cmp, "lqg", bare, payload, score=residual_score(cmp, bare, payload))
print(f"chosen: {robust.label()}")
print(robust.certificate.describe())
for label, radius, score in robust.tried[:8]:
    print(f"  {label:60s} worst radius {radius:.6f}")

# %% [markdown]
# The worst spectral radius over the payload range, nominal design against the robust one
# (a dense scan of the linear loop, the search's own function): the robust design stays
# inside the unit circle at every payload.

# %%
masses = np.linspace(0.0, 0.5, 26)
radius = {}
for label, ctrl in (("nominal LQG", cmp.controllers["lqg"]), ("robust LQG", robust.controller)):
    radius[label] = [np.max(np.abs(np.linalg.eigvals(
        loop_matrix(ctrl, cmp.plant.params.replace(m_t=float(m)), 0.0, 0.0005)[0]))) for m in masses]
fig, ax = plt.subplots(figsize=(7, 3.5))
for label, r in radius.items():
    ax.plot(masses, r, marker="o", ms=3, label=label)
ax.axhline(1.0, color="k", lw=0.8)
ax.set_xlabel("tip payload m_t [kg]")
ax.set_ylabel("spectral radius of the sampled loop [-]")
ax.legend()
ax.grid(alpha=0.3)
plt.show()

# %% [markdown]
# ## 4. Checked on the nonlinear plant: the worst plant, the corners, the centre

# %%
for kind, values in check_points(payload, robust.certificate.worst.values):
    m = run_at(cmp, robust.controller, bare, values, payload)
    print(f"{kind:7s} m_t = {values['m_t']:.3g} kg: {m['verdict']:9s} residual {m['residual_pct_of_openloop']:.3g} % "
          f"of that plant's open loop, peak torque {m['peak_torque_nm']:.1f} N m")

# %% [markdown]
# ## 5. The certified controller as C, with its certificate
#
# The verdict, the worst radius and the worst plant open the header and travel in the
# metadata (`lqg.json`), so whoever flashes the code sees what it was certified for.

# %%
with tempfile.TemporaryDirectory() as tmp:
    code = to_c(robust.controller, Path(tmp) / "c", certificate=robust.certificate.metrics())
    print("\n".join(code.header.splitlines()[:3]))
    print("C compiler:", compiler() or "none (the code is still written)")

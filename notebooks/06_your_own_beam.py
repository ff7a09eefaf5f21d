# %% [markdown]
# # 06 · Your own beam: from a TOML file to an exported controller
#
# The toolbox's defaults come from the beam and the task, not from the paper's 8 m boom. This
# notebook takes a small lab arm (a 1 m x 30 mm x 3 mm aluminium strip on a light hub, driven
# by a 1.5 N m motor) from a parameter file to a tuned controller saved as a state-space system:
#
# 1. the beam in a TOML file, its modes;
# 2. the task in physical terms (90 degrees in 1.2 s) and whether the motor can do it;
# 3. the scaled defaults (Bryson weights, noise levels, settling bands, reference shaping);
# 4. LQR, LQG and MPC in closed loop on the nonlinear FOAM plant;
# 5. loop margins at the plant input;
# 6. a payload range;
# 7. export, and a check with python-control.

# %%
import math
import tempfile
from pathlib import Path

import control
import matplotlib.pyplot as plt
import numpy as np

from controllers import CONTROLLERS, DesignModel, make_controller
from controllers.analysis import closed_loop_poles, loop_margins
from controllers.export import load_controller, save_controller
from hubbeam_ctrl import linearize, load_params
from hubbeam_ctrl.linear.export import load_model, save_model
from hubbeam_ctrl.linear.transforms import discretize
from hubbeam_ctrl.plant.modal import modal_analysis
from hubbeam_ctrl.study import Slew, compare, format_table, make_scenario, payload_comparison, payload_table
from hubbeam_ctrl.study.compare_values import CompareSettings, PayloadChoice, RunChoice

# %% [markdown]
# ## 1. The beam, from a TOML file
# Every field of `Params` can be given in SI units; the motor's torque limit `tau_max` is one of
# them. Three transverse modes are plenty for this short notebook.

# %%
OUT = Path(tempfile.mkdtemp(prefix="hubbeam_own_beam_"))   # change to keep the files
print("writing to", OUT)
(OUT / "arm.toml").write_text("""# lab arm: 1 m x 30 mm x 3 mm aluminium strip
L = 1.0          # [m]
rho = 2700.0     # [kg/m^3]
A = 9e-5         # [m^2]
E = 69e9         # [Pa]
I = 6.75e-11     # [m^4]
J_h = 0.02       # [kg m^2]
r = 0.05         # [m]
m_t = 0.05       # [kg]
tau_max = 1.5    # [N m], the motor
n_axial = 2
n_transverse = 3
""")
p = load_params(OUT / "arm.toml")
modes = modal_analysis("sfoam", 0.0, "free", p)
print(f"J_total = {p.total_inertia:.4f} kg m^2 (hub share {p.J_h / p.total_inertia:.2f})")
print("bending modes, hub free [Hz]:", np.round(modes.bending_hz, 2))

# %% [markdown]
# ## 2. The task in physical terms
# A slew is an angle and a duration. The open-loop baseline is the paper's Eq. 44 torque scaled
# to them, `tau_m = 2 pi J_total Theta / t_f^2`; a duration that needs more torque than the motor
# has is refused with the shortest feasible one.

# %%
task = Slew(angle=math.pi / 2, duration=1.2)
J = p.total_inertia
print(f"Eq. 44 amplitude {task.baseline_torque(J):.3f} N m of {p.tau_max} N m; "
      f"shortest feasible duration {task.shortest_duration(J, p.tau_max):.3f} s")
try:
    make_scenario(Slew(math.pi / 2, 0.9), plant="foam", params=p, t_end=4.0)
except ValueError as exc:
    print("refused:", exc)

# %% [markdown]
# ## 3. Defaults that scale
# The scenario reads the task's scales (angle, time, L, first mode, torque, signal ranges) and
# turns dimensionless tolerances into settings: Bryson's weights, sensor and filter noise,
# settling bands, the residual window and the reference's smoothing.

# %%
sc = make_scenario(task, plant="foam", params=p, t_end=5.0)
print(sc.scales)
print("weights:", sc.defaults["weights"])
print("sensor noise:", {k: f"{v:.3g}" for k, v in sc.sensors.items()})
print("bands:", {k: f"{v:.3g}" for k, v in sc.bands.items()})
print("reference:", sc.reference.description)

# %% [markdown]
# ## 4. Closed loop on the nonlinear plant
# All defaults; the table gives the residual vibration as a share of the open loop's.

# %%
cmp = compare(p, task, "openloop,lqr,lqg,mpc", CompareSettings(run=RunChoice(t_end=5.0)))
print(format_table(cmp.metrics))
fig, ax = plt.subplots(figsize=(7, 3))
for name, res in cmp.results.items():
    ax.plot(res.t, 1e3 * res.v_tip, label=name)
ax.set(xlabel="t [s]", ylabel="tip deflection [mm]")
ax.legend()
plt.show()

# %% [markdown]
# ## 5. Margins at the plant input
# Each linear controller is a python-control system (`ctrl.to_statespace()`); the loop broken at
# the hub torque gives the disk margin (checked against `control.disk_margins`), the classical
# gain and phase margins and the delay margin.

# %%
design = DesignModel.build(p, 0.0, sc.dt)
ctrls = {n: make_controller(n, design, CONTROLLERS[n].settings.for_scenario(sc), sc.reference)
         for n in ("lqr", "lqg")}
for name, c in ctrls.items():
    m = loop_margins(c, check=True)      # check: python-control's disk margin on the same grid too
    print(f"{name}: disk margin {m.disk_margin:.3f} (python-control {m.disk_margin_control:.3f}), "
          f"gain margins {m.gain_margin_lower:.2f}/{m.gain_margin_upper:.2f}, phase margin "
          f"{m.phase_margin_deg:.1f} deg, delay margin {1e3 * m.delay_margin_s:.1f} ms")

# %% [markdown]
# ## 6. A payload range
# LQR, LQG and MPC can be designed for a range of tip payloads: candidate designs (design
# payload, deflections weighted or only their rates, LQG's multi-model Kalman filter) are checked
# on linear models and measured on the nonlinear plant at the ends of the range and the nominal
# payload; the best one's design payload is refined by bisection (docs/controllers.md). The
# report runs the nonlinear plant at those payloads.

# %%
pc = payload_comparison(p, task, "openloop,lqr",
                        CompareSettings(run=RunChoice(t_end=5.0), payload=PayloadChoice(payload_range=(0.0, 0.1))))
print(payload_table(pc))

# %% [markdown]
# ## 7. Export, and a check with python-control
# The controller is saved like the plant models (`.mat`, `.npz`, `.json`: `Ac, Bc, Cc, Dc`, the
# sample time, signal names and units). Closed by signal name with the exported plant model, the
# LQG has the poles of its design.

# %%
lqg = ctrls["lqg"]
save_controller(lqg, OUT / "lqg.mat")
plant = linearize("sfoam", 0.0, p, outputs="theta,theta_dot,root_moment,tip_deflection")
save_model(discretize(plant, sc.dt), OUT / "plant.mat")
P, K = load_model(OUT / "plant.mat").sys, load_controller(OUT / "lqg.mat").sys
closed = control.interconnect([P, K], inplist=["tau"], inputs=["d"], outlist=["tip_deflection"],
                              outputs=["tip_deflection"], check_unused=False)
design_poles = closed_loop_poles(lqg)
gap = max(np.min(np.abs(design_poles - z)) for z in closed.poles())
print(f"{K.nstates} controller states, inputs {K.input_labels}; closed-loop poles match the design to {gap:.1e}")

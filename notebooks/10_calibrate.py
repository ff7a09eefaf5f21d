# %% [markdown]
# # 10 · Calibrate the model to your rig
#
# A real beam is not its data sheet: the stiffness, the hub inertia (gearbox included), the
# payload, the damping and the friction have to be measured. This notebook goes from an
# excitation to a calibrated rig and a design on it:
#
# 1. an excitation within the drive's limits and the tip and hub limits we choose;
# 2. the "measured" records (here made by the toolbox's own FOAM plant with the servo's
#    hardware from a rig whose values we pretend not to know, with all the bending modes a
#    real link shows, encoder quantisation and strain-gauge noise, written to CSV files as a
#    rig's logger would; on hardware they come from the rig);
# 3. the first modes from a free-oscillation test (ERA);
# 4. the fit of five rig fields from the raw files with every default (the fitted plant's modes from
#    the band the records excite, the start from their frequency responses), with intervals,
#    correlations and the fit on a validation record, and the calibrated rig file;
# 5. an LQR designed on the calibrated rig.
#
# The same steps on the command line: `hubbeam excite` and `hubbeam identify` (docs/calibration.md).

# %%
import control
import matplotlib.pyplot as plt
import numpy as np

from hubbeam_ctrl import linearize
from hubbeam_ctrl.calibrate import (
    ModelSettings,
    clamped_modes,
    excitation,
    fit_rig,
    identify_modes,
    load_record,
    save_record,
    synthetic_record,
    validate_record,
)
from hubbeam_ctrl.plant.rig import load_rig, save_rig
from hubbeam_ctrl.plots import plot_record_fit

# %% [markdown]
# ## 1. The rig as we think it is, and the excitation
# The servo link preset with a 20 g payload; damping and Coulomb friction are guesses.

# %%
base = load_rig("servo_link")
guess = base.replace(beam=base.beam.replace(m_t=0.02), damping=base.damping.replace(ratios=(0.005,)),
                     friction=base.friction.replace(coulomb=0.0), sensors=base.sensors.replace(strain_noise=1e-3))
print("guessed clamped modes [Hz]:", np.round(clamped_modes(guess)[0], 3))
chirp_in = excitation(guess, "chirp", 6.0, max_tip_deflection=0.02, max_hub_travel=1.0)
step_in = excitation(guess, "step", 3.0, max_tip_deflection=0.02, max_hub_travel=1.0)
peak_tip = np.max(np.abs(chirp_in.columns["v_tip"]))
print(f"chirp: peak {np.max(np.abs(chirp_in.input)):.3g} V, predicted tip {peak_tip:.3g} m")

# %% [markdown]
# ## 2. The measured records
# The "true" rig differs from the guess as in issue 25: E -7 %, J_h +10 %, payload +30 %,
# damping 0.02 instead of 0.005, Coulomb friction 10 mN m. Its records come from FOAM with six
# bending modes (a real link has them all: the fit is not told how many), and are written to
# CSV files: from here on only the files are used.

# %%
b = guess.beam
truth = guess.replace(beam=b.replace(E=0.93 * b.E, J_h=1.10 * b.J_h, m_t=1.30 * b.m_t),
                      damping=guess.damping.replace(ratios=(0.02,)), friction=guess.friction.replace(coulomb=10e-3))
real_link = ModelSettings(n_transverse=6)
for name, inp, seed in (("chirp", chirp_in.input, 1), ("step", step_in.input, 2),
                        ("reversed_chirp", 0.7 * chirp_in.input[::-1], 3)):
    t_in = step_in.t if name == "step" else chirp_in.t
    save_record(synthetic_record(truth, t_in, inp, seed=seed, source=name, settings=real_link), f"{name}.csv")
chirp, step, check = (load_record(f"{name}.csv") for name in ("chirp", "step", "reversed_chirp"))
print("raw record columns:", list(chirp.columns))

# %% [markdown]
# ## 3. Modes from a free-oscillation test
# The link plucked with the hub held (a high breakaway friction holds it): the free decay of
# the root strain gauge, identified by ERA, against the true rig's clamped modes.

# %%
held = truth.replace(friction=truth.friction.replace(breakaway=1.0))
t = np.arange(3001) * 1e-3
pluck = synthetic_record(held, t, np.r_[1e-3, np.zeros(3000)], q2_0=[0.01, 0.002], source="pluck",
                         settings=ModelSettings(n_transverse=4, frequency_tolerance=5e-3))
est = identify_modes(pluck, band_hz=(0.5, 40.0))
f_true, z_true = clamped_modes(truth)
for k in range(2):
    print(f"mode {k + 1}: {est.frequency_hz[k]:.4f} +- {est.frequency_std_hz[k]:.4f} Hz (true {f_true[k]:.4f}), "
          f"damping {est.damping[k]:.4f} +- {est.damping_std[k]:.4f} (true {z_true[k]:.4f})")

# %% [markdown]
# ## 4. The fit
# Least squares of the simulated encoder and strain gauge against the measured ones, on the
# nonlinear FOAM plant with the DC motor and friction. Nothing is chosen by hand: the plant's
# modes come from the band the records excite (the summary's "plant" line says which modes
# they can identify), the start from their frequency responses; "converged" means the fit
# reaches the records' noise ceiling.

# %%
res = fit_rig(guess, [chirp, step], "E,J_h,m_t,damping,friction", progress=False)
print(res.summary())
true_values = [truth.beam.E, truth.beam.J_h, truth.beam.m_t, 0.02, 10e-3]
for name, e, v in zip(res.names, res.estimate, true_values):
    print(f"{name:>9}: error {100 * (e / v - 1):+.2f} %")

# %%
# the reversed chirp at 70 % is small: on the strain gauge its noise (1 mN m) sets the ceiling of the fit
fits, y = validate_record(res.rig, check, settings=res.model)
print("validation fit [%]:", {k: round(v, 2) for k, v in fits.items()})
fig = plot_record_fit(check.t, {k: check.columns[k] for k in y}, y, fits, title="validation record")
plt.show()
if res.converged:                        # hubbeam identify writes it only then (or with --force)
    save_rig(res.rig, "servo_link_calibrated.toml")
    print("wrote servo_link_calibrated.toml")

# %% [markdown]
# ## 5. A design on the calibrated rig
# An LQR on the linear SFOAM model of the calibrated beam (hub torque input), its closed-loop poles
# against those of the same design on the guessed beam.

# %%
for name, rig in (("guess", guess), ("calibrated", res.rig)):
    lm = linearize("sfoam", 0.0, rig.plant_params.replace(n_transverse=2), outputs="theta")
    A, B = lm.sys.A, lm.sys.B
    Q = np.diag([100.0] + [0.0] * (A.shape[0] - 1))
    Q[A.shape[0] // 2, A.shape[0] // 2] = 1.0
    K, _, poles = control.lqr(A, B, Q, np.eye(1))
    slow = poles[np.argsort(np.abs(poles))][:2]
    print(f"{name:>10}: slowest closed-loop poles {np.round(slow, 2)}")

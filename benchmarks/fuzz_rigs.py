"""Random plausible rigs in the rig schema, for finding defaults that fail on rigs nobody tuned them for.

Two kinds, each drawn from published ranges of its class:

* ``link``: lab and industrial links, 0.3-3 m of steel, aluminium or CFRP strip (rectangular
  sections 20-60 mm wide), a hub of 0.2-5 times the beam's inertia, a payload up to 60 % of the
  beam's mass, a torque source or a geared DC motor (12-48 V, 0.5-5 Ohm) sized for a quarter turn in
  0.3-3 s, encoders of 1024-40 000 counts, a root gauge and/or a tip accelerometer, no tachometer
  on 30 %, 1-5 ms, up to a sample of delay (Quanser's rotary flexible link, Feliu's arms and the
  presets of hubbeam_ctrl/data/rigs are in these ranges);
* ``space``: slow booms, 3-20 m CFRP or aluminium tubes on a 0.5-20 times heavier body, a 30 degree
  slew in 20-300 s on a reaction wheel, a star tracker of 5-100 urad and a gyro with a drifting bias,
  10-50 Hz (the space_boom preset's class).

Session 22 (``link`` seeds 31-33) and session 24 (``link`` 34-35, ``space`` 1-2) found with these the
rigs of tests/test_random_rig_findings.py and tests/test_fuzzed_rigs.py.

Run: ``.venv/bin/python benchmarks/fuzz_rigs.py KIND SEED N OUT`` writes ``OUT/rig_<i>.toml``; then
``hubbeam compare --rig OUT/rig_<i>.toml --no-ladder`` (``--slew-angle 0.5236`` for ``space``).
"""

from __future__ import annotations

import math
import os
import random
import sys

MATERIALS = {"steel": (200e9, 7850), "alu": (69e9, 2700), "cfrp": (120e9, 1600)}


def link_rig(rng: random.Random, title: str) -> list:
    """The TOML lines of one random link."""
    mat = rng.choice(list(MATERIALS))
    E, rho = MATERIALS[mat]
    L = math.exp(rng.uniform(math.log(0.3), math.log(3.0)))
    w = rng.uniform(0.02, 0.06)
    h = rng.uniform(0.001, 0.006) * max(1.0, L / 1.0) ** 0.5
    A, I = w * h, w * h ** 3 / 12
    mb = rho * A * L
    Jb = mb * L ** 2 / 3
    J_h = Jb * math.exp(rng.uniform(math.log(0.2), math.log(5)))
    m_t = mb * rng.choice([0, rng.uniform(0.05, 0.6)])
    Jt = J_h + Jb + m_t * L ** 2
    T = math.exp(rng.uniform(math.log(0.3), math.log(3.0)))     # a quarter turn, rigid bang-bang in T
    tau = 4 * (math.pi / 2) * Jt / T ** 2
    dc = rng.random() < 0.5
    dt = rng.choice([1e-3, 1e-3, 2e-3, 5e-3])
    delay = rng.choice([0.0, 0.0, 0.5, 1.0])
    lines = [f"# {title}: {mat} L={L:.3f} T={T:.2f}", "[beam]", f"L = {L:.4g}", f"rho = {rho}", f"A = {A:.5g}",
             f"E = {E:.4g}", f"I = {I:.5g}", f"J_h = {J_h:.5g}", "r = 0.0", f"m_t = {m_t:.4g}"]
    if dc:
        kt, R, V = rng.uniform(0.01, 0.1), rng.uniform(0.5, 5), rng.choice([12.0, 24.0, 48.0])
        N = max(1.0, round(tau / (0.7 * V / R * kt), 1))
        Imax = rng.uniform(0.5, 1.5) * V / R
        lines += ["[motor]", 'kind = "dc_motor"', f"R = {R:.4g}", "L = 0.0", f"k_t = {kt:.4g}", f"k_e = {kt:.4g}",
                  f"N = {N}", "eta_forward = 0.9", "eta_backward = 0.9", f"J_r = {rng.uniform(0, 1e-5):.3g}",
                  f"V_max = {V}", f"I_max = {Imax:.4g}"]
        fr = N * kt * min(V / R, Imax) * 0.9
    else:
        lines += [f"tau_max = {tau:.5g}"]
        fr = tau
    if rng.random() < 0.5:
        lines += ["[friction]", f"viscous = {rng.uniform(0, 0.02) * fr:.4g}",
                  f"coulomb = {rng.uniform(0, 0.08) * fr:.4g}"]
    lines += ["[damping]", f"ratios = [{rng.uniform(0.002, 0.02):.4g}]"]
    sens = rng.choice(["gauge", "accel", "both"])
    lines += ["[sensors]", f"encoder_counts = {rng.choice([1024, 2000, 4096, 10000, 40000])}",
              f"strain_gauges = {'[0.0]' if sens != 'accel' else '[]'}"]
    if sens != "gauge":
        lines += ["tip_accelerometer = true", "accel_noise = 0.01"]
    if rng.random() < 0.3:
        lines += ["rate = false"]
    return lines + ["[timing]", f"dt = {dt}", f"delay = {delay}"]


def space_rig(rng: random.Random, title: str) -> list:
    """The TOML lines of one random slow boom."""
    E, rho = rng.choice([MATERIALS["cfrp"], MATERIALS["alu"]])
    L = math.exp(rng.uniform(math.log(3.0), math.log(20.0)))
    D, t = rng.uniform(0.02, 0.08), rng.uniform(0.0005, 0.002)
    A, I = math.pi * D * t, math.pi * D ** 3 * t / 8
    mb = rho * A * L
    Jb = mb * L ** 2 / 3
    J_h = Jb * math.exp(rng.uniform(math.log(0.5), math.log(20)))
    m_t = rng.choice([0.0, rng.uniform(0.1, 2.0)])
    r = rng.uniform(0.0, 1.0)
    Jt = J_h + Jb + m_t * (r + L) ** 2
    T = math.exp(rng.uniform(math.log(20), math.log(300)))      # 30 degrees, rigid bang-bang in T
    tau = 4 * (math.pi / 6) * Jt / T ** 2
    dt = rng.choice([0.05, 0.1, 0.2])
    return [f"# {title}: L={L:.2f} T={T:.1f}", "[beam]", f"L = {L:.4g}", f"rho = {rho}", f"A = {A:.5g}",
            f"E = {E:.4g}", f"I = {I:.5g}", f"J_h = {J_h:.5g}", f"r = {r:.3g}", f"m_t = {m_t:.4g}",
            f"tau_max = {tau:.4g}", "[damping]", f"ratios = [{rng.uniform(0.001, 0.01):.4g}]",
            "[sensors]", f"angle_noise = {rng.uniform(5e-6, 1e-4):.3g}", f"rate_noise = {rng.uniform(2e-6, 5e-5):.3g}",
            f"rate_bias = {rng.uniform(0, 5e-6):.3g}", f"rate_bias_walk = {rng.uniform(0, 5e-7):.3g}",
            "strain_gauges = " + rng.choice(["[]", "[0.0]"]),
            "[timing]", f"dt = {dt}", f"delay = {rng.choice([0.0, 0.5, 1.0])}"]


def main(argv=None) -> None:
    kind, seed, n, out = (argv or sys.argv[1:])[:4]
    make = {"link": link_rig, "space": space_rig}[kind]
    rng = random.Random(int(seed))
    os.makedirs(out, exist_ok=True)
    for i in range(int(n)):
        lines = make(rng, f"{kind} fuzz seed {seed} rig {i}")
        with open(os.path.join(out, f"rig_{i}.toml"), "w", encoding="utf-8") as fh:
            fh.write("\n".join(lines) + "\n")
    print(out)


if __name__ == "__main__":
    main()

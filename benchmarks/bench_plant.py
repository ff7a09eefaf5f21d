"""Plant benchmark: wall time and accuracy of a 30 s torque-driven run (issue 2, item 9).

Case: Eq. 44 torque, tau_m = 200 N m, t_f = 10 s, m_t = 0.1 kg, 5 + 5 modes, 30 s, output
every 10 ms. For CFOAM and FOAM it times

* ``toolbox``: :func:`hubbeam_ctrl.sim.simulate` (implicit form, IDAS, BDF order <= 2);
* ``direct``: the named alternative, the Lagrangian differentiated symbolically with CasADi,
  the mass matrix solved symbolically (``casadi.solve`` on SX), the explicit ODE handed to
  CasADi's CVODES over the output grid (default settings, rtol = atol = 1e-8). It is run on
  a shorter horizon (``--direct-horizon``, default 5 s) and scaled linearly to 30 s;

and measures accuracy as ``max |v_tip - v_ref| / max |v_ref|`` against a tight run of the
same model (IDAS rtol = atol = 1e-11, BDF order 5). Prints one JSON object.

Run: ``.venv/bin/python benchmarks/bench_plant.py [--direct-horizon S]``.
"""

from __future__ import annotations

import argparse
import json
import time

import casadi as ca
import numpy as np

from hubbeam_ctrl import Params, TorquePulse, build_model, simulate

T_END, DT = 30.0, 0.01
PULSE = TorquePulse(200.0, 10.0)


def direct_formulation(model, horizon: float) -> float:
    """Seconds for the direct symbolic formulation over ``horizon`` (build + integrate)."""
    n = model.n_q
    x = ca.SX.sym("x", 2 * n)
    t = ca.SX.sym("t")
    q, v = x[:n], x[n:]
    start = time.perf_counter()
    M = model.mass_matrix_function(q)
    rhs = -model.bias_function(q, v)
    rhs[0] += PULSE(t)
    acc = ca.solve(M, rhs)                       # symbolic solve of the 11 x 11 system
    grid = np.arange(DT, horizon + DT / 2, DT)
    F = ca.integrator("direct", "cvodes", {"x": x, "t": t, "ode": ca.vertcat(v, acc)}, 0.0, grid,
                      {"abstol": 1e-8, "reltol": 1e-8, "max_num_steps": 100000})
    F(x0=np.zeros(2 * n))
    return time.perf_counter() - start


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--direct-horizon", type=float, default=30.0,
                        help="horizon of the direct formulation [s], scaled to 30 s")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    params = Params()
    report = {"case": "Eq. 44, tau_m = 200 N m, t_f = 10 s, m_t = 0.1 kg, 5+5 modes, 30 s",
              "targets_s": {"cfoam": 1.0, "foam": 0.5}, "tolerance_rel": 1e-3}
    for name in ("cfoam", "foam"):
        model = build_model(name, params)
        simulate(model, PULSE, 1.0)                               # warm-up (function setup)
        walls, res = [], None
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            res = simulate(model, PULSE, T_END)
            walls.append(time.perf_counter() - t0)
        ref = simulate(model, PULSE, T_END, rtol=1e-11, atol=1e-11, max_order=5)
        err = float(np.max(np.abs(res.v_tip - ref.v_tip)) / np.max(np.abs(ref.v_tip)))
        direct = direct_formulation(model, args.direct_horizon)
        direct_scaled = direct * T_END / args.direct_horizon
        report[name] = {
            "toolbox_wall_s": float(np.median(walls)),
            "tip_error_vs_tight_rel": err,
            "peak_tip_m": float(np.max(np.abs(res.v_tip))),
            "reference_wall_s": ref.wall_s,
            "direct_wall_s_measured": direct,
            "direct_horizon_s": args.direct_horizon,
            "direct_wall_s_scaled_to_30s": direct_scaled,
            "speedup_vs_direct": direct_scaled / float(np.median(walls)),
            "meets_target": bool(np.median(walls) <= report["targets_s"][name] and err <= 1e-3),
        }
    print(json.dumps(report, indent=2))
    return report


if __name__ == "__main__":
    main()

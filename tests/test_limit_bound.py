"""The yardstick of ``hubbeam optimal`` on a DC drive, and an optimisation that does not converge
(issue 36 item 8)."""

import functools
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hubbeam_ctrl.cli.main import main
from hubbeam_ctrl.limit import (
    OptimalSettings,
    drive_bang_bang_time,
    rigid_bang_bang_time,
    rigid_bound,
    time_optimal_slew,
)
from hubbeam_ctrl.limit.bound import _drive_terms
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.plant.rig import load_rig


def _simulated_bang_bang(J, theta, drive):
    """Reference: the rigid body run at full drive torque, then full braking, the switch found by
    bisection so that it stops at ``theta`` (an ODE solver, not the quadrature of the module)."""
    stall, k, current, viscous, coulomb = drive[:5]

    def run(switch):
        def f(t, y):
            w = y[1]
            a = (min(stall - k * w, current) - viscous * w - coulomb if t < switch
                 else -(min(stall + k * w, current) + viscous * w + coulomb))
            return [w, a / J]
        stop = lambda t, y: y[1] if t > switch else 1.0   # noqa: E731
        stop.terminal, stop.direction = True, -1
        sol = solve_ivp(f, (0.0, 2.0), [0.0, 0.0], events=stop, max_step=1e-4, rtol=1e-10, atol=1e-12)
        return sol.t[-1], sol.y[0, -1]

    lo, hi = 0.0, 1.0
    for _ in range(42):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if run(mid)[1] < theta else (lo, mid)
    return run(lo)[0]


@pytest.mark.slow
def test_drive_bound_is_the_rigid_bang_bang_within_back_emf_and_friction():
    """servo_link, 90 degrees: the drive's torque falls with the speed (back-EMF) and friction takes
    its share, so the rigid body needs 0.1569 s, not the 0.1329 s of a constant 1.86 N m (18 % more);
    a simulated bang-bang agrees to 1e-6. Without speed terms it is the closed form."""
    rig = load_rig("servo_link")
    p, drive = rig.plant_params, _drive_terms(rig)
    bound = rigid_bound(p, math.pi / 2, rig)
    assert bound == pytest.approx(_simulated_bang_bang(p.total_inertia, math.pi / 2, drive), rel=1e-6)
    assert bound == pytest.approx(0.15687, rel=1e-4)
    assert rigid_bang_bang_time(p, math.pi / 2) == pytest.approx(0.13295, rel=1e-4)
    # a long slew reaches the top speed (stall - coulomb) / (k_emf + viscous) and cruises there
    stall, k, _, viscous, coulomb = drive[:5]
    top = (stall - coulomb) / (k + viscous)
    assert rigid_bound(p, 1000.0, rig) - rigid_bound(p, 500.0, rig) == pytest.approx(500.0 / top, rel=1e-6)
    assert rigid_bound(p, 1000.0, rig) > 1000.0 / top
    # no back-EMF, no friction, the current limit above the stall torque: 2 sqrt(Theta J / tau)
    assert drive_bang_bang_time(248.5, 12.8, (200.0, 0.0, 300.0, 0.0, 0.0)) == pytest.approx(
        2 * math.sqrt(12.8 * 248.5 / 200.0), rel=1e-9)
    # the current limit below the stall torque caps the low-speed torque: slower than with the stall torque
    capped = drive_bang_bang_time(p.total_inertia, math.pi / 2, (stall, k, 0.5 * stall, viscous, coulomb))
    assert capped == pytest.approx(_simulated_bang_bang(p.total_inertia, math.pi / 2,
                                                        (stall, k, 0.5 * stall, viscous, coulomb)), rel=1e-6)
    assert capped > bound


def test_time_optimal_slew_reports_the_drive_bound():
    """``rigid_bound_s`` of a rig's time-optimal slew is the drive's bound; a beam's stays the closed form."""
    rig = load_rig("servo_link")
    quick = OptimalSettings(intervals=8, coarse_intervals=0, modes=1, max_iter=1, check=False)
    r = time_optimal_slew(rig, math.pi / 2, settings=quick)
    assert r.rigid_bound_s == pytest.approx(rigid_bound(rig.plant_params, math.pi / 2, rig), rel=1e-12)
    assert r.rigid_bound_s > rigid_bang_bang_time(rig.plant_params, math.pi / 2) * 1.15
    p = Params(n_transverse=1)
    r = time_optimal_slew(p, 1.0, settings=quick)
    assert r.rigid_bound_s == pytest.approx(2 * math.sqrt(p.total_inertia / p.tau_max), rel=1e-12)


def test_optimal_that_does_not_converge_exits_1_in_one_line(monkeypatch, capsys):
    """IPOPT stopped at its iteration limit (forced to 3 here): exit 1 and one line saying so, not a
    T* with exit 0; --json still prints the summary (``converged: false``)."""
    import hubbeam_ctrl.limit as limit
    monkeypatch.setattr(limit, "OptimalSettings", functools.partial(OptimalSettings, max_iter=3))
    for extra in ([], ["--json"]):
        assert main(["optimal", "--slew-angle", "1", "--n-modes", "1", "--no-check", *extra]) == 1
        out, err = capsys.readouterr()
        assert err.count("\n") == 1 and err.startswith("hubbeam: error: optimal: IPOPT did not converge "
                                                       "(Maximum_Iterations_Exceeded after 3 iterations)")
        assert "is its last iterate, not the time-optimal slew's duration" in err
        if extra:
            assert '"converged": false' in out
    monkeypatch.undo()
    assert main(["optimal", "--slew-angle", "1", "--n-modes", "1", "--no-check"]) == 0
    out, err = capsys.readouterr()
    assert "IPOPT converged" in out and err == ""
    assert np.isfinite(float(out.split(" s = ")[0].split()[-1]))


def test_compare_yardstick_on_a_dc_drive_is_the_drive_bound():
    """The rigid yardstick of a comparison on a rig with a DC motor is the drive's bang-bang (longer
    than the constant-torque bound); on an ideal rig, a spin-up, or without a rig it is unchanged."""
    from hubbeam_ctrl.study.scenarios import make_scenario
    from hubbeam_ctrl.study.yardstick import DRIVE_BOUND, rigid_limit, task_limit
    rig = load_rig("servo_link")
    p = rig.plant_params
    sc = make_scenario("slew", params=p, t_f=0.6, dt=rig.timing.dt, slew_angle=math.pi / 2, t_end=None)
    lim = task_limit(sc, "rigid", rig)
    assert lim["limit_kind"] == DRIVE_BOUND
    assert lim["limit_s"] == pytest.approx(rigid_bound(p, math.pi / 2, rig), rel=1e-12)
    assert lim["limit_s"] == pytest.approx(0.15687, rel=1e-4) and rigid_limit(sc) == pytest.approx(0.13295, rel=1e-4)
    assert task_limit(sc, "rigid") == {"limit_s": rigid_limit(sc), "limit_kind": "rigid bound"}
    spin = make_scenario("spinup", params=p, t_f=0.6, dt=rig.timing.dt, w_f=5.0, t_end=None)
    assert task_limit(spin, "rigid", rig)["limit_kind"] == "rigid bound"

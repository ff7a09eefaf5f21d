"""Issue 37 (the house): ``optimal`` shows IPOPT's iterations on a progress bar, on a terminal only."""

from __future__ import annotations

import io
import re

import casadi as ca
import pytest

from hubbeam_ctrl.core.progress import progress_bar
from hubbeam_ctrl.limit import time_optimal_slew
from hubbeam_ctrl.limit.ipopt_progress import iteration_callback
from hubbeam_ctrl.limit.slew import OptimalSettings
from hubbeam_ctrl.plant.params import Params


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_the_callback_counts_ipopt_iterations():
    """Rosenbrock with a constraint: IPOPT calls back once per iteration and once at the start."""
    x = ca.MX.sym("x", 2)
    nlp = {"x": x, "f": (x[0] - 1) ** 2 + 100 * (x[1] - x[0] ** 2) ** 2, "g": x[0] + x[1]}
    bar = progress_bar(100, "test", file=_Terminal())
    callback = iteration_callback(nlp, bar)
    solver = ca.nlpsol("s", "ipopt", nlp, {"iteration_callback": callback, "print_time": False,
                                           "ipopt": {"print_level": 0, "sb": "yes"}})
    sol = solver(x0=[-1, 1], lbg=-10, ubg=10)
    assert solver.stats()["success"] and abs(float(sol["x"][0]) - 1) < 1e-6
    assert bar.n == solver.stats()["iter_count"] + 1
    assert iteration_callback(nlp, progress_bar(100, "quiet", enabled=False)) is None
    assert iteration_callback(nlp, progress_bar(100, "pipe", file=io.StringIO())) is None


@pytest.mark.slow
def test_optimal_draws_its_iterations_on_a_terminal_only(monkeypatch):
    settings = OptimalSettings(check=False)
    terminal = _Terminal()
    monkeypatch.setattr("sys.stderr", terminal)
    r = time_optimal_slew(Params(), 1.0, settings=settings, progress=True)
    drawn = [(int(n), int(total)) for n, total in
             re.findall(r"optimal: IPOPT iterations:\s+\d+%\|[^|]*\|\s*(\d+)/(\d+)", terminal.getvalue())]
    solves = 2 if 0 < settings.coarse_intervals < settings.intervals else 1
    counts = [n for n, _ in drawn]
    assert r.converged and len(drawn) >= 2 and counts == sorted(counts)
    # redrawn at most every 0.5 s: the last count drawn is at most the iterations plus one start per solve
    assert 0 < counts[-1] <= r.iterations + solves
    assert {total for _, total in drawn} == {settings.max_iter * solves}
    pipe = io.StringIO()
    monkeypatch.setattr("sys.stderr", pipe)
    quiet = time_optimal_slew(Params(), 1.0, settings=settings, progress=True)
    assert pipe.getvalue() == "" and quiet.iterations == r.iterations

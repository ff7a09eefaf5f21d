"""Issue 37 (everyday speed): a comparison's closed loops run side by side (part of them in a forked
child) give the numbers they give one after the other; the child's exceptions are raised here and
what it cannot hand back is run here."""

from __future__ import annotations

import json
import os
import signal

import numpy as np
import pytest
from conftest import ENV

import hubbeam_ctrl.study.compare as compare_module
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.study.compare_values import CompareSettings, RunChoice
from hubbeam_ctrl.study.forked_runs import can_fork, side_by_side


def _text(metrics: dict) -> str:
    """The metrics as JSON text without timings (NaN equals NaN there)."""
    return json.dumps({k: v for k, v in metrics.items() if "wall" not in k and not k.startswith("step_time")},
                      sort_keys=True, default=str)


needs_fork = pytest.mark.skipif(not can_fork(), reason="no fork or a single processor")


@needs_fork
def test_side_by_side_equals_one_after_the_other(monkeypatch, fast_backend):
    settings = CompareSettings(run=RunChoice(t_end=16.0))
    runs = {}
    for flag in (True, False):
        monkeypatch.setattr(compare_module, "SIDE_BY_SIDE", flag)
        runs[flag] = compare_module.compare(None, "slew", "openloop,pd,lqr,lqg", settings)
    a, b = runs[True], runs[False]
    assert list(a.metrics) == list(b.metrics) == ["openloop", "pd", "lqr", "lqg"]
    for name in a.metrics:
        assert np.array_equal(a.results[name].q, b.results[name].q)
        assert np.array_equal(a.results[name].tau, b.results[name].tau)
        assert _text(a.metrics[name]) == _text(b.metrics[name]), name
        assert repr(a.certificates[name]) == repr(b.certificates[name])
    assert a.notes == b.notes


@needs_fork
def test_the_childs_exception_is_raised_here():
    parent = os.getpid()

    def run(name):
        if name == "b" and os.getpid() != parent:
            raise ParameterError("b: refused in the child")
        return name.upper()

    with pytest.raises(ParameterError, match="b: refused in the child"):
        side_by_side(["a", "b", "c"], run)


@needs_fork
def test_what_the_child_cannot_hand_back_is_run_here():
    parent = os.getpid()
    where = {}

    def run(name):
        if os.getpid() != parent:
            os.kill(os.getpid(), signal.SIGKILL)            # the child dies without its results
        where[name] = "here"
        return name * 2

    assert side_by_side(["a", "b", "c"], run) == {"a": "aa", "b": "bb", "c": "cc"}
    assert sorted(where) == ["a", "b", "c"]
    assert side_by_side(["x"], lambda n: n + "!") == {"x": "x!"}    # one run: here


@needs_fork
def test_run_choice_side_by_side_and_the_early_loop_figure(monkeypatch, fast_backend):
    """``RunChoice(side_by_side=True)`` (what ``hubbeam compare`` asks for) runs the loops side by side
    with the numbers of one after the other; the margins and ``designed=`` come in this process after
    the fork, before its own runs, and the loop figure of the comparison handed to ``designed`` (drawn
    while the controllers run) is the finished comparison's, byte for byte."""
    from hubbeam_ctrl.study.report import loop_png
    forks = []
    monkeypatch.setattr(compare_module, "side_by_side", lambda names, run, here=None: forks.append(list(names))
                        or side_by_side(names, run, here))
    seen = []
    a = compare_module.compare(None, "slew", "openloop,pd,lqr",
                               CompareSettings(run=RunChoice(t_end=16.0, side_by_side=True)),
                               designed=lambda c: seen.append((c, dict(c.results), len(forks))))
    b = compare_module.compare(None, "slew", "openloop,pd,lqr", CompareSettings(run=RunChoice(t_end=16.0)))
    assert forks == [["openloop", "pd", "lqr"]]                # b ran one after the other
    for name in b.metrics:
        assert np.array_equal(a.results[name].q, b.results[name].q)
        assert _text(a.metrics[name]) == _text(b.metrics[name]), name
    early, results_then, forks_then = seen[0]
    assert len(seen) == 1 and results_then == {} and forks_then == 1 and list(early.controllers) == ["pd", "lqr"]
    assert {n: m.disk_margin for n, m in a.margins.items()} == {n: m.disk_margin for n, m in b.margins.items()}
    assert loop_png(early).result() == loop_png(b).result()


@needs_fork
def test_here_runs_in_this_process_before_its_runs_and_its_exception_is_raised():
    parent, order = os.getpid(), []

    def run(name):
        if os.getpid() == parent:
            order.append(name)
        return name

    assert side_by_side(["a", "b", "c"], run, here=lambda: order.append("here")) == {"a": "a", "b": "b", "c": "c"}
    assert order == ["here", "a"]                           # b and c ran in the child
    with pytest.raises(ParameterError, match="refused here"):
        side_by_side(["a", "b"], run, here=lambda: (_ for _ in ()).throw(ParameterError("refused here")))


#: The Ctrl-C test's body, run in a process of its own: a Ctrl-C 1 s into side_by_side's wait for a child
#: whose share sleeps 60 s must raise KeyboardInterrupt at once and leave no child behind.
CTRL_C_SCRIPT = """
import os, signal, sys, threading, time
from hubbeam_ctrl.study.forked_runs import side_by_side
parent, pidfile = os.getpid(), sys.argv[1]

def run(name):
    if os.getpid() != parent:
        open(pidfile, "w").write(str(os.getpid()))
        time.sleep(60)
    return name

threading.Timer(1.0, os.kill, (parent, signal.SIGINT)).start()
t0 = time.perf_counter()
try:
    side_by_side(["a", "b"], run)
except KeyboardInterrupt:
    wall = time.perf_counter() - t0
    try:
        os.kill(int(open(pidfile).read()), 0)
        print("child left running")
    except ProcessLookupError:
        print(f"interrupted in {wall:.1f} s, child reaped")
    sys.exit(0)
print("not interrupted")
sys.exit(1)
"""


@needs_fork
def test_ctrl_c_while_waiting_for_the_child_stops_it(tmp_path):
    """In a fresh process (as a user's command runs): in the suite's worker processes, what earlier tests
    left behind (threads, pools, handlers) made this fail twice on fresh clones in session 24, never alone."""
    import subprocess
    import sys
    out = subprocess.run([sys.executable, "-c", CTRL_C_SCRIPT, str(tmp_path / "child.pid")], capture_output=True,
                         text=True, timeout=120, env=ENV)
    assert out.returncode == 0 and "child reaped" in out.stdout, (out.stdout, out.stderr[-2000:])
    assert float(out.stdout.split("interrupted in ")[1].split(" s")[0]) < 30


@needs_fork
def test_forked_runs_with_several_children_and_stop(tmp_path):
    """Several shares run in as many children; ``collect`` gives every result share by share; ``stop``
    (leaving the block) kills and reaps children still running."""
    import time

    from hubbeam_ctrl.study.forked_runs import ForkedRuns
    parent = os.getpid()
    pids = set()

    def run(name):
        assert os.getpid() != parent or name == "lost"
        return (name, os.getpid())

    with ForkedRuns([["a", "b"], ["c"], []], run) as f:
        got = f.collect()
    assert [k for k in got] == ["a", "b", "c"]
    pids = {pid for _, pid in got.values()}
    assert len(pids) == 2 and parent not in pids and got["a"][1] == got["b"][1] != got["c"][1]

    def slow(name):
        (tmp_path / f"{name}.pid").write_text(str(os.getpid()))
        time.sleep(60)
        return name

    t0 = time.perf_counter()
    with ForkedRuns([["x"], ["y"]], slow):
        while len(list(tmp_path.glob("*.pid"))) < 2:
            time.sleep(0.05)
    assert time.perf_counter() - t0 < 30
    for name in ("x", "y"):
        with pytest.raises(ProcessLookupError):             # killed and reaped
            os.kill(int((tmp_path / f"{name}.pid").read_text()), 0)

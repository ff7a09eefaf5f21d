"""Issue 28: progress on the long commands (quiet under --json and off a terminal); native solver
output and library diagnostics go to the --verbose log, never the terminal."""

import io
import subprocess
import sys

from conftest import ENV

NOISY = r"""
import argparse, logging, os, sys
import numpy as np
from hubbeam_ctrl.cli.main import _run

def noisy(args):
    os.write(1, b"native stdout banner\n")
    os.write(2, b"native stderr: iteration matrix\n")
    print("casadi printout")
    logging.getLogger("solver").warning("raw matrix %s", np.arange(6.0).reshape(2, 3))
    print("RESULT", file=args.stdout)
    return 0

log = sys.argv[1] if len(sys.argv) > 1 else None
sys.exit(_run(noisy, argparse.Namespace(verbose=log)))
"""


def test_native_output_and_library_logging_never_reach_the_terminal(tmp_path):
    r = subprocess.run([sys.executable, "-c", NOISY], env=ENV, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout == "RESULT\n", r
    assert r.stderr.count("\n") == 1 and "lines of solver output and warnings suppressed" in r.stderr, r.stderr
    assert "matrix" not in r.stderr and "banner" not in r.stderr
    log = tmp_path / "hubbeam.log"
    r = subprocess.run([sys.executable, "-c", NOISY, str(log)], env=ENV, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0 and r.stdout == "RESULT\n" and r.stderr == "", r
    text = log.read_text()
    for piece in ("native stdout banner", "native stderr: iteration matrix", "casadi printout", "raw matrix"):
        assert piece in text, piece


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_payload_range_design_reports_progress_per_candidate(monkeypatch):
    """design_for_range advances one bar step per candidate and per refinement."""
    import controllers.robust as robust
    from controllers import CONTROLLERS, DesignModel, make_controller
    from hubbeam_ctrl.plant.params import Params
    from hubbeam_ctrl.study.scenarios import make_scenario
    seen = {}
    real = robust.progress_bar

    def recording(total, label, enabled=True, **kw):
        bar = real(total, label, enabled=enabled, file=_Terminal(), **kw)
        seen.update(total=total, label=label, enabled=enabled, bar=bar)
        return bar
    monkeypatch.setattr(robust, "progress_bar", recording)
    p = Params(n_axial=1, n_transverse=1)
    sc = make_scenario("slew", plant="foam", params=p, t_f=1.0, t_end=6.5, dt=0.01)
    design = DesignModel.build(p, sc.design_spin, 0.01, 1)
    st = CONTROLLERS["lqr"].settings.for_scenario(sc)
    w = 2 * 3.141592653589793 / sc.t_f
    baseline = lambda t: (t <= sc.t_f) * sc.baseline_tau_m * __import__("numpy").sin(w * t)
    rd = robust.design_for_range("lqr", make_controller, design, st, sc.reference, (0.0, 0.3), t_f=sc.t_f,
                                 t_end=sc.t_end, delay=sc.bands["residual_delay"], baseline=baseline, progress=True)
    assert seen["enabled"] and seen["label"] == "lqr payload range"
    assert seen["bar"].n == seen["total"] >= len(rd.scores) >= 4     # one step per evaluation
    assert "lqr payload range" in seen["bar"].fp.getvalue()          # drawn on a terminal


def test_sweep_progress_only_on_a_terminal_and_not_under_json(monkeypatch, tmp_path, capsys):
    from hubbeam_ctrl.cli.main import main
    from hubbeam_ctrl.study.sweep import sweep
    spec = {"study": {"controllers": ["openloop"], "t_f": 1.0, "t_end": 6.5, "plant_modes": 2},
            "params": {"n_axial": 2, "n_transverse": 2}, "grid": {"m_t": [0.0, 0.1]}}
    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    sweep(spec, workers=1, progress=True)
    assert "sweep" in term.getvalue() and "2/2" in term.getvalue()
    term.seek(0)
    term.truncate()
    sweep(spec, workers=1, progress=False)
    assert term.getvalue() == ""
    monkeypatch.undo()
    path = tmp_path / "s.toml"
    path.write_text('[study]\ncontrollers = ["openloop"]\nt_f = 1.0\nt_end = 6.5\nplant_modes = 2\n'
                    '[params]\nn_axial = 2\nn_transverse = 2\n[grid]\nm_t = [0.0]\n')
    assert main(["sweep", str(path), "--out", str(tmp_path / "o"), "--workers", "1", "--json"]) == 0
    assert "sweep" not in capsys.readouterr().err                  # --json: no bar


def test_tune_prints_no_progress_lines_off_a_terminal(tmp_path, capsys):
    from hubbeam_ctrl.study.tune import TuneOptions, tune
    spec = {"study": {"controllers": ["lqr"], "t_f": 1.0, "t_end": 6.5, "plant_modes": 2},
            "params": {"n_axial": 2, "n_transverse": 2}}
    tune(spec, "lqr", options=TuneOptions(maxiter=1, popsize=1), workers=1, progress=True)
    assert "generation" not in capsys.readouterr().err                # was one print per generation

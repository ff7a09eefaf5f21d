"""Issue 28: what ``hubbeam design`` prints, and the ``--verbose`` hints of the CLI."""

import json

import pytest

from hubbeam_ctrl.cli.main import _options_of, build_parser, main


def test_design_prints_its_margins(tmp_path, capsys):
    out = tmp_path / "c.mat"
    assert main(["design", "--controller", "lqr", "--out", str(out), "--n-modes", "2"]) == 0
    text = capsys.readouterr().out
    assert "LQR on SFOAM (2 modes" in text and "disk margin" in text and "phase margin" in text
    assert f"saved to {out}" in text and out.exists()


def test_design_json_and_verbose(tmp_path, capsys):
    out, log = tmp_path / "c.npz", tmp_path / "design.log"
    assert main(["design", "--controller", "lqr", "--out", str(out), "--n-modes", "2", "--json",
                 "--verbose", str(log)]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out)                          # the whole stdout is one JSON document
    assert summary["controller"] == "lqr" and summary["out"] == str(out)
    m = summary["margins"]
    assert m["stable"] and 0 < m["spectral_radius"] < 1 and 0 < m["disk_margin"] < 2
    assert m["disk_gain_margin"][0] < 1 < m["disk_gain_margin"][1]


@pytest.mark.parametrize("command", ["modes", "critical-speed", "simulate", "linearize", "compare", "design",
                                     "sweep", "tune"])
def test_every_command_that_hints_verbose_accepts_it(command):
    """The 'suppressed (--verbose LOG keeps them)' and '--verbose LOG for details' hints are shown
    only where the option exists; the commands that run solvers have it."""
    assert "--verbose" in _options_of(build_parser(), command)


def test_no_verbose_hint_on_a_command_without_the_option(capsys):
    import argparse

    from hubbeam_ctrl.cli.main import _fail, _run

    def noisy(args):
        print("solver banner")
        return 0
    assert _run(noisy, argparse.Namespace()) == 0
    err = capsys.readouterr().err
    assert "1 line of solver output" in err and "--verbose" not in err
    assert _fail(1, "boom", argparse.Namespace(), RuntimeError("x")) == 1
    assert "--verbose" not in capsys.readouterr().err

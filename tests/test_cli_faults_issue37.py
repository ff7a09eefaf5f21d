"""Issue 37, "Bad input and faults": the cases of the fault battery that still failed.

Each bad command line must exit with status 2 and one line on stderr, without a traceback, that
names the option or rig key as the user wrote it (``--rig``, ``--max-tip``, ``beam.tau_max``),
and write nothing. Classes: ``tb`` a traceback (or an exception's name, exit 1) before,
``sw`` a silent wrong result (exit 0) before, ``nm`` a refusal that named the wrong thing.
"""

import errno
import os
import subprocess
import sys

import pytest
from conftest import assert_refused_in_one_line

from hubbeam_ctrl.cli.main import main

LONG_NAME = "a" * 256
PAST_PATH_MAX = "/".join(["b" * 200] * 25) + ".toml"          # 5 000 characters > PATH_MAX (4096)
EXCITE = ["excite", "--rig", "servo_link", "--kind", "chirp", "--duration", "4", "--out", "x.csv"]
MODAL = ["identify", "--modal-table", "modal.csv", "--rig", "servo_link", "--fit", "E", "--out", "idout"]

#: (class, argv, words the one line must hold).
CASES = [
    # tracebacks
    ("tb", ["compare", "--scenario", "spinup", "--wf=0", "--controllers", "lqr", "--out", "c"],
     "--wf must be a finite number != 0 [rad/s] (a spin-up to rest is no task), got 0"),
    ("tb", ["compare", "--scenario", "spinup", "--wf=1e-300", "--controllers", "lqr", "--out", "c"],
     "--wf must be a finite number with |wf| >= 1e-06 [rad/s], got 1e-300"),
    ("tb", ["compare", "--t-end=1e308", "--out", "c"], "--t-end must be in [0.001, 1e+09] [s], got 1e+308"),
    ("tb", ["compare", "--slew-angle=1e-300", "--controllers", "lqr", "--out", "c"],
     "--slew-angle must be a finite number with |slew_angle| >= 1e-06 [rad], got 1e-300"),
    ("tb", ["design", "--controller", "lqr", "--slew-angle=1e-300", "--out", "d.json"],
     "--slew-angle must be a finite number with |slew_angle| >= 1e-06 [rad]"),
    ("tb", EXCITE + ["--modes", "0"], "--modes (n_modes) must be an integer in 1..20, got 0"),
    ("tb", EXCITE + ["--modes=-1"], "--modes (n_modes) must be an integer in 1..20, got -1"),
    ("tb", EXCITE + ["--dt=1e-300"], "--dt must be in [1e-06, 10] [s], got 1e-300"),
    ("tb", EXCITE[:-4] + ["--duration", "3600", "--dt=1e-5", "--out", "x.csv"],
     "--dt = 1e-05 s over duration = 3600 s makes 3.6e+08 samples, at most 1e+07"),
    ("tb", ["excite", "--rig", "servo_link", "--kind", "prbs", "--duration", "4", "--seed=-1", "--out", "x.csv"],
     "--seed must be an integer in 0..9223372036854775807, got -1"),
    ("tb", ["optimal", "--slew-angle=1e308"],
     "--slew-angle = 1e+308 rad spins the hub up to inf rad/s (sqrt(|Theta| tau_max / J_total), bang-bang), "
     "above Params.max_spin = 78.73 rad/s"),
    ("tb", ["optimal", "--slew-angle=1e-300"], "--slew-angle must be a finite number with |slew_angle| >= 1e-06"),
    ("tb", ["optimal", "--slew-angle=1", "--tolerance=1e308"],
     "--tolerance must be in [8e-09, 8] [m] (1e-09 L to the beam length L), got 1e+308"),
    ("tb", ["optimal", "--slew-angle=1", "--tolerance=1e-300"], "--tolerance must be in [8e-09, 8] [m]"),
    ("tb", ["optimal", "--slew-angle=1", "--duration=1e308"], "--duration must be in (0, 1e+06] [s], got 1e+308"),
    ("tb", ["optimal", "--slew-angle=1", "--duration=1e-300"],
     "--duration must be >= 0.025404 s (a slew by 1 rad in T reaches the rigid peak rate 2 |Theta| / T"),
    ("tb", ["codegen", "--controller", "lqr", "--out", LONG_NAME], "--out: file name too long"),
    ("tb", ["codegen", "--controller", "lqr", "--rig", PAST_PATH_MAX, "--out", "cg"],
     "cannot be read (File name too long)"),
    ("tb", ["identify", "--modal-table", PAST_PATH_MAX, "--rig", "servo_link", "--fit", "E", "--out", "o"],
     "cannot be read (File name too long)"),
    ("tb", ["sweep", "spec.toml", "--rig", PAST_PATH_MAX, "--out", "s", "--workers", "1"],
     "cannot be read (File name too long)"),
    ("nm", ["compare", "--schedule=1e308", "--controllers", "lqr", "--out", "c"],
     "--schedule must be an integer >= 1 and <= 1000 (number of spin rates; 1 = a single design at the "
     "scenario's design spin), got 1e+308"),
    ("nm", ["codegen", "--controller", "lqr", "--schedule=1e308", "--out", "cg"],
     "--schedule must be an integer >= 1 and <= 1000 (number of spin rates; 1 = a single design at the "
     "scenario's design spin), got 1e+308"),
    ("tb", ["tune", "spec.toml", "--controller", "lqr", "--out", "t", "--workers", "1", "--decades=1e308"],
     "--decades (tune.decades) must be in [1e-06, 10]"),
    # silent wrong results
    ("sw", ["codegen", "--controller", "lqr", "--rig", "servo_link", "--dt", "0.01", "--out", "cg"],
     "--dt must be the --rig's sample time timing.dt = 0.001 s (or left out), got 0.01"),
    ("sw", ["design", "--controller", "lqr", "--rig", "servo_link", "--dt", "0.01", "--out", "d.json"],
     "--dt must be the --rig's sample time timing.dt = 0.001 s"),
    ("sw", ["compare", "--rig", "servo_link", "--dt", "0.01", "--controllers", "lqr", "--out", "c"],
     "--dt must be the --rig's sample time timing.dt = 0.001 s"),
    ("sw", MODAL + ["--bounds", "E=-1:1e12"], "--bounds: E bounds -1:1e+12 must lie within its range [100000, 1e+13]"),
    *[("tb", ["sweep", f"bad_{key}.toml", "--out", "s", "--workers", "1"], words) for key, words in (
        ("t_end", "study.t_end = 1e+308 s at study.dt = 0.01 s (1e+15 samples per run) needs about"),
        ("schedule", "study.schedule must be an integer >= 1 and <= 1000"),
        ("plant_modes", "study.plant_modes must be an integer in 1..20, got 9223372036854775807"),
        ("w_f", "study.w_f must be a finite number != 0 [rad/s] (a spin-up to rest is no task), got 0"))],
    ("sw", ["sweep", "empty.toml", "--out", "s", "--workers", "1"], "spec is empty"),
    ("sw", ["sweep", "string_controllers.toml", "--out", "s", "--workers", "1"],
     "study.controllers must be a list of names (controllers = [\"lqr\"]), got 'openloop'"),
    # refusals that named the wrong thing
    *[("nm", [cmd, *extra, "--rig", rig], f"--rig file {rig} {words}")
      for cmd, extra in (("compare", ["--out", "c"]), ("optimal", ["--slew-angle", "1"]),
                         ("codegen", ["--controller", "lqr", "--out", "cg"]),
                         ("excite", ["--kind", "chirp", "--out", "x.csv"]))
      for rig, words in (("missing.toml", "does not exist"), ("adir", "is not a regular file"),
                         ("/dev/zero", "is not a regular file"), ("fifo.toml", "is not a regular file"),
                         ("binary.toml", "is not UTF-8 text"), ("latin1.toml", "is not UTF-8 text (byte 0)"),
                         ("invalid.toml", "is not valid TOML"), ("huge.toml", "is larger than 1000000 bytes"))],
    ("nm", ["identify", "--modal-table", "modal.csv", "--params", "missing.toml", "--fit", "E", "--out", "o"],
     "--params file missing.toml does not exist"),
    ("nm", EXCITE + ["--max-tip=-1"], "--max-tip (max_tip_deflection) must be a finite number > 0 [m], got -1"),
    ("nm", EXCITE + ["--max-hub=0"], "--max-hub (max_hub_travel) must be a finite number > 0 [rad], got 0"),
    ("nm", EXCITE + ["--band=-1:1"], "--band (band_hz) must be (lo, hi) with 0 < lo < hi [Hz]"),
    ("nm", MODAL + ["--plant-modes", "0"], "--plant-modes (n_transverse) must be an integer in 1..20, got 0"),
    ("nm", ["compare", "--rig", "tau_huge.toml", "--out", "c"],
     "--rig file tau_huge.toml: beam.tau_max must be in (0, 1e+09] [N m], got 1e+300"),
    ("nm", ["compare", "--rig", "tau_large.toml", "--controllers", "lqr", "--out", "c"],
     "the motor's Params.tau_max (beam.tau_max of a rig) = 1e+08 N m over tf = 10 s spins the hub"),
    ("nm", ["codegen", "--controller", "lqr", "--slew-angle=1e308", "--out", "cg"],
     "--slew-angle must be a finite number with |slew_angle| <= 3.9363e+07 [rad] (a slew in the longest tf, "
     "1e+06 s, within Params.max_spin), got 1e+308"),
    ("nm", [], "usage: hubbeam [-h] [--version] COMMAND ..."),
    # a hang: the rig's default slew by 1e5 rad lasts 8432 s (the drive's rigid bound); its reference was
    # planned on 8.4 million samples for 49 s before running out of memory
    ("hg", ["compare", "--rig", "servo_link", "--slew-angle=1e5", "--controllers", "lqr", "--no-ladder", "--out", "c"],
     "the task's runs (at least 3 tf = 25296.5 s) at dt = 0.001 s (1 runs of 25296493 samples) needs about 13 GB of "
     "memory, above max_memory_mb = 2048 MB"),
]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """A folder with the bad files the cases name."""
    d = tmp_path_factory.mktemp("issue37")
    (d / "adir").mkdir()
    os.mkfifo(d / "fifo.toml")
    (d / "binary.toml").write_bytes(bytes(range(256)) * 4)
    (d / "latin1.toml").write_bytes(b"\xb2 = 1\n")                  # a Latin-1 superscript two
    (d / "invalid.toml").write_text("[beam]\nL = = 2\n")
    (d / "huge.toml").write_text("# " + "x" * 1_100_000 + "\n")
    (d / "tau_huge.toml").write_text("[beam]\ntau_max = 1e300\n")
    (d / "tau_large.toml").write_text("[beam]\ntau_max = 1e8\n")
    (d / "empty.toml").write_text("")
    (d / "string_controllers.toml").write_text('[study]\ncontrollers = "openloop"\n')
    (d / "spec.toml").write_text('[study]\ncontrollers = ["lqr"]\nt_f = 1.0\nt_end = 6.5\nplant_modes = 2\n'
                                 '[params]\nn_axial = 2\nn_transverse = 2\n[grid]\nm_t = [0.1]\n')
    for key, value in (("t_end", "1e308"), ("schedule", "9223372036854775807"),
                       ("plant_modes", "9223372036854775807"), ("w_f", '0.0\nscenario = "spinup"')):
        (d / f"bad_{key}.toml").write_text(f'[study]\ncontrollers = ["lqr"]\n{key} = {value}\n'
                                           '[params]\nn_axial = 2\nn_transverse = 2\n[grid]\nm_t = [0.1]\n')
    (d / "modal.csv").write_text("spin [rad/s],m_t [kg],mode [-],frequency [Hz],damping [-]\n"
                                 "0,0.0,1,2.0,0.01\n0,0.0,2,12.0,0.01\n")
    return d


@pytest.mark.parametrize("klass, argv, words", [pytest.param(c, a, w, id=f"{c}-{' '.join(a)[:60]}")
                                                for c, a, w in CASES])
def test_refused_in_one_line_naming_the_option(inputs, monkeypatch, capsys, klass, argv, words):
    monkeypatch.chdir(inputs)
    assert_refused_in_one_line(argv, words, inputs, capsys, max_len=600)


def test_unreadable_rig_is_named_as_rig(tmp_path, capsys):
    path = tmp_path / "secret.toml"
    path.write_text("[beam]\nm_t = 0.2\n")
    path.chmod(0)
    try:
        if os.access(path, os.R_OK):
            pytest.skip("running as a user who can read anything")
        assert main(["compare", "--rig", str(path), "--out", str(tmp_path / "c")]) == 2
        assert f"--rig file {path} cannot be read (Permission denied)" in capsys.readouterr().err
    finally:
        path.chmod(0o600)


def test_plot_on_a_full_disk_names_plot(tmp_path, monkeypatch, capsys):
    """A ``--plot`` the system cannot write (ENOSPC): status 1 (not bad input), named ``--plot``."""
    def full(*_a, **_k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    monkeypatch.setattr(os, "replace", full)
    plot = tmp_path / "p.png"
    code = main(["simulate", "--model", "sfoam", "--maneuver", "torque", "--t-end", "0.1", "--n-modes", "1",
                 "--plot", str(plot)])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1, err
    assert f"--plot: cannot write {plot}" in err and "No space left on device" in err, err
    assert list(tmp_path.iterdir()) == []


def test_closed_pipe_ends_quietly():
    """``hubbeam cache info | head``: the reader leaves first; no BrokenPipeError, no message."""
    proc = subprocess.Popen([sys.executable, "-m", "hubbeam_ctrl", "cache", "info"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    proc.stdout.close()                      # before the interpreter has started: every write fails
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 141, err
    assert err == "", err

"""Bad input on the command line (issue 14): table-driven over every subcommand.

Every case must give exit status 2, exactly one line on stderr that names the option as typed,
no traceback, nothing on stdout and nothing written. The ids start with the issue's class
(``c2``: unbounded work, ``c4``: NaN models, ``c5``: huge finite values, ``c6``: outputs,
``c7``: ``--params`` files, ``c8``: nonsense accepted, ``sm``: the "Smaller" list).
"""

import os

import pytest

from hubbeam_ctrl.cli.main import main

#: The smallest valid command line of each subcommand (the cases add one bad option to it).
BASE = {
    "modes": ["modes"],
    "critical-speed": ["critical-speed"],
    "simulate": ["simulate", "--model", "sfoam", "--maneuver", "torque", "--t-end", "1"],
    "linearize": ["linearize", "--out", "m.npz"],
    "compare": ["compare", "--plant", "foam", "--out", "cmp"],
    "fmu": ["fmu", "--out", "p.fmu"],
}
COMMANDS = tuple(BASE)

#: Bad values of the options every subcommand has: (class, argv, words the error must hold).
COMMON = [
    ("c5", ["--tip-mass", "1e308"], "--tip-mass (m_t) must be in [0, 1e+06] [kg]"),
    ("c5", ["--tip-mass", "2000"], "--tip-mass (m_t) must be <= 1615 [kg]"),
    ("c5", ["--tip-position", "1e308"], "--tip-position (l) must be in [0, L]"),
    ("c5", ["--n-modes", "1" + "0" * 400], "--n-modes (n_axial) must be an integer in 1..20"),
    ("c5", ["--tip-mass", "1e400"], "--tip-mass must be a finite number"),
    ("sm", ["--tip-mass", "-1"], "--tip-mass (m_t) must be in [0, 1e+06] [kg], got -1"),
    ("sm", ["--tip-mass", "nan"], "--tip-mass must be a finite number, got nan"),
    ("sm", ["--tip-mass", "True"], "--tip-mass must be a number"),
    ("sm", ["--n-modes", "2.5"], "--n-modes must be an integer"),
    ("sm", ["--n-modes", "0"], "--n-modes (n_axial) must be an integer in 1..20, got 0"),
    ("c7", ["--params", ""], "--params must name a file"),
    ("c7", ["--params", "adir"], "--params file adir is not a regular file"),
    ("c7", ["--params", "binary.toml"], "--params file binary.toml is not UTF-8 text"),
    ("c7", ["--params", "deep.toml"], "--params file deep.toml"),
    ("c7", ["--params", "many_unknown.toml"], "--params file many_unknown.toml: unknown parameter(s)"),
    ("c7", ["--params", "huge.toml"], "--params file huge.toml is larger than"),
    ("c7", ["--params", "fifo.toml"], "--params file fifo.toml is not a regular file"),
    ("c7", ["--params", "missing.toml"], "--params file missing.toml does not exist"),
    ("c7", ["--params", "invalid.toml"], "--params file invalid.toml is not valid TOML"),
    ("c7", ["--params", "string_value.toml"], "--params file string_value.toml: L must be a number"),
    ("c5", ["--params", "L_big.toml"], "--params file L_big.toml: L must be in [0.01, 1000] [m]"),
    ("c5", ["--params", "L_tiny.toml"], "--params file L_tiny.toml: L must be in [0.01, 1000] [m]"),
    ("c5", ["--params", "rho_tiny.toml"], "--params file rho_tiny.toml: rho must be in [1, 100000]"),
    ("c5", ["--params", "mt_huge.toml"], "--params file mt_huge.toml: m_t must be in [0, 1e+06]"),
    ("c5", ["--params", "slender.toml"], "--params file slender.toml: I must be in"),
]

#: Bad input of one subcommand: (class, subcommand, extra argv, words the error must hold).
SPECIFIC = [
    # c2: work without bounds
    ("c2", "simulate", ["--t-end", "1e6"], "--t-end = 1e+06 s at dt = 0.01 s"),
    ("c2", "simulate", ["--t-end", "1e6"], "raise max_memory_mb; command line: --allow-large"),
    ("c2", "simulate", ["--t-end", "2e4", "--allow-large", "--max-wall", "5"],
     "above max_wall_s = 5 s (raise max_wall_s; command line: --max-wall SECONDS)"),
    ("c2", "simulate", ["--max-wall", "0"], "--max-wall (max_wall_s) must be in [0.001, 1e+07] [s]"),
    ("c2", "simulate", ["--max-wall", "inf"], "--max-wall must be a finite number"),
    ("c2", "compare", ["--t-end", "1e6"], "--t-end = 1e+06 s at dt = 0.01 s"),
    ("c2", "compare", ["--horizon", "1000"], "with horizon = 1000 needs about 2.6 GB of memory"),
    ("c2", "compare", ["--horizon", "100000"], "--horizon must be an integer in 1..5000"),
    ("c2", "compare", ["--horizon", "0"], "--horizon must be an integer in 1..5000"),
    ("c2", "compare", ["--t-end", "3000", "--allow-large", "--max-wall", "10"], "above max_wall_s = 10 s"),
    ("c2", "compare", ["--max-wall", "-5"], "--max-wall (max_wall_s) must be in"),
    # c4: NaN/inf models
    ("c4", "linearize", ["--dt", "1e308"], "--dt must be in [1e-06, 10] [s], got 1e+308"),
    ("c4", "linearize", ["--dt", "1e-320"], "--dt must be in [1e-06, 10] [s]"),
    ("c4", "linearize", ["--spin", "1e308"], "--spin must be in [-78.73, 78.73] [rad/s]"),
    ("c4", "linearize", ["--model", "tlam", "--spin", "78", "--dt", "10"],
     "--dt = 10 s is too long for this model"),
    ("c4", "linearize", ["--damping", "1"], "--damping (damping_ratio) must be in [0, 1)"),
    ("c4", "linearize", ["--damping", "-0.1"], "--damping (damping_ratio) must be in [0, 1)"),
    # c5: huge finite values
    ("c5", "modes", ["--spin", "1e308"], "--spin must be in [-78.73, 78.73] [rad/s]"),
    ("c5", "modes", ["--spin", "-100"], "--spin must be in [-78.73, 78.73] [rad/s]"),
    ("c5", "simulate", ["--t-end", "1e308"], "--t-end must be in [0.01, 1e+09] [s]"),
    ("c5", "simulate", ["--tau-max", "1e300"], "--tau-max (tau_m) must be in (0, 1e+09] [N m]"),
    ("c5", "simulate", ["--tau-max", "1e6"], "--tau-max (tau_m) = 1e+06 N m over t_f = 10 s spins the hub"),
    ("c5", "simulate", ["--tf", "1e300"], "--tf (t_f) must be in [0.001, 1e+06] [s]"),
    ("c5", "compare", ["--tau-max", "1e7"], "--tau-max must be in (0, 200] N m (the motor's tau_max"),
    ("c5", "compare", ["--tf", "1000", "--t-end", "7000"],
     "the motor's Params.tau_max (beam.tau_max of a rig) = 200 N m over tf = 1000 s spins the hub"),
    ("c5", "compare", ["--scenario", "spinup", "--wf", "1e5"], "--wf must be in [-78.73, 78.73] [rad/s]"),
    ("c5", "compare", ["--dt", "1e300"], "--dt must be in [1e-06, 10] [s]"),
    # c6: outputs checked before the run
    ("c6", "simulate", ["--out", "adir"], "--out must end in .csv, .npz"),
    ("c6", "simulate", ["--out", "adir.csv"], "--out: adir.csv is a folder, not a file name"),
    ("c6", "simulate", ["--out", "/proc/x.csv"], "--out: cannot write to folder /proc"),
    ("c6", "simulate", ["--out", "a" * 300 + ".csv"], "--out: file name too long"),
    ("c6", "simulate", ["--out", "nodir/x.csv"], "--out: folder nodir does not exist"),
    ("c6", "simulate", ["--out", "fifo.csv"], "--out: fifo.csv exists and is not a regular file"),
    ("c6", "simulate", ["--out", ""], "--out must end in .csv, .npz"),
    ("c6", "simulate", ["--plot", "adir.png"], "--plot: adir.png is a folder, not a file name"),
    ("c6", "simulate", ["--plot", "/proc/p.png"], "--plot: cannot write to folder /proc"),
    ("c6", "simulate", ["--plot", "x.txt"], "--plot must end in .png"),
    ("c6", "linearize", ["--out", "adir.mat"], "--out: adir.mat is a folder, not a file name"),
    ("c6", "linearize", ["--out", "/proc/m.mat"], "--out: cannot write to folder /proc"),
    ("c6", "linearize", ["--out", "b" * 300 + ".json"], "--out: file name too long"),
    ("c6", "linearize", ["--out", "m.txt"], "--out must end in .mat, .npz, .json"),
    ("c6", "compare", ["--out", "/proc/cmp"], "--out: cannot write to folder /proc"),
    ("c6", "compare", ["--out", "binary.toml"], "--out: binary.toml exists and is not a folder"),
    ("c6", "compare", ["--out", "nodir/cmp"], "--out: folder nodir does not exist"),
    ("c6", "compare", ["--out", "c" * 300], "--out: file name too long"),
    ("c6", "modes", ["--verbose", "/proc/log.txt"], "--verbose: cannot write to folder /proc"),
    # c8: nonsense that exited 0
    ("c8", "simulate", ["--t-end", "0.004"], "--t-end must be in [0.01, 1e+09] [s] (at least two samples"),
    ("c8", "simulate", ["--wf", "2"], "--wf does not apply to --maneuver torque (only to spinup)"),
    ("c8", "simulate", ["--maneuver", "spinup", "--tau-max", "100"],
     "--tau-max does not apply to --maneuver spinup (only to torque)"),
    ("c8", "compare", ["--wf", "2"], "--wf does not apply to --scenario slew (only to spinup)"),
    ("c8", "compare", ["--controllers", "lqr,pd", "--horizon", "20"],
     "--horizon does not apply to --controllers lqr,pd (only to mpc, msmpc)"),
    ("c8", "compare", ["--controllers", "lqr", "--solver", "qpoases"], "--solver does not apply"),
    ("c8", "compare", ["--out", ""], "--out must name a folder"),
    ("c8", "compare", ["--out", " "], "--out must name a folder"),
    ("c8", "compare", ["--t-end", "12"], "--t-end must exceed tf + 0.5 tf = 15 s"),
    ("c8", "compare", ["--controllers", ""], "--controllers"),
    ("c8", "compare", ["--controllers", "lqr,lqr"], "--controllers: each may appear once"),
    ("c8", "linearize", ["--outputs", "tip_deflection,tip_deflection"], "--outputs must not repeat"),
    ("c8", "linearize", ["--outputs", ""], "--outputs must name at least one"),
    ("c8", "modes", ["--hub", "banana"], "--hub: invalid choice: 'banana'"),
    ("c8", "modes", ["--model", "beam"], "--model: invalid choice: 'beam'"),
    ("c8", "critical-speed", ["--model", "cfoam"], "--model: invalid choice: 'cfoam'"),
    ("c8", "modes", ["--spin", "fast"], "--spin must be a number, got 'fast'"),
    ("c8", "simulate", ["--t-end", "-3"], "--t-end must be in [0.01, 1e+09] [s]"),
    ("c8", "simulate", ["--axial", "quasi-static"], "--axial = 'quasi-static' needs a model with axial modes"),
    ("c8", "simulate", ["--axial", "static"], "--axial: invalid choice: 'static'"),
    # hubbeam compare --rig (issue 21)
    ("c8", "compare", ["--rig", "servo_link", "--params", "L_big.toml"], "--rig and --params are exclusive"),
    ("c8", "compare", ["--rig", "nope"], "--rig 'nope' is neither a file nor a preset"),
    ("c8", "compare", ["--no-ladder"], "--no-ladder applies with --rig only"),
    ("c8", "compare", ["--integral", "off"], "--integral applies with --rig only"),
    ("c8", "compare", ["--integral", "maybe"], "--integral: invalid choice: 'maybe'"),
    # a rig's beam.tau_max against its drive's (issue 36)
    ("c8", "compare", ["--rig", "tau_conflict.toml"],
     "--rig file tau_conflict.toml: beam.tau_max must be within 1 % of 1.861 N m (the DC motor's stall torque"),
    ("c8", "compare", ["--rig", "motor_tau.toml"], "motor.tau_max is the limit of a torque source"),
    # hubbeam compare --settle-angle / --settle-tip (issue 36 item 6)
    ("c8", "compare", ["--settle-angle", "2furlongs"], "--settle-angle must be a number [rad] or with a unit: "
                                                       "1e-3rad, 1.5mrad, 0.05deg, 2counts"),
    ("c8", "compare", ["--settle-angle=-1deg"], "--settle-angle must be > 0 and finite"),
    ("c8", "compare", ["--settle-tip", "0.5 parsecs"], "--settle-tip must be a number [m] or with a unit: 1e-3m, "
                                                       "0.5mm, 1e-3L (a fraction of L), got '0.5 parsecs'"),
    ("c8", "compare", ["--settle-tip", "0L"], "--settle-tip must be > 0 and finite"),
    ("c8", "compare", ["--settle-angle", "2counts"], "--settle-angle 2counts: counts need a rig with an angle sensor "
                                                     "(--rig with sensors.encoder_counts or sensors.angle_noise)"),
    ("c8", "compare", ["--rig", "paper", "--settle-angle", "1count"], "--settle-angle 1count: counts need a rig"),
    ("c8", "compare", ["--settle-tip", "1mm", "--payload-range", "0,0.2"],
     "--settle-angle and --settle-tip do not take --payload-range yet"),
    # hubbeam fmu (issue 26)
    ("c8", "fmu", ["--model", "tlam"], "--model: invalid choice: 'tlam'"),
    ("c8", "fmu", ["--rig", "servo_link", "--params", "L_big.toml"], "--rig and --params are exclusive"),
    ("c8", "fmu", ["--rig", "nope"], "--rig 'nope' is neither a file nor a preset"),
    ("c8", "fmu", ["--rig", ""], "--rig must name a rig"),
    ("c8", "fmu", ["--dt", "-1"], "--dt must be in [1e-06, 10] [s], got -1"),
    ("c8", "fmu", ["--substeps", "0"], "--substeps must be an integer in [1, 200], got 0"),
    ("c6", "fmu", ["--out", "adir"], "--out must name a .fmu file"),
    ("c6", "fmu", ["--out", "nofolder/p.fmu"], "--out: folder nofolder does not exist"),
]

CASES = ([pytest.param(c, cmd, argv, words, id=f"{c}-{cmd}-{' '.join(argv)[:40]}") for c, argv, words in COMMON
          for cmd in COMMANDS]
         + [pytest.param(c, cmd, argv, words, id=f"{c}-{cmd}-{' '.join(argv)[:40]}")
            for c, cmd, argv, words in SPECIFIC])


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """A folder with the bad files the cases name."""
    d = tmp_path_factory.mktemp("bad_inputs")
    (d / "adir").mkdir()
    (d / "adir.csv").mkdir()
    (d / "adir.png").mkdir()
    (d / "adir.mat").mkdir()
    (d / "binary.toml").write_bytes(bytes(range(256)) * 4)
    (d / "deep.toml").write_text("L = " + "[" * 100000 + "]" * 100000 + "\n")
    (d / "many_unknown.toml").write_text("".join(f"k{i} = 1\n" for i in range(20000)))
    (d / "huge.toml").write_text("".join(f"key{i} = 1\n" for i in range(200000)))
    (d / "invalid.toml").write_text("m_t = = 2\n")
    (d / "string_value.toml").write_text('L = "eight"\n')
    (d / "L_big.toml").write_text("L = 1e300\n")
    (d / "L_tiny.toml").write_text("L = 1e-300\n")
    (d / "rho_tiny.toml").write_text("rho = 1e-300\n")
    (d / "mt_huge.toml").write_text("m_t = 1e308\n")
    (d / "slender.toml").write_text("I = 1e-3\n")
    (d / "tau_conflict.toml").write_text("[beam]\ntau_max = 3.0\n[motor]\nkind = 'dc_motor'\nN = 70.0\n"
                                          "eta_forward = 0.9\n")
    (d / "motor_tau.toml").write_text("[motor]\nkind = 'dc_motor'\ntau_max = 5.0\n")
    os.mkfifo(d / "fifo.toml")
    os.mkfifo(d / "fifo.csv")
    return d


def _listing(folder):
    return sorted(os.listdir(folder))


@pytest.mark.parametrize("klass, command, argv, words", CASES)
def test_bad_input_is_one_line_exit_2_nothing_written(inputs, monkeypatch, capsys, klass, command, argv, words):
    monkeypatch.chdir(inputs)
    before = _listing(inputs)
    code = main(BASE[command] + argv)
    out, err = capsys.readouterr()
    assert code == 2, err
    assert err.startswith("hubbeam: error: ") and err.count("\n") == 1 and len(err) < 600, err
    assert words in err, err
    assert "Traceback" not in err and out == ""
    assert _listing(inputs) == before


def test_unreadable_params_file(inputs, monkeypatch, capsys, tmp_path):
    path = tmp_path / "secret.toml"
    path.write_text("m_t = 0.2\n")
    path.chmod(0)
    try:
        if os.access(path, os.R_OK):
            pytest.skip("running as a user who can read anything")
        assert main(["modes", "--params", str(path)]) == 2
        assert "cannot be read (Permission denied)" in capsys.readouterr().err
    finally:
        path.chmod(0o600)


def test_every_subcommand_is_covered():
    covered = {cmd for _, cmd, _, _ in SPECIFIC} | set(COMMANDS)
    assert covered == set(BASE)

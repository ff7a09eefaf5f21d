"""Issue 37, the fault battery rerun (``benchmarks/fault_battery.py``) over every command: what it found.

Each bad command line exits with status 2 and one line on stderr, without a traceback, naming the
option as typed and its range, and writes nothing. Kinds: ``sw`` a silent wrong result (status 0)
before, ``tb`` a traceback (an exception's name, status 1) before, ``nm`` a refusal that named the
wrong thing (``modal table`` for ``--modal-table``), ``late`` refused only after the run.
"""

import os
from importlib import resources

import pytest
from conftest import assert_refused_in_one_line

COMPARE = ["compare", "--controllers", "lqr", "--n-modes", "2", "--tf", "1", "--t-end", "2", "--out", "c"]
EXCITE = ["excite", "--rig", "servo_link", "--kind", "step", "--duration", "0.1", "--out", "x.csv"]
SWEEP = ["sweep", "spec.toml", "--out", "s"]
TUNE = ["tune", "spec.toml", "--controller", "lqr", "--out", "t", "--workers", "1"]
CERTIFY = ["certify", "lqr", "--n-modes", "2", "--tf", "1", "--t-end", "2", "--dt", "0.01", "--uncertainty",
           "m_t=0:0.1", "--grid", "2", "--check", "none", "--out", "ce"]
MODAL = ["identify", "--rig", "servo_link", "--fit", "E", "--out", "idout", "--modal-table"]

#: (kind, argv, words the one line must hold).
CASES = [
    # settling bands past one turn / the beam (any run "settled")
    ("sw", COMPARE + ["--settle-angle=1e308"], "--settle-angle must be at most 2 pi rad (one turn), got '1e308'"),
    ("sw", COMPARE + ["--settle-angle=400deg"], "--settle-angle must be at most 2 pi rad (one turn), got '400deg' "
                                                "= 6.981 rad"),
    ("sw", COMPARE + ["--settle-tip=9223372036854775808"], "--settle-tip must be at most the beam length L = 8 m"),
    ("sw", COMPARE + ["--settle-tip=2L"], "--settle-tip must be at most the beam length L = 8 m, got '2L' = 16 m"),
    # worker counts past any pool (OverflowError from the pool's semaphore before)
    ("tb", TUNE[:-2] + ["--workers=1e308"], "--workers must be an integer in 1..1024, got"),
    ("sw", SWEEP + ["--workers=9223372036854775808"], "--workers must be an integer in 1..1024, got 92233720368547"),
    ("sw", SWEEP + ["--scheduler", ""], "--scheduler must name a scheduler address, got ''"),
    ("sw", TUNE + ["--scheduler", " "], "--scheduler must name a scheduler address, got ' '"),
    ("sw", TUNE + ["--seed=9223372036854775808"], "--seed (tune.seed) must be an integer in 0..9223372036854775807"),
    # a search width whose bounds round to the scaled defaults (1e-300: one run, the defaults called tuned)
    ("sw", TUNE + ["--decades=1e-300"], "--decades (tune.decades) must be in [1e-06, 10] (the weights searched "
                                        "within 10^-decades..10^decades of the scaled defaults), got 1e-300"),
    # a rig's default slew by --slew-angle (no --tf): named 'angle', or '--tf' the user did not type, before
    *[("nm", [*cmd, "--rig", "servo_link", "--slew-angle=1e-300", "--out", out],
       "--slew-angle must be a finite number with |slew_angle| >= 1e-06 [rad], got 1e-300")
      for cmd, out in ((["compare", "--controllers", "lqr"], "c"), (["design", "--controller", "lqr"], "d.json"))],
    ("nm", ["compare", "--rig", "servo_link", "--slew-angle=1e308", "--controllers", "lqr", "--out", "c"],
     "--slew-angle = 1e+308 rad takes the rig's default slew 8.432e+306 s (1.5 x (rigid bound + first-mode "
     "period)), past the longest tf, 1e+06 s"),
    # excitation limits past the beam / any rig
    ("sw", EXCITE + ["--max-tip=1e308"], "--max-tip (max_tip_deflection) must be in (0, 0.381] [m] (at most the "
                                         "beam length L), got 1e+308"),
    ("sw", EXCITE + ["--max-hub=9223372036854775808"], "--max-hub (max_hub_travel) must be in (0, 1e+06] [rad]"),
    # the modal table: named as typed, every unreadable kind one line
    ("tb", MODAL + ["binary.csv"], "--modal-table file binary.csv is not UTF-8 text (byte 37)"),
    ("tb", MODAL + ["latin1.csv"], "--modal-table file latin1.csv is not UTF-8 text (byte 0)"),
    ("nm", MODAL + ["huge.csv"], "--modal-table file huge.csv is larger than 1000000 bytes"),
    ("nm", MODAL + ["ragged.csv"], "--modal-table file ragged.csv: row 3 has 2 cells for 3 columns"),
    ("nm", MODAL + ["negative.csv"], "--modal-table file negative.csv: frequency [Hz] must be finite and > 0"),
    ("nm", MODAL + ["missing.csv"], "--modal-table file missing.csv does not exist"),
    ("nm", MODAL + ["adir"], "--modal-table file adir is not a regular file"),
    ("nm", MODAL + ["/dev/zero"], "--modal-table file /dev/zero is not a regular file"),
    ("nm", MODAL + ["badheader.csv"], "--modal-table file badheader.csv: header item 'a' is not one of spin [rad/s]"),
    # --c-out checked before the comparison, not after it (a refusal after the work, progress lines above it)
    ("late", CERTIFY + ["--c-out", "afile"], "--c-out: afile exists and is not a folder"),
    ("late", CERTIFY + ["--c-out", "no/such"], "--c-out: folder no does not exist"),
    # a rig missing beam.I (Table 1's, 8 m of aluminium) or beam.J_h: named --band / --amplitude, not typed
    ("nm", EXCITE[:2] + ["no_I.toml"] + EXCITE[3:], "the default band of the rig's first bending mode reaches "
                                                    "557.568 Hz, past the Nyquist frequency 500 Hz of dt = 0.001 s"),
    ("nm", EXCITE[:2] + ["no_J_h.toml"] + EXCITE[3:], "the drive's full amplitude 10 V moves the hub at most 2.52e-05 "
                                                      "rad, not more than 2 counts of the encoder (0.00307 rad)"),
]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """A folder with the files the cases name."""
    d = tmp_path_factory.mktemp("battery")
    (d / "adir").mkdir()
    (d / "afile").write_text("x")
    (d / "binary.csv").write_bytes(b"spin [rad/s],mode [-],frequency [Hz]\n" + bytes(range(128, 256)))
    (d / "latin1.csv").write_bytes(b"\xb2 = 1\n")
    (d / "huge.csv").write_text("spin [rad/s],mode [-],frequency [Hz]\n" + "0,1,2\n" * 200_000)
    (d / "ragged.csv").write_text("spin [rad/s],mode [-],frequency [Hz]\n0,1,2\n0,1\n")
    (d / "negative.csv").write_text("spin [rad/s],mode [-],frequency [Hz]\n0,1,-2\n")
    (d / "badheader.csv").write_text("a,b\n1,2\n")
    (d / "spec.toml").write_text('[study]\ncontrollers = ["lqr"]\nt_f = 1.0\nt_end = 2.5\ndt = 0.01\nplant_modes = 1\n'
                                 '[params]\nn_axial = 1\nn_transverse = 1\n[grid]\nm_t = [0.1]\n')
    rig = (resources.files("hubbeam_ctrl") / "data" / "rigs" / "servo_link.toml").read_text()
    for key in ("I", "J_h"):
        (d / f"no_{key}.toml").write_text("".join(line for line in rig.splitlines(keepends=True)
                                                  if not line.startswith(f"{key} = ")))
    return d


@pytest.mark.parametrize("kind, argv, words", [pytest.param(k, a, w, id=f"{k}-{' '.join(a[-2:])[:50]}")
                                               for k, a, w in CASES])
def test_refused_in_one_line_naming_the_option(inputs, monkeypatch, capsys, kind, argv, words):
    monkeypatch.chdir(inputs)
    assert_refused_in_one_line(argv, words, inputs, capsys)


def test_full_disk_inside_an_output_folder_is_a_resource_error(tmp_path):
    """A disk that fills while a results folder is written: status 1 (not bad input, not 2 after the run), one
    line naming ``--out`` and the folder, not the temporary file inside it; nothing left behind."""
    import errno

    from hubbeam_ctrl.core.errors import ResourceError, write_error
    from hubbeam_ctrl.core.fileio import write_folder

    def write(folder):
        raise write_error(OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)), f"out: cannot write {folder}/metrics.csv")
    with pytest.raises(ResourceError) as info:
        write_folder(tmp_path / "c", write, "--out")
    assert str(info.value) == f"--out: cannot write {tmp_path / 'c'}: No space left on device"
    assert list(tmp_path.iterdir()) == []


def _battery():
    import importlib.util
    path = os.path.join(os.path.dirname(__file__), "..", "benchmarks", "fault_battery.py")
    spec = importlib.util.spec_from_file_location("fault_battery", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_battery_covers_every_command_and_classes_by_the_issue(tmp_path):
    """benchmarks/fault_battery.py reads the commands from the parser (a command added later is battered
    too) and classes a run as the issue does."""
    from hubbeam_ctrl.cli.main import build_parser
    fb = _battery()
    parser = build_parser()
    commands = {a for a in parser._actions if a.dest == "command"}.pop().choices
    assert set(fb.BASES) == set(commands)
    cases = fb.cases(parser, set(), str(tmp_path), {"missing": str(tmp_path / "missing.toml")},
                     {"file": str(tmp_path / "afile")})
    assert {c[0] for c in cases} == set(commands) | set(fb.VARIANTS)
    tune_workers = [c for c in cases if c[:3] == ("tune", "--workers", "value:1e308")]
    argv = tune_workers[0][3]
    assert argv[-1] == "--workers=1e308" and "--workers" not in argv[:-1]      # the base's --workers 1 replaced
    case = ("tune", "--workers", "value:1e308", [])
    run = {"status": 2, "err": "hubbeam: error: --workers must be an integer in 1..1024, got 1e308\n"}
    assert fb.classify(case, run) == "refused"
    assert fb.classify(case, dict(run, err="hubbeam: error: workers must be ...\n")) == "wrong_name"
    assert fb.classify(case, {"status": 1, "err": "hubbeam: error: OverflowError: too large\n"}) == "traceback"
    assert fb.classify(case, {"status": 0, "err": ""}) == "silent_wrong"
    assert fb.classify(case, {"status": None, "err": ""}) == "hang"
    assert fb.classify(("tune", "--seed", "value:0", []), {"status": 0, "err": ""}) == "accepted"

"""Issue 28, general guards: every input file through one guarded reader, loaders, resume,
budgets, CLI numbers, API arguments, disk-full. One line, the option or key named, no traceback."""

import os
import threading

import pytest

from hubbeam_ctrl.cli.main import main

GOOD_SPEC = """[study]
controllers = ["lqr"]
t_f = 1.0
t_end = 6.5
plant_modes = 2
[params]
n_axial = 2
n_transverse = 2
[grid]
m_t = [0.1]
"""


def _one_line(capsys, status, expected_status=2):
    err = capsys.readouterr().err
    assert status == expected_status, err
    assert err.count("\n") == 1 and err.startswith("hubbeam: error: ") and "Traceback" not in err, err
    return err


# -- spec and --settings files: the reader of --params ---------------------------------------------
def _bad_files(tmp_path):
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe" * 10)
    big = tmp_path / "big.toml"
    big.write_text("# " + "x" * 5_000_000 + "\n")
    return {"fifo": (fifo, "not a regular file"), "device": ("/dev/zero", "not a regular file"),
            "folder": (tmp_path, "not a regular file"), "binary": (binary, "not UTF-8"),
            "big": (big, "larger than"), "missing": (tmp_path / "none.toml", "does not exist")}


@pytest.mark.parametrize("kind", ["fifo", "device", "folder", "binary", "big", "missing"])
def test_spec_and_settings_files_are_read_with_the_guards(tmp_path, capsys, kind):
    path, text = _bad_files(tmp_path)[kind]
    good = tmp_path / "good.toml"
    good.write_text(GOOD_SPEC)
    done = []
    for argv, what in ((["sweep", str(path), "--out", str(tmp_path / "o")], "spec: file"),
                       (["sweep", str(good), "--out", str(tmp_path / "o"), "--settings", str(path)], "settings: file"),
                       (["tune", str(path), "--controller", "lqr", "--out", str(tmp_path / "t")], "spec: file")):
        worker = threading.Thread(target=lambda a=argv: done.append(main(a)), daemon=True)
        worker.start()
        worker.join(60)
        assert not worker.is_alive(), f"{argv} hangs"              # a FIFO or /dev/zero must not block
        err = _one_line(capsys, done[-1])
        assert what in err and text in err, err
    assert not (tmp_path / "o").exists() and not (tmp_path / "t").exists()


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads every file")
def test_unreadable_spec_is_one_line(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(GOOD_SPEC)
    path.chmod(0)
    err = _one_line(capsys, main(["sweep", str(path), "--out", str(tmp_path / "o")]))
    assert "cannot be read" in err


@pytest.mark.parametrize("text, needle", [
    ("study = 1\n", "spec: study must be a table"),
    ("params = \"x\"\n", "spec: params must be a table"),
    ("[settings]\nlqr = 1\n", "settings.lqr must be a table"),
    ("[study]\nt_f = \"x\"\n", "t_f"),
    ("[study]\ncontrollers = 1\n", "study.controllers"),
])
def test_mistyped_spec_values_are_one_line(tmp_path, capsys, text, needle):
    path = tmp_path / "s.toml"
    path.write_text(text)
    err = _one_line(capsys, main(["sweep", str(path), "--out", str(tmp_path / "o")]))
    assert needle in err, err


def test_mistyped_settings_file_is_one_line(tmp_path, capsys):
    good = tmp_path / "good.toml"
    good.write_text(GOOD_SPEC)
    bad = tmp_path / "settings.toml"
    bad.write_text("settings = 1\n")
    err = _one_line(capsys, main(["sweep", str(good), "--out", str(tmp_path / "o"), "--settings", str(bad)]))
    assert "settings:" in err and "[settings.NAME]" in err

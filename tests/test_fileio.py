"""Atomic writes (:mod:`hubbeam_ctrl.core.fileio`): all or nothing, no temporary file left."""

import pytest

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write, atomic_write_text


def test_write_lands_under_the_final_name(tmp_path):
    seen = []

    def write(tmp):
        seen.append(tmp)
        with open(tmp, "wb") as fh:
            fh.write(b"\x00payload")

    path = atomic_write(tmp_path / "data.npz", write)
    assert path == tmp_path / "data.npz" and path.read_bytes() == b"\x00payload"
    # the temporary file was a hidden sibling with the fixed prefix and the target's extension
    # (np.savez insists)
    tmp = seen[0]
    assert str(tmp).startswith(str(tmp_path / ".hubbeam-tmp-")) and str(tmp).endswith("-data.npz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data.npz"]


def test_suffix_of_the_temporary_file_can_be_chosen(tmp_path):
    seen = []
    atomic_write(tmp_path / "model", lambda tmp: seen.append(tmp) or open(tmp, "w").close(), suffix=".mat")
    assert str(seen[0]).endswith(".mat") and (tmp_path / "model").exists()


def test_error_leaves_no_temporary_file_and_keeps_the_old_content(tmp_path):
    target = tmp_path / "out.csv"
    target.write_text("old\n")

    def failing(tmp):
        with open(tmp, "w") as fh:
            fh.write("half of the new con")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        atomic_write(target, failing)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]
    assert target.read_text() == "old\n"


def test_interrupt_leaves_no_temporary_file(tmp_path):
    def interrupted(tmp):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        atomic_write(tmp_path / "x.json", interrupted)
    assert list(tmp_path.iterdir()) == []


def test_missing_folder_is_a_parameter_error(tmp_path):
    with pytest.raises(ParameterError, match="does not exist"):
        atomic_write_text(tmp_path / "no" / "such" / "file.txt", "x")
    assert list(tmp_path.iterdir()) == []


def test_text_is_utf8_and_replaces(tmp_path):
    path = tmp_path / "notes.md"
    atomic_write_text(path, "first")
    atomic_write_text(path, "Ω = 2.8 rad/s\n")
    assert path.read_bytes() == "Ω = 2.8 rad/s\n".encode("utf-8")
    assert [p.name for p in tmp_path.iterdir()] == ["notes.md"]


def test_relative_path_writes_in_the_working_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    atomic_write_text("plain.txt", "ok")
    assert (tmp_path / "plain.txt").read_text() == "ok"


def test_system_refusal_is_a_parameter_error_naming_the_path(tmp_path):
    def refused(tmp):
        raise PermissionError(13, "Permission denied")

    with pytest.raises(ParameterError, match=r"out: cannot write .*run\.npz: Permission denied"):
        atomic_write(tmp_path / "run.npz", refused)
    assert list(tmp_path.iterdir()) == []


def test_folder_as_file_name_is_a_parameter_error(tmp_path):
    (tmp_path / "results").mkdir()
    with pytest.raises(ParameterError, match="is a folder"):
        atomic_write_text(tmp_path / "results", "x")
    assert [p.name for p in tmp_path.iterdir()] == ["results"]

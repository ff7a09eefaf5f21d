"""Files (issue 14, classes 3, 9, 10): temporaries cleaned after kills, umask permissions,
output folders marked complete, loaders that validate and never block."""

import json
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hubbeam_ctrl import ParameterError, linearize, load_model, save_model
from hubbeam_ctrl.core.fileio import (
    MANIFEST,
    TEMP_PREFIX,
    atomic_write,
    atomic_write_text,
    check_writable,
    read_manifest,
    remove_stale_temporaries,
    write_folder,
)

ROOT = Path(__file__).resolve().parents[1]
SLOW_WRITER = """
import sys, time
from hubbeam_ctrl.core.fileio import atomic_write
def write(tmp):
    with open(tmp, "w") as fh:
        fh.write("x" * 100000)
        fh.flush()
        time.sleep(60)
atomic_write(sys.argv[1], write)
"""


def _temporaries(folder):
    return [p for p in os.listdir(folder) if p.startswith(TEMP_PREFIX)]


def _start_slow_writer(target: Path) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-c", SLOW_WRITER, str(target)], env=env)
    for _ in range(300):                       # wait until the temporary file exists
        if _temporaries(target.parent):
            return proc
        time.sleep(0.05)
    proc.kill()
    pytest.fail("the writer never created its temporary file")


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_signal_during_a_write_removes_the_temporary(tmp_path, sig):
    proc = _start_slow_writer(tmp_path / "big.csv")
    proc.send_signal(sig)
    proc.wait(timeout=30)
    assert proc.returncode != 0
    assert os.listdir(tmp_path) == []            # neither the temporary nor a partial file


def test_sigkill_leftover_is_removed_by_the_next_writer(tmp_path):
    proc = _start_slow_writer(tmp_path / "big.csv")
    proc.kill()
    proc.wait(timeout=30)
    assert len(_temporaries(tmp_path)) == 1     # SIGKILL cannot be caught...
    atomic_write_text(tmp_path / "other.txt", "hello")
    assert os.listdir(tmp_path) == ["other.txt"]  # ...but the next writer in the folder cleans up


def test_a_live_writers_temporary_is_left_alone(tmp_path):
    mine = tmp_path / f"{TEMP_PREFIX}{os.getpid()}-abcd1234-x.csv"
    mine.write_text("in progress")
    assert remove_stale_temporaries(tmp_path) == [] and mine.exists()


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_final_files_get_the_umask_permissions(tmp_path, umask):
    old = os.umask(umask)
    try:
        path = atomic_write_text(tmp_path / "a.txt", "x")
        path.chmod(0o600)                             # overwriting does not keep 0600 either
        atomic_write_text(path, "y")
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask


def test_failed_write_leaves_nothing(tmp_path):
    def boom(tmp):
        Path(tmp).write_text("half")
        raise RuntimeError("disk on fire")
    with pytest.raises(RuntimeError):
        atomic_write(tmp_path / "a.csv", boom)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("make,needle", [
    (lambda d: d / "sub", "is a folder"),
    (lambda d: d / "missing" / "x.csv", "does not exist"),
    (lambda d: d / ("a" * 300 + ".csv"), "file name too long"),
    (lambda d: Path("/proc/x.csv"), "cannot write to folder /proc"),
    (lambda d: "", "must name a file"),
    (lambda d: d / "fifo.csv", "not a regular file"),
])
def test_check_writable_refuses_before_any_work(tmp_path, make, needle):
    (tmp_path / "sub").mkdir()
    os.mkfifo(tmp_path / "fifo.csv")
    with pytest.raises(ParameterError, match=needle):
        check_writable(make(tmp_path), "--out")


def test_read_only_folder_is_refused(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if os.access(ro, os.W_OK):
            pytest.skip("running as a user who can write anywhere")
        with pytest.raises(ParameterError, match="cannot write to folder"):
            check_writable(ro / "x.csv", "--out")
    finally:
        ro.chmod(0o700)


# -- output folders --------------------------------------------------------------------------
def _files(names):
    def write(folder):
        for name, text in names.items():
            (Path(folder) / name).write_text(text)
    return write


def test_new_folder_appears_complete_with_a_manifest(tmp_path):
    out = write_folder(tmp_path / "run", _files({"a.csv": "1", "report.md": "# r"}))
    doc = read_manifest(out)
    assert sorted(doc["files"]) == ["a.csv", "report.md"] and doc["files"]["a.csv"]["bytes"] == 1
    assert sorted(os.listdir(tmp_path)) == ["run"]


def test_interrupted_write_leaves_no_new_folder(tmp_path):
    def half(folder):
        (Path(folder) / "a.csv").write_text("1")
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        write_folder(tmp_path / "run", half)
    assert os.listdir(tmp_path) == []


def test_interrupted_update_is_detectable(tmp_path):
    out = write_folder(tmp_path / "run", _files({"a.csv": "old", "report.md": "old"}))
    (out / MANIFEST).unlink()                      # what an update killed half-way leaves
    (out / "a.csv").write_text("new")
    with pytest.raises(ParameterError, match="incomplete"):
        read_manifest(out)
    write_folder(out, _files({"a.csv": "new", "report.md": "new"}))
    assert read_manifest(out)["files"]["report.md"]["bytes"] == 3


def test_changed_file_is_detected(tmp_path):
    out = write_folder(tmp_path / "run", _files({"a.csv": "1"}))
    (out / "a.csv").write_text("2")
    with pytest.raises(ParameterError, match="inconsistent"):
        read_manifest(out)


# -- load_model ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def saved_npz(tmp_path_factory):
    path = tmp_path_factory.mktemp("m") / "m.npz"
    save_model(linearize("sfoam", 1.0, outputs="theta,tip_deflection", n_modes=3), path)
    return path


def _rewrite(src: Path, dst: Path, arrays=None, meta=None) -> Path:
    with np.load(src, allow_pickle=False) as data:
        a = {k: data[k] for k in data.files if k != "metadata"}
        m = json.loads(str(data["metadata"]))
    a.update(arrays or {})
    m.update(meta or {})
    np.savez(dst, metadata=np.array(json.dumps(m)), **a)
    return dst


@pytest.mark.parametrize("arrays,meta,needle", [
    ({"A": np.full((8, 8), np.nan)}, None, "A holds NaN or infinity"),
    ({"B": np.full((8, 1), np.inf)}, None, "B holds NaN or infinity"),
    ({"A": np.zeros((8, 8)) + 1j}, None, "A holds complex128 values"),
    ({"A": np.zeros((8, 8), bool)}, None, "A holds bool values"),
    ({"A": np.zeros((7, 7))}, None, "A has shape (7, 7)"),
    ({"C": np.zeros((2, 8, 1))}, None, "C has 3 dimensions"),
    (None, {"state_names": ["x"] * 8}, "state_names repeats a name"),
    (None, {"state_names": ["theta"]}, "for 1 states"),
    (None, {"model": "bogus"}, "model 'bogus' is not one of"),
    (None, {"spin_rad_s": float("nan")}, "spin_rad_s must be in"),
    (None, {"spin_rad_s": 1e6}, "spin_rad_s must be in"),
    (None, {"dt": -1.0}, "dt -1.0 is not 0 or in"),
    (None, {"input_names": ["u"]}, "inputs"),
    (None, {"params": {"L": -1}}, "L must be in"),
    (None, {"reduction": "magic"}, "reduction 'magic'"),
    (None, {"name": ""}, "name '' is not"),
])
def test_load_model_validates(saved_npz, tmp_path, arrays, meta, needle):
    bad = _rewrite(saved_npz, tmp_path / "bad.npz", arrays, meta)
    with pytest.raises(ParameterError) as err:
        load_model(bad)
    assert needle in str(err.value) and "\n" not in str(err.value)


def test_load_model_fifo_does_not_block(tmp_path):
    fifo = tmp_path / "x.npz"
    os.mkfifo(fifo)
    t0 = time.perf_counter()
    with pytest.raises(ParameterError, match="not a regular file"):
        load_model(fifo)
    assert time.perf_counter() - t0 < 1.0


@pytest.mark.parametrize("content", [b"", b"PK\x03\x04garbage", b"\x00" * 100, "{}".encode(),
                                     b"[" * 100000])
@pytest.mark.parametrize("suffix", [".npz", ".mat", ".json"])
def test_load_model_garbage_is_one_line(tmp_path, content, suffix):
    path = tmp_path / f"g{suffix}"
    path.write_bytes(content)
    with pytest.raises(ParameterError) as err:
        load_model(path)
    assert "\n" not in str(err.value) and len(str(err.value)) < 400

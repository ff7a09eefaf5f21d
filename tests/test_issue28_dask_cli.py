"""Issue 28: ``hubbeam sweep --scheduler`` against a real Dask scheduler and worker processes."""

import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import ENV, sweep_spec

from hubbeam_ctrl.cli.main import main
from hubbeam_ctrl.study.spec_files import load_spec
from hubbeam_ctrl.study.sweep import TIMING_COLUMNS, read_results, sweep

SPEC = sweep_spec(["openloop", "lqr"], 6.5, [0.0, 0.2, 0.4])


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _dask(*args):
    exe = shutil.which("dask", path=str(Path(sys.executable).parent))
    cmd = [exe, *args] if exe else [sys.executable, "-m", f"distributed.cli.dask_{args[0]}", *args[1:]]
    return subprocess.Popen(cmd, env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def _stop(proc) -> None:
    if proc.poll() is None:
        os.kill(proc.pid, 15)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            os.kill(proc.pid, 9)
            proc.wait()


@pytest.mark.slow
def test_cli_sweep_on_a_real_scheduler_equals_the_local_pool(tmp_path, capsys):
    pytest.importorskip("distributed")
    spec_file = tmp_path / "s.toml"
    spec_file.write_text(SPEC)
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs = [_dask("scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard")]
    try:
        deadline = time.time() + 120
        while time.time() < deadline:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                time.sleep(0.2)
        procs.append(_dask("worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard",
                           "--preload", "hubbeam_ctrl.study.sweep"))
        from distributed import Client
        with Client(address, timeout=60, set_as_default=False) as probe:
            probe.wait_for_workers(1, timeout=180)
        out = tmp_path / "cluster"
        status = main(["sweep", str(spec_file), "--out", str(out), "--scheduler", address, "--json"])
        assert status == 0, capsys.readouterr().err
    finally:
        for p in procs[::-1]:
            _stop(p)
    spec = load_spec(str(spec_file))
    cluster = read_results(out, spec)
    pool = sweep(spec, workers=2, progress=False)
    assert len(cluster) == 6 and (cluster["error"] == "").all()
    assert list(cluster.columns) == list(pool.columns)
    for c in cluster.columns:
        if c in TIMING_COLUMNS:
            continue
        x, y = cluster[c].to_numpy(), pool[c].to_numpy()
        if x.dtype.kind == "f":
            assert np.array_equal(x, y, equal_nan=True), c          # bit for bit
        else:
            assert list(x) == list(y), c


@pytest.mark.parametrize("address, text", [
    ("tcp://127.0.0.1:9", "no Dask scheduler answered"),
    ("foo://", "--scheduler must be an address tcp://HOST:PORT"),
    ("tcp://[::1", "--scheduler must be an address tcp://HOST:PORT"),
    ("tcp://127.0.0.1:99999", "--scheduler must be an address tcp://HOST:PORT"),
])
def test_unreachable_or_malformed_scheduler_is_one_line(tmp_path, capsys, address, text):
    spec_file = tmp_path / "s.toml"
    spec_file.write_text(SPEC)
    t0 = time.perf_counter()
    status = main(["sweep", str(spec_file), "--out", str(tmp_path / "o"), "--scheduler", address,
                   "--scheduler-timeout", "1"])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and text in err, err
    assert "Traceback" not in err and time.perf_counter() - t0 < 10
    assert not (tmp_path / "o").exists()


def test_a_server_that_is_not_a_scheduler_is_one_line(tmp_path):
    """A port that answers with garbage (here: a plain socket that sends bytes and closes)."""
    import threading
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(4)
    port = srv.getsockname()[1]

    def serve():
        while True:
            try:
                conn, _ = srv.accept()
            except OSError:
                return
            try:
                conn.sendall(b"\xff" * 64)
            except OSError:
                pass
            conn.close()
    threading.Thread(target=serve, daemon=True).start()
    spec_file = tmp_path / "s.toml"
    spec_file.write_text(SPEC)
    try:
        r = subprocess.run([sys.executable, "-m", "hubbeam_ctrl.cli", "sweep", str(spec_file), "--out",
                            str(tmp_path / "o"), "--scheduler", f"tcp://127.0.0.1:{port}",
                            "--scheduler-timeout", "2"], env=ENV, capture_output=True, text=True, timeout=120)
    finally:
        srv.close()
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "--scheduler" in r.stderr and "Traceback" not in r.stderr, r.stderr

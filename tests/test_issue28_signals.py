"""Issue 28: an interrupted ``hubbeam sweep --workers 2`` ends, and takes its processes with it.

Double Ctrl-C (SIGINT to the whole foreground process group, as a terminal sends it) used to
hang in the pool's shutdown; SIGTERM to the main process alone used to leave the forkserver
and the workers running, holding the pipes (``| tee`` never ended). Both cases run at once
in their own sessions; every wait is bounded and whatever is left is killed by its id.
"""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import ENV, sweep_spec

SPEC = sweep_spec(["lqr", "lqg"], 60.0, [0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35])


def _session(sid: int) -> list:
    """Live (not zombie) processes of session ``sid``."""
    pids = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_bytes().rsplit(b")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(stat[3]) == sid and stat[0] not in (b"Z", b"X"):
            pids.append(int(entry))
    return pids


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc to find the worker processes")
def test_double_ctrl_c_and_sigterm_stop_the_sweep_and_its_workers(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    procs = {how: subprocess.Popen([sys.executable, "-m", "hubbeam_ctrl.cli.main", "sweep", str(spec),
                                    "--workers", "2", "--out", str(tmp_path / how)],
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=ENV, cwd=tmp_path,
                                   start_new_session=True)
             for how in ("sigint_twice", "sigterm_main")}
    try:
        deadline = time.monotonic() + 60
        started = set()
        while len(started) < 2 and time.monotonic() < deadline:     # main, tracker, forkserver, 2 workers
            started |= {how for how, p in procs.items() if len(_session(p.pid)) >= 5}
            time.sleep(0.2)
        assert started == set(procs), "the workers did not start within 60 s"
        time.sleep(1.0)                                              # mid-batch
        os.killpg(procs["sigint_twice"].pid, signal.SIGINT)
        time.sleep(0.3)
        os.killpg(procs["sigint_twice"].pid, signal.SIGINT)
        procs["sigterm_main"].send_signal(signal.SIGTERM)           # the main process alone
        for how, p in procs.items():
            _, err = p.communicate(timeout=30)                       # EOF: no one holds the pipes
            assert "Traceback" not in err.decode(), how
            assert p.returncode in (130, -signal.SIGINT), (how, p.returncode)
        time.sleep(1.0)
        assert {how: _session(p.pid) for how, p in procs.items()} == {how: [] for how in procs}
    finally:
        for p in procs.values():
            for pid in _session(p.pid):
                os.kill(pid, signal.SIGKILL)
            if p.poll() is None:
                p.kill()
                p.wait(5)

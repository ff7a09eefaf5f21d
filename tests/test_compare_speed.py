"""What made ``hubbeam compare`` faster keeps its numbers (issue 28, Speed): the designs without
python-control give python-control's matrices bit for bit, the comparison's code path does not
import it, and a reused loop figure draws the same pixels as a new one. The timings themselves
are in benchmarks/bench_compare.py (a benchmark, not a test)."""

from __future__ import annotations

import io
import subprocess
import sys

import numpy as np
import pytest

from controllers import PD, DesignModel, Weights
from controllers.riccati import dlqe, dlqr
from hubbeam_ctrl.linear.statespace import linear_matrices, linearize
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.plots.loops import plot_loop
from hubbeam_ctrl.study.loops import loop_response


@pytest.fixture(scope="module")
def design():
    return DesignModel.build(Params(), 0.5, 0.01, 3)


def test_riccati_is_python_controls_scipy_path_bit_for_bit(design):
    """The SciPy path also with Slycot installed (the robust extra): Slycot's sg02ad fails on these designs."""
    control = pytest.importorskip("control")
    Q, R = Weights().matrices(design)
    for mine, theirs in zip(dlqr(design.Ad, design.Bd, Q, R),
                            control.dlqr(design.Ad, design.Bd, Q, R, method="scipy")):
        assert np.array_equal(mine, theirs)
    n = design.Ad.shape[0]
    Qn, Rn = 1e-6 * np.eye(n), np.diag([1e-6, 1e-4, 1e-2])
    for mine, theirs in zip(dlqe(design.Ad, np.eye(n), design.C_sensors, Qn, Rn),
                            control.dlqe(design.Ad, np.eye(n), design.C_sensors, Qn, Rn, method="scipy")):
        assert np.array_equal(mine, theirs)
    Q_bad = Q.copy()
    Q_bad[0, 1] += 1.0
    with pytest.raises(ValueError, match="Q must be a symmetric matrix"):
        dlqr(design.Ad, design.Bd, Q_bad, R)


def test_design_model_is_linearize_and_discretize_bit_for_bit(design):
    lm = design.linear_model                     # python-control's sampled system, built on first use
    assert np.array_equal(design.Ad, lm.A) and np.array_equal(design.Bd, lm.B)
    assert np.array_equal(design.C_sensors, lm.C[:3]) and np.array_equal(design.C_tip, lm.C[3:])
    assert design.state_names == list(lm.state_names)
    outputs = ("theta", "theta_dot", "root_moment")
    A, B, C, D = linear_matrices("sfoam", 0.5, design.params, outputs)
    ref = linearize("sfoam", 0.5, design.params, outputs)
    assert all(np.array_equal(x, y) for x, y in ((A, ref.A), (B, ref.B), (C, ref.C), (D, ref.D)))


def test_compare_path_imports_neither_python_control_nor_scipy_signal():
    """The comparison's designs, loop margins, certificate and loop data, as ``hubbeam compare``
    runs them, without python-control, SciPy's signal package or pyplot (about 1.5 s of import);
    nor Matplotlib at all (issue 37: the figure worker imports it while the controllers run)."""
    code = ("import sys\n"
            "import hubbeam_ctrl.cli.compare, hubbeam_ctrl.study.compare, hubbeam_ctrl.study.report\n"
            "from controllers import DesignModel, LQG, LQGSettings, LQR, LQRSettings\n"
            "from controllers.analysis import loop_margins\n"
            "from hubbeam_ctrl.study.certificate import certify\n"
            "from hubbeam_ctrl.study.loops import loop_response\n"
            "from hubbeam_ctrl.plant.params import Params\n"
            "d = DesignModel.build(Params(), 0.0, 0.01, 2)\n"
            "for ctrl in (LQR(d, LQRSettings()), LQG(d, LQGSettings())):\n"
            "    loop_margins(ctrl); loop_response(ctrl); certify(ctrl, Params(n_transverse=4))\n"
            "print(sorted(m for m in ('control', 'scipy.signal', 'scipy.stats', 'matplotlib')"
            " if m in sys.modules))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "[]"


def test_reused_loop_figure_draws_the_pixels_of_a_new_one(design):
    first = [loop_response(PD(DesignModel.build(Params(), 0.0, 0.01, 2)), t_end=5.0)]   # 2 modes at rest
    second = [loop_response(PD(design), t_end=5.0)]                                       # 3 modes, spinning

    def pixels(fig):
        buf = io.BytesIO()
        fig.savefig(buf, dpi=30, format="raw")
        return np.frombuffer(buf.getvalue(), np.uint8)

    fresh = pixels(plot_loop(second, "b"))
    fig = plot_loop(first, "a")
    pixels(fig)                                    # drawn once: ticks, limits and texts of the first loops
    again = plot_loop(second, "b", fig=fig)
    assert again is fig
    assert np.array_equal(pixels(again), fresh)


def test_split_frequency_response_keeps_the_margins_bit_for_bit(design, monkeypatch):
    """A hub-beam loop is not diagonalisable (the free hub's Jordan block at z = 1): its frequency
    response splits off the repeated eigenvalues (fast, for grids and plots); the margins' roots
    and peaks take the solves, so every margin is what the solves alone give, bit for bit."""
    import controllers.frequency as frequency
    from controllers import LQG, LQR
    from controllers.analysis import FrequencyResponse, frequency_grid, loop_margins, loop_matrices
    for ctrl in (PD(design), LQR(design), LQG(design)):
        A, B, C, D = loop_matrices(ctrl)
        fr = FrequencyResponse(A, B, C, D)
        assert fr._modal is None and fr._split is not None and fr._split[0].shape == (2, 2)   # the Jordan block
        z = np.exp(1j * frequency_grid(np.linalg.eigvals(A), ctrl.dt, 500) * ctrl.dt)
        fast, precise = fr(z), fr(z, precise=True)
        rel = np.abs(fast / precise - 1)
        assert np.median(rel) < 1e-10 and np.max(rel[np.abs(precise) < 1e5]) < 1e-2
        with_split = loop_margins(ctrl).to_dict()
        with monkeypatch.context() as m:
            m.setattr(frequency, "_cluster_split", lambda *a, **k: None)
            assert FrequencyResponse(A, B, C, D)._split is None
            solves = loop_margins(ctrl).to_dict()
        with_split.pop("disk_margin_grid"), solves.pop("disk_margin_grid")    # the grid's own maximum
        assert with_split == solves


def test_figure_worker_draws_the_bytes_of_a_figure_saved_here(tmp_path, monkeypatch):
    """A figure drawn by the forked worker, drawn here without one, and saved to a file by
    save_figure: the same PNG bytes (the report's files do not depend on where they were drawn)."""
    from types import SimpleNamespace

    from hubbeam_ctrl.plots import worker
    from hubbeam_ctrl.plots.closedloop import plot_torque
    from hubbeam_ctrl.plots.plant import save_figure
    t = np.linspace(0.0, 2.0, 201)
    runs = {"a": SimpleNamespace(t=t, tau=np.sin(3 * t), stopped=False),
            "b": SimpleNamespace(t=t, tau=np.cos(2 * t), stopped=True)}
    here = worker.render(plot_torque, runs, 1.0, "torque").result()
    assert not worker.running()
    try:
        assert worker.start() and worker.running()
        job = worker.render(plot_torque, runs, 1.0, "torque")
        assert job._future is not None                     # sent to the worker
        drawn = job.result()
    finally:
        worker.stop()
    assert not worker.running()
    save_figure(plot_torque(runs, 1.0, "torque"), tmp_path / "torque.png")
    assert drawn == here == (tmp_path / "torque.png").read_bytes()
    assert here[:8] == b"\x89PNG\r\n\x1a\n"

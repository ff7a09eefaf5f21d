"""Figures drawn into PNG bytes in a worker process while the caller computes.

Importing Matplotlib and drawing a comparison's four PNGs took about a second of
``hubbeam compare``'s five, all of it after the closed-loop runs. :func:`start` forks a
worker before the work starts; it imports Matplotlib and loads its fonts while the
controllers are designed and run, then draws each figure :func:`render` sends it (the
plotting function and its data) into PNG bytes, which the caller writes. Without a worker
(none started, or no ``fork`` on this system) :func:`render` draws in the calling process,
lazily, the same bytes.

Examples
--------
>>> from hubbeam_ctrl.plots.worker import render
>>> from hubbeam_ctrl.plots.plant import plot_campbell
>>> png = render(plot_campbell, [0.0, 1.0], [[0.5, 3.0], [0.6, 3.1]]).result()
>>> png[:8] == b"\\x89PNG\\r\\n\\x1a\\n"
True
"""

from __future__ import annotations

import io
import multiprocessing
import signal
import threading
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

__all__ = ["start", "stop", "render", "running", "PNG_OPTIONS"]

#: Pillow's options of every PNG (zlib level 1: the same pixels, encoded three times faster than
#: at Pillow's 6; see :func:`hubbeam_ctrl.plots.plant.save_figure`).
PNG_OPTIONS = {"compress_level": 1}

_POOL: ProcessPoolExecutor | None = None
_LOCK = threading.Lock()


def _warm() -> None:
    """In the worker: import Matplotlib's Agg canvas and Pillow, and draw text once (fonts).

    Ctrl-C is the caller's to handle (it stops the worker); SIGTERM ends the worker plainly
    (the caller's clean-up handlers, copied by the fork, are not the worker's to run).
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    from hubbeam_ctrl.plots.figure import new_figure
    fig = new_figure(figsize=(1, 1))
    fig.subplots().set_title("warm")
    fig.savefig(io.BytesIO(), format="png", dpi=20, pil_kwargs=PNG_OPTIONS)


def _draw(plot, args: tuple, kwargs: dict, dpi: int) -> bytes:
    """``plot(*args, **kwargs)`` saved as PNG bytes at ``dpi``."""
    fig = plot(*args, **kwargs)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, pil_kwargs=PNG_OPTIONS)
    return buf.getvalue()


def start(workers: int = 1) -> bool:
    """Fork the figure worker(s) now, so that they import Matplotlib while the caller computes.

    Call it before the work whose figures :func:`render` will draw; a second call while
    they run does nothing. The workers hold a copy of the caller's memory as it is now:
    what :func:`render` sends them later is pickled.

    Parameters
    ----------
    workers : int
        Worker processes (each draws one figure at a time).

    Returns
    -------
    bool
        True when workers run; False where ``fork`` is not available (figures are then
        drawn in the calling process).
    """
    global _POOL
    with _LOCK:
        if _POOL is not None:
            return True
        if "fork" not in multiprocessing.get_all_start_methods():
            return False
        _POOL = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("fork"),
                                    initializer=_warm)
        _POOL.submit(int)                    # forks the workers now (a fork pool starts them all at once)
        return True


def running() -> bool:
    """Whether :func:`start` started workers that :func:`stop` has not stopped."""
    return _POOL is not None


def stop() -> None:
    """Stop the workers (figures not yet drawn are dropped); :func:`render` then draws in-process."""
    global _POOL
    with _LOCK:
        pool, _POOL = _POOL, None
    if pool is not None:
        pool.shutdown(wait=True, cancel_futures=True)


class _Job:
    """A figure's PNG: the worker's future, or drawn here when asked for (no worker, or it died)."""

    def __init__(self, plot, args, kwargs, dpi, future: Future | None = None):
        self._job, self._future, self._png = (plot, args, kwargs, dpi), future, None

    def result(self) -> bytes:
        """The PNG's bytes (an exception of the drawing is raised here)."""
        if self._png is None and self._future is not None:
            try:
                self._png = self._future.result()
            except BrokenProcessPool:            # the worker was killed: draw here
                self._future = None
        if self._png is None:
            self._png = _draw(*self._job)
        return self._png


def render(plot, *args, dpi: int = 120, **kwargs) -> _Job:
    """``plot(*args, **kwargs)`` as PNG bytes: drawn by the worker when one runs, else here.

    Parameters
    ----------
    plot : callable
        A module-level function returning a :class:`matplotlib.figure.Figure` (sent to the
        worker by reference, its arguments pickled).
    *args, **kwargs
        Its arguments (data: arrays, numbers, strings, dicts, dataclasses).
    dpi : int
        Resolution of the PNG [dots per inch].

    Returns
    -------
    object
        ``.result()`` gives the PNG's bytes (an exception of the drawing is raised there).
    """
    pool, future = _POOL, None
    if pool is not None:
        try:
            future = pool.submit(_draw, plot, args, kwargs, dpi)
        except (RuntimeError, BrokenProcessPool):     # shut down meanwhile, or the worker died
            future = None
    return _Job(plot, args, kwargs, dpi, future)

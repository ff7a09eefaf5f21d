"""A Matplotlib figure, with Matplotlib imported on first use.

The plotting modules make their figures with :func:`new_figure`, so importing them (and the
study layer that uses them) does not import Matplotlib: a command that draws nothing, or
that draws in a worker process (:mod:`hubbeam_ctrl.plots.worker`), does not pay for it.
"""

from __future__ import annotations

__all__ = ["new_figure"]


def new_figure(**kwargs):
    """``matplotlib.figure.Figure(**kwargs)`` (no pyplot, no global state).

    Parameters
    ----------
    **kwargs
        Passed to :class:`matplotlib.figure.Figure` (``figsize`` [in], ``constrained_layout``...).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure
    return Figure(**kwargs)

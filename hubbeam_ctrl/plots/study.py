"""Plots of robustness studies (a sweep's DataFrame in, a Matplotlib figure out).

The DataFrame has one row per (case, controller) with the factor values as columns, as
:func:`hubbeam_ctrl.study.sweep.sweep` returns it; nothing is computed here beyond
grouping. A row counts as *unstable* when its ``verdict`` says ``unstable`` or
``diverged``, or (without a verdict) when the run did not complete or raised.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hubbeam_ctrl.plots.figure import new_figure

if TYPE_CHECKING:                  # Matplotlib is imported when a figure is made, not on import
    from matplotlib.figure import Figure

__all__ = ["plot_robustness_curves", "plot_heatmap", "plot_stable_region", "plot_convergence", "unstable_mask",
           "ROBUSTNESS_METRICS"]

#: Metrics drawn against each factor: column -> (axis label, log scale).
ROBUSTNESS_METRICS = {
    "residual_tip_max_m": ("residual max |v_tip| [m]", True),
    "peak_tip_m": ("peak |v_tip| [m]", False),
    "final_angle_error_rad": ("|final angle error| [rad]", True),
    "peak_torque_nm": ("peak |tau| [N m]", False),
}


def unstable_mask(df) -> np.ndarray:
    """Boolean array: rows whose run was unstable, diverged or failed (see module docstring).

    Parameters
    ----------
    df : pandas.DataFrame
        Sweep results (:func:`hubbeam_ctrl.study.sweep.sweep`).
    """
    verdict = df["verdict"].astype(object) if "verdict" in df else None
    failed = (df["error"].astype(str) != "") | (~df["completed"].astype(bool))
    if verdict is None:
        return failed.to_numpy()
    has = verdict.notna() & (verdict.astype(str) != "")
    bad = verdict.isin(["unstable", "diverged", "failed"])
    return np.where(has.to_numpy(), bad.to_numpy(), failed.to_numpy())


def _controllers(df, controllers):
    return list(controllers) if controllers is not None else list(dict.fromkeys(df["controller"]))


def plot_robustness_curves(df, factor: str, metrics=None, controllers=None, title: str = "",
                           styles: dict | None = None) -> Figure:
    """Each metric against one factor, one colour per controller.

    Every case is a dot; the line joins the worst case (largest absolute value) at each
    factor value, so a grid shows its worst case over the other factors and a Monte Carlo
    study shows its scatter.

    Parameters
    ----------
    df : pandas.DataFrame
        Sweep rows.
    factor : str
        Column on the horizontal axis.
    metrics : sequence of str, optional
        Columns to plot (default :data:`ROBUSTNESS_METRICS` present in ``df``).
    controllers : sequence of str, optional
        Default: all in ``df``, in order.
    title : str
    styles : dict, optional
        Controller name -> ``{"color": ..., "label": ...}`` (e.g. :func:`controllers.controller_styles`);
        default: Matplotlib's colour cycle and the names.

    Returns
    -------
    Figure
    """
    names = _controllers(df, controllers)
    style = {n: (styles or {}).get(n, {}) for n in names}
    color = {n: style[n].get("color") or f"C{i}" for i, n in enumerate(names)}
    metrics = [m for m in (metrics or ROBUSTNESS_METRICS) if m in df]
    fig = new_figure(figsize=(5.0 * min(len(metrics), 2), 3.4 * _ceil_div(len(metrics), 2)), constrained_layout=True)
    axes = np.atleast_1d(fig.subplots(_ceil_div(len(metrics), 2), min(len(metrics), 2), squeeze=False)).ravel()
    for ax, metric in zip(axes, metrics):
        label, log = ROBUSTNESS_METRICS.get(metric, (metric, False))
        for name in names:
            sub = df[df["controller"] == name]
            x = sub[factor].to_numpy(dtype=float)
            y = np.abs(sub[metric].to_numpy(dtype=float))
            ax.plot(x, y, ".", color=color[name], alpha=0.5)
            xs = np.unique(x[np.isfinite(x)])
            worst = [np.nanmax(y[x == v]) if np.any(np.isfinite(y[x == v])) else np.nan for v in xs]
            ax.plot(xs, worst, "-", color=color[name], label=style[name].get("label") or name)
        ax.set_xlabel(factor)
        ax.set_ylabel(label)
        if log:
            ax.set_yscale("log")
        ax.grid(True, alpha=0.3)
    for ax in axes[len(metrics):]:
        ax.set_visible(False)
    axes[0].legend(fontsize="small")
    fig.suptitle(title or f"Robustness against {factor} (line: worst case)")
    return fig


def _ceil_div(a: int, b: int) -> int:
    return max(1, -(-a // b))


def plot_heatmap(df, x: str, y: str, metric: str = "residual_tip_max_m", controllers=None,
                 title: str = "") -> Figure:
    """Worst case of ``metric`` over two factors, one panel per controller (log colour scale).

    Parameters
    ----------
    df : pandas.DataFrame
    x, y : str
        Factor columns (their distinct values make the grid).
    metric : str
    controllers : sequence of str, optional
    title : str

    Returns
    -------
    Figure
    """
    from matplotlib.colors import LogNorm
    names = _controllers(df, controllers)
    fig = new_figure(figsize=(4.2 * len(names), 3.6), constrained_layout=True)
    axes = np.atleast_1d(fig.subplots(1, len(names), squeeze=False)).ravel()
    xs, ys = np.unique(df[x].to_numpy(dtype=float)), np.unique(df[y].to_numpy(dtype=float))
    grids = [_worst_grid(df[df["controller"] == n], x, y, metric, xs, ys) for n in names]
    finite = np.concatenate([g[np.isfinite(g) & (g > 0)] for g in grids] + [np.array([1.0])])
    norm = LogNorm(vmin=finite.min(), vmax=max(finite.max(), finite.min() * 1.0001))
    for ax, name, grid in zip(axes, names, grids):
        im = ax.pcolormesh(_edges(xs), _edges(ys), np.ma.masked_invalid(grid), norm=norm, cmap="viridis")
        ax.set_title(name)
        ax.set_xlabel(x)
        ax.set_ylabel(y)
    fig.colorbar(im, ax=list(axes), label=f"worst {metric}")
    fig.suptitle(title or f"Worst-case {metric} over {x} and {y}")
    return fig


def _worst_grid(sub, x, y, metric, xs, ys) -> np.ndarray:
    grid = np.full((len(ys), len(xs)), np.nan)
    vx, vy = sub[x].to_numpy(dtype=float), sub[y].to_numpy(dtype=float)
    vm = np.abs(sub[metric].to_numpy(dtype=float))
    for i, yv in enumerate(ys):
        for j, xv in enumerate(xs):
            vals = vm[(vx == xv) & (vy == yv)]
            if np.any(np.isfinite(vals)):
                grid[i, j] = np.nanmax(vals)
    return grid


def _edges(v: np.ndarray) -> np.ndarray:
    if len(v) == 1:
        return np.array([v[0] - 0.5, v[0] + 0.5]) if v[0] == 0 else v[0] * np.array([0.9, 1.1])
    mid = 0.5 * (v[1:] + v[:-1])
    return np.concatenate([[2 * v[0] - mid[0]], mid, [2 * v[-1] - mid[-1]]])


def plot_stable_region(df, x: str, y: str | None = None, controllers=None, title: str = "") -> Figure:
    """Stable and unstable cases over one or two factors, one panel per controller.

    Parameters
    ----------
    df : pandas.DataFrame
    x : str
        Factor on the horizontal axis.
    y : str, optional
        Second factor (default: the controllers are stacked on one axis).
    controllers : sequence of str, optional
    title : str

    Returns
    -------
    Figure
    """
    names = _controllers(df, controllers)
    bad = unstable_mask(df)
    from matplotlib.colors import ListedColormap
    cmap = ListedColormap(["tab:green", "tab:red"])
    fig = new_figure(figsize=(4.2 * len(names) if y else 7, 3.6 if y else 1 + 0.5 * len(names)),
                 constrained_layout=True)
    axes = np.atleast_1d(fig.subplots(1, len(names) if y else 1, squeeze=False)).ravel()
    for k, name in enumerate(names):
        sel = (df["controller"] == name).to_numpy()
        ax = axes[k] if y else axes[0]
        yy = df.loc[sel, y].to_numpy(dtype=float) if y else np.full(sel.sum(), k)
        ax.scatter(df.loc[sel, x].to_numpy(dtype=float), yy, c=bad[sel].astype(int), cmap=cmap,
                   vmin=0, vmax=1, s=28, marker="s")
        if y:
            ax.set_title(name)
            ax.set_ylabel(y)
        ax.set_xlabel(x)
    if not y:
        axes[0].set_yticks(range(len(names)), names)
        axes[0].set_ylim(-0.5, len(names) - 0.5)
    fig.suptitle(title or "Stable (green) and unstable, diverged or failed (red) cases")
    return fig


def plot_convergence(history, reference: float | None = None, title: str = "") -> Figure:
    """Best objective after each generation of a tuner.

    Parameters
    ----------
    history : sequence of float
        Best objective per generation.
    reference : float, optional
        Objective of the starting design (dashed line).
    title : str

    Returns
    -------
    Figure
    """
    fig = new_figure(figsize=(6, 3.6), constrained_layout=True)
    ax = fig.subplots()
    gen = np.arange(1, len(history) + 1)
    ax.plot(gen, history, "o-", label="best candidate")
    if reference is not None:
        ax.axhline(reference, color="0.4", ls="--", label="starting design")
    ax.set_xlabel("generation")
    ax.set_ylabel("objective")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    ax.set_title(title or "Convergence")
    return fig

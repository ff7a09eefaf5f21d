"""Outputs of a robustness study: ``summary.csv``, robustness plots and ``report.md``."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from controllers import controller_styles
from hubbeam_ctrl.core.fileio import atomic_write_text
from hubbeam_ctrl.plots.plant import save_figure
from hubbeam_ctrl.plots.study import (
    plot_heatmap,
    plot_robustness_curves,
    plot_stable_region,
)
from hubbeam_ctrl.study.spec import StudySpec

__all__ = ["summarize", "write_sweep_outputs", "SUMMARY_COLUMNS"]

#: Columns of summary.csv, one row per controller.
SUMMARY_COLUMNS = ("controller", "n_cases", "n_errors", "residual_tip_max_m_worst", "residual_tip_max_m_median",
                   "residual_pct_of_openloop_worst", "peak_tip_m_worst", "abs_final_angle_error_rad_worst",
                   "peak_torque_nm_worst", "settling_time_s_worst", "fraction_settled", "fraction_unstable",
                   "fraction_failed")


def _worst(values) -> float:
    v = np.abs(np.asarray(values, dtype=float))
    return float(np.nanmax(v)) if np.any(np.isfinite(v)) else math.nan


def summarize(df):
    """Per controller: worst case and median over the cases, fractions settled, unstable and failed.

    ``fraction_unstable`` counts the verdicts ``unstable`` and ``diverged``;
    ``fraction_failed`` the runs whose integrator or controller failed (verdict ``failed``)
    and the cases that raised: a failed run says nothing about the loop's stability.
    Worst cases are taken over the cases that ran;
    ``settling_time_s_worst`` is NaN when any case did not settle. Settled means the
    verdict says so or, without a verdict, a finite settling time.

    Parameters
    ----------
    df : pandas.DataFrame
        Rows of :func:`hubbeam_ctrl.study.sweep.sweep`.

    Returns
    -------
    pandas.DataFrame
        Columns :data:`SUMMARY_COLUMNS`.
    """
    import pandas as pd
    rows = []
    for name in dict.fromkeys(df["controller"]):
        sel = (df["controller"] == name).to_numpy()
        sub = df[sel]
        settle = sub["settling_time_s"].to_numpy(dtype=float)
        verdict = sub["verdict"].astype(object).where(sub["verdict"].notna(), "").astype(str)
        settled = np.where(verdict != "", verdict == "settled", np.isfinite(settle))
        errors = (sub["error"].astype(str) != "").to_numpy()
        failed = (verdict == "failed").to_numpy() | errors
        unstable = verdict.isin(["unstable", "diverged"]).to_numpy() | \
            ((verdict == "").to_numpy() & ~errors & ~sub["completed"].astype(bool).to_numpy())
        rows.append({
            "controller": name, "n_cases": int(sel.sum()), "n_errors": int((sub["error"].astype(str) != "").sum()),
            "residual_tip_max_m_worst": _worst(sub["residual_tip_max_m"]),
            "residual_tip_max_m_median": float(np.nanmedian(sub["residual_tip_max_m"].to_numpy(dtype=float)))
            if np.any(np.isfinite(sub["residual_tip_max_m"].to_numpy(dtype=float))) else math.nan,
            "residual_pct_of_openloop_worst": _worst(sub["residual_pct_of_openloop"]),
            "peak_tip_m_worst": _worst(sub["peak_tip_m"]),
            "abs_final_angle_error_rad_worst": _worst(sub["final_angle_error_rad"]),
            "peak_torque_nm_worst": _worst(sub["peak_torque_nm"]),
            "settling_time_s_worst": float(np.max(settle)) if np.all(np.isfinite(settle)) else math.nan,
            "fraction_settled": float(np.mean(settled)), "fraction_unstable": float(np.mean(unstable)),
            "fraction_failed": float(np.mean(failed)),
        })
    return pd.DataFrame(rows, columns=list(SUMMARY_COLUMNS))


def _plot_factors(df, spec: StudySpec) -> list:
    """Factors that take more than one value (the ones worth a plot), numeric only."""
    out = []
    for f in spec.factors:
        vals = df[f].dropna()
        if vals.nunique() > 1 and np.issubdtype(vals.to_numpy().dtype, np.number):
            out.append(f)
    return out


def write_sweep_outputs(df, spec: StudySpec, out_dir, wall_s: float | None = None) -> dict:
    """Write summary.csv, robustness_<factor>.png, heatmap.png, stable_region.png and report.md.

    Parameters
    ----------
    df : pandas.DataFrame
        Rows of :func:`hubbeam_ctrl.study.sweep.sweep`.
    spec : StudySpec
    out_dir : str or Path
        Existing folder (the one holding results.csv).
    wall_s : float, optional
        Wall time of the study [s], for the report.

    Returns
    -------
    dict
        File kind -> Path.
    """
    out = Path(out_dir)
    summary = summarize(df)
    paths = {"summary": atomic_write_text(out / "summary.csv", summary.to_csv(index=False))}
    factors = _plot_factors(df, spec)
    styles = controller_styles(spec.controllers)
    for f in factors:
        paths[f"robustness_{f}"] = save_figure(plot_robustness_curves(df, f, styles=styles),
                                               out / f"robustness_{f}.png")
    if len(factors) >= 2:
        paths["heatmap"] = save_figure(plot_heatmap(df, factors[0], factors[1]), out / "heatmap.png")
    if factors:
        y = factors[1] if len(factors) >= 2 else None
        paths["stable_region"] = save_figure(plot_stable_region(df, factors[0], y), out / "stable_region.png")
    paths["report"] = atomic_write_text(out / "report.md", _report(df, summary, spec, paths, wall_s))
    return paths


def _fmt(v) -> str:
    if isinstance(v, float):
        return "-" if not math.isfinite(v) else f"{v:.3g}"
    return str(v)


def _report(df, summary, spec: StudySpec, paths: dict, wall_s) -> str:
    n_cases = df["case"].nunique() if len(df) else 0
    spread = [f"`{f}` over {df[f].nunique()} values" for f in spec.factors]
    lines = [f"# Robustness study: {spec.scenario} on {spec.plant.upper()}", "",
             f"- Cases: {n_cases} ({', '.join(spread) or 'base parameters only'}); controllers: "
             f"{', '.join(spec.controllers)}.",
             f"- Design: {'on the base parameters' if spec.design == 'base' else 'redesigned for each case'} "
             f"(m_t = {spec.params.m_t:g} kg, {spec.params.n_axial}+{spec.params.n_transverse} modes); "
             f"tau_max = {spec.torque_budget:g} N m, t_f = {spec.t_f:g} s, t_end = {spec.t_end:g} s, "
             f"dt = {spec.dt:g} s.",
             f"- Spec hash {spec.hash()[:12]}" + (f"; wall time {wall_s:.1f} s." if wall_s is not None else "."),
             "", "| " + " | ".join(summary.columns) + " |", "|" + "---|" * len(summary.columns)]
    lines += ["| " + " | ".join(_fmt(v) for v in row) + " |" for row in summary.itertuples(index=False)]
    errors = df[df["error"].astype(str) != ""]
    if len(errors):
        lines += ["", "## Failed runs", ""]
        lines += [f"- case {r.case}, {r.controller}: {r.error}" for r in errors.head(20).itertuples()]
    lines += ["", "## Plots", ""]
    lines += [f"![{k}]({Path(p).name})" for k, p in paths.items() if str(p).endswith(".png")]
    return "\n".join(lines) + "\n"

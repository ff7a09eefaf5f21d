"""Outputs of a comparison: metrics.csv, metrics.json, plots, report.md and printed tables."""

from __future__ import annotations

import csv
import io
import math
import sys
from pathlib import Path

import numpy as np

from hubbeam_ctrl.core.fileio import atomic_write_text, strict_json, write_folder
from hubbeam_ctrl.plots.closedloop import plot_hub_angle, plot_tip_deflection, plot_torque
from hubbeam_ctrl.plots.plant import save_figure
from hubbeam_ctrl.study.metrics import METRIC_UNITS

__all__ = ["write_outputs", "print_table", "format_table", "markdown_table", "CSV_FIELDS"]


# -- output -----------------------------------------------------------------------------------
#: Columns of metrics.csv, in order.
CSV_FIELDS = (["controller", "plant", "scenario"] + list(METRIC_UNITS)
              + ["residual_pct_of_openloop", "within_torque_limit", "completed", "qp_solves",
                 "qp_fallbacks", "fallback_fraction", "wall_s", "message"])


def _clean(value):
    if isinstance(value, (np.floating, np.integer)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _json_metrics(metrics: dict) -> list:
    return [{k: _clean(v) for k, v in m.items()} for m in metrics.values()]


def _targets(comparison) -> list:
    """Rows ``(controller, residual_ok, torque_ok, angle_ok)`` of the slew targets."""
    m = comparison.metrics
    rows = []
    base = m.get("openloop", {}).get("residual_tip_max_m")
    for name, mm in m.items():
        res_ok = (base is not None and mm["residual_tip_max_m"] <= 0.01 * base) if name != "openloop" else None
        rows.append((name, res_ok, mm.get("within_torque_limit"),
                     abs(mm["final_angle_error_rad"]) <= 1e-3))
    return rows


def write_outputs(comparison, out_dir) -> dict:
    """Write metrics.csv, metrics.json, tip_deflection.png, hub_angle.png, torque.png, report.md.

    The files go through :func:`~hubbeam_ctrl.core.fileio.write_folder`: a new folder appears
    complete in one rename, an existing one is updated file by file, and ``MANIFEST.json``
    (written last) tells a finished folder from an interrupted one.

    Parameters
    ----------
    comparison : Comparison
    out_dir : str or Path
        Created if missing (its parent must exist).

    Returns
    -------
    dict
        File kind -> Path (in ``out_dir``).
    """
    out = Path(out_dir)
    names = {"csv": "metrics.csv", "json": "metrics.json", "tip_deflection.png": "tip_deflection.png",
             "hub_angle.png": "hub_angle.png", "torque.png": "torque.png", "report": "report.md"}
    write_folder(out, lambda folder: _write_files(comparison, Path(folder), names))
    paths = {kind: out / name for kind, name in names.items()}
    comparison.paths = paths
    return paths


def _write_files(comparison, out: Path, names: dict) -> None:
    """The files of :func:`write_outputs`, written into ``out``."""
    sc, metrics, results = comparison.scenario, comparison.metrics, comparison.results
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=CSV_FIELDS, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for m in metrics.values():
        writer.writerow({k: ("" if _clean(m.get(k)) is None else _clean(m.get(k))) for k in CSV_FIELDS})
    atomic_write_text(out / names["csv"], buf.getvalue())
    atomic_write_text(out / names["json"], strict_json(_json_metrics(metrics), indent=2) + "\n")
    title = f"{sc.plant.upper()}, {sc.name}: "
    styles = comparison.styles
    figs = {
        "tip_deflection.png": plot_tip_deflection(results, sc.t_f, sc.t_f + 5.0,
                                                  title + "tip deflection (shaded: residual window)",
                                                  styles=styles),
        "hub_angle.png": plot_hub_angle(results, sc.t_f, title + "hub angle and error vs reference",
                                        styles=styles),
        "torque.png": plot_torque(results, sc.tau_max, title + "hub torque (dotted: +-tau_max)",
                                  styles=styles),
    }
    for fname, fig in figs.items():
        save_figure(fig, out / names[fname])
    atomic_write_text(out / names["report"], _report(comparison))


def _report(comparison) -> str:
    sc = comparison.scenario
    lines = [f"# Closed-loop comparison: {sc.name} on {sc.plant.upper()}", "",
             f"- Scenario: {sc.description}.",
             f"- Feedback reference: {sc.reference.description}.",
             f"- Torque budget tau_max = {sc.tau_max:g} N m; sample time {sc.dt * 1e3:g} ms "
             f"(zero-order hold); t_end = {sc.t_end:g} s.",
             f"- Design model: SFOAM linearised at {sc.design_spin:g} rad/s; plant {sc.plant.upper()} "
             f"with {sc.params.n_axial} axial and {sc.params.n_transverse} transverse modes, "
             f"m_t = {sc.params.m_t:g} kg.",
             f"- Residual vibration: |v_tip| from tf + 5 s = {sc.t_f + 5:g} s to the end. "
             f"Settling: hub-angle error within 1 mrad and |v_tip| within 1 mm for good.",
             f"- Wall time of the comparison: {comparison.wall_s:.1f} s.", "",
             markdown_table(comparison.metrics), ""]
    if sc.name == "slew" and "openloop" in comparison.metrics:
        lines += ["## Targets (slew)", "",
                  "| controller | residual <= 1 % of open loop | abs(tau) <= tau_max | final error <= 1 mrad |",
                  "|---|---|---|---|"]
        yes = {True: "yes", False: "**no**", None: "-"}
        for name, r_ok, t_ok, a_ok in _targets(comparison):
            note = "" if name in comparison.targets or name == "openloop" else " (reported only)"
            lines.append(f"| {name}{note} | {yes[r_ok]} | {yes[t_ok]} | {yes[a_ok]} |")
        lines.append("")
    notes = [f"- {name}: {m['message']}" for name, m in comparison.metrics.items() if not m["completed"]]
    notes += [f"- {name}: {m['qp_fallbacks']} of {m['qp_solves']} QPs failed and fell back to LQR"
              for name, m in comparison.metrics.items() if m.get("qp_fallbacks")]
    if notes:
        lines += ["## Notes", ""] + notes + [""]
    lines += ["## Plots", "", "![tip deflection](tip_deflection.png)", "",
              "![hub angle](hub_angle.png)", "", "![torque](torque.png)", ""]
    return "\n".join(lines)


_TABLE = [
    ("controller", "controller", "{}"),
    ("peak_tip_m", "peak v_tip m", "{:.4f}"),
    ("residual_tip_max_m", "resid max m", "{:.2e}"),
    ("residual_tip_rms_m", "resid rms m", "{:.2e}"),
    ("residual_pct_of_openloop", "% of OL", "{:.3g}"),
    ("angle_error_tf_rad", "err(tf) rad", "{:.2e}"),
    ("final_angle_error_rad", "err(end) rad", "{:.2e}"),
    ("settling_time_s", "settle s", "{:.2f}"),
    ("peak_torque_nm", "peak tau Nm", "{:.1f}"),
    ("torque_squared_integral_n2m2s", "int tau^2", "{:.3g}"),
    ("step_time_median_ms", "step med ms", "{:.3f}"),
    ("step_time_p99_ms", "step p99 ms", "{:.3f}"),
]


def _cells(m: dict) -> list:
    cells = []
    for key, _, fmt in _TABLE:
        v = _clean(m.get(key))
        cells.append("-" if v is None else (fmt.format(v) if not isinstance(v, str) else v))
    if not m.get("completed", True):
        cells[0] += " (stopped)"
    if m.get("qp_fallbacks"):
        cells[0] += f" [{m['qp_fallbacks']} fb]"
    return cells


def format_table(metrics: dict) -> str:
    """The metrics as an aligned plain-text table."""
    rows = [[h for _, h, _ in _TABLE]] + [_cells(m) for m in metrics.values()]
    widths = [max(len(r[i]) for r in rows) for i in range(len(_TABLE))]
    return "\n".join("  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths)))
                     for r in rows)


def markdown_table(metrics: dict) -> str:
    """The metrics as a Markdown table."""
    head = [h for _, h, _ in _TABLE]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(_cells(m)) + " |" for m in metrics.values()]
    return "\n".join(lines)


def print_table(metrics, file=None) -> None:
    """Print the metrics of :func:`run_compare` (or a :class:`Comparison`) as a table."""
    if hasattr(metrics, "metrics"):
        metrics = metrics.metrics
    print(format_table(metrics), file=file or sys.stdout)



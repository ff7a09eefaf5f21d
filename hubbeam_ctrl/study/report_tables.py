"""The printed and Markdown tables of a comparison's metrics (``hubbeam compare``'s table,
report.md's): one column per metric, formatted with its unit (split from
:mod:`hubbeam_ctrl.study.report`, which re-exports them)."""

from __future__ import annotations

import math
import sys

import numpy as np

__all__ = ["format_table", "markdown_table", "print_table", "against_openloop"]


def _clean(value):
    if isinstance(value, (np.floating, np.integer)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value



#: Format of a quantity in the command's unit: the number and its unit (``command_unit``).
_COMMAND = "command"
#: Columns shown only when some run has them (a DC motor's voltage and current).
_OPTIONAL = ("peak_voltage_v", "peak_current_a")

_TABLE = [
    ("verdict", "verdict", "{}"),
    ("controller", "controller", "{}"),
    ("peak_tip_m", "peak v_tip m", "{:.4f}"),
    ("residual_tip_max_m", "resid max m", "{:.2e}"),
    ("residual_tip_rms_m", "resid rms m", "{:.2e}"),
    ("residual_pct_of_L", "resid %L", "{:.3g}"),
    ("residual_pct_of_openloop", "% of OL", "{:.3g}"),
    ("angle_error_tf_rad", "err(tf) rad", "{:.2e}"),
    ("final_angle_error_rad", "err(end) rad", "{:.2e}"),
    ("settling_time_s", "settle s", "{:.2f}"),
    ("settling_over_limit", "settle/limit", "{:.2f}"),
    ("peak_command", "peak u", _COMMAND),
    ("peak_command_step", "max du/sample", _COMMAND),
    ("time_at_limit_s", "u at limit s", "{:.3g}"),
    ("peak_hub_torque_nm", "peak tau_hub Nm", "{:.4g}"),
    ("peak_voltage_v", "peak V", "{:.3g}"),
    ("peak_current_a", "peak A", "{:.3g}"),
    ("loop_spectral_radius", "loop |z|", "{:.7f}"),
    ("torque_squared_integral_n2m2s", "int tau_hub^2", "{:.3g}"),
    ("step_time_median_ms", "step med ms", "{:.3f}"),
    ("step_time_p99_ms", "step p99 ms", "{:.3f}"),
]


def _columns(metrics: dict) -> list:
    """The table's columns for these runs (a DC motor's voltage and current only when present)."""
    return [c for c in _TABLE if c[0] not in _OPTIONAL
            or any(_clean(m.get(c[0])) is not None for m in metrics.values())]


def against_openloop(metrics: dict, band: float) -> list:
    """Each run's residual in % of the open loop's (``residual_pct_of_openloop``, in place) and the
    report's line when the open loop's residual is already within the tip band: the ``% of OL`` column
    then compares a quiet run with another and reads ``OL in band`` (``openloop_within_tip_band``;
    found on slow space booms, where it read 10^6-10^20 %).

    Parameters
    ----------
    metrics : dict
        Controller name -> metrics, updated in place; nothing without an ``openloop`` run.
    band : float
        The task's tip band [m].

    Returns
    -------
    list of str
        The line, or nothing.
    """
    if "openloop" not in metrics:
        return []
    base = metrics["openloop"]["residual_tip_max_m"]
    finite = base is not None and math.isfinite(base)
    quiet = finite and base <= band
    for m in metrics.values():
        m["residual_pct_of_openloop"] = 100.0 * m["residual_tip_max_m"] / base if finite and base else float("nan")
        m["openloop_within_tip_band"] = bool(quiet)
    if not quiet:
        return []
    ol = metrics["openloop"]
    err, angle_band = ol.get("final_angle_error_rad"), ol.get("settle_angle_rad")
    missed = (f", but it ends {abs(err):.3g} rad off the target, outside the angle band {angle_band:.3g} rad: it "
              "did not do the task (a drive that cannot break the hub's friction away leaves no vibration)"
              if err is not None and angle_band is not None and abs(err) > angle_band else "")
    return [f"the open loop's residual {base:.3g} m is within the tip band {band:.3g} m{missed}: `% of OL` compares "
            "a quiet run with another and is left out of the table (metrics.json keeps it); the bands judge the runs"]


def _cells(m: dict, columns=None) -> list:
    cells = []
    for key, _, fmt in (columns or _TABLE):
        v = _clean(m.get(key))
        if v is not None and fmt == _COMMAND:
            cells.append(f"{v:.3g} {m.get('command_unit', 'N m')}")
            continue
        cells.append("-" if v is None else (fmt.format(v) if not isinstance(v, str) else v))
    keys = [c[0] for c in (columns or _TABLE)]
    if m.get("openloop_within_tip_band") and "residual_pct_of_openloop" in keys:
        cells[keys.index("residual_pct_of_openloop")] = "OL in band"
    if not m.get("completed", True):
        cells[1] += " (stopped)"
    if m.get("outside_validated_range"):
        cells[1] += " (>range)"
    if m.get("qp_fallbacks"):
        cells[1] += f" [{m['qp_fallbacks']} fb]"
    return cells


def format_table(metrics: dict) -> str:
    """The metrics as an aligned plain-text table.

    Parameters
    ----------
    metrics : dict
        Controller name -> metrics.
    """
    columns = _columns(metrics)
    rows = [[h for _, h, _ in columns]] + [_cells(m, columns) for m in metrics.values()]
    widths = [max(len(r[i]) for r in rows) for i in range(len(columns))]
    return "\n".join("  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths)))
                     for r in rows)


def markdown_table(metrics: dict) -> str:
    """The metrics as a Markdown table.

    Parameters
    ----------
    metrics : dict
        Controller name -> metrics.
    """
    columns = _columns(metrics)
    head = [h for _, h, _ in columns]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(_cells(m, columns)) + " |" for m in metrics.values()]
    return "\n".join(lines)


def print_table(metrics, file=None) -> None:
    """Print the metrics of :func:`run_compare` (or a :class:`Comparison`) as a table.

    Parameters
    ----------
    metrics : dict or Comparison
        Controller name -> metrics, or a comparison.
    file : file-like, optional
        Where to print (default ``sys.stdout``).
    """
    if hasattr(metrics, "metrics"):
        metrics = metrics.metrics
    print(format_table(metrics), file=file or sys.stdout)

"""Outputs of a comparison: metrics.csv, metrics.json, plots, report.md and printed tables."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from types import SimpleNamespace

from hubbeam_ctrl.core.fileio import atomic_write_text, write_folder
from hubbeam_ctrl.core.jsonio import strict_json
from hubbeam_ctrl.plots.closedloop import plot_hub_angle, plot_tip_deflection, plot_torque
from hubbeam_ctrl.plots.loops import plot_loop_comparison
from hubbeam_ctrl.plots.plant import save_png
from hubbeam_ctrl.plots.worker import render
from hubbeam_ctrl.study.drive_figures import drive_of
from hubbeam_ctrl.study.metrics import METRIC_UNITS, SATURATION_LIMIT
from hubbeam_ctrl.study.report_rig import damping_text, rig_lines
from hubbeam_ctrl.study.report_tables import _clean, format_table, markdown_table, print_table  # noqa: F401
from hubbeam_ctrl.study.yardstick import DRIVE_BOUND

__all__ = ["write_outputs", "loop_png", "print_table", "format_table", "markdown_table", "CSV_FIELDS", "PLANT_NOTE",
           "check_plant_lines", "ladder_lines", "drive_limits_text", "band_lines"]


# -- output -----------------------------------------------------------------------------------
#: Columns of metrics.csv, in order.
CSV_FIELDS = (["verdict", "controller", "plant", "scenario"] + list(METRIC_UNITS)
              + ["command_unit", "command_limit", "within_drive_limits", "within_voltage_limit",
                 "within_current_limit", "limit_kind", "residual_pct_of_openloop", "within_torque_limit", "completed",
                 "outside_validated_range", "outside_range_time_s", "plant_modes", "plant_axial_modes",
                 "design_modes", "substeps", "step_s", "step_mode_hz", "qp_solves", "qp_fallbacks",
                 "fallback_fraction", "wall_s", "message"])

#: What the README says about the plant models against an exact beam (issue 10's figures).
PLANT_NOTE = ("FOAM is the default plant: against a geometrically exact beam (planar ANCF, "
              "Exudyn) the default slew's open-loop residual is 0.2747 m; FOAM gives 0.2824 m "
              "(+2.8 %), CFOAM 0.3515 m (+28 %), so CFOAM's \"% of open loop\" figures look "
              "better than they are at large deflection.")


def _json_metrics(metrics: dict) -> list:
    return [{k: _clean(v) for k, v in m.items()} for m in metrics.values()]


def _targets(comparison) -> list:
    """Rows ``(controller, settled, residual_ok, drive_ok, angle_ok)`` of the slew targets
    (``drive_ok``: every drive quantity within its own limit, ``within_drive_limits``)."""
    m = comparison.metrics
    rows = []
    base = m.get("openloop", {}).get("residual_tip_max_m")
    for name, mm in m.items():
        res_ok = (base is not None and mm["residual_tip_max_m"] <= 0.01 * base) if name != "openloop" else None
        rows.append((name, mm["verdict"] == "settled", res_ok, mm.get("within_drive_limits"),
                     abs(mm["final_angle_error_rad"]) <= comparison.scenario.bands["settle_angle"]))
    return rows


def _command_text(comparison) -> str:
    """What the controllers command, in which unit, within which limits (one sentence)."""
    first = next(iter(comparison.results.values()), None)
    drive = drive_of(first) if first is not None else None
    if drive is not None and not drive.is_ideal:
        return (f"the DC motor's voltage [V] within +-V_max = {drive.V_max:g} V (current limit I_max = "
                f"{drive.I_max:g} A); peak u, max du/sample and u at limit are in V, the hub torque, voltage and "
                "current columns each in its own unit.")
    return (f"the hub torque [N m] within +-{comparison.scenario.tau_max:g} N m; u at limit is the time the "
            "command sits within 0.1 % of its limit.")


def drive_limits_text(comparison) -> str:
    """The drive-limit check of the Targets, each quantity with its own limit and unit.

    Parameters
    ----------
    comparison : Comparison

    Returns
    -------
    str
        ``"abs(u) <= V_max = 10 V, abs(i) <= I_max = 4 A"`` on a DC motor, ``"abs(tau) <= tau_max =
        200 N m"`` on a torque source.
    """
    first = next(iter(comparison.results.values()), None)
    drive = drive_of(first) if first is not None else None
    if drive is not None and not drive.is_ideal:
        return (f"abs(u) <= V_max = {drive.V_max:g} V, abs(i) <= I_max = {drive.I_max:g} A, hub torque within the "
                f"drive's {drive.peak_hub_torque:.3g} N m")
    return f"abs(tau) <= tau_max = {comparison.scenario.tau_max:g} N m"


def band_lines(sc) -> list:
    """Report lines saying where each settling band of a scenario came from.

    Parameters
    ----------
    sc : Scenario
        Its ``band_sources`` (:func:`hubbeam_ctrl.study.bands.with_task_bands`).

    Returns
    -------
    list of str
        ``"  - Angle band: raised to 2 counts of the encoder ... = 0.00307 rad ..."`` and the tip's.
    """
    sources = sc.band_sources or {}
    return [f"  - {what} band: {sources[key]}." for key, what in (("settle_angle", "Angle"), ("settle_tip", "Tip"))
            if key in sources]


def _number_text(value) -> str:
    """A parameter's value for the report: a number, or a list of them (per-mode damping ratios)."""
    if isinstance(value, (tuple, list)):
        shown = ", ".join(f"{v:.3g}" for v in value[:4])
        return f"({shown}{', ...' if len(value) > 4 else ''})"
    return f"{value:g}"


def _plant_lines(comparison) -> list:
    """Report lines saying which plant (model, modes, parameters, step) judged the controllers."""
    sc, ev = comparison.scenario, comparison.plant
    p = ev.params if ev is not None else sc.params
    first = next(iter(comparison.results.values()), None)
    st = first.settings if first is not None else {}
    design = sc.params
    lines = [f"- Design model: SFOAM linearised at {sc.design_spin:g} rad/s with "
             f"{ev.design_modes if ev else design.n_transverse} transverse modes "
             f"(m_t = {design.m_t:g} kg, J_h = {design.J_h:g} kg m^2)."]
    if ev is not None:
        lines.append(f"- Evaluation plant: {ev.model.upper()} with {p.n_axial} axial and {p.n_transverse} "
                     f"transverse modes ({ev.reason}), {damping_text(p)}.")
        differs = sorted(k for k, v in p.to_dict().items()
                         if k not in ("n_axial", "n_transverse") and v != design.to_dict()[k])
        values = ", ".join(f"{k} = {_number_text(v)}" for k, v in p.to_dict().items()
                           if k not in ("n_axial", "n_transverse") and v is not None)
        lines.append(f"- Plant parameters (SI units): {values}; "
                     + (f"{', '.join(differs)} differ from the design's." if differs
                        else "the design's physical parameters."))
    if "step_reason" in st:
        lines.append(f"- Integration: generalized-alpha (rho_inf = {st.get('rho_inf', 0.9):g}), "
                     f"{st['step_reason']}.")
    if "plant_element_reason" in st:
        lines.append(f"- Exact beam: {st['plant_element_reason']}.")
    lines.append(f"- {PLANT_NOTE}")
    return lines


def write_outputs(comparison, out_dir, loops=None) -> dict:
    """Write metrics.csv, metrics.json, tip_deflection.png, hub_angle.png, torque.png, report.md.

    The files go through :func:`~hubbeam_ctrl.core.fileio.write_folder`: a new folder appears
    complete in one rename, an existing one is updated file by file, and ``MANIFEST.json``
    (written last) tells a finished folder from an interrupted one.

    Parameters
    ----------
    comparison : Comparison
    out_dir : str or Path
        Created if missing (its parent must exist).
    loops : object, optional
        loops.png's render job, started before the runs by :func:`loop_png` on the comparison
        as designed (``compare(..., designed=...)``; the same figure); default: started here.

    Returns
    -------
    dict
        File kind -> Path (in ``out_dir``).
    """
    out = Path(out_dir)
    names = {"csv": "metrics.csv", "json": "metrics.json", "tip_deflection.png": "tip_deflection.png",
             "hub_angle.png": "hub_angle.png", "torque.png": "torque.png", "report": "report.md"}
    write_folder(out, lambda folder: _write_files(comparison, Path(folder), names, loops))
    paths = {kind: out / name for kind, name in names.items()}
    comparison.paths = paths
    return paths


def _write_files(comparison, out: Path, names: dict, loops=None) -> None:
    """The files of :func:`write_outputs`, written into ``out``.

    The figures are handed to :func:`hubbeam_ctrl.plots.worker.render` as soon as their data
    are known (drawn by the figure worker while the tables and the loop data are computed
    here, when ``hubbeam compare`` started one; else here) and written once drawn.
    """
    sc, metrics, results = comparison.scenario, comparison.metrics, comparison.results
    modes = f" ({comparison.plant.modes} modes)" if comparison.plant is not None else ""
    title = f"{sc.plant.upper()}{modes}, {sc.name}: "
    styles, runs, command = comparison.styles, _plot_runs(results), _command_args(comparison, title)
    pngs = {
        "tip_deflection.png": render(plot_tip_deflection, runs, sc.t_f, sc.t_f + sc.bands["residual_delay"],
                                     title + "tip deflection (shaded: residual window)", styles=styles),
        "hub_angle.png": render(plot_hub_angle, runs, sc.t_f, title + "hub angle and error vs reference",
                                styles=styles),
        "torque.png": render(plot_torque, runs, *command[0], styles=styles, **command[1]),
    }
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=CSV_FIELDS, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for m in metrics.values():
        writer.writerow({k: ("" if _clean(m.get(k)) is None else _clean(m.get(k))) for k in CSV_FIELDS})
    atomic_write_text(out / names["csv"], buf.getvalue())
    atomic_write_text(out / names["json"], strict_json(_json_metrics(metrics), indent=2) + "\n")
    loops = loop_png(comparison) if loops is None else loops
    for fname, png in pngs.items():
        save_png(png.result(), out / names[fname])
    _write_report(comparison, out, names, loops)      # report.md, the loop figure and report.html


def _plot_runs(results: dict) -> dict:
    """What the closed-loop figures read of each run (``t``, ``v_tip``, ``theta``, ``theta_ref``,
    ``tau``, ``stopped``): a light copy to send to the figure worker."""
    return {name: SimpleNamespace(t=r.t, v_tip=r.v_tip, theta=r.theta, theta_ref=r.theta_ref, tau=r.tau,
                                  stopped=r.stopped) for name, r in results.items()}


def loop_png(comparison):
    """loops.png of the report, as :func:`~hubbeam_ctrl.plots.worker.render` draws it: the loop
    data computed here, the figure drawn by the figure worker when one runs.

    It reads the comparison's scenario, styles, evaluation plant and linear controllers only,
    so it can start before the closed-loop runs (``compare(..., designed=loop_png)``).

    Parameters
    ----------
    comparison : Comparison
        From :func:`hubbeam_ctrl.study.compare.compare`, or as handed to its ``designed``.

    Returns
    -------
    object or None
        The render job (``.result()``: the PNG's bytes); None without a linear controller.
    """
    from hubbeam_ctrl.study.loops import comparison_loop_data
    data = comparison_loop_data(comparison)
    if data is None:
        return None
    loops, title, colors = data
    return render(plot_loop_comparison, loops, title, colors=colors, dpi=100)


def _command_args(comparison, title: str) -> tuple:
    """:func:`~hubbeam_ctrl.plots.closedloop.plot_torque`'s limit and title, and its keywords, for the
    commands over time in their unit (torque.png)."""
    first = next(iter(comparison.results.values()), None)
    drive = drive_of(first) if first is not None else None
    if drive is not None and not drive.is_ideal:
        return (drive.V_max, title + "command voltage (dotted: +-V_max)"), {"ylabel": "command voltage [V]"}
    return (comparison.scenario.tau_max, title + "hub torque (dotted: +-tau_max)"), {}


def _command_figure(comparison, title: str, styles):
    """The commands over time in their unit, with their limit (torque.png's figure)."""
    args, kwargs = _command_args(comparison, title)
    return plot_torque(comparison.results, *args, styles=styles, **kwargs)


def _report(comparison) -> str:
    sc = comparison.scenario
    verdicts = ", ".join(f"{name} **{m['verdict']}**" for name, m in comparison.metrics.items())
    lines = [f"# Closed-loop comparison: {sc.name} on {sc.plant.upper()}", "",
             f"Verdicts: {verdicts}.", "",
             f"- Scenario: {sc.description}.",
             f"- Feedback reference: {sc.reference.description}.",
             f"- Torque budget tau_max = {sc.tau_max:g} N m; sample time {sc.dt * 1e3:g} ms "
             f"(zero-order hold); t_end = {sc.t_end:g} s.",
             f"- Command: {_command_text(comparison)}"]
    lines += _plant_lines(comparison)
    lines += [f"- Residual vibration: |v_tip| from tf + {sc.bands['residual_delay']:g} s = "
              f"{sc.t_f + sc.bands['residual_delay']:g} s to the end. Settling: hub-angle error within "
              f"{1e3 * sc.bands['settle_angle']:.3g} mrad and |v_tip| within {1e3 * sc.bands['settle_tip']:.3g} mm "
              f"for the hold before the end (a tenth of the residual window, at least one first-mode period; "
              f"settle_hold_s in metrics.json).",
              *band_lines(sc),
              f"- Verdicts: failed (the integrator or the controller failed, or the wall-clock limit), "
              f"diverged (the plant passed its divergence limit), unstable (the linear certificate's loop "
              f"grows, or the envelope of the tip, the torque ripple or the angle error grows at a "
              f"resolved rate, or the command is at its limit more than {100 * SATURATION_LIMIT:g} % of the "
              f"residual window), settled (inside both bands for the hold), not settled.",
              _wall_line(comparison), ""]
    lines += _yardstick_lines(comparison)
    lines += ["",
              markdown_table(comparison.metrics), ""]
    if sc.name == "slew" and "openloop" in comparison.metrics:
        lines += ["## Targets (slew)", "",
                  f"| controller | settled | residual <= 1 % of open loop | {drive_limits_text(comparison)} "
                  f"| final error <= the angle band ({sc.bands['settle_angle']:.3g} rad) |",
                  "|---|---|---|---|---|"]
        yes = {True: "yes", False: "**no**", None: "-"}
        for name, s_ok, r_ok, t_ok, a_ok in _targets(comparison):
            note = "" if name in comparison.targets or name == "openloop" else " (reported only)"
            lines.append(f"| {name}{note} | {yes[s_ok]} | {yes[r_ok]} | {yes[t_ok]} | {yes[a_ok]} |")
        lines.append("")
    lines += check_plant_lines(comparison)
    lines += rig_lines(comparison)
    lines += ladder_lines(getattr(comparison, "ladder", []))
    lines += _certificate_lines(comparison)
    lines += _friction_lines(comparison)
    lines += _robust_lines(comparison)
    rig = getattr(comparison, "rig", None)
    lines += _margin_lines(getattr(comparison, "margins", {}),
                           0.0 if rig is None else rig.timing.delay * sc.dt)
    notes = [f"- {name}: {m['message']}" for name, m in comparison.metrics.items()
             if not m["completed"] or m.get("outside_validated_range")]
    notes += [f"- {name}: {m['qp_fallbacks']} of {m['qp_solves']} QPs failed and fell back to LQR"
              for name, m in comparison.metrics.items() if m.get("qp_fallbacks")]
    notes += [f"- {line}" for line in getattr(comparison, "notes", [])]
    if notes:
        lines += ["## Notes", ""] + notes + [""]
    lines += ["## Plots", "", "![tip deflection](tip_deflection.png)", "",
              "![hub angle](hub_angle.png)", "", "![torque](torque.png)", ""]
    return "\n".join(lines)


def _range_text(res, L: float) -> tuple:
    """``(time, limit)`` at which a run passed the assumed-mode models' validated range (time None: never)."""
    limit = float(res.settings.get("range_limit", 0.3))
    when = res.stats.get("outside_range_time_s")
    if when is None:
        when = res.stats.get("past_assumed_mode_range_time_s")
    return when, limit


def check_plant_lines(comparison) -> list:
    """The report's section on ``PlantChoice(check_plant=...)`` of ``compare``: every controller on both plants, their
    peak ``|v_tip|/L`` and range, and which plant left its validated range (lines; none without a
    check plant).

    Parameters
    ----------
    comparison : Comparison

    Returns
    -------
    list of str
        Markdown lines.
    """
    check = getattr(comparison, "check_plant", None)
    if check is None or not comparison.check_results:
        return []
    main_name, check_name = comparison.plant.model, check.model
    L = comparison.plant.params.L
    label = {"ancf": "ANCF (exact beam)", "foam": "FOAM", "cfoam": "CFOAM"}
    lines = [f"## {label[main_name]} and {label[check_name]} on the same loop", "",
             f"Every controller also ran on {label[check_name]} with the same modes ({check.modes}), step, "
             "sensors and hardware. The assumed-mode models (FOAM, CFOAM) are validated to 0.3 L of tip "
             "deflection and flag a run that passes it; the exact beam has no such range (passing it is "
             "recorded, not flagged).", "",
             "| controller | plant | peak abs(v_tip) [m] | peak abs(v_tip) / L | passed the range at [s] "
             "| residual max [m] | verdict |",
             "|---|---|---|---|---|---|---|"]
    notes = []
    for name, res in comparison.results.items():
        res_c = comparison.check_results.get(name)
        if res_c is None:
            continue
        rows = {}
        for plant, r, mm in ((main_name, res, comparison.metrics[name]),
                             (check_name, res_c, comparison.check_metrics[name])):
            when, limit = _range_text(r, L)
            peak = mm["peak_tip_m"]
            rows[plant] = (peak, when, limit, mm["residual_tip_max_m"])
            where = "-" if when is None else f"{when:.3f}" + (" (recorded)" if plant == "ancf" else " (**left**)")
            lines.append(f"| {name} | {label[plant]} | {peak:.4g} | {peak / L:.3f} | {where} | "
                         f"{mm['residual_tip_max_m']:.4g} | {mm['verdict']} |")
        assumed = [pl for pl in rows if pl != "ancf" and rows[pl][1] is not None]
        for pl in assumed:
            peak, when, limit, _ = rows[pl]
            text = (f"- {name}: {label[pl]} left its validated range (|v_tip| > {limit:g} L at t = {when:.3f} s; "
                    f"peak {peak / L:.3f} L)")
            if "ancf" in rows:
                pe = rows["ancf"][0]
                text += (f"; the exact plant did not (it has no such range): peak {pe / L:.3f} L, "
                         f"{100 * (peak / pe - 1):+.1f} % for {label[pl]}")
            notes.append(text + ".")
    lines.append("")
    if notes:
        lines += notes + [""]
    return lines


def _wall_line(comparison) -> str:
    """The report's wall-time line: the comparison's, and with a rig ladder the two together."""
    ladder_s = getattr(comparison, "ladder_wall_s", None)
    if ladder_s is None:
        return f"- Wall time of the comparison: {comparison.wall_s:.1f} s."
    return (f"- Wall time of the comparison and the rig ladder: {comparison.wall_s:.1f} s "
            f"(the ladder's steps run beside the comparison; waited for them after it: {ladder_s:.1f} s).")


def ladder_lines(rows: list) -> list:
    """The ladder as a Markdown section (lines), for the report.

    Parameters
    ----------
    rows : list of dict
        From :func:`rig_ladder`.
    """
    if not rows:
        return []
    lines = ["## The rig ladder: what each part of the hardware does", "",
             "The same comparison on the beam alone, then with the rig's parts added one at a time "
             "(each step keeps the ones above; parts that are ideal in the rig are left out).", "",
             "| step | controller | verdict | residual [mm] | final angle error [mrad] | settling [s] | max command |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        unit = "V" if r["command"] == "voltage" else "N m"
        settle = "-" if r["settling_time_s"] is None else f"{r['settling_time_s']:.3g}"
        lines.append(f"| {r['step']} | {r['controller']} | {r['verdict']} | {1e3 * r['residual_tip_max_m']:.4g} | "
                     f"{1e3 * r['final_angle_error_rad']:.3g} | {settle} | {r['command_max']:.3g} {unit} |")
    return lines + [""]


def _yardstick_lines(comparison) -> list:
    """What the settling times are measured against (issue 22): the task's physical limit."""
    first = next(iter(comparison.metrics.values()), {})
    if "limit_s" not in first:
        return []
    sc = comparison.scenario
    what = ("the rigid body's shortest time with tau_max, 2 sqrt(|Theta| J / tau_max), a bound no flexible beam "
            "beats" if first["limit_kind"] == "rigid bound" else
            "the rigid body's bang-bang within the DC drive's voltage limit through back-EMF, its current limit and "
            "friction, a bound no flexible beam beats" if first["limit_kind"] == DRIVE_BOUND else
            "the time-optimal slew of the nonlinear beam within the drive's limits that ends with its residual "
            "vibration below 0.1 % of L (hubbeam_ctrl.limit)")
    if sc.name == "spinup" and first["limit_kind"] == "rigid bound":
        what = "the rigid body's shortest spin-up with tau_max, J |w_f| / tau_max"
    return [f"- Yardstick: {first['limit_kind']} {first['limit_s']:.4g} s ({what}); `settle/limit` is each "
            f"controller's settling time over it (1 = the physical limit; the task itself takes t_f = "
            f"{sc.t_f:g} s = {sc.t_f / first['limit_s']:.3g} x the limit), `resid %L` its residual vibration in % of "
            f"the beam's length L = {sc.params.L:g} m; `% of OL` (against the Eq. 44 open loop) comes second."]


def _margin_lines(margins: dict, delay_s: float = 0.0) -> list:
    """The report's section on the linear loops' margins at the plant input (design model); on a
    rig with a computation delay ``delay_s`` [s] the loop carries it, and the delay margin is the
    delay it tolerates beyond it (set beside it)."""
    if not margins:
        return []
    f = lambda v, fmt: "-" if v is None or not math.isfinite(v) else fmt.format(v)
    lines = ["## Loop margins at the plant input (design model)", "",
             "Disk margin (balanced; python-control's `disk_margins` on the same grid in brackets where "
             "`loop_margins(ctrl, check=True)` asked for it), "
             "the gains and phase it guarantees together, classical gain and phase margins and the delay "
             "margin (controllers.analysis.loop_margins).", ""]
    if delay_s > 0:
        lines += [f"The loops carry the rig's computation delay of {1e3 * delay_s:.3g} ms (with the drive and "
                  "the estimator): the delay margin is the further delay each tolerates, and the last column the "
                  "whole delay it tolerates against the rig's.", ""]
    extra = " total delay tolerated ms (rig's) |" if delay_s > 0 else ""
    lines += ["| controller | stable | disk margin | disk gains | disk phase deg | gain margins | "
              "phase margin deg | delay margin ms |" + extra, "|---|---|---|---|---|---|---|---|"
              + ("---|" if delay_s > 0 else "")]
    for name, m in margins.items():
        lo, hi = m.disk_gain_margin
        total = (f" {f((m.delay_margin_s + delay_s) * 1e3, '{:.3g}')} ({1e3 * delay_s:.3g}) |"
                 if delay_s > 0 else "")
        lines.append(f"| {name} | {'yes' if m.stable else '**no**'} | {m.disk_margin:.3f} "
                     f"({f(m.disk_margin_control, '{:.3f}')}) | {lo:.3f}..{f(hi, '{:.3f}')} | "
                     f"{m.disk_phase_margin_deg:.1f} | {f(m.gain_margin_lower, '{:.3g}')} / "
                     f"{f(m.gain_margin_upper, '{:.3g}')} | {f(m.phase_margin_deg, '{:.1f}')} | "
                     f"{f(m.delay_margin_s * 1e3, '{:.3g}')} |" + total)
    return lines + [""]


def _certificate_lines(comparison) -> list:
    """The linear certificates and what decided each verdict (issue 27)."""
    certs = getattr(comparison, "certificates", {}) or {}
    if not certs:
        return []
    lines = ["## Stability: linear certificate and verdict", "",
             "Each controller's sampled loop with the evaluation plant's linear model (all of its modes, "
             "zero-order hold); a spectral radius above 1 + 1e-7 is unstable whatever the run shows.", "",
             "| controller | verdict | certificate | why |", "|---|---|---|---|"]
    for name, m in comparison.metrics.items():
        cert = certs.get(name)
        text = cert.describe() if cert is not None else "-"
        lines.append(f"| {name} | {m['verdict']} | {text} | {m.get('verdict_reason', '')} |")
    return lines + [""]


def _friction_lines(comparison) -> list:
    """What the rig's Coulomb friction and its encoder's counts leave at rest, predicted from each
    linear loop (:func:`hubbeam_ctrl.study.friction_bound.friction_prediction`,
    :func:`~hubbeam_ctrl.study.friction_bound.count_prediction`)."""
    lines = []
    for key, title in (("friction_prediction", "Friction at rest"), ("count_prediction", "Encoder counts at rest")):
        rows = [(name, m) for name, m in comparison.metrics.items() if m.get(key)]
        if rows:
            lines += [f"## {title}: predicted from the linear loop", ""]
            lines += [f"- {name} ({m['verdict']}): {m[key]}." for name, m in rows] + [""]
    return lines


def _robust_lines(comparison) -> list:
    """The robust certificates over the rig's ``[uncertainty]`` (issue 39)."""
    robust = getattr(comparison, "robust", {}) or {}
    if not robust:
        return []
    first = next(iter(robust.values()))
    lines = ["## Robust certificate over the rig's uncertainty", "",
             f"The set: {first.uncertainty.describe()}. The loop as it runs (drive, sensors, delay, estimator) "
             "with the linear plant of each point the search visits (a grid with its corners, then local "
             "searches from the worst points): the worst radius is searched, not proven; the first-order bound "
             "is said beside it (hubbeam_ctrl.study.worst_case).", "",
             "| controller | verdict | worst radius | worst plant | nominal radius | bound | smallest disk margin |",
             "|---|---|---|---|---|---|---|"]
    for name, wc in robust.items():
        where = ", ".join(f"{k} = {v:.4g}" for k, v in wc.worst.values.items())
        dm = "-" if wc.disk_margin is None else f"{wc.disk_margin:.3g}"
        lines.append(f"| {name} | {wc.verdict()} | {wc.worst.radius:.8f} | {where} | {wc.nominal.radius:.8f} | "
                     f"{wc.bound:.3g} | {dm} |")
    return lines + [""]


def _write_report(comparison, out: Path, names: dict, loops=None) -> None:
    """report.md (with loops.png, the loops of every linear controller overlaid, linked from it)
    and report.html, the same report as one page with the figures embedded. ``loops``: the loop
    figure's render job (:func:`loop_png`), None without a linear controller."""
    from hubbeam_ctrl.core.htmlpage import markdown_to_html
    text = _report(comparison)
    if loops is not None:
        names["loops.png"] = "loops.png"
        save_png(loops.result(), out / names["loops.png"])
        text += ("\n## Loop plots (linear controllers)\n\nEvery linear controller's loop at the plant input, "
                 "overlaid, closed on the linear SFOAM with the evaluation plant's modes: the loop gain |L|, its "
                 "Nyquist curve with the disk-margin disk, the sensitivity |S| with its peak, the sampled "
                 "closed-loop poles and the tip deflection after a reference step and after a torque step "
                 "(hubbeam_ctrl.study.loops.comparison_loop_figure; one controller in full, on the design "
                 "and the evaluation model: loop_figure).\n\n![loop plots](loops.png)\n\n")
    atomic_write_text(out / names["report"], text)
    names["report.html"] = "report.html"
    atomic_write_text(out / names["report.html"], markdown_to_html(text, out))

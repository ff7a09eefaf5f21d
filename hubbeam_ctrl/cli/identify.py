"""``hubbeam identify``: fit rig fields to measured records and write a calibrated rig and a report.

Example::

    hubbeam identify chirp.csv prbs.csv --rig servo_link --fit E,J_h,m_t,damping,friction \\
        --validate multisine.csv --out calib/

Writes into ``--out``: ``report.md`` (estimates with 95 % intervals, correlations, fit per
record and sensor, residuals, warnings, measured-vs-model plots ``fit_<k>.png``),
``result.json`` and, only when the fit converged and the rig file reads back equal to the
estimate, ``rig.toml``. "Converged" means the optimiser stopped on its tolerance and every
record's sensor is fitted within a point of its noise ceiling (the fit a perfect model reaches
with the record's noise). Otherwise the report keeps the last estimate and says why (not
converged, below the noise ceiling by X points, stopped at ``--max-wall``), no rig is written
unless ``--force`` is given, and the status is 2. The fitted plant's modes come from the
records' excited band unless ``--plant-modes`` is given.
"""

from __future__ import annotations

from hubbeam_ctrl.cli.args import Command

__all__ = ["RECORD_OPTIONS"]


def _options(p) -> None:
    """``hubbeam identify``'s options on its parser ``p``."""
    from hubbeam_ctrl.cli.args import add_rig_option, add_verbose, integer, nonempty, real

    p.add_argument("records", metavar="RECORD", nargs="*", type=nonempty("record file"),
                   help="records (.csv with a 'name [unit]' header, or .npz), each starting at rest")
    p.add_argument("--modal-table", metavar="TABLE.csv", type=nonempty("file"),
                   help="fit to measured frequencies (and damping ratios) against spin rate and tip mass instead "
                        "of records: header spin [rad/s],m_t [kg],mode [-],frequency [Hz],damping [-]")
    src = p.add_mutually_exclusive_group(required=True)
    add_rig_option(src, "rig TOML file or preset")
    src.add_argument("--params", metavar="P.toml", type=nonempty("file"),
                     help="parameter file (the beam alone, ideal hardware)")
    p.add_argument("--fit", metavar="E,J_h,...", required=True,
                   help="fields to fit: beam fields, damping (first-mode ratio), friction (Coulomb), "
                        "viscous, or table.key")
    p.add_argument("--out", metavar="DIR", type=nonempty("folder"), required=True)
    p.add_argument("--validate", metavar="RECORD", action="append", type=nonempty("record file"), default=[],
                   help="a record not used in the fit: its fit percentage with the calibrated rig")
    p.add_argument("--bounds", metavar="NAME=LO:HI", action="append", default=[],
                   help="bounds of a fitted field (repeatable)")
    p.add_argument("--sensors", metavar="S1,S2", help="sensors to fit (default every rig sensor in the records)")
    p.add_argument("--max-evaluations", metavar="N", type=integer(), default=60,
                   help="most residual evaluations of the optimiser (default 60)")
    p.add_argument("--plant-modes", metavar="N", type=integer(), default=None,
                   help="bending modes of the simulated plant, 1..20 (default from the records: every mode of the "
                        "guess below the excited band's top, plus the first above it)")
    p.add_argument("--max-wall", metavar="SECONDS", type=real("s"), default=None,
                   help="stop the fit after this wall time and keep its best estimate (the status says so)")
    p.add_argument("--force", action="store_true",
                   help="write the calibrated rig even when the fit did not converge to the records' noise floor")
    p.add_argument("--json", action="store_true", help="print each fitted field's estimate and interval as JSON")
    add_verbose(p)


def _parse_bounds(items) -> dict:
    from hubbeam_ctrl.core.errors import ParameterError
    out = {}
    for item in items:
        name, sep, rng = item.partition("=")
        lo, sep2, hi = rng.partition(":")
        try:
            if not sep or not sep2:
                raise ValueError
            a, b = float(lo), float(hi)
        except ValueError:
            raise ParameterError(f"--bounds must be NAME=LO:HI, got {item!r}") from None
        if a > b:
            raise ParameterError(f"--bounds: {name} has lo = {a:g} > hi = {b:g}")
        out[name.strip()] = (a, b)
    return out


#: The options of a fit to records (not of ``--modal-table``'s fit by modal analysis).
RECORD_OPTIONS = ("--validate", "--sensors", "--plant-modes", "--max-wall")


def _plan(args) -> dict:
    """``rig`` (Rig, from ``--rig`` or ``--params``), ``fields`` (the resolved ``--fit``), ``bounds``, ``out``
    (Path), ``force``, ``json``, ``settings`` (FitSettings) and either ``table`` (the ``--modal-table`` path)
    or ``records``, ``validate`` (paths: the run reads them) and ``sensors`` (tuple or None)."""
    from hubbeam_ctrl.calibrate.fit import FitSettings, check_bounds, resolve_fields
    from hubbeam_ctrl.calibrate.model import ModelSettings
    from hubbeam_ctrl.cli.args import check_output_dir
    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.plant.rig import load_rig

    if args.records and args.modal_table:
        raise ParameterError("--modal-table does not apply with RECORD files (identify fits records or a modal "
                             "table, not both)")
    if not args.records and not args.modal_table:
        raise ParameterError("identify needs records or --modal-table TABLE.csv (one of the two)")
    if args.plant_modes is not None and not 1 <= args.plant_modes <= 20:
        raise ParameterError(f"--plant-modes (n_transverse) must be an integer in 1..20, got {args.plant_modes}")
    if args.max_wall is not None and not args.max_wall > 0:
        raise ParameterError(f"--max-wall must be > 0 [s], got {args.max_wall:g}")
    if args.modal_table:         # options of a fit to records
        for option in RECORD_OPTIONS:
            if getattr(args, option[2:].replace("-", "_")) not in (None, []):
                raise ParameterError(f"{option} does not apply with --modal-table (it fits records)")
    out = check_output_dir("--out", args.out)
    rig = load_rig(args.rig) if args.rig is not None else load_rig(args.params, "params")
    fields = resolve_fields(args.fit, rig)
    bounds = _parse_bounds(args.bounds)
    check_bounds(fields, bounds)                 # before the records are read and simulated
    plan = {"rig": rig, "fields": tuple(fields), "bounds": bounds, "out": out, "force": args.force, "json": args.json}
    if args.modal_table:
        return {**plan, "table": args.modal_table, "settings": FitSettings(max_evaluations=args.max_evaluations)}
    return {**plan, "records": tuple(args.records), "validate": tuple(args.validate),
            "sensors": None if args.sensors is None else tuple(s.strip() for s in args.sensors.split(",")),
            "settings": FitSettings(model=ModelSettings(), plant_modes=args.plant_modes,
                                    max_evaluations=args.max_evaluations, max_wall=args.max_wall)}


def _run(args) -> int:
    """Fit, write the report (and the calibrated rig) and print the estimates."""
    from hubbeam_ctrl.calibrate.fit import check_record_for_rig, fit_rig, predict, validate_record
    from hubbeam_ctrl.calibrate.records import load_record
    from hubbeam_ctrl.cli.args import print_result

    plan = _plan(args)
    if args.modal_table:
        return _run_modal_table(args, plan)
    rig, sensors, out = plan["rig"], plan["sensors"], plan["out"]
    records = [load_record(r).resampled() for r in plan["records"]]
    validation = [load_record(r).resampled() for r in plan["validate"]]
    for rec in records:
        check_record_for_rig(rec, rig, sensors)
    for rec in validation:
        check_record_for_rig(rec, rig, sensors, "--validate")
    result = fit_rig(rig, records, [f.name for f in plan["fields"]], bounds=plan["bounds"], sensors=sensors,
                     settings=plan["settings"], progress=not args.json)
    valid = {}
    series = []
    for k, rec in enumerate(records):
        used = check_record_for_rig(rec, rig, sensors)
        series.append((f"fit_{k + 1}.png", rec, predict(result.rig, rec, used, result.model),
                       result.fit[rec.source]))
    for k, rec in enumerate(validation):
        fits, y = validate_record(result.rig, rec, sensors, result.model)
        valid[rec.source] = fits
        series.append((f"validate_{k + 1}.png", rec, y, fits))
    summary, rig_text = _write_outputs(result, plan, valid, series)
    text = [result.summary()] + [f"  validation {src}: " + ", ".join(f"{k} {v:.2f} %" for k, v in fits.items())
                                 for src, fits in valid.items()]
    text.append(f"wrote {out}/report.md" + (f", {out}/rig.toml" if rig_text else " (no calibrated rig)"))
    print_result(args, summary, "\n".join(text))
    return _refusal(result, out, rig_text is not None)


def _write_outputs(result, plan, valid, series) -> tuple:
    """Write into ``--out`` the plots of ``series`` (measured against model), result.json, report.md and the
    calibrated rig (when checked, :func:`_checked_rig_text`); returns ``(summary, rig text or None)``."""
    import numpy as np

    from hubbeam_ctrl.core.fileio import write_folder
    from hubbeam_ctrl.core.jsonio import strict_json
    rig_text = _checked_rig_text(result, plan["force"])
    summary = result.to_dict()
    if result.kind != "modal_table":
        summary["validation_fit_percent"] = valid
    summary["rig_written"] = rig_text is not None

    def write(folder):
        if series:
            from hubbeam_ctrl.plots.calibration import plot_record_fit
            from hubbeam_ctrl.plots.plant import save_figure
        for name, rec, y, fits in series:
            fig = plot_record_fit(rec.t, {s: rec.columns[s] for s in y}, y, fits, title=rec.source)
            save_figure(fig, folder / name)
        (folder / "result.json").write_text(strict_json(summary) + "\n", encoding="utf-8")
        (folder / "report.md").write_text(_report(result, valid, series, rig_text is not None, np), encoding="utf-8")
        if rig_text is not None:
            (folder / "rig.toml").write_text(rig_text, encoding="utf-8")
    write_folder(plan["out"], write, "--out")
    return summary, rig_text


def _refusal(result, out, written) -> int:
    """Exit status: 0 when converged; else 2 with one line naming why and ``--force``."""
    import sys
    if result.converged:
        return 0
    if written:
        print(f"hubbeam: warning: identify: {result.status}: {result.message}; {out}/rig.toml was written "
              "because of --force", file=sys.stderr)
        return 0
    print(f"hubbeam: error: identify: {result.status}: {result.message}; no calibrated rig was written (--force "
          f"writes it anyway); the last estimate is in {out}/report.md", file=sys.stderr)
    return 2


def _checked_rig_text(result, force=False):
    """The calibrated rig's TOML when the fit converged (or ``force``) and the text reads back equal, else None."""
    import tomllib

    from hubbeam_ctrl.plant.rig import rig_from_dict, rig_to_toml
    if not result.converged and not force:
        return None
    rig = _with_intervals(result)
    text = rig_to_toml(rig)
    if rig_from_dict(tomllib.loads(text)) == rig:
        return text
    result.warnings.append("the calibrated rig did not read back equal from its TOML: not written")
    return None


def _with_intervals(result):
    """The calibrated rig carrying the fit's 95 % intervals as its ``[uncertainty]`` (issue 39): the
    parameters an uncertainty set knows, each clipped to what the rig accepts; one that does not
    fit is left out with a warning."""
    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.plant.uncertainty import Uncertainty
    kept = {}
    for f, (lo, hi) in zip(result.fields, result.interval):
        field = getattr(f, "name", f)
        try:
            one = Uncertainty.from_intervals({field: (float(min(lo, hi)), float(max(lo, hi)))})
            if not one.is_set:
                continue
            r = one.ranges[0]
            lo_ok = max(r.lo, 0.0)
            Uncertainty.from_table({r.name: (lo_ok, r.hi)}).check(result.rig)
        except ParameterError as exc:        # a non-finite interval (a fit that did not converge), out of range
            result.warnings.append(f"interval of {field} left out of [uncertainty]: {exc}")
            continue
        kept[r.name] = (lo_ok, r.hi)
    return result.rig.replace(uncertainty=Uncertainty.from_table(kept)) if kept else result.rig


def _run_modal_table(args, plan) -> int:
    """``identify --modal-table``: fit to measured frequencies by modal analysis."""
    from hubbeam_ctrl.calibrate.table import fit_modal_table, load_modal_table
    from hubbeam_ctrl.cli.args import print_result

    table = load_modal_table(plan["table"], "--modal-table file")
    result = fit_modal_table(plan["rig"], table, [f.name for f in plan["fields"]], bounds=plan["bounds"],
                             settings=plan["settings"], progress=not args.json)
    summary, rig_text = _write_outputs(result, plan, {}, [])
    print_result(args, summary, result.summary)
    return _refusal(result, plan["out"], rig_text is not None)


def _report(result, valid, series, written, np) -> str:
    import math
    lines = ["# Calibration report", "",
             f"Fit {'converged' if result.converged else f'**{result.status}**'}: {result.message} "
             f"({result.evaluations} evaluations, {result.wall_s:.1f} s). "
             + ("The calibrated rig is `rig.toml`." if written else "**No calibrated rig was written** (`--force` "
                                                                   "writes it anyway)."), ""]
    if result.design is not None:
        lines += ["## Plant and starts", "", f"Plant: {result.design.reason}; fitted with "
                  f"{result.model.n_transverse} modes.", ""]
        for k in ("given", "frequency response"):
            if k in result.starts:
                v = result.starts[k]
                lines.append(f"- start {k}: " + ", ".join(f"{f.name} = {x:.6g}" for f, x in zip(result.fields,
                                                                                               v["values"]))
                             + f" (whole-record cost {v['cost']:.4g})")
        for k, v in result.starts.get("fits", {}).items():
            lines.append(f"- fit {k} from the {result.starts['won']} start: cost {v['cost']:.4g}"
                         + (" (won)" if k == result.starts.get("fit_won") else ""))
        lines.append("")
    lines += [
             "## Estimates (95 % intervals" + (" probed at their own scale" if result.intervals.get("method") == "rough"
                                               else " from the Jacobian") + ")", "",
             "| name | field | start | estimate | 95 % interval | unit |", "|---|---|---|---|---|---|"]
    for f, s, e, (lo, hi) in zip(result.fields, result.start, result.estimate, result.interval):
        lines.append(f"| {f.name} | {f.path} | {s:.6g} | {e:.6g} | [{lo:.6g}, {hi:.6g}] | {f.unit} |")
    note = ("The intervals assume white residuals; model error and coloured noise make them optimistic."
            if result.intervals.get("method") != "rough" else
            "The intervals hold the noise (a sandwich covariance, per record and sensor) and the cost's roughness at "
            f"the estimate ({result.intervals['roughness'] / result.intervals['noise_cost']:.3g} times the noise's "
            "95 % level; stick-slip sticking makes it jump); they assume the model's structure is right.")
    lines += ["", note]
    drive = [] if getattr(result, "drive", None) is None else result.drive.lines()
    if drive:                  # drive fields the records cannot separate, and what they determine (calibrate.drive)
        lines += ["", "## Drive constants", ""] + [f"- {line}" for line in drive]
    lines += ["",
              "## Correlations", "", "| | " + " | ".join(result.names) + " |",
              "|---" * (len(result.names) + 1) + "|"]
    for name, row in zip(result.names, result.correlation):
        lines.append(f"| {name} | " + " | ".join(f"{v:+.3f}" for v in row) + " |")
    if result.kind == "modal_table":
        lines += ["", "## Frequency errors", "", "| what | largest error [%] |", "|---|---|"]
        lines += [f"| {k} | {v:.4f} |" for k, v in result.fit.get("modal table", {}).items()]
    else:
        lines += ["", "## Fit per record and sensor", "", "`100 (1 - ||y - y_model|| / ||y - mean(y)||)`", "",
                  "The noise ceiling is the fit a perfect model reaches with the record's noise (estimated from "
                  "its spectrum above the excited band, at least an encoder's rounding q / sqrt(12)).", "",
                  "| record | sensor | fit [%] | noise ceiling [%] | residual RMS |", "|---|---|---|---|---|"]
    for name, rec, y, fits in series:
        tag = " (validation)" if rec.source in valid else ""
        for s, v in fits.items():
            rms = float(np.sqrt(np.mean((rec.columns[s] - y[s]) ** 2)))
            cap = result.ceiling.get(rec.source, {}).get(s, math.nan) if not tag else math.nan
            lines.append(f"| {rec.source}{tag} | {s} | {v:.2f} | {cap:.2f} | {rms:.4g} |")
    if result.warnings:
        lines += ["", "## Warnings", ""] + [f"- {w}" for w in result.warnings]
    if series:
        lines += ["", "## Measured against model", ""] + [f"![{rec.source}]({name})" for name, rec, _, _ in series]
    return "\n".join(lines) + "\n"


COMMAND = Command(
    "identify", _options, _run, beam=False, plan=_plan,
    help="calibrate rig fields from measured records (least squares on FOAM with the hardware)",
    description=("Fits the --fit fields of the rig to the records by least squares of the simulated sensors "
                 "(nonlinear FOAM with the rig's drive and friction) against the measured ones; writes the "
                 "calibrated rig (only if the fit converged and was checked), report.md with measured-vs-model "
                 "plots, and result.json."))

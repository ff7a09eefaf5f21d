"""``hubbeam certify``: a controller's robust certificate over what the user does not know
(:mod:`hubbeam_ctrl.study.worst_case`), checked by nonlinear runs at the worst plant found.

Exit status: 0 when every controller is certified, 1 when one is not (a plant of the set was
found where its loop does not decay), 2 for bad input.
"""

from __future__ import annotations

import io
import math
import sys

from hubbeam_ctrl.cli.args import Command, check_output_dir, stdout
from hubbeam_ctrl.cli.compare import COMMAND as COMPARE
from hubbeam_ctrl.cli.compare import add_compare_options
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write_text
from hubbeam_ctrl.core.jsonio import strict_json

__all__ = ["parse_uncertainty", "CHECKS", "DESIGNS"]

#: Where the nonlinear check runs: the worst plant found, also the set's corners, or nowhere.
CHECKS = ("worst", "corners", "none")
#: What is certified: the nominal design, or the design chosen over the set.
DESIGNS = ("nominal", "robust")
#: Options of ``compare`` that certify refuses, with the reason.
REFUSES = {"--payload-range": "give the payload range as --uncertainty m_t=LO:HI",
           "--learn-payload": "a learning controller has no fixed linear loop to certify",
           "--no-ladder": "certify runs no rig ladder",
           "--check-plant": "the certificate's nonlinear checks run on --plant"}
#: Options that ``--design robust`` refuses: its candidates are built without them.
ROBUST_REFUSES = {"--shaping": "the robust design's candidates follow the task's reference unshaped",
                  "--schedule": "the robust design's candidates are single design points"}


def _options(p) -> None:
    """``hubbeam certify``'s options on its parser ``p``: its own, then compare's."""
    p.add_argument("controller", metavar="CONTROLLER",
                   help="registered controller(s) with a linear feedback law, comma-separated (lqr, lqg, mpc, pd...)")
    p.add_argument("--uncertainty", metavar="NAME=LO:HI,...",
                   help="the uncertainty set, e.g. m_t=0:0.5,damping=0.0005:0.02,delay=0.3:0.7 (SI units; names: "
                        "m_t l E J_h damping viscous coulomb k_t k_e R delay); default the rig's [uncertainty]")
    p.add_argument("--grid", metavar="N", type=int, default=3,
                   help="grid points per uncertain parameter before the local searches, 2..9 (default 3)")
    p.add_argument("--check", choices=CHECKS, default="worst",
                   help="nonlinear runs: at the worst plant found (default), also at every corner and the centre of "
                        "the set, or none")
    p.add_argument("--design", choices=DESIGNS, default="nominal",
                   help="nominal: certify the design compare makes for the nominal rig (default); robust: search the "
                        "design's choices (design point, gain and filter modes, filter noise, weighting) for the "
                        "smallest worst-case radius over the set, and certify that (hubbeam_ctrl.study.robust_design)")
    p.add_argument("--c-out", metavar="DIR",
                   help="also write each certified controller as C99 into DIR/NAME (hubbeam codegen's output, with "
                        "the certificate in the header's first comment and NAME.json); controllers the code "
                        "generator cannot export are named on stderr")
    add_compare_options(p, controllers=False)


def parse_uncertainty(text: str):
    """``NAME=LO:HI,...`` (a single value fixes a parameter) as an :class:`Uncertainty`.

    Parameters
    ----------
    text : str

    Returns
    -------
    Uncertainty
    """
    from hubbeam_ctrl.plant.uncertainty import Uncertainty
    table = {}
    for item in str(text).split(","):
        item = item.strip()
        if not item:
            continue
        name, sep, rng = item.partition("=")
        if not sep:
            raise ParameterError(f"--uncertainty must be NAME=LO:HI,..., got {item!r}")
        lo, _, hi = rng.partition(":")
        try:
            pair = (float(lo), float(hi if hi else lo))
        except ValueError:
            raise ParameterError(f"--uncertainty {name.strip()} must be LO:HI (two numbers), got {rng!r}") from None
        table[name.strip()] = pair
    if not table:
        raise ParameterError(f"--uncertainty must name at least one parameter (NAME=LO:HI), got {text!r}")
    try:
        return Uncertainty.from_table(table)
    except ParameterError as exc:
        raise ParameterError(f"--uncertainty: {str(exc).removeprefix('uncertainty.')}") from None


def _plan(args):
    from hubbeam_ctrl.plant.rig import Rig
    for option, why in REFUSES.items():
        if getattr(args, option.lstrip("-").replace("-", "_"), None):
            raise ParameterError(f"{option} does not apply to certify ({why})")
    if args.design == "robust":
        for option, why in ROBUST_REFUSES.items():
            value = getattr(args, option.lstrip("-").replace("-", "_"), None)
            if value is not None and not (option == "--schedule" and value == 1):
                raise ParameterError(f"{option} does not apply with --design robust ({why})")
    if not 2 <= args.grid <= 9:
        raise ParameterError(f"--grid must be an integer in [2, 9], got {args.grid}")
    args.controllers = args.controller
    plan = COMPARE.plan(args)
    opts = dict(plan.options)
    rig = opts.get("rig")
    if rig is None:
        rig = Rig(beam=opts["params"])
        opts.update(params=None, rig=rig)
    u = parse_uncertainty(args.uncertainty) if args.uncertainty is not None else rig.uncertainty
    if not u.is_set:
        raise ParameterError("certify needs an uncertainty set: --uncertainty NAME=LO:HI,... or a rig with an "
                             "[uncertainty] table")
    try:
        opts["rig"] = rig.replace(uncertainty=u)
    except ParameterError as exc:
        raise ParameterError(f"--uncertainty: {exc}") from None
    if "openloop" in opts["controllers"]:
        raise ParameterError("controller openloop has no feedback law to certify")
    opts["controllers"] = ("openloop",) + tuple(opts["controllers"])
    return plan, opts


def _run(args) -> int:
    """Certify the controllers and write the certificate; the status is 0 when every one is certified, else 1."""
    real_sink = stdout(args)
    sink = io.StringIO() if args.json else real_sink      # --json: the JSON alone on stdout
    from hubbeam_ctrl.study.compare import compare
    from hubbeam_ctrl.study.compare_values import compare_arguments
    from hubbeam_ctrl.study.robust_check import check_points, run_at
    plan, opts = _plan(args)
    rig = opts["rig"]
    c_root = None if args.c_out is None else check_output_dir("--c-out", args.c_out)     # before any work
    comparison = compare(**compare_arguments(**opts))
    names = [n for n in opts["controllers"] if n != "openloop"]
    missing = [n for n in names if n not in comparison.robust]
    if missing:
        raise ParameterError(f"controller {missing[0]!r} has no linear feedback law to certify")
    u = rig.uncertainty
    bare = rig.replace(uncertainty=type(u)())
    doc = {"set": u.to_table(), "controllers": {}}
    verdicts = {}
    lines = [f"# Robust certificate: {comparison.scenario.description}", "", f"Set: {u.describe()}.", ""]
    for name in names:
        ctrl, wc, design_doc = comparison.controllers[name], comparison.robust[name], _design_doc(comparison, name)
        if args.design == "robust":
            from hubbeam_ctrl.study.robust_check import residual_score
            from hubbeam_ctrl.study.robust_design import design_for_set
            sd = design_for_set(comparison, name, bare, u, score=residual_score(comparison, bare, u),
                                progress=not args.json)
            ctrl, wc = sd.controller, sd.certificate
            design_doc = {"kind": "robust", "choice": sd.label(), "knobs": sd.choice,
                          "nominal_design_radius": sd.nominal_radius,
                          "tried": [{"candidate": k, "worst_radius": r, "worst_residual_pct_of_openloop": p}
                                    for k, r, p in sd.tried]}
            print(f"{name}: robust design {sd.label()} (worst radius {wc.worst.radius:.8f}; nominal design "
                  f"{sd.nominal_radius:.8f}; {len(sd.tried)} candidates)", file=sink)
        points = check_points(u, wc.worst.values) if args.check == "corners" else [("worst", wc.worst.values)]
        checks = [] if args.check == "none" else \
            [{"point": kind, **run_at(comparison, ctrl, bare, values, u)} for kind, values in points]
        nominal = comparison.metrics[name]
        doc["controllers"][name] = {"design": design_doc, "certificate": wc.metrics(), "nominal_run": {
            k: nominal.get(k) for k in ("verdict", "settling_time_s", "residual_pct_of_openloop",
                                        "peak_torque_nm", "within_drive_limits")}, "checks": checks}
        print(wc.describe(), file=sink)
        lines += [f"## {name}: {wc.verdict()}", "", f"Design: {design_doc.get('choice', 'nominal')}.", "",
                  wc.describe(), ""]
        if checks:
            lines += ["| point | plant | verdict | settle s | % of OL | peak tau N m | within limits |",
                      "|---|---|---|---|---|---|---|"]
            for c in checks:
                where = ", ".join(f"{k} = {v:.4g}" for k, v in c["values"].items())
                settle = "-" if c["settling_time_s"] is None else f"{c['settling_time_s']:.2f}"
                pct = c["residual_pct_of_openloop"]
                pct_text = "-" if pct is None or not math.isfinite(pct) else f"{pct:.3g}"
                lines.append(f"| {c['point']} | {where} | {c['verdict']} | {settle} | {pct_text} | "
                             f"{c['peak_torque_nm']:.4g} | {c['within_drive_limits']} |")
                print(f"  nonlinear at {c['point']} ({where}): {c['verdict']}, settle {settle} s, {pct_text} % of "
                      f"its open loop, peak {c['peak_torque_nm']:.4g} N m", file=sink)
            lines.append("")
        verdicts[name] = wc.certified
        if args.c_out is not None and wc.certified:
            doc["controllers"][name]["c_code"] = _write_c(ctrl, c_root / name, wc)
    plan.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(plan.out / "certificate.json", strict_json(doc, indent=2) + "\n")
    atomic_write_text(plan.out / "certificate.md", "\n".join(lines) + "\n")
    if args.json:
        print(strict_json(doc), file=real_sink)
    else:
        print(f"wrote {plan.out}/certificate.json, certificate.md", file=sink)
    failed = [n for n in names if not verdicts[n]]
    if failed:
        print(f"hubbeam: not certified: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


def _design_doc(comparison, name: str) -> dict:
    """What was certified: the nominal design, or (multi-stage MPC) the tree over the set's payloads."""
    from hubbeam_ctrl.study.robust_design import innermost
    payloads = getattr(innermost(comparison.controllers[name]), "payloads", None)
    if payloads is None or len(payloads) < 2:
        return {"kind": "nominal"}
    prefix = f"{name}: the scenario tree over the set's payload range ("
    choice = next((n[len(prefix):-1] for n in comparison.notes if n.startswith(prefix)), None)
    return {"kind": "scenario tree", "choice": choice, "scenarios_kg": list(payloads)}


def _write_c(ctrl, folder, wc) -> dict:
    """The certified controller as C (:func:`hubbeam_ctrl.deploy.to_c`) with its certificate; a kind
    the generator cannot export is said, not fatal."""
    from hubbeam_ctrl.deploy import to_c
    if getattr(ctrl, "measurement", None) == "state":
        reason = ("the certified loop reads the plant's modal states; its C runs an observer the certificate "
                  "did not close the loop with (certify it on a rig, --rig, where the observer is part of the loop)")
        print(f"hubbeam: {ctrl.name} not written as C: {reason}", file=sys.stderr)
        return {"written": False, "reason": reason}
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        code = to_c(ctrl, folder, certificate=wc.metrics(), force=True)
    except ParameterError as exc:
        print(f"hubbeam: {ctrl.name} not written as C: {exc}", file=sys.stderr)
        return {"written": False, "reason": str(exc)}
    return {"written": True, "header": str(code.header_path), "source": str(code.source_path)}


COMMAND = Command(
    "certify", _options, _run, help="robust certificate of controllers over an uncertainty set",
    description=("Design CONTROLLER as compare does (same options), then search the uncertainty set (the rig's "
                 "[uncertainty] table, or --uncertainty) for the plant where the sampled loop as it runs (drive, "
                 "sensors, delay, estimator) decays slowest, and run the controller and the open loop on the "
                 "nonlinear plant there. Certified: worst spectral radius found <= 1 - 1e-6. Writes certificate.json "
                 "and certificate.md to --out. Exit 1 when a controller is not certified."))

"""Designs for a payload range and the report over it (``hubbeam compare --payload-range``).

:func:`range_designs` gives LQR, LQG and MPC the design chosen for a payload range
(:func:`controllers.robust.design_for_range`: the nominal design verified and retuned on
linear models over the range); :func:`payload_comparison` runs every controller on the
nonlinear plant at ``m_min``, the nominal payload and ``m_max`` (or any payloads asked for)
and judges each run against the open loop on the same plant, with a verdict.

Example
-------
>>> from hubbeam_ctrl.study import payload_comparison, payload_table
>>> from hubbeam_ctrl.study import CompareSettings, PayloadChoice
>>> s = CompareSettings(payload=PayloadChoice(payload_range=(0.0, 0.5)))
>>> pc = payload_comparison(None, "slew", "openloop,lqr", s)     # doctest: +SKIP
>>> print(payload_table(pc))                                    # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from dataclasses import dataclass, field

from controllers.robust import check_payload_range
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.fileio import atomic_write_text, output_folder
from hubbeam_ctrl.plant.params import Params
from hubbeam_ctrl.study.compare_values import DEFAULT_T_F, CompareSettings, PayloadChoice, as_rig
from hubbeam_ctrl.study.range_design import ROBUST_CONTROLLERS, range_designs  # noqa: F401 (re-exported)
from hubbeam_ctrl.study.yardstick import task_dt

__all__ = ["ROBUST_CONTROLLERS", "range_designs", "PayloadComparison", "payload_comparison", "payload_verdict",
           "payload_table", "write_payload_outputs"]


def payload_verdict(m: dict) -> str:
    """``"diverged"`` (run stopped), ``"settled"`` or ``"not settled"`` (or the metrics' own verdict).

    Parameters
    ----------
    m : dict
        Metrics of one run (:func:`~hubbeam_ctrl.study.metrics.closed_loop_metrics`).
    """
    if "verdict" in m:
        return m["verdict"]
    if not m.get("completed", True):
        return "diverged"
    return "settled" if m.get("settling_time_s") is not None else "not settled"


@dataclass
class PayloadComparison:
    """A comparison over a payload range.

    Attributes
    ----------
    payload_range : tuple of float
        ``(m_min, m_max)`` the controllers were designed for [kg].
    masses : tuple of float
        Payloads of the plants run [kg].
    comparisons : dict
        Payload -> :class:`~hubbeam_ctrl.study.compare.Comparison` on that plant.
    designs : dict
        Controller name -> :class:`controllers.robust.RangeDesign`.
    paths : dict
        Files written by :func:`write_payload_outputs`.
    """

    payload_range: tuple
    masses: tuple
    comparisons: dict
    designs: dict
    paths: dict = field(default_factory=dict)

    def rows(self) -> list:
        """One dictionary per (payload, controller): residual and its share of the open loop's,
        verdict, final angle error, peak torque."""
        rows = []
        for m, comp in self.comparisons.items():
            for name, mm in comp.metrics.items():
                rd = self.designs.get(name)
                learned = getattr(comp.controllers.get(name), "log", None)
                design = rd.choice if rd else "nominal"
                design_mass = rd.design_mass if rd else comp.scenario.params.m_t
                if learned is not None:          # controllers.payload_learning.PayloadLearning
                    design = "learns the payload: " + ", ".join(
                        f"{e['payload_kg']:.4g} kg at {e['t_s']:.3g} s" + (" (dropped)" if e["dropped"] else "")
                        for e in learned)
                    design_mass = next((e["payload_kg"] for e in reversed(learned) if not e["dropped"]), design_mass)
                estimate = getattr(comp.controllers.get(name), "payload", None)
                if learned is None and hasattr(estimate, "history"):     # the NMPC's own, every sample
                    design = f"learns the payload every sample: {estimate.mass:.4g} kg at the end"
                    design_mass = estimate.mass
                rows.append({"payload_kg": m, "controller": name, "verdict": payload_verdict(mm),
                             "settling_time_s": mm.get("settling_time_s"),
                             "residual_tip_max_m": mm["residual_tip_max_m"],
                             "residual_pct_of_openloop": mm.get("residual_pct_of_openloop"),
                             "final_angle_error_rad": mm["final_angle_error_rad"],
                             "peak_torque_nm": mm["peak_torque_nm"],
                             "settling_over_limit": mm.get("settling_over_limit"),
                             "loop_spectral_radius": mm.get("loop_spectral_radius"),
                             "check_verdict": mm.get("check_verdict"),
                             "design_mass_kg": design_mass,
                             "design": design})
        return rows


def payload_comparison(rig=None, task="slew", controllers=None, settings: CompareSettings | None = None, *,
                       masses=None, progress: bool = False) -> PayloadComparison:
    """Design for a payload range and run every controller at ``m_min``, nominal and ``m_max``.

    Parameters
    ----------
    rig : Params, optional
        The nominal beam (SI units; default Table 1, 0.1 kg at the tip). A rig's drive and
        sensors are not modelled over a payload range yet.
    task : str or Slew or SpinUp
        As for :func:`~hubbeam_ctrl.study.compare.compare`.
    controllers : str or sequence of str, optional
        As for ``compare``.
    settings : CompareSettings
        As for ``compare``; ``settings.payload.payload_range`` ``(m_min, m_max)`` [kg],
        ``0 <= m_min <= m_max``, holding the nominal ``m_t``, is required.
        ``plant.plant_params``: the plant's beam (damping, stiffness...; default the nominal),
        its tip mass set to each payload. A wall-time limit in ``run.sim_settings`` bounds the
        whole range. With ``payload.payload_learning`` (its range set to the payload range) LQR,
        LQG and MPC keep the nominal design and learn the payload during the slew instead of a
        design for the range. ``run.dt`` and ``run.t_end`` default to the task's
        (:func:`~hubbeam_ctrl.study.yardstick.task_dt`, ``task_t_end``).
    masses : sequence of float, optional
        Plant payloads [kg] (default ``m_min``, nominal, ``m_max``), each in the range.
    progress : bool
        Print one line per controller and payload on stderr.

    Returns
    -------
    PayloadComparison
    """
    from controllers import DesignModel
    from hubbeam_ctrl.study.compare import _parse_controllers, compare
    from hubbeam_ctrl.study.scenarios import make_scenario
    settings = CompareSettings() if settings is None else settings
    if not isinstance(settings, CompareSettings):
        raise ParameterError(f"settings must be a CompareSettings, got {type(settings).__name__}")
    rig_value, params = as_rig(rig)
    if rig_value is not None:
        raise ParameterError("rig: a rig's drive and sensors are not modelled over a payload range yet; "
                             "give the rig's beam (Rig.plant_params)")
    params = params if params is not None else Params()
    pc, dc, rc, scn, pay = settings.plant, settings.design, settings.run, settings.scenario, settings.payload
    lo, hi = check_payload_range(pay.payload_range, params.m_t)
    masses = tuple(sorted({lo, params.m_t, hi})) if masses is None else tuple(masses)
    for m in masses:
        if not (isinstance(m, (int, float)) and lo <= m <= hi):
            raise ParameterError(f"masses must lie in the payload range [{lo:g}, {hi:g}] kg, got {m!r}")
    names = _parse_controllers(controllers)
    plant_base = pc.plant_params if pc.plant_params is not None else params  # its tip mass each payload's
    dt = rc.dt if rc.dt is not None else task_dt(params)
    sc = make_scenario(task, plant=pc.plant, params=params,          # the range designs see the task's reference
                       reference="rigid" if dc.reference == "optimal" else dc.reference, tau_max=scn.tau_max,
                       t_f=DEFAULT_T_F if scn.t_f is None else scn.t_f, t_end=rc.t_end, dt=dt, w_f=scn.w_f,
                       slew_angle=scn.slew_angle, tolerances=dc.tolerances)   # t_end None: the task's own
    learning = pay.payload_learning
    if learning is not None:                         # the nominal design learns the payload instead
        learning = learning.replace(payload_min_kg=lo, payload_max_kg=hi)
        designs = {}
    else:
        design = DesignModel.build(sc.params, sc.design_spin, sc.dt, dc.design_modes)
        designs = range_designs(names, sc, design, (lo, hi), dc.settings, horizon=dc.horizon, solver=dc.solver,
                                plant_modes=pc.plant_modes)
    comparisons, clock = {}, time.perf_counter()
    for m in masses:                                 # --max-wall bounds the whole range, not each payload
        run = dataclasses.replace(rc, dt=dt, t_end=sc.t_end,
                                  sim_settings=_remaining(rc.sim_settings, time.perf_counter() - clock))
        each = dataclasses.replace(settings, plant=dataclasses.replace(pc, plant_params=plant_base.replace(m_t=m)),
                                   run=run, payload=PayloadChoice(payload_learning=learning))
        comparisons[m] = compare(params, task, names, each, designs=designs or None, progress=progress)
    return PayloadComparison((lo, hi), masses, comparisons, designs)


def _remaining(sim_settings, elapsed: float):
    """``sim_settings`` with its wall-time limit less the ``elapsed`` seconds (unchanged without one)."""
    limit = sim_settings.get("max_wall_s") if isinstance(sim_settings, dict) else getattr(sim_settings, "max_wall_s",
                                                                                           None)
    if limit is None or sim_settings is None:
        return sim_settings
    left = max(1e-3, limit - elapsed)
    return dict(sim_settings, max_wall_s=left) if isinstance(sim_settings, dict) else \
        dataclasses.replace(sim_settings, max_wall_s=left)


_COLUMNS = (("payload_kg", "payload kg", "{:g}"), ("controller", "controller", "{}"),
            ("verdict", "verdict", "{}"), ("settling_time_s", "settle s", "{:.3g}"),
            ("residual_pct_of_openloop", "% of OL", "{:.3g}"),
            ("residual_tip_max_m", "resid max m", "{:.2e}"), ("final_angle_error_rad", "err(end) rad", "{:.2e}"),
            ("peak_torque_nm", "peak tau Nm", "{:.4g}"), ("settling_over_limit", "settle/limit", "{:.3g}"),
            ("loop_spectral_radius", "radius", "{:.6g}"), ("check_verdict", "check plant", "{}"),
            ("design_mass_kg", "design kg", "{:g}"))


def _cell(value, fmt) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return fmt.format(value)


def payload_table(pc: PayloadComparison, markdown: bool = False) -> str:
    """The rows of a :class:`PayloadComparison` as a plain-text (or Markdown) table.

    Parameters
    ----------
    pc : PayloadComparison
        The runs over the payload range.
    markdown : bool
        Markdown instead of plain text.
    """
    rows = pc.rows()
    columns = [c for c in _COLUMNS if c[0] != "check_verdict" or any(r["check_verdict"] for r in rows)]
    head = [h for _, h, _ in columns]
    body = [[_cell(r[k], f) for k, _, f in columns] for r in rows]
    if markdown:
        return "\n".join(["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
                         + ["| " + " | ".join(r) + " |" for r in body])
    widths = [max(len(x[i]) for x in [head] + body) for i in range(len(head))]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in [head] + body)


def write_payload_outputs(pc: PayloadComparison, out_dir) -> dict:
    """Write ``payload.json`` (the rows and the designs' scores) and ``payload_report.md``.

    Parameters
    ----------
    pc : PayloadComparison
        The comparison over the payload range (:func:`payload_comparison`).
    out_dir : str or Path
        Created if missing (its parent must exist).

    Returns
    -------
    dict
        File kind -> Path.
    """
    out = output_folder(out_dir)
    designs = {n: {"design_mass_kg": d.design_mass, "choice": d.choice, "score": d.score,
                   "candidates": d.scores, "payloads_verified_kg": list(d.grid)} for n, d in pc.designs.items()}
    clean = lambda v: None if isinstance(v, float) and not math.isfinite(v) else v
    doc = {"payload_range_kg": list(pc.payload_range), "masses_kg": list(pc.masses),
           "rows": [{k: clean(v) for k, v in r.items()} for r in pc.rows()],
           "designs": {n: {k: ({kk: clean(vv) for kk, vv in v.items()} if isinstance(v, dict) else clean(v))
                           for k, v in d.items()} for n, d in designs.items()}}
    sc = next(iter(pc.comparisons.values())).scenario
    lines = [f"# Payload range {pc.payload_range[0]:g}-{pc.payload_range[1]:g} kg: {sc.name} on {sc.plant.upper()}",
             "", f"- Task: {sc.description}.",
             f"- Designs chosen on linear models at {', '.join(f'{m:g}' for m in next(iter(pc.designs.values())).grid)}"
             " kg (controllers.robust.design_for_range):" if pc.designs else "- No range designs" + (
                 ": the nominal design learns the payload during the slew (controllers.payload_learning)."
                 if any(r["design"].startswith("learns") for r in pc.rows()) else "."), ""]
    for n, d in pc.designs.items():
        lines.append(f"  - {n}: {d.choice}; worst linear score {d.score:.3g} (residual relative to the "
                     "open loop's; for a spin-up, the spectral radius)")
    from hubbeam_ctrl.study.report import _plant_lines
    lines += ["", f"Plant at {pc.masses[0]:g} kg (each row's plant has that row's tip mass m_t):", ""]
    lines += _plant_lines(next(iter(pc.comparisons.values())))
    lines += ["", "Each plant is judged against the open loop (Eq. 44 baseline) on the same plant; radius: the "
              "spectral radius of the sampled linear loop (the certificate; < 1 is stable).", "",
              payload_table(pc, markdown=True), ""]
    paths = {"json": atomic_write_text(out / "payload.json", json.dumps(doc, indent=1) + "\n"),
             "report": atomic_write_text(out / "payload_report.md", "\n".join(lines))}
    pc.paths = paths
    return paths

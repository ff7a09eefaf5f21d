"""The rig ladder: the same comparison with the rig's hardware added one part at a time.

A design that works on the ideal plant and fails on the rig leaves the user asking which
part of the hardware broke it. :func:`rig_ladder` runs the comparison on the beam alone,
then adds the rig's damping, friction, drive, sensors and computation delay one after the
other (each step keeps the ones before), and reports each controller's verdict, residual
and final angle error at every step. Steps whose part is ideal in the rig are left out.
"""

from __future__ import annotations

import dataclasses
import math
import multiprocessing
import signal
from concurrent.futures import ProcessPoolExecutor

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import Damping, Drive, Friction, Rig, Sensors, Timing
from hubbeam_ctrl.study.compare import _design_modes, _sim_settings, compare
from hubbeam_ctrl.study.compare_values import CompareSettings
from hubbeam_ctrl.study.sweep import check_workers
from hubbeam_ctrl.study.yardstick import task_on_rig

__all__ = ["LADDER_STEPS", "ladder_rigs", "rig_ladder"]

#: The ladder's steps in order: label and the rig part it adds.
LADDER_STEPS = (("ideal plant", None), ("+ damping", "damping"), ("+ friction", "friction"),
                ("+ drive", "drive"), ("+ sensors", "sensors"), ("+ delay", "timing"))

_IDEAL = {"damping": Damping, "friction": Friction, "drive": Drive, "sensors": Sensors}


def ladder_rigs(rig: Rig) -> list:
    """The rigs of the ladder: ``[(label, Rig), ...]``, from the beam alone to ``rig`` itself.

    The first step keeps the rig's sample time (a design choice, not hardware); a step whose
    part is ideal in ``rig`` is left out, so the last rig equals ``rig``.

    Parameters
    ----------
    rig : Rig

    Returns
    -------
    list of (str, Rig)
    """
    if not isinstance(rig, Rig):
        raise ParameterError(f"rig must be a Rig, got {type(rig).__name__}")
    parts = {name: cls() for name, cls in _IDEAL.items()}
    parts["timing"] = Timing(dt=rig.timing.dt)
    out = [("ideal plant", Rig(beam=rig.beam, **parts))]
    for label, part in LADDER_STEPS[1:]:
        value = getattr(rig, part)
        if value == parts[part]:
            continue
        parts[part] = value
        out.append((label, Rig(beam=rig.beam, **parts)))
    return out


def rig_ladder(rig: Rig, task="slew", controllers=None, settings: CompareSettings | None = None, *,
               progress=None, done=None, workers: int = 1) -> list:
    """Run :func:`~hubbeam_ctrl.study.compare.compare` on each rig of :func:`ladder_rigs`.

    Parameters
    ----------
    rig : Rig
    task : str or Slew or SpinUp
        The task (as for ``compare``).
    controllers : str or sequence of str, optional
        As for ``compare``.
    settings : CompareSettings, optional
        As for ``compare``; ``settings.run.t_end`` defaults to the full rig's task time, so every
        step runs the same window; give the full rig's bands (``settings.scenario.settle_angle``,
        ``settle_tip``: its ``Comparison.scenario.bands``, as ``hubbeam compare --rig`` does) to
        judge every step by them rather than by its own sensors' defaults.
    progress : callable, optional
        Called with each step's label, in order, as its rows are in.
    done : Comparison, optional
        The comparison of ``rig`` already run (``hubbeam compare --rig`` runs it first): the
        last step, the rig itself, takes its runs instead of running them again when it ran
        on that rig, task and controllers with the step's settings (its own ``t_end`` and bands
        resolved as the step's are); otherwise the step runs.
    workers : int
        Processes that run the steps side by side (forked: each starts with this process's
        compiled functions and caches; the rows are the same as run here). Default 1: here,
        one after the other (on the shared, loaded 2-core machine two ladder workers took 88 s
        against 68 s, ``benchmarks/results/bench_compare_2026-11-28_ladder*.json``); more where
        processors are free.

    Returns
    -------
    list of dict
        One row per step and controller: ``step``, ``controller``, ``verdict``,
        ``residual_tip_max_m``, ``final_angle_error_rad``, ``settling_time_s``, ``command_max``
        (N m or V), ``command`` (``"torque"`` or ``"voltage"``).
    """
    settings = CompareSettings() if settings is None else settings
    check_workers(workers)
    steps = ladder_rigs(rig)
    asked, asked_settings = task, settings
    task, scenario, _ = task_on_rig(rig, task, settings.scenario)       # every step: the full rig's task
    settings = dataclasses.replace(settings, scenario=scenario)
    rows, t_end = {}, settings.run.t_end
    todo = list(range(len(steps)))
    if t_end is None:                    # the first step sets the window of the others
        c = compare(steps[0][1], task, controllers, settings)
        rows[0], t_end = _rows(steps[0][0], c), c.scenario.t_end
        todo.pop(0)
    step = dataclasses.replace(settings, run=dataclasses.replace(settings.run, t_end=t_end))
    last = len(steps) - 1
    if last in todo and _same_run(done, steps[last][1], asked, controllers, dataclasses.replace(
            asked_settings, run=dataclasses.replace(asked_settings.run, t_end=t_end))):
        rows[last] = _rows(steps[last][0], done)
        todo.remove(last)
    jobs = [(steps[k][0], steps[k][1], task, controllers, step) for k in todo]
    n = min(workers, len(jobs))
    if n > 1 and "fork" in multiprocessing.get_all_start_methods():
        with ProcessPoolExecutor(max_workers=n, mp_context=multiprocessing.get_context("fork"),
                                 initializer=_quiet) as pool:
            futures = dict(zip(todo, (pool.submit(_run_step, *job) for job in jobs)))
            for k in sorted(futures):
                rows[k] = futures[k].result()
    else:
        for k, job in zip(todo, jobs):
            rows[k] = _run_step(*job)
    out = []
    for k, (label, _) in enumerate(steps):
        if progress is not None:
            progress(label)
        out += rows[k]
    return out


def _quiet() -> None:
    """In a ladder worker: Ctrl-C is the caller's to handle (it stops the workers)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _run_step(label: str, rig: Rig, task, controllers, settings: CompareSettings) -> list:
    """The rows of one ladder step (run here or in a worker)."""
    return _rows(label, compare(rig, task, controllers, settings))


def _rows(label: str, c) -> list:
    """One row per controller of the comparison ``c`` (see :func:`rig_ladder`)."""
    rows = []
    for name, m in c.metrics.items():
        res = c.results[name]
        hw = res.settings.get("hardware") or {}
        rows.append({"step": label, "controller": name, "verdict": m["verdict"],
                     "residual_tip_max_m": m["residual_tip_max_m"],
                     "final_angle_error_rad": m["final_angle_error_rad"],
                     "settling_time_s": m.get("settling_time_s"),
                     "command_max": float(max(abs(float(v)) for v in res.tau if math.isfinite(v)))
                     if len(res.tau) else float("nan"),
                     "command": hw.get("command", "torque")})
    return rows


def _resolved(settings: CompareSettings, sc) -> CompareSettings:
    """``settings`` with what ``compare`` resolves on the scenario ``sc`` resolved: the simulated time,
    the settling bands, the closed loop's settings and the design model's modes (whether the runs went
    side by side does not change them)."""
    run, design = settings.run, settings.design
    return dataclasses.replace(
        settings, run=dataclasses.replace(run, t_end=sc.t_end, sim_settings=_sim_settings(run.sim_settings, sc),
                                          side_by_side=False),
        design=dataclasses.replace(design, design_modes=_design_modes(design.design_modes, sc.params)),
        scenario=dataclasses.replace(settings.scenario, settle_angle=sc.bands["settle_angle"],
                                     settle_tip=sc.bands["settle_tip"]))


def _same_run(done, rig: Rig, task, controllers, settings: CompareSettings) -> bool:
    """Whether the comparison ``done`` is what ``compare(rig, task, controllers, settings)`` would run."""
    if done is None or done.settings is None or done.rig != rig or not isinstance(task, str) \
            or done.scenario.name != task:
        return False
    names = tuple(done.metrics)
    if controllers is not None and tuple(c.strip().lower() for c in (controllers.split(",") if isinstance(
            controllers, str) else controllers)) != names:
        return False
    try:
        return _resolved(done.settings, done.scenario) == _resolved(settings, done.scenario)
    except (ParameterError, KeyError, TypeError):
        return False

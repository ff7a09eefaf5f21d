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

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import Damping, Drive, Friction, Rig, Sensors, Timing
from hubbeam_ctrl.study.compare import _design_modes, _parse_controllers, _sim_settings, compare
from hubbeam_ctrl.study.compare_values import CompareSettings
from hubbeam_ctrl.study.forked_runs import ForkedRuns, can_fork
from hubbeam_ctrl.study.sweep import check_workers
from hubbeam_ctrl.study.yardstick import task_on_rig

__all__ = ["LADDER_STEPS", "ladder_rigs", "rig_ladder", "LadderRun"]

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
        Processes that run the steps' closed loops side by side (forked; each step's controllers
        dealt among them: each starts with this process's compiled functions and caches; the rows are
        the same as run here). Default 1: here, one step after the other.

    Returns
    -------
    list of dict
        One row per step and controller: ``step``, ``controller``, ``verdict``,
        ``residual_tip_max_m``, ``final_angle_error_rad``, ``settling_time_s``, ``command_max``
        (N m or V), ``command`` (``"torque"`` or ``"voltage"``).
    """
    with LadderRun(rig, task, controllers, settings, workers=workers, done=done) as ladder:
        return ladder.rows(done, progress=progress)


class LadderRun:
    """The rig ladder started now, its rows collected by :meth:`rows` (:func:`rig_ladder` in two halves).

    With ``workers > 1`` the steps' runs start at once in forked workers (each step's controllers dealt
    among them), so the caller can go on meanwhile: ``hubbeam compare --rig`` starts the ladder as soon as
    its own comparison's designs are made and runs that comparison while the workers run the ladder.
    The last step (the rig itself) is left to :meth:`rows`, which takes it from the finished
    comparison when that ran it (see :func:`rig_ladder`'s ``done``).

    Parameters
    ----------
    rig, task, controllers, settings
        As for :func:`rig_ladder`.
    workers : int
        Forked workers (1: every step runs in :meth:`rows`, here).
    done : Comparison, optional
        The comparison of ``rig`` when it is already known: its last step is then not started
        unless it differs from what the step would run.

    Notes
    -----
    Use it as a context manager (or call :meth:`stop`): leaving the block by an exception, Ctrl-C
    included, stops the workers.
    """

    def __init__(self, rig: Rig, task="slew", controllers=None, settings: CompareSettings | None = None, *,
                 workers: int = 1, done=None):
        settings = CompareSettings() if settings is None else settings
        check_workers(workers)
        self.steps = ladder_rigs(rig)
        self._asked, self._asked_settings, self._controllers = task, settings, controllers
        self.task, scenario, _ = task_on_rig(rig, task, settings.scenario)    # every step: the full rig's task
        settings = dataclasses.replace(settings, scenario=scenario)
        self._rows, t_end = {}, settings.run.t_end
        todo = list(range(len(self.steps)))
        if t_end is None:                    # the first step sets the window of the others
            c = compare(self.steps[0][1], self.task, controllers, settings)
            self._rows[0], t_end = _rows(self.steps[0][0], c), c.scenario.t_end
            todo.pop(0)
        self.settings = dataclasses.replace(settings, run=dataclasses.replace(settings.run, t_end=t_end))
        last = len(self.steps) - 1
        if last in todo and (done is None or self._takes(done)):
            todo.remove(last)                # the comparison's own runs (or run in rows() if they differ)
        self._todo, self._forked = todo, None
        if workers > 1 and todo and can_fork():
            # each step's controllers dealt to the workers (a step's larger part to each worker in turn)
            shares = [[] for _ in range(workers)]
            for i, k in enumerate(todo):
                names = self._names(k)
                for j in range(workers):
                    if names[j::workers]:
                        shares[(i + j) % workers].append((k, names[j::workers]))
            self._forked = ForkedRuns(shares, self._job)

    def __enter__(self) -> "LadderRun":
        return self

    def __exit__(self, kind, exc, tb) -> None:
        self.stop()

    def stop(self) -> None:
        """Stop the workers still running (idempotent)."""
        if self._forked is not None:
            self._forked.stop()

    def _takes(self, done) -> bool:
        """Whether the last step takes the comparison ``done`` instead of running."""
        asked = self._asked_settings
        return _same_run(done, self.steps[-1][1], self._asked, self._controllers, dataclasses.replace(
            asked, run=dataclasses.replace(asked.run, t_end=self.settings.run.t_end)))

    def _names(self, k: int) -> tuple:
        """The controllers step ``k`` runs (as ``compare`` picks them: without pd on a rig with no rate
        sensor when none were named)."""
        names = _parse_controllers(self._controllers)
        if self._controllers is None and not self.steps[k][1].sensors.rate:
            names = tuple(n for n in names if n != "pd")
        return names

    def _job(self, job) -> list:
        """The rows of some controllers of one step (run in a worker)."""
        k, names = job
        s = self.settings
        own = {n: v for n, v in (s.design.settings or {}).items() if n in names} or None
        s = dataclasses.replace(s, design=dataclasses.replace(s.design, settings=own))
        return _run_step(self.steps[k][0], self.steps[k][1], self.task, names, s)

    def rows(self, done=None, progress=None) -> list:
        """The ladder's rows, step by step (waits for the workers; runs here what they did not).

        Parameters
        ----------
        done : Comparison, optional
            As for :func:`rig_ladder`.
        progress : callable, optional
            Called with each step's label, in order, as its rows are in.

        Returns
        -------
        list of dict
            As :func:`rig_ladder` returns them.
        """
        rows, last = dict(self._rows), len(self.steps) - 1
        if self._forked is not None:
            got = {(k, row["controller"]): row for (k, _), part in self._forked.collect().items() for row in part}
            for k in self._todo:
                rows[k] = [got[(k, name)] for name in self._names(k)]
        else:
            for k in self._todo:
                rows[k] = _run_step(self.steps[k][0], self.steps[k][1], self.task, self._controllers, self.settings)
        if last not in rows:
            rows[last] = (_rows(self.steps[last][0], done) if done is not None and self._takes(done) else
                          _run_step(self.steps[last][0], self.steps[last][1], self.task, self._controllers,
                                    self.settings))
        out = []
        for k, (label, _) in enumerate(self.steps):
            if progress is not None:
                progress(label)
            out += rows[k]
        return out


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
    modes = _design_modes(design.design_modes, sc.params, sc.dt if settings.plant.plant_modes is None else None)[0]
    return dataclasses.replace(
        settings, run=dataclasses.replace(run, t_end=sc.t_end, sim_settings=_sim_settings(run.sim_settings, sc),
                                          side_by_side=False),
        design=dataclasses.replace(design, design_modes=modes),
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

"""The verdict's rules on the fuzzed rigs that set them (issue 36): each case's LQR (and the rig's other laws
where the rule compares them) with the rule as it runs, against the rule before, in the same process.

Cases (their rigs are the tests', from ``benchmarks/fuzz_rigs.py``):

- ``count_cycle_growth``: ``tests/test_friction_bound.py``'s 0.88 m steel link on a geared DC motor, 4096
  counts, no tachometer, 1 ms. The default law's tip envelope rises in the window; ``judge.count_cause``
  calls the run "not settled" by the counts where it was "unstable". ``longer`` is a run 4 times longer.
- ``slow_pole``: link rig 2 of seed 37 (``tests/test_fuzzed_rigs.py``'s ``SLOW_POLE_LINK``): the window ends
  before the loop's slowest pole decays; ``judge.slow_pole_cause`` names it and ``longer`` is the run
  3 decay times longer.
- ``settle_hold``: link rig 1 of seed 37 (``tests/test_settling.py``'s ``COUNT_CYCLE_LINK``): a count cycle
  at 2.3 x the tip band; ``before`` is the last sample deciding "settled" (no hold), ``now`` the hold
  of :mod:`hubbeam_ctrl.study.settling`.

docs/rig.md and docs/controllers.md quote this file's numbers and ``tests/test_settling.py`` keeps them equal.

Run: ``.venv/bin/python benchmarks/bench_verdict_causes.py [--out F.json]`` (about a minute on 2 cores).
"""

from __future__ import annotations

import os
import platform
import sys
import tempfile

sys.path.insert(0, os.path.dirname(__file__))
from benchjson import bench_parser, emit  # noqa: E402

import hubbeam_ctrl.study.metrics as metrics_module  # noqa: E402
from hubbeam_ctrl.plant.rig import load_rig, rig_from_dict  # noqa: E402
from hubbeam_ctrl.study.compare import compare  # noqa: E402
from hubbeam_ctrl.study.compare_values import CompareSettings, RunChoice  # noqa: E402
from hubbeam_ctrl.study.judge import SLOW_POLE_SPANS  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))
from test_friction_bound import CHATTER_RIG  # noqa: E402
from test_fuzzed_rigs import SLOW_POLE_LINK  # noqa: E402
from test_settling import COUNT_CYCLE_LINK  # noqa: E402

#: The figures kept of each run.
KEYS = ("verdict", "residual_tip_max_m", "settle_tip_m", "tip_growth_rate_per_s", "growth_resolution_per_s",
        "loop_spectral_radius", "loop_slowest_decay_s", "count_tip_bound_m", "settling_time_s",
        "inside_bands_at_end_s", "settle_hold_s")


def _figures(c, name: str) -> dict:
    m = c.metrics[name]
    out = {k: m.get(k) for k in KEYS}
    out["t_end_s"] = float(c.scenario.t_end)
    out["window_s"] = float(c.scenario.t_end - c.scenario.t_f - c.scenario.bands["residual_delay"])
    return out


def _run(rig, controllers, t_end=None):
    settings = CompareSettings(run=RunChoice(t_end=t_end)) if t_end is not None else CompareSettings()
    return compare(rig, "slew", list(controllers), settings)


def count_cycle_growth() -> dict:
    """The coarse encoder's bounded cycle, and a run 4 times longer."""
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "chatter.toml")
        with open(path, "w", encoding="utf-8") as f:
            f.write(CHATTER_RIG)
        rig = load_rig(path)
    c = _run(rig, ["lqr"])
    now = _figures(c, "lqr")
    longer = _figures(_run(rig, ["lqr"], 4 * c.scenario.t_end), "lqr")
    return {"now": now, "longer": longer}


def slow_pole() -> dict:
    """The window shorter than 3 decay times of the slowest pole, and the run that much longer."""
    rig = rig_from_dict(SLOW_POLE_LINK)
    c = _run(rig, ["lqr"])
    now = _figures(c, "lqr")
    longer = _figures(_run(rig, ["lqr"], c.scenario.t_end + SLOW_POLE_SPANS * now["loop_slowest_decay_s"]), "lqr")
    return {"now": now, "longer": longer}


def settle_hold() -> dict:
    """LQR, LQG and MPC in a count cycle, with the hold and with the last sample deciding."""
    rig = rig_from_dict(COUNT_CYCLE_LINK)
    laws = ("lqr", "lqg", "mpc")
    c = _run(rig, laws)
    now = {k: _figures(c, k) for k in laws}
    saved = metrics_module.settle_hold
    metrics_module.settle_hold = lambda *a: 0.0
    try:
        b = _run(rig, laws)
    finally:
        metrics_module.settle_hold = saved
    return {"now": now, "before": {k: _figures(b, k) for k in laws}}


def main(argv=None) -> dict:
    args = bench_parser(__doc__).parse_args(argv)
    out = {"benchmark": "the verdict's causes and hold on the fuzzed rigs that set them, LQR (and LQG, MPC)",
           "machine": platform.machine(), "cpus": os.cpu_count(), "python": platform.python_version(),
           "cases": {"count_cycle_growth": count_cycle_growth(), "slow_pole": slow_pole(),
                     "settle_hold": settle_hold()}}
    emit(out, args.out)
    return out


if __name__ == "__main__":
    main()

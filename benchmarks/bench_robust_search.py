"""The robust design search with the bounded residual score against the plain one (issue 39, issue 37's speed).

:func:`hubbeam_ctrl.study.robust_design.design_for_set` scores each certified candidate by the worst
nonlinear residual over the set's corners and centre
(:class:`~hubbeam_ctrl.study.robust_check.ResidualScore`). The score is a largest value over
points, so a candidate's runs may stop once one point reaches the best score so far (``bound``).
Both variants run here in the same process on the same comparison: ``bounded`` (the score as
``design_for_set`` gets it) and ``plain`` (the same score behind a wrapper that hides ``bound``,
so every point of every candidate runs). They must choose the same design; the benchmark records
the closed-loop runs and the wall time of each.

Case: notebook 12_robust's, Table 1's beam, its default slew, LQG over payload 0-0.5 kg with a
0.05 % damping floor.

Run: ``.venv/bin/python benchmarks/bench_robust_search.py [--out F.json]`` (about 1 min on 2 cores).
"""

from __future__ import annotations

import os
import platform
import sys
import time

sys.path.insert(0, os.path.dirname(__file__))
from benchjson import bench_parser, emit  # noqa: E402

from hubbeam_ctrl import Params  # noqa: E402
from hubbeam_ctrl.plant.rig import Rig  # noqa: E402
from hubbeam_ctrl.plant.uncertainty import Uncertainty  # noqa: E402
from hubbeam_ctrl.study.compare import compare  # noqa: E402
from hubbeam_ctrl.study.robust_check import residual_score  # noqa: E402
from hubbeam_ctrl.study.robust_design import design_for_set  # noqa: E402


class _Plain:
    """The score without ``bound``: every point of every candidate runs (the alternative)."""

    def __init__(self, score):
        self.score = score

    def __call__(self, ctrl):
        return self.score(ctrl)


def main(argv=None) -> dict:
    args = bench_parser(__doc__).parse_args(argv)
    payload = Uncertainty.from_table({"m_t": (0.0, 0.5), "damping": (0.0005, 0.0005)})
    rig = Rig(beam=Params(), uncertainty=payload)
    cmp = compare(rig, "slew", ["openloop", "lqg"])
    bare = rig.replace(uncertainty=Uncertainty())
    out = {"benchmark": "design_for_set: bounded residual score against the plain one",
           "case": "Table 1, default slew, LQG, m_t 0-0.5 kg, damping 0.0005",
           "machine": platform.machine(), "cpus": os.cpu_count(), "python": platform.python_version(),
           "load_average_1min": os.getloadavg()[0], "variants": {}}
    for label in ("bounded", "plain"):
        score = residual_score(cmp, bare, payload)
        t0 = time.perf_counter()
        design = design_for_set(cmp, "lqg", bare, payload, score=score if label == "bounded" else _Plain(score))
        out["variants"][label] = {"wall_s": time.perf_counter() - t0, "closed_loop_runs": score.runs,
                                  "candidates": len(design.tried), "chosen": design.label(),
                                  "worst_radius": design.certificate.worst.radius}
    b, p = out["variants"]["bounded"], out["variants"]["plain"]
    out["same_choice"] = b["chosen"] == p["chosen"] and b["worst_radius"] == p["worst_radius"]
    out["runs_ratio"] = b["closed_loop_runs"] / p["closed_loop_runs"]
    out["wall_ratio"] = b["wall_s"] / p["wall_s"]
    emit(out, args.out)
    return out


if __name__ == "__main__":
    main()

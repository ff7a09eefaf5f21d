"""Loop margins through Hessenberg solves against dense solves at every point (issue 37's speed).

:class:`controllers.frequency.FrequencyResponse` solves ``(zI - A) x = B`` at every point of a
loop whose modal form is ill conditioned and has no cluster to split off. ``hessenberg``:
Laub's method as it runs now (``A`` reduced to Hessenberg form once, ``O(n^2)`` a point, batches
of points vectorised); ``dense``: a dense LAPACK solve at every point (the method before, and
what the root finder's single points still take), by raising ``FEW_POINTS`` past the grid. Both
in the same process on the same loop; they must give the same margins.

Case: the loop of session 22's random rig s32/0 (a 2.53 m steel strip on a 493 N m torque source
with Coulomb friction, 10000 counts, a root gauge, 1 kHz and one sample of delay; see
``tests/test_frozen.py``), its default LQR: 87 states, about 20 000 grid points.

Run: ``.venv/bin/python benchmarks/bench_frequency.py [--out F.json]`` (about 40 s on 2 cores).
"""

from __future__ import annotations

import os
import platform
import sys
import time

sys.path.insert(0, os.path.dirname(__file__))
from benchjson import bench_parser, emit  # noqa: E402

import controllers.frequency as frequency  # noqa: E402
from controllers.analysis import loop_matrices, margins_of_loop  # noqa: E402
from hubbeam_ctrl.plant.rig import rig_from_dict  # noqa: E402
from hubbeam_ctrl.study.compare import compare  # noqa: E402

#: The strip: random rig s32/0 of session 22's fuzzing, kept with the tests of its frozen loop.
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))
from test_frozen import AXIAL_RIG as STRIP  # noqa: E402


def main(argv=None) -> dict:
    args = bench_parser(__doc__).parse_args(argv)
    cmp = compare(rig_from_dict(STRIP), "slew", ["openloop", "lqr"])
    ctrl = cmp.controllers["lqr"]
    A, B, C, D = loop_matrices(ctrl)
    out = {"benchmark": "loop margins: Hessenberg solves against dense solves",
           "case": "random rig s32/0 (2.53 m strip, 1 kHz, one sample of delay), default LQR",
           "states": int(A.shape[0]), "machine": platform.machine(), "cpus": os.cpu_count(),
           "python": platform.python_version(), "load_average_1min": os.getloadavg()[0], "variants": {}}
    few = frequency.FEW_POINTS
    margins = {}
    for label, points in (("hessenberg", few), ("dense", 10 ** 9)):
        frequency.FEW_POINTS = points
        walls = []
        for _ in range(3):
            t0 = time.perf_counter()
            lm = margins_of_loop(A, B, C, D, ctrl.dt, "lqr")
            walls.append(time.perf_counter() - t0)
        frequency.FEW_POINTS = few
        margins[label] = lm.to_dict()
        out["variants"][label] = {"wall_median_s": sorted(walls)[1], "walls_s": walls,
                                  "disk_margin": lm.disk_margin, "delay_margin_s": lm.delay_margin_s}
    a, b = margins["hessenberg"], margins["dense"]
    a.pop("disk_margin_grid"), b.pop("disk_margin_grid")          # the grid's own maximum
    out["same_margins"] = a == b
    out["speedup"] = out["variants"]["dense"]["wall_median_s"] / out["variants"]["hessenberg"]["wall_median_s"]
    emit(out, args.out)
    return out


if __name__ == "__main__":
    main()

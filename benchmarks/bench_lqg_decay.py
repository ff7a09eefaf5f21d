"""The LQG filter's decay derived from the sensor noise (issue 22): the ladder per beam, and its cost.

Run: ``.venv/bin/python benchmarks/bench_lqg_decay.py [--out F.json]`` (about 30 s). Prints JSON.

For each beam and task, the tip's noise-driven standard deviation over the tip band at every
decay of :data:`controllers.lqg.DECAY_LADDER` (:func:`controllers.lqg.noise_tip_std`) and the
decay the default design derives; for Table 1's beam at 1.5 x its time-optimal slew, the LQG's
settling time and loop margins at every decay against its LQR's (``compare(...).metrics``).
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchjson import bench_parser, emit  # noqa: E402

from controllers import LQG, DesignModel, LQGSettings  # noqa: E402
from controllers.lqg import DECAY_LADDER, noise_tip_std  # noqa: E402
from hubbeam_ctrl import Params  # noqa: E402
from hubbeam_ctrl.plant.rig import load_rig  # noqa: E402
from hubbeam_ctrl.study.compare import compare  # noqa: E402
from hubbeam_ctrl.study.compare_values import CompareSettings, DesignChoice
from hubbeam_ctrl.study.rig_loop import rig_noise  # noqa: E402
from hubbeam_ctrl.study.scenarios import make_scenario  # noqa: E402
from hubbeam_ctrl.study.tasks import Slew  # noqa: E402

LAB = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)
PAPER_TF = 1.5 * 2.6419525            # 1.5 x Table 1's time-optimal 1 rad slew [s] (docs/limit.md)
MARGINS = ("disk_margin", "gain_margin_upper", "phase_margin_deg", "delay_margin_s")


def ladder() -> dict:
    """std / tip band at each decay and the derived decay, per beam and task."""
    rig = load_rig("servo_link")
    cases = {"paper, 1.5 x T_opt": (make_scenario(Slew(1.0, PAPER_TF), params=Params()), None),
             "paper, Eq. 44 slew": (make_scenario("slew"), None),
             "lab arm, 90 deg": (make_scenario(Slew(math.pi / 2, 1.5 * 0.8404), params=LAB), None),
             "servo link beam": (make_scenario(Slew(math.pi / 2, 0.4457), params=rig.plant_params), None),
             "servo_link rig, encoder": (make_scenario(Slew(math.pi / 2, 0.4531), params=rig.plant_params,
                                                       dt=rig.timing.dt), rig)}
    out = {}
    for name, (sc, with_rig) in cases.items():
        design = DesignModel.build(sc.params, sc.design_spin, sc.dt)
        st = LQGSettings.for_scenario(sc)
        if with_rig is not None:
            st = rig_noise(st, with_rig)
        band = sc.bands["settle_tip"]
        stds = [noise_tip_std(LQG(design, dataclasses.replace(st, error_decay=d, tip_noise_budget_m=None))) / band
                for d in DECAY_LADDER]
        out[name] = {"std_over_band": dict(zip(map(str, DECAY_LADDER), stds)),
                     "derived_decay": LQG(design, st).settings.error_decay}
        print(f"{name:26s} " + " / ".join(f"{x:.3f}" for x in stds)
              + f"  -> {out[name]['derived_decay']}", file=sys.stderr)
    return out


def margins() -> dict:
    """Table 1's beam at 1.5 x T_opt: the LQG at each decay and the LQR."""
    p = Params()
    sc = make_scenario(Slew(1.0, PAPER_TF), params=p)
    out = {}
    for decay in DECAY_LADDER:
        st = LQGSettings.for_scenario(sc, error_decay=decay)
        m = compare(p, Slew(1.0, PAPER_TF), "lqg",
                    CompareSettings(design=DesignChoice(settings={"lqg": st}))).metrics["lqg"]
        out[f"lqg {decay}"] = {"settling_time_s": m["settling_time_s"], **{k: m[k] for k in MARGINS}}
    m = compare(p, Slew(1.0, PAPER_TF), "lqr").metrics["lqr"]
    out["lqr"] = {"settling_time_s": m["settling_time_s"], **{k: m[k] for k in MARGINS}}
    for name, row in out.items():
        print(f"{name:8s} " + "  ".join(f"{k} {v:.4g}" for k, v in row.items()), file=sys.stderr)
    return out


def main(argv=None) -> int:
    """Entry point; prints the JSON and writes it to ``--out`` when given."""
    ap = bench_parser(__doc__)
    args = ap.parse_args(argv)
    emit({"benchmark": "bench_lqg_decay", "issue": 22, "ladder": ladder(), "margins": margins()}, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The count and noise shares on the fuzzed rigs that set them (issue 36): each rig's LQR with the rule
as it runs, against the rule before (``COUNT_SHARE`` 0.5; no noise rule), in the same process.

``COUNT_SHARE`` (:mod:`hubbeam_ctrl.study.rig_loop`): the largest share of the command's limit one
encoder count toggling each sample may move the command by; ``NOISE_SHARE``: the largest RMS share of
the limit the sensors' stated noise may move it by. Where a law breaks either, ``on_rig`` raises the
filter's angle noise, then the torque weight (``SOFTER_LADDER``).

Cases (their rigs are ``tests/test_fuzzed_rigs.py``'s, from ``benchmarks/fuzz_rigs.py``):

- ``ring_link``: link rig 6 of seed 34, a 1.26 m aluminium link on a geared DC motor, 2000 counts, a
  root gauge, no tachometer, 5 ms and one sample of delay; ``before`` is ``COUNT_SHARE`` = 0.5.
- ``noisy_boom``: space rig 0 of seed 1, an 8.8 m boom, a 16 mN m actuator, a 90 urad star tracker
  at 20 Hz; ``before`` is no noise rule (``NOISE_SHARE`` 1e300), the law from the task's weights.

docs/rig.md quotes this file's numbers and ``tests/test_fuzzed_rigs.py`` keeps the two equal.

Run: ``.venv/bin/python benchmarks/bench_rig_shares.py [--out F.json]`` (about a minute on 2 cores).
"""

from __future__ import annotations

import os
import platform
import sys

sys.path.insert(0, os.path.dirname(__file__))
from benchjson import bench_parser, emit  # noqa: E402

import hubbeam_ctrl.study.rig_loop as rig_loop  # noqa: E402
from hubbeam_ctrl.plant.rig import rig_from_dict  # noqa: E402
from hubbeam_ctrl.study.compare import compare  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))
from test_fuzzed_rigs import NOISY_BOOM, RING_LINK  # noqa: E402

#: The rule before, by case: the module constants patched for the ``before`` run.
BEFORE = {"ring_link": {"COUNT_SHARE": 0.5}, "noisy_boom": {"NOISE_SHARE": 1e300}}
#: The rigs, by case.
RIGS = {"ring_link": RING_LINK, "noisy_boom": NOISY_BOOM}


def run_case(rig_dict: dict, patch: dict) -> dict:
    """One LQR comparison on the rig's default slew with the rig_loop constants in ``patch``.

    Parameters
    ----------
    rig_dict : dict
        The rig, as a rig file's tables.
    patch : dict
        ``rig_loop`` constant name -> value for this run (restored after).

    Returns
    -------
    dict
        The run's verdict, residual tip RMS and band [m], their ratio, time at the limit [s], the
        law's count and noise shares [-] and the factors the rule chose (filter noise, torque weight).
    """
    saved = {k: getattr(rig_loop, k) for k in patch}
    try:
        for k, v in patch.items():
            setattr(rig_loop, k, v)
        c = compare(rig_from_dict(rig_dict), "slew", ["lqr"])
    finally:
        for k, v in saved.items():
            setattr(rig_loop, k, v)
    m, law = c.metrics["lqr"], c.controllers["lqr"]
    while not hasattr(law, "count_noise_factor") and hasattr(law, "inner"):
        law = law.inner
    return {"verdict": m["verdict"], "residual_tip_rms_m": m["residual_tip_rms_m"],
            "settle_tip_m": m["settle_tip_m"], "rms_over_band": m["residual_tip_rms_m"] / m["settle_tip_m"],
            "time_at_limit_s": m["time_at_limit_s"], "t_end_s": float(c.scenario.t_end),
            "count_share": float(law.count_share), "noise_share": float(getattr(law, "noise_share", 0.0)),
            "filter_noise_factor": int(getattr(law, "count_noise_factor", 1)),
            "torque_weight_factor": getattr(law, "count_softened", None)}


def main(argv=None) -> dict:
    args = bench_parser(__doc__).parse_args(argv)
    out = {"benchmark": "count and noise shares: the rule as it runs against the rule before, LQR",
           "shares": {"COUNT_SHARE": rig_loop.COUNT_SHARE, "NOISE_SHARE": rig_loop.NOISE_SHARE},
           "machine": platform.machine(), "cpus": os.cpu_count(), "python": platform.python_version(),
           "cases": {}}
    for case, rig in RIGS.items():
        out["cases"][case] = {"before": {"patch": BEFORE[case], **run_case(rig, BEFORE[case])},
                              "now": run_case(rig, {})}
    emit(out, args.out)
    return out


if __name__ == "__main__":
    main()

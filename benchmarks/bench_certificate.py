"""Cost of the linear certificate in ``compare`` (issue 27: at most 10 % of a FOAM comparison).

Prints one JSON object. Run: ``.venv/bin/python benchmarks/bench_certificate.py [--beam paper|lab]``.

The named alternative is the same comparison judged without the certificate: ``compare`` on
FOAM with the five default controllers (warm: one run first builds and compiles the plant),
timed whole; then, for the same controllers and runs, the certificates alone
(:func:`hubbeam_ctrl.study.certificate.certify`, cold cache of the linear plant as in a
fresh comparison, then warm) and the metrics without a certificate. ``certificate_share``
is the certificates' CPU time over the comparison's.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

from hubbeam_ctrl import Params
from hubbeam_ctrl.study import Slew, compare
from hubbeam_ctrl.study.certificate import certify
from hubbeam_ctrl.study.compare_values import compare_arguments
from hubbeam_ctrl.study.metrics import closed_loop_metrics
from hubbeam_ctrl.study.sampled_loop import linear_plant

LAB = Params(L=1, rho=2700, A=9e-5, E=69e9, I=6.75e-11, J_h=0.02, r=0.05, m_t=0.05, tau_max=1.5)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--beam", choices=["paper", "lab"], default="paper")
    args = ap.parse_args()
    kw = {} if args.beam == "paper" else {"scenario": Slew(1.5708, 1.2), "params": LAB}
    load0 = os.getloadavg()
    compare(**compare_arguments("foam", **kw))                                   # warm-up: plant build and compile
    t0, c0 = time.perf_counter(), time.process_time()
    comp = compare(**compare_arguments("foam", **kw))
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    ctrls = comp.controllers
    linear_plant.cache_clear()
    c1 = time.process_time()
    certs = {}
    for name, res in comp.results.items():
        if name in comp.certificates and comp.certificates[name].available:
            ctrl = ctrls.get(name)
            if ctrl is not None:
                certs[name] = certify(ctrl, comp.plant.params, spins=(0.0,), name=name)
    cert_cold = time.process_time() - c1
    c2 = time.process_time()
    for name in certs:
        certify(ctrls[name], comp.plant.params, spins=(0.0,), name=name)
    cert_warm = time.process_time() - c2
    sc = comp.scenario
    c3 = time.process_time()
    for res in comp.results.values():
        closed_loop_metrics(res, sc.t_f, tau_max=sc.tau_max, **sc.bands)
    plain_metrics = time.process_time() - c3
    print(json.dumps({
        "benchmark": "certificate", "beam": args.beam, "machine": platform.machine(),
        "load_before": load0, "load_after": os.getloadavg(),
        "compare_wall_s": wall, "compare_cpu_s": cpu, "plant_modes": comp.plant.modes,
        "certified": sorted(certs), "certificates_cpu_s_cold": cert_cold, "certificates_cpu_s_warm": cert_warm,
        "metrics_without_certificate_cpu_s": plain_metrics,
        "certificate_share": cert_cold / cpu, "target_share": 0.10,
        "verdicts": {n: m["verdict"] for n, m in comp.metrics.items()},
    }, indent=2))


if __name__ == "__main__":
    main()

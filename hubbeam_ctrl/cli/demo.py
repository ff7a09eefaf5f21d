"""The main job behind ``make demo``.

1. The paper's spin-up comparison (Section 4.2, Fig. 5): TLAM vs FOAM vs CFOAM spun up to
   2.8 rad/s in 30 s, no tip mass; plot and summary written to the output folder.
2. If the controllers are installed, the closed-loop comparison on the default evaluation
   plant (FOAM with every bending mode below the sampling frequency) with the default slew
   (``hubbeam compare``), printing its table.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from hubbeam_ctrl.cli.args import Command
from hubbeam_ctrl.core.fileio import atomic_write_text
from hubbeam_ctrl.plant.params import Params

__all__ = ["spinup_comparison", "main"]

#: The paper's quoted values at w_f = 2.8 rad/s (Section 4.2).
PAPER_PEAKS_M = {"foam": 0.22, "tlam": 0.49}


def spinup_comparison(out_dir, w_f: float = 2.8, t_f: float = 30.0, t_end: float = 60.0,
                      params: Params = Params(m_t=0.0)) -> dict:
    """Spin TLAM, FOAM and CFOAM up to ``w_f`` and compare their tip deflections.

    Parameters
    ----------
    out_dir : str or Path
        Folder for ``spinup_comparison.png`` and ``spinup_summary.json``.
    w_f : float
        Final rate [rad/s].
    t_f : float
        Spin-up time [s].
    t_end : float
        Simulated time [s].
    params : Params
        Default: Table 1 without tip mass (the paper's Section 4.2).

    Returns
    -------
    dict
        Model -> summary (see :meth:`hubbeam_ctrl.sim.results.Result.summary`).
    """
    # imported here: `hubbeam` builds its parser from this module and must start light
    from hubbeam_ctrl.plant.maneuvers import SpinUp
    from hubbeam_ctrl.plots.plant import plot_tip_comparison, save_figure
    from hubbeam_ctrl.sim.simulate import simulate

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    results = {}
    for name in ("tlam", "foam", "cfoam"):
        results[name] = simulate(name, SpinUp(w_f, t_f), t_end, params=params)
    summary = {name: res.summary() for name, res in results.items()}
    ratio = summary["tlam"]["residual_tip_m"] / summary["foam"]["residual_tip_m"]
    summary["tlam_over_foam_residual"] = ratio
    fig = plot_tip_comparison({k.upper(): v for k, v in results.items()},
                              title=f"Spin-up to {w_f:g} rad/s in {t_f:g} s (no tip mass)")
    save_figure(fig, out / "spinup_comparison.png")
    atomic_write_text(out / "spinup_summary.json", json.dumps(summary, indent=2))
    return summary


def main(argv=None) -> int:
    """Run the demo; print its tables.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (default: ``sys.argv[1:]``).
    """
    parser = argparse.ArgumentParser(prog="python -m hubbeam_ctrl.cli.demo")
    parser.add_argument("--out", default="demo_out", help="output folder")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    summary = spinup_comparison(args.out)
    print("Spin-up to 2.8 rad/s in 30 s, no tip mass (paper Section 4.2, Fig. 5)")
    print(f"{'model':>6} {'peak |v_tip| [m]':>17} {'paper [m]':>10} {'residual [m]':>13} {'diverged':>9}")
    for name in ("tlam", "foam", "cfoam"):
        s = summary[name]
        paper = PAPER_PEAKS_M.get(name)
        print(f"{name.upper():>6} {s['peak_tip_m']:17.4f} {paper if paper else '-':>10} "
              f"{s['residual_tip_m']:13.3e} {str(s['diverged']):>9}")
    print(f"TLAM/FOAM residual vibration ratio: {summary['tlam_over_foam_residual']:.0f} (paper: ~100)")
    print(f"wrote {Path(args.out) / 'spinup_comparison.png'} and spinup_summary.json")
    try:
        from hubbeam_ctrl.study import print_table, run_compare
    except ImportError:
        run_compare = None
    if run_compare is not None:
        print("\nClosed loop on FOAM (10 modes), slew (Eq. 44 budget), all controllers:")
        metrics = run_compare(None, "slew", out_dir=Path(args.out) / "compare")
        print_table(metrics)
    print(f"demo finished in {time.perf_counter() - t0:.1f} s")
    return 0


def _options(p) -> None:
    """``hubbeam demo``'s options on its parser ``p``."""
    p.add_argument("--out", metavar="DIR", default="demo_out", help="output folder (default demo_out)")


def _run(args) -> int:
    """Run the demo into ``--out`` (status 0)."""
    import contextlib

    from hubbeam_ctrl.cli.args import check_output_dir, stdout
    check_output_dir("--out", args.out)
    with contextlib.redirect_stdout(stdout(args)):
        return main(["--out", str(args.out)])


COMMAND = Command(
    "demo", _options, _run, beam=False,
    help="the paper's spin-up comparison and the closed-loop comparison (make demo)",
    description=("TLAM, FOAM and CFOAM spun up to 2.8 rad/s (the paper's Fig. 5), then the five controllers on the "
                 "default slew on FOAM; plots, metrics and reports in --out."))


if __name__ == "__main__":
    sys.exit(main())

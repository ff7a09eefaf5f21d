"""``hubbeam design``: design a linear controller on SFOAM and save it as a state-space system.

Example::

    hubbeam design --params arm.toml --controller lqg --slew-angle 1.5708 --tf 1.2 --out lqg.mat

The controller is designed for a task (a slew by ``--slew-angle`` in ``--tf``, or a spin-up to
``--wf``) with the defaults that scale with the beam and the task (:mod:`controllers.scaling`),
optionally for a payload range (``--payload-range MIN,MAX``, :mod:`hubbeam_ctrl.study.payload`).
The file holds ``Ac, Bc, Cc, Dc``, the sample time, the signal names and units and the design
(see :mod:`controllers.export`); the command prints the loop margins at the plant input on
the design model (:func:`controllers.analysis.loop_margins`).
"""

from __future__ import annotations

import json
import math

from hubbeam_ctrl.cli.args import Command

__all__ = ["LINEAR_CONTROLLERS"]

#: The controllers that are linear systems (MPC and the open loop are not).
LINEAR_CONTROLLERS = ("pd", "lqr", "lqg")


def _options(p) -> None:
    """``hubbeam design``'s options on its parser ``p``."""
    from hubbeam_ctrl.cli.args import add_rig_option, add_task_options, add_verbose

    p.add_argument("--controller", choices=LINEAR_CONTROLLERS, required=True,
                   help="linear controller to design")
    add_task_options(p, "the rig's; else 20 samples per period of the first flexible mode, at most 0.01")
    p.add_argument("--payload-range", metavar="MIN,MAX",
                   help="tip payloads [kg] to design LQR or LQG for (must hold the parameters' tip mass)")
    add_rig_option(p, "design for this rig (a rig file or a preset): its beam with the rotor's reflected inertia and "
                      "its damping, its drive's torque limit and its sample time; the saved controller is in torque "
                      "(hubbeam codegen --rig adds the voltage stage and integral action)")
    p.add_argument("--out", metavar="FILE.mat|FILE.npz|FILE.json", required=True,
                   help="output file; the format follows the extension")
    p.add_argument("--json", action="store_true", help="print a JSON summary with the margins")
    add_verbose(p)


def _finite(value):
    """``value`` with every non-finite float replaced by None (strict JSON)."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return None if isinstance(value, float) and not math.isfinite(value) else value


def _run(args) -> int:
    """Design the controller, save it and print its margins."""
    from pathlib import Path

    from controllers import CONTROLLERS, make_controller
    from controllers.analysis import loop_margins
    from controllers.export import FORMATS, save_controller
    from hubbeam_ctrl.cli.args import beam_from_args, design_task, refuse_inapplicable, stdout
    from hubbeam_ctrl.cli.compare import parse_payload_range
    from hubbeam_ctrl.cli.main import check_output_folder
    from hubbeam_ctrl.core.errors import ParameterError
    from hubbeam_ctrl.study.payload import range_designs

    sink = stdout(args)      # sys.stdout is captured during the run (native solver output)
    refuse_inapplicable(args, f"--scenario {args.scenario}", {"--wf": ("spinup",), "--slew-angle": ("slew",)})
    refuse_inapplicable(args, f"--controller {args.controller}", {"--payload-range": ("lqr", "lqg")})
    out = Path(args.out)
    if out.suffix.lower() not in FORMATS:
        raise ParameterError(f"out must end in {', '.join(FORMATS)}, got {args.out!r}")
    check_output_folder("out", out)
    rig, params = beam_from_args(args)
    sc, design = design_task(args, rig, params)
    modes = design.n_modes
    settings = CONTROLLERS[args.controller].settings.for_scenario(sc)
    if args.payload_range is not None:
        rng = parse_payload_range(args.payload_range, params.m_t)
        chosen = range_designs([args.controller], sc, design, rng, progress=not args.json)[args.controller]
        design, settings = chosen.design, chosen.settings
    ctrl = make_controller(args.controller, design, settings, sc.reference)
    save_controller(ctrl, out)
    m = loop_margins(ctrl)
    if args.json:
        summary = {"controller": ctrl.name, "n_states": int(ctrl.to_statespace().nstates),
                   "inputs": list(ctrl.to_statespace().input_labels), "dt": ctrl.dt,
                   "tau_max_nm": ctrl.tau_max, "margins": m.to_dict(), "out": str(out)}
        print(json.dumps(_finite(summary)), file=sink)
        return 0
    sys = ctrl.to_statespace()
    print(f"{ctrl.name.upper()} on SFOAM ({modes} modes, m_t = {design.params.m_t:g} kg) at spin "
          f"{sc.design_spin:g} rad/s, dt = {sc.dt:g} s, for {sc.description}: "
          f"{sys.nstates} states, inputs {', '.join(sys.input_labels)}, output tau; "
          f"|tau| <= {ctrl.tau_max:g} N m", file=sink)
    print(f"  closed loop on the design model: {'stable' if m.stable else 'UNSTABLE'} "
          f"(spectral radius {m.spectral_radius:.6f})", file=sink)
    print(f"  disk margin {m.disk_margin:.3f} (gain {m.disk_gain_margin[0]:.3f}..{m.disk_gain_margin[1]:.3f}, "
          f"phase {m.disk_phase_margin_deg:.1f} deg); gain margins {m.gain_margin_lower:.3g} / "
          f"{m.gain_margin_upper:.3g}; phase margin {m.phase_margin_deg:.1f} deg at "
          f"{m.crossover_rad_s:.4g} rad/s; delay margin {m.delay_margin_s * 1e3:.3g} ms", file=sink)
    print(f"  saved to {out}", file=sink)
    return 0


COMMAND = Command(
    "design", _options, _run, help="design a linear controller and save it (.mat/.npz/.json)",
    description=("Design PD, LQR or LQG on the sampled SFOAM model linearised at --spin and save it as a discrete "
                 "state-space system (Ac, Bc, Cc, Dc, dt, signal names and units): input the measured deviation "
                 "from the reference, output the torque beyond the feedforward [N m]. Prints the closed-loop "
                 "spectral radius and the disk, gain, phase and delay margins at the plant input on the design "
                 "model."))

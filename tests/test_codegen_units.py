"""Generated C headers state the command's unit and limits (issue 36, Build 4).

On a DC motor the generated step returns volts clipped at +-V_max (the torque law through
the drive's static inverse, controllers.drive.VoltageCommand); on a torque source it returns
the hub torque in N m within +-tau_max. The header says which.
"""

import dataclasses
import re

import pytest

from controllers import LQG, DesignModel, LQGSettings, slew_reference
from controllers.drive import VoltageCommand
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.deploy import to_c
from hubbeam_ctrl.plant.rig import load_rig
from hubbeam_ctrl.sim.hardware import Hardware


def _lqg(rig, dt, t_f):
    p = rig.plant_params.replace(n_axial=1, n_transverse=1)
    design = DesignModel.build(p, 0.0, dt)
    ref = slew_reference(0.5, t_f, p.total_inertia, p.tau_max, dt, 2 * t_f)
    return LQG(design, LQGSettings(), reference=ref)


def _command_line(header: str) -> str:
    """The header's ``command:`` paragraph, as one line."""
    text = header.split("command:", 1)[1].split("*/", 1)[0]
    return " ".join(part.strip(" *") for part in text.splitlines()).strip()


def test_servo_link_header_says_volts_within_v_max():
    rig = load_rig("servo_link")
    code = to_c(VoltageCommand(_lqg(rig, 1e-3, 1.0), Hardware.from_rig(rig)), name="servo_lqg")
    line = _command_line(code.header)
    assert line.startswith("the DC motor's voltage [V] to hold until the next sample, within +-V_max = 10 V"), line
    # the torque law's limit is named with its own unit, never as the command's
    assert "(the torque law's hub torque, within +-1.86 N m" in line, line
    assert "hub torque [N m] to hold" not in code.header
    assert re.search(r"^#define SERVO_LQG_V_MAX 10  /\* \[V\] \*/$", code.header, re.M)
    assert re.search(r"^#define SERVO_LQG_TAU_MAX 1\.86(0000000000000)?1?  /\* \[N m\] \*/$", code.header, re.M)
    assert code.metadata()["command"]["unit"] == "V"
    # and the source clips the returned voltage at 10 V
    assert "drive_voltage(" in code.source and "return v > 10.0 ? 10.0 : (v < -10.0 ? -10.0 : v);" in code.source


def test_paper_beam_header_says_newton_metres_within_tau_max():
    rig = load_rig("paper")
    code = to_c(_lqg(rig, 0.05, 8.0), name="paper_lqg")
    line = _command_line(code.header)
    assert line == "the hub torque [N m] to hold until the next sample, within +-200 N m.", line
    assert "V_MAX" not in code.header and "[V]" not in code.header
    assert re.search(r"^#define PAPER_LQG_TAU_MAX 200  /\* \[N m\] \*/$", code.header, re.M)


def test_volts_through_a_slew_limited_amplifier_are_refused_naming_the_rig_key():
    """The C filter would need the torque a slew-limited voltage gives: refused in one line."""
    rig = load_rig("servo_link")
    rig = dataclasses.replace(rig, drive=dataclasses.replace(rig.drive, slew_rate=100.0))
    with pytest.raises(ParameterError, match=r"^controller: .*\(motor\.slew_rate\) cannot be generated as C") as err:
        to_c(VoltageCommand(_lqg(rig, 1e-3, 1.0), Hardware.from_rig(rig)), name="servo_lqg")
    assert "\n" not in str(err.value)

"""Issue 37: an excitation too small for the angle sensor to see is refused (it wrote a record of zeros)."""

from __future__ import annotations

import pytest

from hubbeam_ctrl.calibrate.excitation import excitation
from hubbeam_ctrl.cli.main import main
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import load_rig


def test_an_amplitude_the_encoder_cannot_see_is_refused(tmp_path, capsys):
    rig = load_rig("servo_link")
    with pytest.raises(ParameterError, match=r"2 counts of the encoder \(0.00307 rad\)"):
        excitation(rig, "chirp", 4.0, amplitude=1e-6)
    rec = excitation(rig, "chirp", 4.0, amplitude=0.5)             # a usable record still passes
    assert abs(rec.columns["theta"]).max() > 2 * 2 * 3.141592653589793 / rig.sensors.encoder_counts
    out = tmp_path / "x.csv"
    assert main(["excite", "--rig", "servo_link", "--kind", "chirp", "--duration", "4", "--amplitude=1e-300",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--amplitude" in err and "at most 10 V" in err
    assert not out.exists()

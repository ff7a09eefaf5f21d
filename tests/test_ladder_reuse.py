"""Issue 37 (everyday speed): the rig ladder takes the comparison already run as its last step
(the rig itself) instead of running it again, with the same rows; any other comparison is not taken;
its steps run side by side in forked workers give the rows they give one after the other."""

from __future__ import annotations

import json

import pytest

import hubbeam_ctrl.study.ladder as ladder_module
from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.rig import Rig, load_rig
from hubbeam_ctrl.study.compare import compare
from hubbeam_ctrl.study.compare_values import CompareSettings, RunChoice, ScenarioChoice
from hubbeam_ctrl.study.ladder import ladder_rigs, rig_ladder


def _rows(rows):
    return json.dumps(rows, sort_keys=True, default=str)


@pytest.mark.slow
def test_ladder_takes_the_comparison_as_its_last_step(monkeypatch, fast_backend):
    full = load_rig("servo_link")
    rig = Rig(beam=full.beam, drive=full.drive, friction=full.friction, timing=full.timing.replace(delay=0.0))
    settings = CompareSettings(run=RunChoice(t_end=1.0), scenario=ScenarioChoice(slew_angle=1.5708, t_f=0.6))
    done = compare(rig, "slew", "lqg", settings)
    calls = []
    real = ladder_module.compare
    monkeypatch.setattr(ladder_module, "compare", lambda *a, **k: calls.append(a[0]) or real(*a, **k))
    fresh = rig_ladder(rig, "slew", "lqg", settings, workers=1)
    steps = len(ladder_rigs(rig))
    assert len(calls) == steps >= 3
    reused = rig_ladder(rig, "slew", "lqg", settings, done=done, workers=1)
    assert len(calls) == 2 * steps - 1                     # the last step not run again
    assert _rows(reused) == _rows(fresh)
    assert [r["step"] for r in reused][-1] == ladder_rigs(rig)[-1][0]
    # a comparison of another slew, of other controllers or without its settings: the last step runs
    other = compare(rig, "slew", "lqg", CompareSettings(run=RunChoice(t_end=1.0),
                                                        scenario=ScenarioChoice(slew_angle=1.0, t_f=0.6)))
    rig_ladder(rig, "slew", "lqg", settings, done=other, workers=1)
    assert len(calls) == 3 * steps - 1
    rig_ladder(rig, "slew", "openloop,lqg", settings, done=done, workers=1)
    assert len(calls) == 4 * steps - 1
    labels = []
    side_by_side = rig_ladder(rig, "slew", "lqg", settings, done=done, workers=2, progress=labels.append)
    assert len(calls) == 4 * steps - 1                     # run in the workers, not here
    assert _rows(side_by_side) == _rows(fresh)
    assert labels == [label for label, _ in ladder_rigs(rig)]
    with pytest.raises(ParameterError, match=r"workers must be an integer in 1\.\.1024, got 0"):
        rig_ladder(rig, "slew", "lqg", settings, workers=0)


@pytest.mark.slow
def test_ladder_started_before_the_comparison_takes_it_at_the_end(monkeypatch, fast_backend):
    """``LadderRun`` as ``hubbeam compare --rig`` uses it: started in forked workers before the comparison
    exists, its rows taken with the comparison as the last step are those of the ladder run after it, and
    the last step is not run here again."""
    from hubbeam_ctrl.study.ladder import LadderRun
    full = load_rig("servo_link")
    rig = Rig(beam=full.beam, drive=full.drive, friction=full.friction, timing=full.timing.replace(delay=0.0))
    settings = CompareSettings(run=RunChoice(t_end=1.0), scenario=ScenarioChoice(slew_angle=1.5708, t_f=0.6))
    serial = rig_ladder(rig, "slew", "openloop,lqg", settings, workers=1)
    calls = []
    real = ladder_module.compare
    monkeypatch.setattr(ladder_module, "compare", lambda *a, **k: calls.append(a[0]) or real(*a, **k))
    with LadderRun(rig, "slew", "openloop,lqg", settings, workers=2) as ladder:
        done = compare(rig, "slew", "openloop,lqg", settings)       # the comparison, meanwhile
        rows = ladder.rows(done=done)
    assert calls == []                                               # every step in the workers or taken
    assert _rows(rows) == _rows(serial)

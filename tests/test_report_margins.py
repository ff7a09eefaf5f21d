"""The report's margins section sets the delay margin beside the rig's computation delay (issue 36
item 2): the loop carries the delay, so the margin is the delay tolerated beyond it."""

from controllers import LQR, DesignModel
from controllers.analysis import loop_margins
from hubbeam_ctrl.study.report import _margin_lines


def _margins(delay: float):
    d = DesignModel.build(n_modes=2, dt=0.01)
    if delay:
        d = d.on_rig(None, delay)
    return {"lqr": loop_margins(LQR(d), n_points=400)}


def test_without_a_delay_the_table_has_no_delay_column():
    lines = _margin_lines(_margins(0.0))
    header = next(line for line in lines if line.startswith("| controller"))
    assert "total delay" not in header and header.count("|") == 9


def test_with_a_delay_the_total_is_the_margin_plus_the_rigs_delay():
    m = _margins(0.5)
    lines = _margin_lines(m, 0.005)
    header = next(line for line in lines if line.startswith("| controller"))
    assert header.endswith("total delay tolerated ms (rig's) |")
    row = next(line for line in lines if line.startswith("| lqr"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert len(cells) == 9
    assert float(cells[-1].split()[0]) == float(f"{(m['lqr'].delay_margin_s + 0.005) * 1e3:.3g}")
    assert cells[-1].endswith("(5)")

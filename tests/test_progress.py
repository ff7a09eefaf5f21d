"""Progress bars (:mod:`hubbeam_ctrl.core.progress`): drawn on terminals only, silent on request."""

import io

import pytest

from hubbeam_ctrl.core.progress import progress_bar


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def _run(total, stream, enabled=True):
    with progress_bar(total, "work", enabled=enabled, file=stream, mininterval=0.0) as bar:
        for _ in range(total):
            bar.update(1)
    return stream.getvalue()


def test_bar_is_drawn_on_a_terminal():
    text = _run(4, _Terminal())
    assert "work" in text and "4/4" in text


@pytest.mark.parametrize("stream,enabled", [(io.StringIO(), True), (_Terminal(), False)])
def test_bar_is_silent_off_a_terminal_or_when_disabled(stream, enabled):
    assert _run(4, stream, enabled) == ""

"""The command line, ``hubbeam ...``: the top layer, beside :mod:`hubbeam_ctrl.study`."""

from hubbeam_ctrl.cli.main import main

__all__ = ["main"]

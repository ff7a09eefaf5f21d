"""The command line, ``hubbeam ...``: the top layer, beside :mod:`hubbeam_ctrl.study`.

Before NumPy and SciPy load their OpenBLAS, the command line sets ``OPENBLAS_THREAD_TIMEOUT=4``
(unless it is set already): OpenBLAS's helper threads then sleep right after each call instead of
spinning for 2**28 cycles (about 0.1 s), which on these small matrices used a second core for
nothing and, when the figure worker or another process wanted it, slowed the comparison down
(``hubbeam compare``: 3.3 s CPU instead of 4.3 s under load; the numbers are the same, the
threads split the same work). It applies only where OpenBLAS is not loaded yet (not to a
Python session that imported NumPy before calling :func:`main`).
"""

import os as _os

_os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")

from hubbeam_ctrl.cli.main import main  # noqa: E402  (after the variable, before NumPy loads)

__all__ = ["main"]

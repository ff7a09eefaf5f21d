"""Shared by the benchmarks: print a run's JSON and keep it (``--out``), written atomically."""

from __future__ import annotations

import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from hubbeam_ctrl.core.fileio import atomic_write_text  # noqa: E402


def emit(doc: dict, out: str | None = None) -> None:
    """Print ``doc`` as indented JSON (numbers NumPy gives as floats) and write it to ``out`` when given.

    Parameters
    ----------
    doc : dict
        The benchmark's results.
    out : str, optional
        File to write the same text to (atomically).
    """
    text = json.dumps(doc, indent=1, default=float)
    print(text)
    if out:
        atomic_write_text(out, text + "\n")

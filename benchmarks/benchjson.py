"""Shared by the benchmarks: their command line (:func:`bench_parser`), print a run's JSON and keep it
(``--out``), written atomically."""

from __future__ import annotations

import argparse
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


def bench_parser(doc: str) -> argparse.ArgumentParser:
    """A benchmark's argument parser: described by the first line of its docstring ``doc``, with
    ``--out`` (the file :func:`emit` also writes the JSON to).

    Parameters
    ----------
    doc : str
        The benchmark module's docstring.
    """
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--out", default=None, help="also write the JSON here")
    return ap


def comma_floats(text: str, ok, expected: str) -> list:
    """An option's comma-separated numbers, for ``argparse``'s ``type=``.

    Parameters
    ----------
    text : str
        The option's value.
    ok : callable
        ``ok(values)``: whether the list of numbers is allowed.
    expected : str
        What the option takes, for the one-line refusal (``"must be ..."``).
    """
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if not values or not ok(values):
        raise argparse.ArgumentTypeError(f"must be {expected}, got {text!r}")
    return values

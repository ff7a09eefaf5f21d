"""Shared fixtures: non-GUI plotting, common parameter sets."""

import os

os.environ.setdefault("MPLBACKEND", "Agg")
# The normal suite runs on CasADi's VM (no compiler needed, nothing compiled per parameter
# set); tests/test_compiled.py runs the compiled backend where a compiler exists.
os.environ.setdefault("HUBBEAM_BACKEND", "vm")

import pytest  # noqa: E402

from hubbeam_ctrl import Params  # noqa: E402


@pytest.fixture(scope="session")
def no_tip():
    """Table 1 without the tip mass (the paper's Sections 4.1-4.3)."""
    return Params(m_t=0.0)


@pytest.fixture(scope="session")
def table1():
    """Table 1 with 0.1 kg at the tip."""
    return Params()

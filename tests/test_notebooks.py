"""The tutorial notebooks: one source each, and every one runs top to bottom (issues 5 and 8).

The only source of a notebook is ``notebooks/NN_name.py`` in jupytext's percent format
(``# %%`` code cells, ``# %% [markdown]`` markdown cells); no ``.ipynb`` is committed.
The fast tests check that each source parses as such a notebook. The slow test converts
each source to a notebook in memory and executes it with nbclient in a fresh ``python3``
kernel, with ``MPLBACKEND=Agg`` and a temporary working directory (so nothing is written
into the repository). It fails if any cell raises or hangs (per-cell timeout). The 90 s time
budget per notebook is a benchmark, ``benchmarks/bench_notebooks.py``, not a timed test.
"""

from __future__ import annotations

import re
import subprocess
import time
from pathlib import Path

import pytest
from conftest import FAST_BACKEND

jupytext = pytest.importorskip("jupytext")
nbclient = pytest.importorskip("nbclient")

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOK_DIR = ROOT / "notebooks"
#: The notebook sources, in reading order (the file names start with 01, 02, ...).
SOURCES = sorted(p for p in NOTEBOOK_DIR.glob("*.py") if not p.name.startswith("_"))
IDS = [p.stem for p in SOURCES]
FMT = "py:percent"

#: Per-cell timeout [s]: a hung cell fails instead of stalling the suite.
CELL_TIMEOUT_S = 120


def read_source(path: Path):
    """The notebook (nbformat v4 node) that the percent-format source ``path`` describes."""
    return jupytext.read(path, fmt=FMT)


def test_sources_numbered_in_order():
    names = [p.name for p in SOURCES]
    assert "01_paper_reproduction.py" in names, f"notebook sources found: {names}"
    prefixes = [p.name[:3] for p in SOURCES]
    assert all(len(x) == 3 and x[:2].isdigit() and x[2] == "_" for x in prefixes), \
        f"notebook sources must be named NN_*.py: {names}"
    numbers = [int(x[:2]) for x in prefixes]
    # numbers follow the issues that add them (06 is reserved for the own-beam notebook), so gaps
    # are allowed, but each number appears once and the order is the reading order
    assert numbers == sorted(set(numbers)) and numbers[0] == 1, \
        f"notebook sources must carry distinct increasing numbers from 01: {names}"


def committed_ipynb() -> list[str]:
    """The ``.ipynb`` files that git tracks under ``notebooks/`` (on disk without git)."""
    try:
        out = subprocess.run(["git", "ls-files", "--", "notebooks/*.ipynb"], cwd=ROOT,
                             capture_output=True, text=True, check=True, timeout=30).stdout
    except (OSError, subprocess.SubprocessError):       # no git, or not a checkout
        return sorted(p.name for p in NOTEBOOK_DIR.glob("*.ipynb"))
    return out.split()


def test_no_ipynb_committed():
    tracked = committed_ipynb()
    assert not tracked, f"the .py sources are the only notebooks; remove {tracked} from git"


@pytest.mark.parametrize("path", SOURCES, ids=IDS)
def test_source_is_percent_notebook(path):
    text = path.read_text(encoding="utf-8")
    compile(text, str(path), "exec")                    # the magics are commented out
    nb = read_source(path)
    kinds = [c.cell_type for c in nb.cells]
    markers = re.findall(r"^# %%", text, flags=re.MULTILINE)
    assert len(markers) == len(nb.cells), f"{path.name}: every cell must start with a '# %%' line"
    assert kinds[0] == "markdown" and re.match(r"# \S", nb.cells[0].source), \
        f"{path.name}: the first cell must be a markdown cell with a '# title'"
    assert "code" in kinds, f"{path.name}: no code cell"
    empty = [i for i, c in enumerate(nb.cells) if not c.source.strip()]
    assert not empty, f"{path.name}: empty cells {empty}"


@pytest.mark.slow
@pytest.mark.parametrize("path", SOURCES, ids=IDS)
def test_notebook_executes(path, tmp_path, monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")          # inherited by the kernel process
    if "cfoam" not in path.read_text(encoding="utf-8").lower():
        monkeypatch.setenv("HUBBEAM_BACKEND", FAST_BACKEND)  # FOAM only: see tests/conftest.py
    monkeypatch.chdir(tmp_path)
    before = sorted(NOTEBOOK_DIR.iterdir())
    nb = read_source(path)
    client = nbclient.NotebookClient(
        nb, kernel_name="python3", timeout=CELL_TIMEOUT_S, allow_errors=False,
        resources={"metadata": {"path": str(tmp_path)}})   # kernel's working directory
    start = time.perf_counter()
    try:
        client.execute()
    except nbclient.exceptions.CellExecutionError as exc:
        plain = re.sub(r"\x1b\[[0-9;]*m", "", str(exc))      # drop the ANSI colours
        pytest.fail(f"{path.name}: a cell raised\n{plain}", pytrace=False)
    elapsed = time.perf_counter() - start
    print(f"{path.name}: {elapsed:.1f} s (budget: benchmarks/bench_notebooks.py)")
    assert sorted(NOTEBOOK_DIR.iterdir()) == before, "the notebook wrote into notebooks/"

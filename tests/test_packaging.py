"""Packaging (issue 24): one version everywhere; the wheel builds and installs without warnings.

The slow test builds the sdist and the wheel with ``python -m build`` (build isolation: the
build backend comes from the package index), installs the wheel into a fresh virtual
environment with ``pip install --no-deps --no-index`` and runs ``hubbeam`` from a folder
outside the repository. The fresh environment reaches the dependencies (NumPy, CasADi...)
through a ``.pth`` file naming this interpreter's site-packages, written after the install so
pip sees an empty environment.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import json
import os
import re
import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

import pytest
import tomllib

import hubbeam_ctrl
from hubbeam_ctrl.cli.main import main

ROOT = Path(__file__).resolve().parents[1]


def _clean_env() -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "PIP_REQUIRE"))}
    env.pop("VIRTUAL_ENV", None)
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    return env


def _warnings(text: str) -> list:
    return [line for line in text.splitlines() if re.search(r"warn|deprecat", line, re.I)]


def test_version_single_sourced(capsys):
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in pyproject["project"] and "version" in pyproject["project"]["dynamic"]
    assert pyproject["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "hubbeam_ctrl.__version__"}
    assert re.fullmatch(r"\d+\.\d+\.\d+", hubbeam_ctrl.__version__)
    assert importlib.metadata.version("hubbeam-ctrl") == hubbeam_ctrl.__version__
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"hubbeam {hubbeam_ctrl.__version__}"


def test_citation_and_changelog():
    yaml = pytest.importorskip("yaml")
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["type"] == "software"
    assert str(cff["version"]) == hubbeam_ctrl.__version__
    paper = cff["references"][0]
    assert [a["family-names"] for a in paper["authors"]] == ["Bai", "Ben-Tzvi", "Zhou", "Huang"]
    assert (paper["journal"], paper["volume"], paper["year"]) == ("Sensors & Transducers", 5, 2009)
    changelog = (ROOT / "CHANGELOG.md").read_text()
    assert f"## [{hubbeam_ctrl.__version__}]" in changelog


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("build") is None, reason="the 'build' package is not installed "
                    "(it is in the test extra: pip install -e '.[test]')")
def test_wheel_installs_into_fresh_venv_without_warnings(tmp_path):
    dist = tmp_path / "dist"
    env = _clean_env()
    built = subprocess.run([sys.executable, "-m", "build", "--outdir", str(dist), str(ROOT)],
                           capture_output=True, text=True, env=env, timeout=300)
    assert built.returncode == 0, built.stdout[-3000:] + built.stderr[-3000:]
    assert _warnings(built.stdout + built.stderr) == []
    version = hubbeam_ctrl.__version__
    wheel = dist / f"hubbeam_ctrl-{version}-py3-none-any.whl"
    assert wheel.is_file() and (dist / f"hubbeam_ctrl-{version}.tar.gz").is_file()

    target = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False).create(target)          # this pip installs into it (--python): no ensurepip
    py = target / "bin" / "python"
    inst = subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps", "--no-index",
                           str(wheel)],
                          capture_output=True, text=True, env=env, timeout=300)
    assert inst.returncode == 0, inst.stdout + inst.stderr
    assert _warnings(inst.stdout + inst.stderr) == []
    site = Path(subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               capture_output=True, text=True, check=True).stdout.strip())
    (site / "zz_project_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")

    outside = tmp_path / "elsewhere"
    outside.mkdir()
    run = lambda *args: subprocess.run([str(target / "bin" / "hubbeam"), *args], capture_output=True,
                                       text=True, env=env, cwd=outside, timeout=300)
    v = run("--version")
    assert v.returncode == 0 and v.stdout.strip() == f"hubbeam {version}", v.stderr
    where = subprocess.run([str(py), "-c", "import importlib.metadata as m, hubbeam_ctrl; "
                            "print(hubbeam_ctrl.__file__); print(m.version('hubbeam-ctrl'))"],
                           capture_output=True, text=True, env=env, cwd=outside, check=True).stdout.split()
    assert Path(where[0]).is_relative_to(site) and where[1] == version
    modes = run("modes", "--json")
    assert modes.returncode == 0, modes.stderr
    hz = json.loads(modes.stdout)["frequencies_hz"]
    assert hz[0] == pytest.approx(0.4145, abs=1e-3)      # FOAM, Table 1, at rest: the first bending mode
    bad = run("modes", "--n-modes", "0")
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    demo = run("demo", "--out", "demo_out")                # the main job, from the installed wheel
    assert demo.returncode == 0, demo.stderr[-2000:]
    assert "TLAM/FOAM residual vibration ratio: 236" in demo.stdout and "settled" in demo.stdout
    assert (outside / "demo_out" / "spinup_comparison.png").is_file()


@pytest.mark.slow
def test_editable_install_prints_no_setuptools_notice(tmp_path):
    """make demo / make test install the checkout in editable mode: setuptools printed a ten-line
    'Editable installation ... be careful with folders ... same name as your package' notice for
    the flat two-package layout (its meta-path finder); with the project root as the package
    directory the install is a plain path entry and prints nothing of ours. Lines about the
    machine's own pip index configuration are not the package's and are left out."""
    env = _clean_env()
    target = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False).create(target)
    py = target / "bin" / "python"
    # this environment's pip, as upgraded as the Makefile's (it runs pip install --upgrade pip), installs into
    # the fresh one (--python): no ensurepip and no upgrade, 10 s of the suite
    inst = subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "--quiet", "--no-deps", "-e",
                           str(ROOT)],
                          capture_output=True, text=True, env=env, timeout=300)
    assert inst.returncode == 0, inst.stdout[-3000:] + inst.stderr[-3000:]
    text = inst.stdout + inst.stderr
    ours = [line for line in _warnings(text) if "is ignored: it is neither a file nor a directory" not in line]
    assert ours == [] and "same name as your package" not in text, ours
    where = subprocess.run([str(py), "-c", "import importlib.util as u; "
                            "print(u.find_spec('hubbeam_ctrl').origin); print(u.find_spec('controllers').origin)"],
                           capture_output=True, text=True, env=env, cwd=tmp_path, check=True).stdout.split()
    assert all(Path(w).is_relative_to(ROOT) for w in where), where

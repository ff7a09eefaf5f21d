"""Issue 28: every submodule of ``hubbeam_ctrl.study`` is the module under its own name
(``study.sweep``, ``study.tune`` and ``study.judge`` were the functions re-exported over them),
and those with a function of the same name still call it."""

import importlib
import inspect
import pkgutil
import sys
import types

import pytest

import hubbeam_ctrl.study as study

SUBMODULES = sorted(m.name for m in pkgutil.iter_modules(study.__path__))


@pytest.mark.parametrize("name", SUBMODULES)
def test_the_package_attribute_is_the_submodule(name):
    module = importlib.import_module(f"hubbeam_ctrl.study.{name}")
    assert isinstance(module, types.ModuleType) and module is sys.modules[f"hubbeam_ctrl.study.{name}"]
    assert getattr(study, name) is module
    if name in module.__all__:                          # a function of its own name
        assert inspect.isfunction(getattr(module, name)) and callable(getattr(study, name))


def test_calling_study_sweep_calls_the_function(monkeypatch):
    module = sys.modules["hubbeam_ctrl.study.sweep"]
    monkeypatch.setattr(module, "sweep", lambda *a, **k: ("called", a, k))
    assert study.sweep("spec.toml", out_dir=None) == ("called", ("spec.toml",), {"out_dir": None})

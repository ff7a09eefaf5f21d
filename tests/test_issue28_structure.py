"""Issue 28: ``hubbeam_ctrl.study.compare`` is the module, and the function stays callable."""

import importlib
import inspect
import sys
import types


def test_compare_module_is_the_module_and_still_callable():
    import hubbeam_ctrl.study.compare as module
    assert isinstance(module, types.ModuleType) and module is sys.modules["hubbeam_ctrl.study.compare"]
    assert inspect.isfunction(module.compare) and module.compare.__module__ == "hubbeam_ctrl.study.compare"
    assert importlib.import_module("hubbeam_ctrl.study.compare") is module
    from hubbeam_ctrl.study import compare
    assert compare is module and callable(compare)
    from hubbeam_ctrl.study.compare import compare as function
    assert inspect.isfunction(function)


def test_calling_the_module_calls_the_function(monkeypatch):
    import hubbeam_ctrl.study.compare as module
    seen = []
    monkeypatch.setattr(module, "compare", lambda *a, **k: seen.append((a, k)) or "result")
    from hubbeam_ctrl import study
    assert study.compare("foam", controllers="lqr") == "result"
    assert seen == [(("foam",), {"controllers": "lqr"})]

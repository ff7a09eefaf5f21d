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
    assert study.compare(None, "slew", "lqr") == "result"
    assert seen == [((None, "slew", "lqr"), {})]


# -- import circles ------------------------------------------------------------------------------
def _import_graph() -> dict:
    """Module -> the package modules it imports (module level and inside functions), by AST."""
    import ast
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    files = {}
    for pkg in ("hubbeam_ctrl", "controllers"):
        for f in (root / pkg).rglob("*.py"):
            parts = f.relative_to(root).with_suffix("").parts
            files[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = f
    graph = {}
    for name, f in files.items():
        deps = set()
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                deps |= {c for c in (node.module, *(f"{node.module}.{a.name}" for a in node.names)) if c in files}
            elif isinstance(node, ast.Import):
                deps |= {a.name for a in node.names if a.name in files}
        graph[name] = deps - {name}
    return graph


def _circles(graph: dict) -> list:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_circle_finder_finds_a_circle():
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _circles({"a": {"b"}, "b": set()}) == []


def test_cli_main_and_cli_linearize_do_not_import_each_other():
    circles = _circles(_import_graph())
    assert not [c for c in circles if "hubbeam_ctrl.cli.main" in c], circles


def test_no_import_circles_in_the_package():
    assert _circles(_import_graph()) == []


def test_payload_range_designs_live_below_both_users():
    graph = _import_graph()
    assert not graph["hubbeam_ctrl.study.range_design"] & {"hubbeam_ctrl.study.compare", "hubbeam_ctrl.study.payload"}
    from hubbeam_ctrl.study import payload, range_design
    assert payload.range_designs is range_design.range_designs

"""Every public callable documents every parameter it takes (numpydoc ``Parameters``).

Walks every module of ``hubbeam_ctrl`` and ``controllers``, takes the public functions,
classes and methods defined there (names without a leading underscore) and checks that
each parameter of the signature (except ``self``/``cls`` and ``*args``/``**kwargs``)
is named in the docstring's ``Parameters`` (or ``Other Parameters``) section; a dataclass may
list its fields under ``Attributes`` instead. A class is
checked against its ``__init__`` signature, in the class docstring or in ``__init__``'s.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re

import pytest

import controllers
import hubbeam_ctrl

_SECTION = re.compile(r"^(\s*)(Parameters|Other Parameters|Attributes)\s*\n\1-{3,}\s*$", re.M)
_ANY_SECTION = re.compile(r"^\s*[A-Z][A-Za-z ]+\s*\n\s*-{3,}\s*$", re.M)
_ENTRY = re.compile(r"^(\s*)([*A-Za-z_][\w*, ]*?)\s*(?::.*)?$")


def _modules():
    names = []
    for package in (hubbeam_ctrl, controllers):
        names.append(package.__name__)
        for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
            if info.name.rsplit(".", 1)[-1] == "__main__":       # runs the command when imported
                continue
            names.append(info.name)
    return sorted(set(names))


def documented_parameters(doc: str | None) -> set[str]:
    """Names listed in the numpydoc ``Parameters``/``Other Parameters``/``Attributes`` sections.

    Parameters
    ----------
    doc : str or None
        A docstring.

    Returns
    -------
    set of str
    """
    if not doc:
        return set()
    doc = inspect.cleandoc(doc)
    names: set[str] = set()
    for match in _SECTION.finditer(doc):
        indent = len(match.group(1))
        body = doc[match.end():]
        following = _ANY_SECTION.search(body)
        if following:
            body = body[:following.start()]
        for line in body.splitlines():
            if not line.strip() or len(line) - len(line.lstrip()) != indent:
                continue
            entry = _ENTRY.match(line)
            if entry:
                for name in entry.group(2).split(","):
                    names.add(name.strip().lstrip("*"))
    return names


def _own_public_callables(module):
    for name, obj in vars(module).items():
        if name.startswith("_") or getattr(obj, "__module__", None) != module.__name__:
            continue
        if inspect.isfunction(obj):
            yield name, obj, obj
        elif inspect.isclass(obj):
            yield name, obj, obj
            for meth_name, meth in vars(obj).items():
                if meth_name.startswith("_"):
                    continue
                func = meth.__func__ if isinstance(meth, (staticmethod, classmethod)) else meth
                if inspect.isfunction(func):
                    yield f"{name}.{meth_name}", func, func


def _required(func) -> list[str]:
    try:
        signature = inspect.signature(func)
    except (TypeError, ValueError):
        return []
    return [p.name for p in signature.parameters.values()
            if p.name not in ("self", "cls")
            and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]


def _missing(qualname, obj) -> list[str]:
    if inspect.isclass(obj):
        init = obj.__dict__.get("__init__")
        if init is None and not hasattr(obj, "__dataclass_fields__"):
            return []
        wanted = _required(obj)
        have = documented_parameters(obj.__doc__) | documented_parameters(getattr(init, "__doc__", None))
    else:
        wanted = _required(obj)
        have = documented_parameters(obj.__doc__)
    return [f"{qualname}({name})" for name in wanted if name not in have]


@pytest.mark.parametrize("module_name", _modules())
def test_every_public_parameter_is_documented(module_name):
    module = importlib.import_module(module_name)
    missing = []
    for qualname, obj, _ in _own_public_callables(module):
        if not (obj.__doc__ or "").strip():
            missing.append(f"{qualname}: no docstring")
            continue
        missing.extend(_missing(qualname, obj))
    assert not missing, f"{module_name}: undocumented parameters: " + ", ".join(missing)


def test_parser_reads_numpydoc_sections():
    doc = """Summary.

    Parameters
    ----------
    a, b : float
        Two numbers [m].
    *args : tuple
        More.
    c : int
        Count.

    Returns
    -------
    d : float
        Not a parameter.
    """
    assert documented_parameters(doc) == {"a", "b", "args", "c"}


def test_checker_flags_an_undocumented_parameter():
    def documented(x, y):
        """Add.

        Parameters
        ----------
        x : float
            First [m].
        """

    assert _missing("documented", documented) == ["documented(y)"]

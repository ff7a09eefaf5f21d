"""Compiled functions found by their recipe, without building the CasADi graph or generating C.

:func:`compile_recipe` is :func:`~hubbeam_ctrl.core.compiled.compile_function` for functions
built the same way every time (the plant step of a model family, size and settings): the
first time the function is built and compiled into the build cache as usual; a side file then
names its library by the recipe, the compiler, CasADi's version and a digest of the package
sources that build it (:data:`RECIPE_SOURCES`), so a later process loads the library without
building the graph or generating its C (issue 37: 0.1-0.5 s of a short command).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import platform
import sys
from functools import lru_cache
from pathlib import Path

import casadi as ca

from hubbeam_ctrl.core import compiled
from hubbeam_ctrl.core.compiled import (
    OPT_HOT,
    CompileError,
    _compiled_by_source,
    _compiler_identity,
    _entry_paths,
    _notice,
    _valid_entry,
    _writable_cache_dir,
    cache_dir,
    find_compiler,
    resolve_backend,
)

__all__ = ["RECIPE_SOURCES", "compile_recipe"]


#: Folders (from the folder holding the ``hubbeam_ctrl`` package) whose sources build the
#: functions of :func:`compile_recipe`: their digest is part of every recipe's key, so any
#: change there makes the recipes build and compile again.
RECIPE_SOURCES = ("hubbeam_ctrl/core", "hubbeam_ctrl/plant", "hubbeam_ctrl/sim")


@lru_cache(maxsize=8)
def _sources_digest(folders: tuple = RECIPE_SOURCES) -> str:
    """SHA-256 of the ``.py`` files (names and contents) in ``folders`` (see :data:`RECIPE_SOURCES`)."""
    root = Path(__file__).resolve().parents[2]
    h = hashlib.sha256()
    for folder in folders:
        for path in sorted((root / folder).glob("*.py")):
            h.update(f"{folder}/{path.name}\0".encode() + path.read_bytes() + b"\0")
    return h.hexdigest()


def _recipe_key(recipe: tuple, opt: str, compiler: list) -> str:
    h = hashlib.sha256()
    for part in (ca.__version__, platform.machine(), sys.platform, _compiler_identity(tuple(compiler)),
                 " ".join(compiler[1:]), opt, _sources_digest(), repr(recipe)):
        h.update(str(part).encode() + b"\0")
    return h.hexdigest()


def _signature(f: ca.Function) -> list:
    """Inputs' and outputs' sparsity patterns of ``f`` (serialized), to check a loaded library."""
    return ([f.sparsity_in(i).serialize() for i in range(f.n_in())],
            [f.sparsity_out(i).serialize() for i in range(f.n_out())])


def _recipe_paths(folder: Path, rkey: str) -> Path:
    return folder / f"recipe-{rkey[:24]}.json"


def _load_recipe(folder: Path, rkey: str):
    """The library a recipe's side file names, loaded and checked (None when anything is amiss)."""
    try:
        info = json.loads(_recipe_paths(folder, rkey).read_text(encoding="utf-8"))
        if info.get("recipe_key") != rkey:
            return None
        name, key = info["function"], info["key"]
        if key in compiled._LOADED:
            return compiled._LOADED[key]
        lib, meta = _entry_paths(folder, name, key)
        if not _valid_entry(lib, meta, key):
            return None
        g = ca.external(name, str(lib))
        if [list(x) for x in _signature(g)] != [list(x) for x in info["signature"]]:
            return None
    except (OSError, ValueError, KeyError, TypeError, AttributeError, RuntimeError):
        return None
    compiled._LOADED[key] = g
    return g


def _save_recipe(folder: Path, rkey: str, recipe: tuple, f: ca.Function, key: str) -> None:
    info = {"recipe_key": rkey, "recipe": repr(recipe), "function": f.name(), "key": key,
            "signature": _signature(f)}
    path = _recipe_paths(folder, rkey)
    tmp = path.with_name(f".{path.name}.{os.getpid()}")
    with contextlib.suppress(OSError):
        tmp.write_text(json.dumps(info), encoding="utf-8")
        os.replace(tmp, path)


def compile_recipe(recipe: tuple, build, backend=None, *, opt: str = OPT_HOT) -> ca.Function:
    """``compiled.compile_function(build(), backend, opt=opt)``, found by ``recipe`` without calling ``build``.

    The first time (in any process) ``build()`` makes the function and it is compiled as
    :func:`~hubbeam_ctrl.core.compiled.compile_function` does; a side file in the cache folder then names its library by
    a key of ``recipe``, ``opt``, the compiler, CasADi's version and a digest of the package's
    sources in :data:`RECIPE_SOURCES`. Later calls, in this or another process, load that
    library (its bytes checked against their digest, its signature against the recorded one)
    and skip building the CasADi graph and generating its C. The numbers are the same: it is
    the same library.

    Parameters
    ----------
    recipe : tuple
        Everything ``build`` depends on besides the sources (e.g. the function's kind, the
        model family, its mode counts, the step settings), as values with a stable ``repr``.
    build : callable
        ``build() -> casadi.Function``, called only when the library is not found (always on
        the ``vm`` backend).
    backend : {"auto", "compiled", "vm"}, optional
        As for :func:`~hubbeam_ctrl.core.compiled.compile_function`.
    opt : str
        Compiler flag (as for :func:`~hubbeam_ctrl.core.compiled.compile_function`).

    Returns
    -------
    casadi.Function
        The compiled function, or ``build()`` itself on the ``vm`` backend or when compiling fails.
    """
    if resolve_backend(backend) == "vm":
        return build()
    try:
        compiler = find_compiler()
    except CompileError as exc:
        _notice(f"{exc}; using the CasADi VM")
        return build()
    override = compiled._hot_flag_override()            # $HUBBEAM_CC_OPT: another library, another key
    rkey = _recipe_key(recipe, override if override is not None and opt == OPT_HOT else opt, compiler)
    if rkey in compiled._LOADED:
        return compiled._LOADED[rkey]
    folder = cache_dir()
    g = _load_recipe(folder, rkey)
    if g is None:
        f = build()
        try:
            g, key = _compiled_by_source(f, opt, None, None, compiler)
        except CompileError as exc:
            _notice(f"{exc}; using the CasADi VM")
            return f
        if _writable_cache_dir() == folder:
            _save_recipe(folder, rkey, recipe, f, key)
    compiled._LOADED[rkey] = g
    return g

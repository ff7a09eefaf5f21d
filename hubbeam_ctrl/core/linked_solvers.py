"""The QP solvers CasADi's generated C calls, and how a build links them.

A CasADi function that solves a QP through ``casadi.conic`` with a plugin such as DAQP generates C
that calls the solver's library (``#include <daqp/api.h>``). CasADi's wheel ships the header and a
static library of those solvers; :func:`solver_link_flags` names them for the compiler, so the
generated C is linked against the library the package index provides, not a copy of it.
"""

from __future__ import annotations

from pathlib import Path

import casadi as ca

from hubbeam_ctrl.core.errors import HubbeamError

__all__ = ["LinkError", "solver_link_flags"]


class LinkError(HubbeamError):
    """A solver the generated C calls is not in CasADi's installation."""


#: QP solvers whose C CasADi's generated code calls (``#include`` line) and the static library of
#: each in CasADi's wheel.
_LINKED_SOLVERS = {"daqp": ("#include <daqp/api.h>", ("libdaqpstat.a", "daqpstat.lib"))}


def solver_link_flags(source: str) -> tuple:
    """What building ``source`` (CasADi's generated C) needs to link the QP solvers it calls.

    DAQP's header and static library come with CasADi's wheel (``casadi/include/daqp``,
    ``casadi/libdaqpstat.a``): the generated C is linked against them, not a copy of them.

    Parameters
    ----------
    source : str
        Generated C.

    Returns
    -------
    tuple of (list, list)
        Compiler flags (include folders) and linker arguments (library files); both empty when
        ``source`` calls no such solver.

    Raises
    ------
    LinkError
        A solver's library is not in CasADi's installation.
    """
    root = Path(ca.__file__).parent
    cflags, libs = [], []
    for name, (include, files) in _LINKED_SOLVERS.items():
        if include not in source:
            continue
        found = [root / f for f in files if (root / f).is_file()]
        if not found or not (root / "include" / name).is_dir():
            raise LinkError(f"the generated C calls {name}, whose header or static library is not in "
                            f"CasADi's installation ({root})")
        cflags, libs = cflags + ["-I" + str(root / "include")], libs + [str(found[0])]
    return cflags, libs

"""IPOPT's iterations on a progress bar (``hubbeam optimal`` on a terminal).

:func:`iteration_callback` gives CasADi's ``nlpsol`` option ``iteration_callback``: a
function IPOPT calls once per iteration (and once at the start point), which advances a
:func:`~hubbeam_ctrl.core.progress.progress_bar`. Only attached when the bar is drawn, so a
run under ``--json`` or into a pipe costs nothing.
"""

from __future__ import annotations

import casadi as ca

__all__ = ["iteration_callback"]   # _IterationCallback: CasADi plumbing, limit.replan uses it too


class _IterationCallback(ca.Callback):
    """IPOPT's ``iteration_callback`` over ``nlpsol``'s outputs: calls ``on_iteration()`` once per
    iteration; a true result asks IPOPT to stop (the re-plan's deadline), else it goes on.

    Parameters
    ----------
    nlp : dict
        The NLP given to ``nlpsol`` (``x``, ``f``, optional ``g`` and ``p``).
    on_iteration : callable
        ``() -> bool or None``: whether to stop.
    """

    def __init__(self, nlp: dict, on_iteration):
        ca.Callback.__init__(self)
        self._sizes = {"x": nlp["x"].numel(), "g": nlp["g"].numel() if "g" in nlp else 0,
                       "p": nlp["p"].numel() if "p" in nlp else 0}
        self._on = on_iteration
        self.construct("ipopt_iterations", {})

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "ret"

    def get_sparsity_in(self, i):
        name = ca.nlpsol_out(i)
        if name == "f":
            return ca.Sparsity.scalar()
        n = self._sizes[name.removeprefix("lam_")]
        return ca.Sparsity.dense(n) if n else ca.Sparsity(0, 0)

    def eval(self, arg):
        return [1 if self._on() else 0]


def iteration_callback(nlp: dict, bar):
    """The ``iteration_callback`` option for ``nlpsol`` on ``nlp`` advancing ``bar`` by one per
    IPOPT iteration, or None when the bar is silent (nothing to attach).

    Parameters
    ----------
    nlp : dict
        The NLP given to ``nlpsol`` (``x``, ``f``, optional ``g`` and ``p``).
    bar : tqdm.tqdm or None
        From :func:`~hubbeam_ctrl.core.progress.progress_bar`.

    Returns
    -------
    casadi.Callback or None
        Keep a reference to it while the solver lives (CasADi does not own it).
    """
    if bar is None or bar.disable:
        return None
    return _IterationCallback(nlp, lambda: bar.update(1) and False)

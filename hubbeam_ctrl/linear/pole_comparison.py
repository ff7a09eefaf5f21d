"""The poles of two models linearised about the same spin, side by side
(:func:`compare_poles`): what one model leaves out (SFOAM's axial modes and coupling against
FOAM's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.linear.statespace import LinearModel
from hubbeam_ctrl.plant.models import MODEL_NAMES
from hubbeam_ctrl.plant.params import Params

__all__ = ["compare_poles", "PoleComparison"]


@dataclass(frozen=True)
class PoleComparison:
    """Poles of two models at the same spin, side by side (from :func:`compare_poles`).

    Attributes
    ----------
    model_a, model_b : str
        Names of the two models.
    spin : float
        [rad/s]
    bending_a_hz, bending_b_hz : ndarray
        Bending natural frequencies [Hz], ascending, both of the same length; NaN for
        the lowest modes of a model that has lost their stiffness (real poles).
    axial_a_hz, axial_b_hz : ndarray
        Axial natural frequencies [Hz] (empty for SFOAM).
    zeta_a, zeta_b : ndarray
        Damping ratios of the bending modes.
    unstable_a, unstable_b : bool
        A mode has lost its stiffness (TLAM above its critical speed).
    """

    model_a: str
    model_b: str
    spin: float
    bending_a_hz: np.ndarray
    bending_b_hz: np.ndarray
    axial_a_hz: np.ndarray
    axial_b_hz: np.ndarray
    zeta_a: np.ndarray
    zeta_b: np.ndarray
    unstable_a: bool
    unstable_b: bool

    @property
    def bending_rel_diff(self) -> np.ndarray:
        """``(f_b - f_a) / f_a`` per bending mode [-] (NaN where a mode is lost)."""
        return (self.bending_b_hz - self.bending_a_hz) / self.bending_a_hz

    def rows(self) -> list:
        """One dict per mode: ``kind``, ``index``, ``a_hz``, ``b_hz``, ``rel_diff``.

        ``None`` marks a mode a model does not have (SFOAM's axial modes) or has lost.
        """
        out = []
        for kind, fa, fb in (("bending", self.bending_a_hz, self.bending_b_hz),
                             ("axial", self.axial_a_hz, self.axial_b_hz)):
            for i in range(max(len(fa), len(fb))):
                a = float(fa[i]) if i < len(fa) and np.isfinite(fa[i]) else None
                b = float(fb[i]) if i < len(fb) and np.isfinite(fb[i]) else None
                rel = (b - a) / a if a is not None and b is not None else None
                out.append({"kind": kind, "index": i + 1, "a_hz": a, "b_hz": b, "rel_diff": rel})
        return out

    def table(self) -> str:
        """The comparison as a text table."""
        a, b = self.model_a.upper(), self.model_b.upper()
        lines = [f"poles at spin {self.spin:g} rad/s (hub free): {a} vs {b}",
                 f"{'mode':<12}{a + ' [Hz]':>16}{b + ' [Hz]':>16}{'(b-a)/a':>14}"]
        for r in self.rows():
            cells = []
            for v in (r["a_hz"], r["b_hz"]):
                gone = "(lost)" if r["kind"] == "bending" else "(absent)"
                cells.append(f"{v:16.6f}" if v is not None else f"{gone:>16}")
            rel = f"{r['rel_diff']:14.3e}" if r["rel_diff"] is not None else f"{'':>14}"
            lines.append(f"{r['kind'] + ' ' + str(r['index']):<12}{cells[0]}{cells[1]}{rel}")
        for m, u in ((a, self.unstable_a), (b, self.unstable_b)):
            if u:
                lines.append(f"{m}: a mode has lost its stiffness (real pole > 0), not listed")
        return "\n".join(lines)

    def __str__(self):
        return self.table()


def compare_poles(model_a="sfoam", model_b="foam", spin: float = 0.0,
                  params: Params | None = None) -> PoleComparison:
    """Set the poles of two models linearised about the same spin side by side.

    Shows what one model leaves out (e.g. SFOAM's missing axial modes and axial coupling
    against FOAM). Modes are classified as bending or axial by where their kinetic energy
    lies (:func:`hubbeam_ctrl.plant.modal.modal_analysis`, hub free).

    Parameters
    ----------
    model_a, model_b : str or LinearModel
        Model names, or models from :func:`linearize` (their model, spin and params are
        used; ``spin`` and ``params`` are then ignored).
    spin : float
        Spin rate [rad/s].
    params : Params, optional

    Returns
    -------
    PoleComparison
        ``print(cmp)`` gives a table.

    Examples
    --------
    >>> c = compare_poles("sfoam", "foam", spin=2.0)
    >>> len(c.axial_a_hz), len(c.axial_b_hz)
    (0, 5)
    """
    from hubbeam_ctrl.plant.modal import modal_analysis

    def analyse(m):
        if isinstance(m, LinearModel):
            return modal_analysis(m.model, m.spin, "free", m.params), m.spin
        if not isinstance(m, str) or m.lower() not in MODEL_NAMES:
            raise ParameterError(f"model must be one of {', '.join(MODEL_NAMES)}, got {m!r}")
        return modal_analysis(m.lower(), float(spin), "free",
                              params if params is not None else Params()), float(spin)

    ra, sa = analyse(model_a)
    rb, sb = analyse(model_b)
    if sa != sb:
        raise ParameterError(f"spin must be the same for both models, got {sa} and {sb}")
    n = max(len(ra.bending_hz), len(rb.bending_hz))

    def pad(values):   # modes that lost their stiffness are the lowest: pad in front
        return np.concatenate([np.full(n - len(values), np.nan), values])

    return PoleComparison(model_a=ra.model, model_b=rb.model, spin=sa,
                          bending_a_hz=pad(ra.bending_hz), bending_b_hz=pad(rb.bending_hz),
                          axial_a_hz=ra.axial_hz, axial_b_hz=rb.axial_hz,
                          zeta_a=pad(ra.damping_ratios), zeta_b=pad(rb.damping_ratios),
                          unstable_a=ra.unstable, unstable_b=rb.unstable)

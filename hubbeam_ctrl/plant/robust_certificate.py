"""A robust certificate as data: read, checked against a rig's set, and said in two sentences.

:mod:`hubbeam_ctrl.study.worst_case` computes a controller's certificate over an
:class:`~hubbeam_ctrl.plant.uncertainty.Uncertainty`; its ``robust_*`` entries
(:meth:`WorstCase.metrics <hubbeam_ctrl.study.worst_case.WorstCase.metrics>`) travel with what
is deployed: the generated C header (:func:`hubbeam_ctrl.deploy.codegen.certificate_comment`)
and the plant FMU's model description (:func:`hubbeam_ctrl.fmu.build_fmu`). This module holds
what both need, once: :func:`certificate_text` (the verdict and the worst plant as two
sentences) and :class:`Certificate` (the certificates of one or more controllers over one set,
read from ``hubbeam certify --json`` or from a ``robust_*`` dict, and refused in one line when
its set is not a rig's).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.uncertainty import Uncertainty

__all__ = ["Certificate", "certificate_text"]


def certificate_text(certificate: dict) -> tuple:
    """The verdict and the worst plant of one controller's certificate, as two sentences.

    Parameters
    ----------
    certificate : dict
        ``robust_*`` entries (:meth:`hubbeam_ctrl.study.worst_case.WorstCase.metrics`): the
        verdict, the set (``name -> [lo, hi]`` in SI units), the worst spectral radius found [-]
        and the plant where it was found.

    Returns
    -------
    tuple of str
        ``("Robust certificate: CERTIFIED over m_t [0, 0.5].", "Worst spectral radius of the
        sampled loop found 0.99999812 at m_t = 0.5 (searched, ...).")``.
    """
    worst = ", ".join(f"{k} = {v:.6g}" for k, v in (certificate.get("robust_worst") or {}).items())
    box = ", ".join(f"{k} [{lo:.6g}, {hi:.6g}]" for k, (lo, hi) in (certificate.get("robust_set") or {}).items())
    radius = certificate.get("robust_radius")
    radius = float("nan") if radius is None else radius
    return (f"Robust certificate: {str(certificate.get('robust_verdict', '?')).upper()} over {box}.",
            f"Worst spectral radius of the sampled loop found {radius:.8f} at {worst} (searched, "
            f"{certificate.get('robust_evaluations')} loops of {certificate.get('robust_plant_modes')} bending "
            "modes; hubbeam_ctrl.study.worst_case).")


def _set(table, where: str) -> Uncertainty:
    """The uncertainty set of a certificate's ``name -> [lo, hi]`` table (one line naming ``where``)."""
    try:
        return Uncertainty.from_table({k: tuple(v) if isinstance(v, list) else v for k, v in dict(table).items()})
    except (ParameterError, TypeError, ValueError) as exc:
        raise ParameterError(f"{where}: its set is not an uncertainty set ({exc})") from None


def _finite_or_none(value):
    return value if not isinstance(value, float) or math.isfinite(value) else None


@dataclass(frozen=True)
class Certificate:
    """The robust certificates of controllers over one uncertainty set.

    Attributes
    ----------
    uncertainty : Uncertainty
        The set every certificate was computed over.
    controllers : tuple of (str, dict)
        ``(controller name, robust_* entries)`` in the order certified; the name is
        ``"controller"`` when read from a bare ``robust_*`` dict (which names none).
    """

    uncertainty: Uncertainty
    controllers: tuple

    @classmethod
    def read(cls, source, where: str = "certificate") -> "Certificate":
        """A certificate from ``hubbeam certify --json`` (a file or its dict) or a ``robust_*`` dict.

        Parameters
        ----------
        source : Certificate, dict, str or Path
            certify's document (``{"set": ..., "controllers": {NAME: {"certificate": {...}}}}``),
            one controller's ``robust_*`` dict (``GeneratedCode.certificate``), or a JSON file of
            either.
        where : str
            Name of the argument in error messages (``"--certificate"`` from the CLI).

        Returns
        -------
        Certificate

        Raises
        ------
        ParameterError
            One line naming ``where``: an unreadable file, or a document that is neither form.
        """
        if isinstance(source, Certificate):
            return source
        if isinstance(source, (str, os.PathLike)):
            path = Path(source)
            try:
                source = json.loads(path.read_text(encoding="utf-8"))
            except OSError as exc:
                raise ParameterError(f"{where}: cannot read {path}: {exc.strerror or exc}") from None
            except (ValueError, UnicodeDecodeError) as exc:
                raise ParameterError(f"{where}: {path} is not JSON ({str(exc).splitlines()[0][:80]})") from None
        if not isinstance(source, dict):
            raise ParameterError(f"{where} must be hubbeam certify's JSON or a robust_* dict, got "
                                 f"{type(source).__name__}")
        if isinstance(source.get("controllers"), dict):
            table = source.get("set")
            entries = [(str(name), doc.get("certificate")) for name, doc in source["controllers"].items()
                       if isinstance(doc, dict)]
        else:
            table, entries = source.get("robust_set"), [("controller", source)]
        entries = [(n, c) for n, c in entries if isinstance(c, dict) and "robust_verdict" in c]
        if not entries or not isinstance(table, dict):
            raise ParameterError(f"{where} must be hubbeam certify's JSON (its \"set\" and \"controllers\") or a "
                                 "robust_* dict (robust_verdict, robust_set, ...); found no certificate in it")
        u = _set(table, where)
        for name, cert in entries:
            own = cert.get("robust_set")
            if own is not None and _set(own, where) != u:
                raise ParameterError(f"{where}: controller {name}'s set is not the document's set")
        return cls(u, tuple((n, {k: _finite_or_none(v) for k, v in c.items()}) for n, c in entries))

    def check(self, uncertainty: Uncertainty, where: str = "certificate") -> None:
        """Refuse (one line naming ``where``) a certificate over another set than ``uncertainty``.

        Parameters
        ----------
        uncertainty : Uncertainty
            The rig's ``[uncertainty]`` table.
        where : str
            Name of the argument in the message.
        """
        if self.uncertainty != uncertainty:
            rig = uncertainty.describe() if uncertainty.is_set else "no [uncertainty] table"
            raise ParameterError(f"{where}: the certificate's set ({self.uncertainty.describe()}) is not the rig's "
                                 f"({rig}); certify the controller on this rig (hubbeam certify CONTROLLER --rig RIG "
                                 "--json)")

    def summary(self) -> str:
        """One line per document: each controller's verdict, worst radius and worst plant."""
        parts = []
        for name, cert in self.controllers:
            verdict, worst = certificate_text(cert)
            parts.append(f"{name}: {verdict} {worst}")
        return " ".join(parts)

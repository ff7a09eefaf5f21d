"""The FMU's ``modelDescription.xml``: the variables with units, the uncertainty set, the certificate.

:func:`model_description` writes the FMI 2.0 model description of :func:`~hubbeam_ctrl.fmu.build_fmu`.
When the rig has an ``[uncertainty]`` table, the parameters the set moves carry their range over
the set as the FMI ``min``/``max`` of their ``<Real>`` element (:func:`set_ranges`), so a sweep in
another tool that keeps within them keeps each parameter within the set's range; the set and, with a
robust certificate (:class:`~hubbeam_ctrl.plant.robust_certificate.Certificate`), each controller's
verdict, worst spectral radius and worst plant are in ``<VendorAnnotations><Tool name="hubbeam_ctrl">``
(:func:`vendor_annotation`, numbers written so that they read back exactly) and in one sentence
each of the ``description``.

The FMU's parameters are those of the model's equations (the mass moments of beam plus tip mass, the
hub inertia, the modal stiffness and damping, the drive's and the friction's numbers), not the physical
parameters of the set: the payload ``m_t`` moves ``p.J``, ``p.V2``, ``p.M2``, ... and ``E`` moves
``p.K1``, ``p.K2`` and ``p.C``. A parameter's ``min``/``max`` is the range of its value over the set:
at every corner of the set's box (and 65 positions of the tip mass along the beam when ``l`` is
uncertain: the mode shapes there are not monotonic). Each parameter within its own range is necessary,
not sufficient, for a plant of the set: the set itself is the annotation's.
"""

from __future__ import annotations

import datetime
import itertools
from typing import NamedTuple
from xml.sax.saxutils import quoteattr

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.plant.uncertainty import UNCERTAIN, Uncertainty

__all__ = ["MODEL_IDENTIFIER", "TOOL_NAME", "SetRanges", "describe_set", "model_description", "set_ranges",
           "vendor_annotation"]

#: modelIdentifier of every FMU (the name of its shared library and of the C entry points' file).
MODEL_IDENTIFIER = "hubbeam_plant"
#: ``name`` of the FMU's ``<Tool>`` annotation.
TOOL_NAME = "hubbeam_ctrl"
#: Uncertain parameters that are not in the FMU (the controller's computation delay).
NOT_IN_FMU = ("delay",)
#: Positions of the tip mass sampled along an uncertain ``l``.
L_POINTS = 65

UNITS = {   # name -> SI base-unit exponents (FMI 2.0 BaseUnit attributes)
    "rad": {"rad": 1}, "rad/s": {"rad": 1, "s": -1}, "N.m": {"kg": 1, "m": 2, "s": -2}, "m": {"m": 1},
    "m/s": {"m": 1, "s": -1}, "V": {"kg": 1, "m": 2, "s": -3, "A": -1}, "ohm": {"kg": 1, "m": 2, "s": -3, "A": -2},
    "A": {"A": 1}, "N.m/A": {"kg": 1, "m": 2, "s": -2, "A": -1},
    "V.s/rad": {"kg": 1, "m": 2, "s": -2, "A": -1, "rad": -1},
    "N.m.s/rad": {"kg": 1, "m": 2, "s": -1, "rad": -1}, "kg.m2": {"kg": 1, "m": 2}, "kg.m": {"kg": 1, "m": 1},
    "kg": {"kg": 1}, "N/m": {"kg": 1, "s": -2}, "N.s/m": {"kg": 1, "s": -1}, "1/m": {"m": -1}, "s": {"s": 1},
    "1": {},
}


def _points(uncertainty: Uncertainty) -> list:
    """The set's points whose hull is every FMU parameter's range: the box's corners (``l``: a grid)."""
    axes = []
    for r in uncertainty.ranges:
        if r.name in NOT_IN_FMU:
            continue
        if r.hi == r.lo:
            axes.append((r.name, (r.lo,)))
        elif r.name == "l":
            axes.append((r.name, tuple(np.linspace(r.lo, r.hi, L_POINTS))))
        else:
            axes.append((r.name, (r.lo, r.hi)))
    names = [a[0] for a in axes]
    return [dict(zip(names, values)) for values in itertools.product(*(a[1] for a in axes))]


class SetRanges(NamedTuple):
    """What the set does to the FMU's parameters.

    Attributes
    ----------
    ranges : dict
        name -> ``(min, max)`` in the parameter's unit, for the parameters whose value moves over
        the set (the others are not covered by it).
    still : tuple of str
        The set's parameters that move none of the FMU's (``delay``; a fixed range; friction on a
        rig built without hardware).
    """

    ranges: dict
    still: tuple


def set_ranges(rig, starts_at) -> SetRanges:
    """Each FMU parameter's range over the rig's uncertainty set.

    Parameters
    ----------
    rig : Rig
        With its ``[uncertainty]`` table (empty: no ranges).
    starts_at : callable
        ``starts_at(rig) -> {name: start}``: the FMU's Real parameters and their start values for a
        rig (the rig's own values: the build's start values).

    Returns
    -------
    SetRanges

    Raises
    ------
    ParameterError
        One line when a start value (the rig's own) is outside its range over the set: the set
        leaves the rig's own value out, and the FMU's start would contradict its ``min``/``max``.
    """
    u = rig.uncertainty
    if not u.is_set:
        return SetRanges({}, ())
    bare = rig.replace(uncertainty=Uncertainty())
    nominal = starts_at(bare)
    points = _points(u)
    samples = [starts_at(u.apply(bare, values)) for values in points]
    ranges = {}
    for name, start in nominal.items():
        vals = np.array([s[name] for s in samples] + [start], dtype=float)
        if np.all(vals == start):
            continue
        lo, hi = float(np.min(vals[:-1])), float(np.max(vals[:-1]))
        tol = 1e-12 * max(abs(lo), abs(hi))
        if not lo - tol <= start <= hi + tol:
            raise ParameterError(_outside(bare, u, name, start, lo, hi))
        ranges[name] = (min(lo, start), max(hi, start))
    return SetRanges(ranges, tuple(n for n in u.names if not _moves(n, points, samples)))


def _moves(name: str, points: list, samples: list) -> bool:
    """Whether changing ``name`` alone, anywhere in the sampled set, changes an FMU parameter."""
    groups = {}
    for values, sample in zip(points, samples):
        if name not in values:
            return False
        key = tuple((k, v) for k, v in values.items() if k != name)
        if groups.setdefault(key, sample) != sample:
            return True
    return False


def _outside(rig, u: Uncertainty, name: str, start: float, lo: float, hi: float) -> str:
    """Why a start value is outside its range over the set: the rig's own value of which parameter."""
    for r in u.ranges:
        if r.name in NOT_IN_FMU:
            continue
        own = Uncertainty.rig_value(rig, r.name)
        if not r.lo <= own <= r.hi:
            unit = "" if r.unit == "-" else f" {r.unit}"
            return (f"rig: its own {r.name} = {own:g}{unit} is outside its [uncertainty] range [{r.lo:g}, {r.hi:g}]: "
                    "the FMU's parameters start at the rig's values and carry the set's range as min/max (put the "
                    "rig's value in the set)")
    return (f"rig: the FMU parameter {name} starts at {start:.6g} (the rig's value), outside its range "
            f"[{lo:.6g}, {hi:.6g}] over the [uncertainty] set ({u.describe()}): the set changes what the rig "
            "holds fixed (damping: every mode's ratio, the axial modes' too)")


def _number(value) -> str:
    """A number as an XML attribute that reads back exactly (``repr`` of a float)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return repr(float(value))


def vendor_annotation(uncertainty: Uncertainty, certificate=None, still: tuple = NOT_IN_FMU) -> list:
    """The ``<VendorAnnotations>`` lines: the set and each controller's certificate.

    Parameters
    ----------
    uncertainty : Uncertainty
        The rig's set (each range with its SI unit).
    certificate : Certificate, optional
        Checked against ``uncertainty`` by the caller. Every scalar ``robust_*`` entry is an
        attribute of ``<Certificate>`` (the prefix dropped; floats as ``repr``, so they read back
        equal to the JSON's); ``robust_worst`` and ``robust_disk_margin_at`` are ``<Worst>`` and
        ``<DiskMarginAt>`` elements, ``robust_not_covered`` ``<NotCovered>``.
    still : tuple of str
        The set's parameters that move none of the FMU's (:attr:`SetRanges.still`):
        ``movesParameters="false"`` on their ``<Range>``.

    Returns
    -------
    list of str
        Empty when there is no set.
    """
    if not uncertainty.is_set:
        return []
    lines = ['  <VendorAnnotations>', f'    <Tool name="{TOOL_NAME}">', '      <Robustness>',
             '        <UncertaintySet>']
    for r in uncertainty.ranges:
        lines.append(f'          <Range name="{r.name}" lo="{_number(r.lo)}" hi="{_number(r.hi)}" '
                     f'unit={quoteattr(r.unit)} description={quoteattr(UNCERTAIN[r.name][3])}'
                     f' movesParameters="{_number(r.name not in still)}"/>')
    lines.append('        </UncertaintySet>')
    for name, cert in (() if certificate is None else certificate.controllers):
        attrs = [f'controller={quoteattr(name)}']
        children = []
        for key, value in cert.items():
            short = key.removeprefix("robust_")
            if key == "robust_set" or value is None:
                continue
            if isinstance(value, dict):
                tag = {"robust_worst": "Worst", "robust_disk_margin_at": "DiskMarginAt"}.get(key)
                if tag is not None:
                    children += [f'          <{tag} name={quoteattr(str(k))} value="{_number(v)}"/>'
                                 for k, v in value.items()]
            elif isinstance(value, (list, tuple)):
                if key == "robust_not_covered":
                    children += [f'          <NotCovered name={quoteattr(str(k))}/>' for k in value]
            elif isinstance(value, str):
                attrs.append(f'{short}={quoteattr(value)}')
            elif isinstance(value, (int, float, np.number)):
                attrs.append(f'{short}="{_number(value)}"')
        lines.append(f'        <Certificate {" ".join(attrs)}' + ('>' if children else '/>'))
        if children:
            lines += children + ['        </Certificate>']
    lines += ['      </Robustness>', '    </Tool>', '  </VendorAnnotations>']
    return lines


def model_description(V: list, guid: str, model_name: str, description: str, dt: float, sources: list,
                      annotation: list = ()) -> str:
    """The FMI 2.0 ``modelDescription.xml`` text.

    Parameters
    ----------
    V : list of dict
        The variables (``name``, ``vr``, ``causality``, ``variability``, ``description``, and
        ``unit``, ``start``, ``type``, ``min``, ``max`` where they apply).
    guid : str
    model_name : str
    description : str
        One line.
    dt : float
        Sample time [s]: the default experiment's step.
    sources : list of str
        The C files of ``sources/``.
    annotation : list of str
        :func:`vendor_annotation`'s lines (between ``DefaultExperiment`` and ``ModelVariables``, as
        the FMI 2.0 schema orders them).

    Returns
    -------
    str
    """
    used = sorted({v["unit"] for v in V if v.get("unit")})
    lines = ['<?xml version="1.0" encoding="UTF-8"?>',
             f'<fmiModelDescription fmiVersion="2.0" modelName={quoteattr(model_name)} guid="{guid}"',
             f'  description={quoteattr(description)}',
             f'  generationTool="hubbeam-ctrl {_version()}"'
             f' generationDateAndTime="{datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")}"',
             '  variableNamingConvention="structured" numberOfEventIndicators="0">',
             f'  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" canHandleVariableCommunicationStepSize="false"'
             ' canInterpolateInputs="false" canGetAndSetFMUstate="false" canSerializeFMUstate="false"'
             ' providesDirectionalDerivative="false">',
             '    <SourceFiles>'] + [f'      <File name="{s}"/>' for s in sources] + [
             '    </SourceFiles>', '  </CoSimulation>', '  <UnitDefinitions>']
    for u in used:
        base = " ".join(f'{k}="{e}"' for k, e in UNITS[u].items())
        lines.append(f'    <Unit name={quoteattr(u)}><BaseUnit {base}/></Unit>' if base
                     else f'    <Unit name={quoteattr(u)}/>')
    lines += ['  </UnitDefinitions>', f'  <DefaultExperiment startTime="0" stopTime="{100 * dt:.17g}" '
              f'stepSize="{dt:.17g}"/>', *annotation, '  <ModelVariables>']
    for v in V:
        attrs = (f'name={quoteattr(v["name"])} valueReference="{v["vr"]}" causality="{v["causality"]}" '
                 f'variability="{v["variability"]}"')
        if v["causality"] in ("parameter", "local") and v["variability"] in ("fixed", "constant"):
            attrs += ' initial="exact"'
        attrs += f' description={quoteattr(v["description"])}'
        typ = v.get("type", "Real")
        inner = ""
        if typ == "Real" and v.get("unit"):
            inner += f' unit={quoteattr(v["unit"])}'
        if typ == "Real" and "min" in v:
            inner += f' min="{v["min"]:.17g}" max="{v["max"]:.17g}"'
        if "start" in v:
            inner += f' start="{v["start"]:.17g}"' if typ == "Real" else f' start="{int(v["start"])}"'
        lines.append(f'    <ScalarVariable {attrs}>')
        lines.append(f'      <{typ}{inner}/>')
        lines.append('    </ScalarVariable>')
    lines += ['  </ModelVariables>', '  <ModelStructure>', '    <Outputs>']
    outputs = [k + 1 for k, v in enumerate(V) if v["causality"] == "output"]
    lines += [f'      <Unknown index="{i}"/>' for i in outputs]
    lines += ['    </Outputs>', '    <InitialUnknowns>']
    lines += [f'      <Unknown index="{i}"/>' for i in outputs]
    lines += ['    </InitialUnknowns>', '  </ModelStructure>', '</fmiModelDescription>', '']
    return "\n".join(lines)


def _version() -> str:
    from hubbeam_ctrl import __version__
    return __version__


def describe_set(uncertainty: Uncertainty, ranges: SetRanges, certificate=None) -> str:
    """What the description adds for a set and a certificate (one line, empty without a set).

    Parameters
    ----------
    uncertainty : Uncertainty
    ranges : SetRanges
        :func:`set_ranges`'s result.
    certificate : Certificate, optional

    Returns
    -------
    str
    """
    if not uncertainty.is_set:
        return ""
    note = f"; {', '.join(ranges.still)} moving none of them" if ranges.still else ""
    out = [f"Uncertainty set {uncertainty.describe()} ({len(ranges.ranges)} parameters carry their range over it "
           f"as min/max{note})."]
    if certificate is not None:
        out.append(certificate.summary())
    return " ".join(out)

"""Settings as frozen dataclasses whose fields declare their unit and range, and one validator.

Every settings class of the toolbox (``Params``, the controllers' settings, the stepper's,
the closed loop's, the sensors', the maneuvers') derives from :class:`Settings` and
declares each field with :func:`setting`::

    @dataclass(frozen=True)
    class PulseSettings(Settings):
        tau_m: float = setting(200.0, unit="N m", lo=0.0, lo_open=True, doc="Torque amplitude.")
        t_f: float = setting(10.0, unit="s", lo=0.0, lo_open=True, doc="Pulse length.")

The unit, range and description live in the field's metadata. :func:`validate`, run by
``Settings.__post_init__``, reads them and raises a one-line
:class:`~hubbeam_ctrl.core.errors.ParameterError` naming the field as the caller wrote it
(``tau_m must be > 0 [N m], got -1``); numbers are stored as ``float`` or ``int``. The class
docstring gets a numpydoc ``Parameters`` section built from the same metadata.

Examples
--------
>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class Pulse(Settings):
...     tau_m: float = setting(200.0, unit="N m", lo=0.0, lo_open=True, doc="Torque amplitude.")
>>> Pulse(tau_m=-1)
Traceback (most recent call last):
...
hubbeam_ctrl.core.errors.ParameterError: tau_m must be > 0 [N m], got -1
>>> Pulse.units()
{'tau_m': 'N m'}
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import textwrap
from dataclasses import MISSING, dataclass, fields, is_dataclass

import numpy as np

from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["Settings", "setting", "validate", "range_text"]

_NUMBER = (int, float, np.integer, np.floating)


def setting(default=MISSING, *, unit: str = "-", doc: str = "", lo=None, hi=None,
            lo_open: bool = False, hi_open: bool = False, choices=None, kind: type | None = None,
            factory=None):
    """A dataclass field with its unit, range and description in the metadata.

    Parameters
    ----------
    default : object
        Default value (``None`` makes the field optional: ``None`` is then accepted).
    unit : str
        Unit of the value (``"-"``: dimensionless).
    doc : str
        One-sentence description (goes into the class docstring).
    lo, hi : float, str or None
        Bounds of a number (``None``: unbounded). A string names another field of the same
        object whose value is the bound (e.g. ``hi="L"``).
    lo_open, hi_open : bool
        Exclude the bound itself (``lo=0, lo_open=True`` means ``> 0``).
    choices : sequence, optional
        The allowed values (e.g. solver names).
    kind : type, optional
        Required type: ``float`` and ``int`` (numbers, stored as such), ``bool``, ``str``, a
        class (``isinstance`` check) or ``object`` (anything). Default: the type of the
        default, or ``factory`` if it is a class.
    factory : callable, optional
        Makes the default (``dataclasses.field(default_factory=...)``) for mutable values.

    Returns
    -------
    dataclasses.Field
    """
    if kind is None:
        if isinstance(factory, type):
            kind = factory
        elif default is None or default is MISSING:
            kind = object
        else:
            kind = type(default)
    meta = {"unit": unit, "doc": doc, "lo": lo, "hi": hi, "lo_open": lo_open, "hi_open": hi_open,
            "choices": None if choices is None else tuple(choices), "kind": kind,
            "optional": default is None}
    if factory is not None:
        return dataclasses.field(default_factory=factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def _bound(bound, owner):
    return getattr(owner, bound) if isinstance(bound, str) and owner is not None else bound


def _fmt(bound) -> str:
    return bound if isinstance(bound, str) else f"{bound:g}"


def range_text(meta, owner=None) -> str:
    """The allowed range of a field as text (``"> 0"``, ``"in [0, 1)"``, ``"in 1..20"``, ``""``).

    Parameters
    ----------
    meta : mapping
        The field's metadata (from :func:`setting`).
    owner : object, optional
        The settings object, to resolve bounds that name other fields (``hi="L"``).

    Returns
    -------
    str
    """
    lo, hi = meta.get("lo"), meta.get("hi")
    if meta.get("kind") is int:
        if lo is not None and hi is not None:
            return f"in {_fmt(lo)}..{_fmt(hi)}"
    if lo is not None and hi is not None:
        text = (f"in {'(' if meta['lo_open'] else '['}{_fmt(lo)}, {_fmt(hi)}"
                f"{')' if meta['hi_open'] else ']'}")
        if owner is not None and (isinstance(lo, str) or isinstance(hi, str)):
            text += f" = [{_fmt(_bound(lo, owner))}, {_fmt(_bound(hi, owner))}]"
        return text
    if lo is not None:
        return f"{'>' if meta['lo_open'] else '>='} {_fmt(lo)}"
    if hi is not None:
        return f"{'<' if meta['hi_open'] else '<='} {_fmt(hi)}"
    return ""


def _in_range(value, meta, owner) -> bool:
    lo, hi = _bound(meta["lo"], owner), _bound(meta["hi"], owner)
    if lo is not None and not (value > lo if meta["lo_open"] else value >= lo):
        return False
    return hi is None or (value < hi if meta["hi_open"] else value <= hi)


def _unit_text(meta) -> str:
    return "" if meta["unit"] in ("", "-") else f" [{meta['unit']}]"


def _check_number(name: str, value, meta, owner):
    integer = meta["kind"] is int
    rng = range_text(meta, owner)
    what = "an integer" + (f" {rng}" if rng else "") if integer else rng
    if isinstance(value, bool) or not isinstance(value, _NUMBER):
        raise ParameterError(f"{name} must be {'an integer' if integer else 'a number'}"
                             f"{(' ' + rng) if rng and integer else ''}{_unit_text(meta)}, got {_short(repr(value))}")
    shown = _short(value)
    if integer:
        if not (_finite(value) and float(value).is_integer() and _in_range(value, meta, owner)):
            raise ParameterError(f"{name} must be {what}{_unit_text(meta)}, got {shown}")
        return int(value)
    if not _finite(value):
        raise ParameterError(f"{name} must be finite{_unit_text(meta)}, got {shown}")
    if not _in_range(value, meta, owner):
        raise ParameterError(f"{name} must be {what}{_unit_text(meta)}, got {shown}")
    return float(value)


def _finite(value) -> bool:
    """``math.isfinite`` that says False for integers too large for a float (``10**400``)."""
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def _short(value) -> str:
    """A number as shown in messages: at most 40 characters (``10**400`` is not printed whole)."""
    text = str(value)
    return text if len(text) <= 40 else f"{text[:12]}...({len(text)} digits)"


def check_value(name: str, value, meta, owner=None):
    """Check one value against a field's declared kind and range; return it normalised.

    Parameters
    ----------
    name : str
        The name used in the error message.
    value : object
    meta : mapping
        The field's metadata (from :func:`setting`).
    owner : object, optional
        The settings object (for bounds that name other fields).

    Returns
    -------
    object
        ``value``, as ``float``/``int``/``bool`` for those kinds.

    Raises
    ------
    ParameterError
        One line naming ``name``, the allowed values and the unit.
    """
    if value is None and meta["optional"]:
        return None
    if meta["choices"] is not None:
        try:
            ok = value in meta["choices"]
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ParameterError(f"{name} must be one of {', '.join(map(repr, meta['choices']))}, "
                                 f"got {_short(repr(value))}")
        return value
    kind = meta["kind"]
    if kind is bool:
        if not isinstance(value, (bool, np.bool_)):
            raise ParameterError(f"{name} must be True or False, got {_short(repr(value))}")
        return bool(value)
    if kind in (int, float):
        return _check_number(name, value, meta, owner)
    if not isinstance(value, kind):
        raise ParameterError(f"{name} must be a {kind.__name__}, got {type(value).__name__}")
    return value


def validate(obj) -> None:
    """Check every field of a settings dataclass against its declared kind and range.

    Normalised values (``float``/``int``/``bool``) are stored back, also on frozen objects.
    Error messages name the field with the class's ``_setting_prefix`` (e.g. ``weights.``).

    Parameters
    ----------
    obj : dataclass instance
        Every field must be declared with :func:`setting`.

    Raises
    ------
    ParameterError
        For the first field out of its range.
    TypeError
        If a field was declared without :func:`setting` (a programming error).
    """
    prefix = getattr(obj, "_setting_prefix", "")
    for f in fields(obj):
        if "kind" not in f.metadata:
            raise TypeError(f"{type(obj).__name__}.{f.name} is not declared with setting()")
        value = getattr(obj, f.name)
        new = check_value(prefix + f.name, value, f.metadata, obj)
        if new is not value:
            object.__setattr__(obj, f.name, new)


def _field_rows(cls):
    """``(name, type text, default text, metadata)`` of every declared field, in order.

    Runs before ``@dataclass`` has processed ``cls``: inherited fields come from the (already
    processed) bases, the class's own from its namespace.
    """
    rows = {}
    for base in reversed(cls.__mro__[1:]):
        if is_dataclass(base):
            for f in fields(base):
                rows[f.name] = (f.name, f.type, f.default, f.default_factory, f.metadata)
    for name, typ in cls.__dict__.get("__annotations__", {}).items():
        f = cls.__dict__.get(name)
        if isinstance(f, dataclasses.Field):
            rows[name] = (name, typ, f.default, f.default_factory, f.metadata)
    return list(rows.values())


def _type_text(typ) -> str:
    return typ if isinstance(typ, str) else getattr(typ, "__name__", str(typ))


def _parameters_section(cls) -> str:
    lines = ["Parameters", "----------"]
    for name, typ, default, factory, meta in _field_rows(cls):
        if "kind" not in meta:
            continue
        if default is not MISSING:
            dflt = f", default {default!r}"
        elif factory is not MISSING:
            dflt = f", default {getattr(factory, '__name__', 'factory')}()"
        else:
            dflt = ""
        lines.append(f"{name} : {_type_text(typ)}{dflt}")
        extra = ", ".join(t for t in ((meta["unit"] if meta["unit"] not in ("", "-") else ""),
                                      range_text(meta)) if t)
        if meta["choices"] is not None:
            extra = ", ".join(filter(None, [extra, "one of " + ", ".join(map(repr, meta["choices"]))]))
        lines.append(textwrap.fill(meta["doc"] + (f" [{extra}]" if extra else ""), width=88,
                                   initial_indent="    ", subsequent_indent="    "))
    return "\n".join(lines)


class _CheckedCall(type):
    """Metaclass of :class:`Settings`: an unknown keyword or too many positional arguments
    are one :class:`ParameterError` naming the class and its fields (not a ``TypeError``);
    it covers ``Settings(...)``, ``replace`` and ``dataclasses.replace`` alike."""

    def __call__(cls, *args, **kwargs):
        if dataclasses.is_dataclass(cls):
            names = [f.name for f in fields(cls) if f.init]
            unknown = sorted(set(kwargs) - set(names))
            if unknown or len(args) > len(names):
                what = f"no field {', '.join(map(repr, unknown))}" if unknown else \
                    f"{len(names)} fields, got {len(args)} positional values"
                raise ParameterError(f"{cls.__name__} has {what}; fields: {', '.join(names)}"[:400])
        return super().__call__(*args, **kwargs)


@dataclass(frozen=True, eq=False)
class Settings(metaclass=_CheckedCall):
    """Base of the toolbox's settings: frozen dataclasses validated from field metadata.

    Subclasses declare every field with :func:`setting`; construction runs :func:`validate`.
    Equality and hashing are each subclass's own (``@dataclass`` default: by value).
    A subclass without a ``Parameters`` section in its docstring gets one generated from the
    fields' descriptions, units and ranges (before its ``Examples``, if any).
    """

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        doc = inspect.cleandoc(cls.__dict__.get("__doc__") or "")
        if "\nParameters\n----------" in "\n" + doc:
            return
        head, sep, tail = doc.partition("\nExamples\n--------")
        section = _parameters_section(cls)
        cls.__doc__ = (head.rstrip() + "\n\n" + section + ("\n\n" + sep.strip() + tail if sep else "")).strip()

    def __post_init__(self):
        validate(self)

    def replace(self, **changes):
        """A copy with some fields changed (validated again).

        Parameters
        ----------
        **changes
            Field name -> new value.

        Returns
        -------
        Settings
        """
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """Plain dictionary of all fields (nested settings as dictionaries)."""
        return dataclasses.asdict(self)

    @classmethod
    def units(cls) -> dict:
        """Mapping field name -> unit string."""
        return {f.name: f.metadata["unit"] for f in fields(cls)}

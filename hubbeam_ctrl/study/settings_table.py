"""Controller settings as plain data: a ``[settings.NAME]`` table read into a controller's
settings object over the task's defaults (:func:`controller_settings`), and written back as
TOML (:func:`settings_to_toml`, what ``hubbeam tune`` saves).

The study spec (:mod:`hubbeam_ctrl.study.spec`) reads its ``[settings]`` tables with these;
the names are importable from there too.
"""

from __future__ import annotations

import dataclasses
import json

from controllers import CONTROLLERS
from hubbeam_ctrl.core.errors import ParameterError

__all__ = ["controller_settings", "settings_to_toml"]


def controller_settings(name: str, table: dict | None, scenario, horizon: int = 50, solver: str = "daqp"):
    """A controller's settings object: the registry's defaults for ``scenario`` (its settings
    class's ``for_scenario``, as in the comparison) with the entries of ``table`` replacing
    them (a nested table updates a dataclass-valued setting, e.g. ``weights = {tip = 1e4}``).

    This is the one place that knows how settings are built from plain data.

    Parameters
    ----------
    name : str
        Controller name.
    table : dict or None
        Setting name -> value.
    scenario : Scenario
    horizon : int
        MPC horizon [samples] (default setting).
    solver : str
        MPC QP solver (default setting).

    Returns
    -------
    ControllerSettings
        The controller's settings (validated).
    """
    if name not in CONTROLLERS:
        raise ParameterError(f"controllers: unknown controller {name!r}; allowed: {', '.join(CONTROLLERS)}")
    base = CONTROLLERS[name].settings.for_scenario(scenario, horizon=horizon, solver=solver)
    table = dict(table or {})
    known = {f.name: f for f in dataclasses.fields(base)}
    bad = sorted(set(table) - set(known))
    if bad:
        raise ParameterError(f"settings.{name}: unknown setting(s) {', '.join(bad)}; allowed: {', '.join(known)}")
    changes = {}
    for key, value in table.items():
        current = getattr(base, key)
        if isinstance(value, dict) and dataclasses.is_dataclass(current):
            sub = {f.name for f in dataclasses.fields(current)}
            unknown = sorted(set(value) - sub)
            if unknown:
                raise ParameterError(f"settings.{name}.{key}: unknown {', '.join(unknown)}; allowed: "
                                     f"{', '.join(sorted(sub))}")
            value = _replaced(name, current, value)
        changes[key] = value
    if "error_decay" in changes and "tip_noise_budget_m" in known and "tip_noise_budget_m" not in changes:
        changes["tip_noise_budget_m"] = None        # a decay the spec gives is used, not derived
    return _replaced(name, base, changes)


def _replaced(name: str, settings, changes: dict):
    """``settings`` with ``changes``, its validation error prefixed by ``settings.NAME``."""
    try:
        return dataclasses.replace(settings, **changes)
    except (TypeError, ParameterError) as exc:
        raise ParameterError(f"settings.{name}: {exc}") from None


def settings_to_toml(settings: dict) -> str:
    """TOML text of ``{controller: {setting: value or {sub: value}}}`` (as ``[settings.NAME]``
    tables, which :func:`load_spec` and ``hubbeam sweep`` read).

    Parameters
    ----------
    settings : dict

    Returns
    -------
    str
    """
    lines = []
    for name, table in settings.items():
        plain = [f"{k} = {_toml_value(v)}" for k, v in table.items() if not isinstance(v, dict) and v is not None]
        if plain or not any(isinstance(v, dict) for v in table.values()):
            lines += [f"[settings.{name}]", *plain, ""]
        for key, value in table.items():
            if isinstance(value, dict):
                lines += [f"[settings.{name}.{key}]"]
                lines += [f"{k} = {_toml_value(v)}" for k, v in value.items() if v is not None] + [""]
    return "\n".join(lines)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(float(value)) if isinstance(value, float) else str(value)
    if isinstance(value, str):
        return json.dumps(value)
    raise ParameterError(f"settings: cannot write {value!r} to TOML")

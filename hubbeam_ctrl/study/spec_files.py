"""Study specs from files: :func:`load_spec` (a TOML path, a dict of tables or a spec, with
the rig or plant of the command line), :func:`load_settings` (controller settings merged in).
"""

from __future__ import annotations

from pathlib import Path

from hubbeam_ctrl.core.errors import ParameterError
from hubbeam_ctrl.core.reading import read_toml
from hubbeam_ctrl.study.spec import StudySpec

__all__ = ["load_spec", "load_settings", "MAX_SPEC_BYTES"]

#: Largest spec or settings file read [bytes].
MAX_SPEC_BYTES = 4_000_000


def _with_rig(data: dict, rig) -> dict:
    """The spec's tables with ``study.rig`` replaced by ``rig`` (unchanged when None)."""
    if rig is None:
        return data
    if not isinstance(data, dict):
        return data                          # from_dict names the bad spec
    study = data.get("study", {})
    study = dict(study) if isinstance(study, dict) else study
    if isinstance(study, dict):
        study["rig"] = str(rig) if isinstance(rig, Path) else rig
    return {**data, "study": study}


def _with_plant(data: dict, plant) -> dict:
    """The spec's tables with ``study.plant`` replaced by ``plant`` (unchanged when None)."""
    if plant is None or not isinstance(data, dict):
        return data
    study = data.get("study", {})
    if isinstance(study, dict):
        study = {**study, "plant": plant}
    return {**data, "study": study}

def load_spec(spec, rig=None, plant=None) -> StudySpec:
    """A :class:`StudySpec` from a TOML path, a dict of tables, or a spec passed through.

    Parameters
    ----------
    spec : str, Path, dict or StudySpec
    rig : str, Path or Rig, optional
        Replaces the spec's ``study.rig`` (``hubbeam sweep --rig``); not with a StudySpec.
    plant : str, optional
        Replaces the spec's ``study.plant`` (``hubbeam sweep --plant``: ``foam``, ``cfoam`` or
        ``ancf``, the exact beam); not with a StudySpec.

    Returns
    -------
    StudySpec
    """
    if isinstance(spec, StudySpec):
        for name, value in (("rig", rig), ("plant", plant)):
            if value is not None:
                raise ParameterError(f"{name}: give the {name} in the spec's tables, not beside a built StudySpec")
        spec.validate()
        return spec
    if isinstance(spec, dict):
        return StudySpec.from_dict(_with_plant(_with_rig(spec, rig), plant))
    if not isinstance(spec, (str, Path)):
        raise ParameterError(f"spec must be a TOML path, a dict of tables or a StudySpec, got {type(spec).__name__}")
    data = _with_plant(_with_rig(read_toml(spec, "spec: file", MAX_SPEC_BYTES), rig), plant)
    if isinstance(data.get("study"), dict) and isinstance(data["study"].get("rig"), str):
        data["_dir"] = str(Path(spec).resolve().parent)        # a rig file's path is relative to the spec
    return StudySpec.from_dict(data)


def load_settings(spec: StudySpec, path) -> StudySpec:
    """``spec`` with the controller settings of a TOML file merged in (what ``hubbeam tune``
    writes: ``[settings.NAME]`` tables, or ``[NAME]`` tables at top level).

    Parameters
    ----------
    spec : StudySpec
    path : str or Path

    Returns
    -------
    StudySpec
        Validated; a controller of the file that the study does not run is an error.
    """
    data = read_toml(path, "settings: file", MAX_SPEC_BYTES)
    data = data.get("settings", data)
    if not isinstance(data, dict):
        raise ParameterError(f"settings: {path} must hold [settings.NAME] tables, got settings = {data!r}"[:300])
    merged = {name: dict(table) for name, table in spec.settings.items()}
    for name, table in data.items():
        if not isinstance(table, dict):
            raise ParameterError(f"settings: {path} must hold [settings.NAME] tables, got {name} = {table!r}")
        merged.setdefault(name, {}).update(table)
    return spec.replace(settings=merged)

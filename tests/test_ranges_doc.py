"""docs/ranges.md is the one table of allowed ranges: generated from the code, and current."""

import re
from dataclasses import fields
from pathlib import Path

import pytest

from hubbeam_ctrl import ParameterError, Params
from hubbeam_ctrl.cli.ranges import ranges_markdown, settings_classes
from hubbeam_ctrl.plant.params import RELATIONS

DOC = Path(__file__).resolve().parents[1] / "docs" / "ranges.md"


def test_doc_matches_the_code():
    assert DOC.read_text(encoding="utf-8") == ranges_markdown(), (
        "docs/ranges.md is stale: run python -m hubbeam_ctrl.cli.ranges docs/ranges.md")


def test_every_field_of_every_settings_class_has_a_row():
    text = ranges_markdown()
    for _, cls in settings_classes():
        section = text.split(f": `{cls.__name__}`\n", 1)[1].split("\n## ", 1)[0]
        for f in fields(cls):
            assert f"| `{f.name}` |" in section, (cls.__name__, f.name)


@pytest.mark.parametrize("relation", RELATIONS, ids=lambda r: r.name)
def test_each_relation_is_enforced_just_past_its_bound(relation):
    """The documented relation's bound is where Params starts refusing (both sides of it)."""
    p = Params()
    for bound, factor in ((relation.hi, 1.001), (relation.lo, 0.999)):
        if bound is None:
            continue
        limit = bound(p)
        Params(**{**p.to_dict(), relation.name: limit * (2 - factor) if limit else 0.0})
        with pytest.raises(ParameterError, match=rf"^{relation.name} must be .*\({re.escape(relation.text)}"):
            Params(**{**p.to_dict(), relation.name: limit * factor})

"""The scorecard's TypedDicts name the keys the JSON schema fixes, required and optional alike,
so the types the code is checked against cannot drift from the cards it writes and reads."""

from __future__ import annotations

import json
from typing import Any

import pytest

from nbv_gym.benchmark import cardtypes
from nbv_gym.benchmark.validation import SCHEMA_PATH

SCHEMA = json.loads(SCHEMA_PATH.read_text())
DEFS = SCHEMA["$defs"]
#: Each TypedDict and the schema object it stands for.
SHAPES: dict[str, dict[str, Any]] = {
    "Scorecard": SCHEMA,
    "SuiteEntry": SCHEMA["properties"]["suite"],
    "NbvGymEntry": SCHEMA["properties"]["nbv_gym"],
    "PolicyEntry": SCHEMA["properties"]["policy"],
    "Timing": SCHEMA["properties"]["timing"],
    "PartEntry": DEFS["part"],
    "RunEntry": DEFS["run"],
    "RobotEntry": DEFS["robot"],
    "Summary": DEFS["summary"],
    "Aggregate": DEFS["aggregate"],
    "Effort": DEFS["aggregate"]["properties"]["effort"],
    "Band": DEFS["band"],
}


@pytest.mark.parametrize("name", SHAPES)
def test_each_typed_dict_has_the_schema_objects_keys(name):
    typed, node = getattr(cardtypes, name), SHAPES[name]
    required = set(node["required"])
    assert typed.__required_keys__ == required
    assert typed.__optional_keys__ == set(node["properties"]) - required


def test_every_object_of_the_schema_with_properties_has_its_typed_dict():
    """Every object the schema spells out key by key (not a map such as ``versions``) is
    covered, so a new one cannot go without its type."""
    nodes = [SCHEMA, *SCHEMA["properties"].values(), *DEFS.values()]
    nodes += DEFS["aggregate"]["properties"].values()
    spelled = [n for n in nodes if n.get("type") == "object" and "properties" in n]
    covered = [id(n) for n in SHAPES.values()]
    assert sorted(id(n) for n in spelled) == sorted(covered)

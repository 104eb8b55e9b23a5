"""The quick schema check (files/schema_check.py) says "conforms" exactly when jsonschema finds
no error, over the shipped scenarios and thousands of their mutations: each key removed, each
value replaced by values of every JSON type and by boundary numbers, unknown keys added. A
check that let through a document jsonschema rejects would run a bad scenario, so the test
counts both kinds of disagreement; it also proves the corpus holds documents of both verdicts."""

from __future__ import annotations

import copy
from pathlib import Path

import jsonschema
import pytest
import yaml

from toggle_cosim.experiments.scenario import SCHEMA, ScenarioError, validate_document
from toggle_cosim.files.schema_check import conforms

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = [
    "fig4_nominal",
    "fig5_external_force",
    "fig6_mass_variation",
    "swap_no_gravity",
    "friction_models",
    "integral_load",
]
REPLACEMENTS = [None, True, False, "x", "", "1.5", -1, 0, 1, 1.0, 2.5, -1e-9, 1e-7, 1e9, 0.5, [], [1], {}, {"a": 1}]


def _paths(node, path=()):  # noqa: ANN001, ANN202
    yield path
    if isinstance(node, dict):
        for key, value in node.items():
            yield from _paths(value, (*path, key))
    elif isinstance(node, list):
        for index, value in enumerate(node):
            yield from _paths(value, (*path, index))


def _set(document, path, value):  # noqa: ANN001, ANN202
    changed = copy.deepcopy(document)
    node = changed
    for part in path[:-1]:
        node = node[part]
    if value is _DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return changed


_DELETE = object()


def _mutations(document):  # noqa: ANN001, ANN202
    yield document
    for path in _paths(document):
        if not path:
            continue
        yield _set(document, path, _DELETE)
        for value in REPLACEMENTS:
            yield _set(document, path, value)
        node = document
        for part in path[:-1]:
            node = node[part]
        if isinstance(node, dict):
            yield _set(document, (*path[:-1], "unknown_key"), 1)
            yield _set(document, (*path[:-1], 7), 1)  # a YAML integer key


def _corpus() -> list:
    documents = []
    for name in SCENARIOS:
        document = yaml.safe_load((ROOT / "scenarios" / f"{name}.yaml").read_text())
        documents.extend(_mutations(document))
    return documents


def test_the_quick_check_agrees_with_jsonschema() -> None:
    validator = jsonschema.Draft202012Validator(SCHEMA)
    verdicts = {"both valid": 0, "both invalid": 0, "quick only": 0, "jsonschema only": 0}
    for document in _corpus():
        quick, full = conforms(document, SCHEMA), validator.is_valid(document)
        agree = "both valid" if quick else "both invalid"
        key = agree if quick == full else ("quick only" if quick else "jsonschema only")
        verdicts[key] += 1
    assert verdicts["quick only"] == 0, verdicts  # never let through what jsonschema rejects
    assert verdicts["jsonschema only"] == 0, verdicts  # and never send a valid file the slow way
    assert verdicts["both valid"] > 100 and verdicts["both invalid"] > 1000, verdicts


def test_an_unknown_keyword_is_left_to_jsonschema() -> None:
    """A schema keyword the quick check does not know (here `multipleOf`) makes it answer False,
    whatever the document: it never claims a verdict it cannot give."""
    assert conforms({"a": 3}, {"type": "object", "properties": {"a": {"type": "number"}}})
    assert not conforms({"a": 3}, {"type": "object", "properties": {"a": {"type": "number", "multipleOf": 3}}})


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"t_end": -1}, "key t_end: -1 is out of range (must be > 0)"),
        ({"plant": {"mu": "high"}}, "key plant.mu: 'high' is not of type number (write a number)"),
        ({"colour": "red"}, "unknown key colour (allowed here:"),
    ],
)
def test_messages_still_come_from_jsonschema(change: dict, message: str) -> None:
    document = yaml.safe_load((ROOT / "scenarios" / "fig4_nominal.yaml").read_text())
    document.update(change)
    with pytest.raises(ScenarioError, match=message.replace("(", r"\(").replace(")", r"\)").replace(".", r"\.")):
        validate_document(document)

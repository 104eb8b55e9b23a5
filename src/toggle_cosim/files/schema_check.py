"""A quick yes to "does this document conform to this JSON schema?", for the keywords our
schemas use, without importing jsonschema.

jsonschema (with the `referencing` and `attrs` packages it loads, and every metaschema it
reads at import) costs about 0.1 s to import: a quarter of a paper run's start-up, spent on a
scenario file that is almost always valid. `conforms` answers True only when it is sure
the document conforms (JSON Schema 2020-12 semantics, as jsonschema applies them); for a
document that does not, or a schema with a keyword it does not know, it answers False and the
caller asks jsonschema, which stays the authority and words the message. The schema itself
is written once (the caller's dict); nothing of it is repeated here.
"""

from __future__ import annotations

import re
from typing import Any

# Keywords checked here; a schema using any other makes `conforms` answer False (ask jsonschema).
CHECKED = frozenset(
    {
        "$schema",
        "description",
        "type",
        "properties",
        "additionalProperties",
        "required",
        "minimum",
        "maximum",
        "exclusiveMinimum",
        "exclusiveMaximum",
        "enum",
        "pattern",
        "propertyNames",
        "minLength",
        "minProperties",
    }
)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _has_type(value: Any, name: str) -> bool:
    if name == "object":
        return isinstance(value, dict)
    if name == "array":
        return isinstance(value, list)
    if name == "string":
        return isinstance(value, str)
    if name == "boolean":
        return isinstance(value, bool)
    if name == "null":
        return value is None
    if name == "number":
        return _is_number(value)
    if name == "integer":  # 2020-12: a number with a zero fractional part, 1.0 included
        return _is_number(value) and (isinstance(value, int) or float(value).is_integer())
    return False


def _number_ok(value: float, schema: dict[str, Any]) -> bool:
    bounds = (
        ("minimum", lambda v, b: v >= b),
        ("maximum", lambda v, b: v <= b),
        ("exclusiveMinimum", lambda v, b: v > b),
        ("exclusiveMaximum", lambda v, b: v < b),
    )
    return all(key not in schema or (_is_number(schema[key]) and holds(value, schema[key])) for key, holds in bounds)


def _object_ok(value: dict, schema: dict[str, Any]) -> bool:
    properties = schema.get("properties", {})
    if any(key not in value for key in schema.get("required", ())):
        return False
    if len(value) < schema.get("minProperties", 0):
        return False
    extra = schema.get("additionalProperties", True)
    names = schema.get("propertyNames")
    for key, item in value.items():
        if names is not None and not conforms(key, names):
            return False
        if key in properties:
            if not conforms(item, properties[key]):
                return False
        elif extra is False or (extra is not True and not conforms(item, extra)):
            return False
    return True


def conforms(instance: Any, schema: Any) -> bool:
    """True if `instance` certainly conforms to `schema`; False if it does not, or if the schema
    uses a keyword outside CHECKED (then only jsonschema can say)."""
    if schema is True:
        return True
    if not isinstance(schema, dict) or not CHECKED.issuperset(schema):
        return False
    if "type" in schema:
        wanted = schema["type"]
        if not any(_has_type(instance, name) for name in (wanted if isinstance(wanted, list) else [wanted])):
            return False
    if "enum" in schema:  # strings only: jsonschema's equality of 1, 1.0 and True is its own
        if not isinstance(instance, str) or not all(isinstance(v, str) for v in schema["enum"]):
            return False
        if instance not in schema["enum"]:
            return False
    if _is_number(instance) and not _number_ok(instance, schema):
        return False
    if isinstance(instance, str):
        if len(instance) < schema.get("minLength", 0):
            return False
        if "pattern" in schema and re.search(schema["pattern"], instance) is None:
            return False
    if isinstance(instance, dict):
        if any(not isinstance(key, str) for key in instance):
            return False  # YAML allows other keys; JSON Schema speaks of strings
        return _object_ok(instance, schema)
    return True


__all__ = ["CHECKED", "conforms"]

"""Every message we write about a failure, bounded: one line of at most MESSAGE_CHARS characters.

A reason comes from anywhere (a user's exception whose text is a 10-million-element list, a
plant's log line, an FMU's error); what the console, run.json, a sweep's table and an error line
say about it is `bounded_text(reason)`: its whitespace collapsed to single spaces, and if still
longer than the limit, its start, "…" and how long it was. A value a user gave, echoed in an
error, is shown by `value_text`: at most VALUE_CHARS characters, its first elements and its size.
"""

from __future__ import annotations

import re
import reprlib

MESSAGE_CHARS = 400  # a reason's length in a console line, run.json or a sweep row
VALUE_CHARS = 200  # a user's value as an error line shows it (`value_text`)


def bounded_text(text: str, limit: int = MESSAGE_CHARS) -> str:
    """`text` on one line, cut to `limit` characters (with "…" and its whole length) when longer.
    Only the first 64 × limit characters are looked at: a huge text is never copied whole."""
    head = text[: limit * 64]
    line = " ".join(head.split())
    if len(line) <= limit and len(head) == len(text):
        return line
    note = f"… ({len(text)} characters in all)"
    return line[: max(limit - len(note), 1)] + note


def error_text(error: BaseException, limit: int = MESSAGE_CHARS) -> str:
    """An exception as one bounded line: "Type: message". str() of the exception itself may be
    huge (its arguments are printed whole), so it is made once and cut at once."""
    try:
        said = str(error)
    except Exception:  # noqa: BLE001 - a user's exception whose __str__ fails
        said = "(its message cannot be printed)"
    return bounded_text(f"{type(error).__name__}: {said}" if said.strip() else type(error).__name__, limit)


_short = reprlib.Repr(maxlevel=3, maxlist=8, maxtuple=8, maxdict=8, maxset=8, maxstring=80, maxother=80)


def short_repr(value: object, limit: int = 120) -> str:
    """repr() of a value a user's code gave (a command, diagnostics), short whatever its size: a
    10-million-element list is shown by its first elements and its length, never printed whole."""
    try:
        text = _short.repr(value)
    except Exception:  # noqa: BLE001 - a user's object whose __repr__ fails
        text = f"<{type(value).__name__}>"
    size = getattr(value, "__len__", None)
    if callable(size) and not isinstance(value, str) and "..." in text:  # shortened: say how long it is
        try:
            text = f"{text} (a {type(value).__name__} of {len(value)})"  # type: ignore[arg-type]
        except Exception:  # noqa: BLE001, S110
            pass
    return bounded_text(text, limit)


def value_text(value: object, limit: int = VALUE_CHARS) -> str:
    """A user's value as an error line shows it: its repr when at most `limit` characters, else
    `short_repr` (its first elements, "...", and its size), so 10 001 inline points are not echoed."""
    try:
        whole = repr(value)
    except Exception:  # noqa: BLE001 - a value whose __repr__ fails
        return short_repr(value, limit)
    return whole if len(whole) <= limit else short_repr(value, limit)


def schema_text(message: str, value: object) -> str:
    """A schema checker's message about `value` (jsonschema writes the value's repr whole, e.g.
    "[[0, 0], ...] is too long") with the value shown by `value_text`, on one bounded line."""
    whole = repr(value)
    if len(whole) > VALUE_CHARS and whole in message:
        message = message.replace(whole, value_text(value))
    return bounded_text(message)


__all__ = [
    "MESSAGE_CHARS",
    "VALUE_CHARS",
    "bounded_text",
    "error_text",
    "said_in",
    "schema_text",
    "short_repr",
    "value_text",
]


def said_in(message: str, text: str) -> bool:
    """True when `text` says `message`, numbers aside: an FMU's message of the same failure at
    another time (a retried step's, say) is said already."""
    return _numberless(message) in _numberless(text)


def _numberless(text: str) -> str:
    return re.sub(r"[-+]?\d[\d.eE+-]*", "#", text)

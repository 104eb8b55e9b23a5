"""A document checked against an XML schema, its first problem said in one line: the one
wording of a schema refusal for every XML file we read or write (SSP files, FMI-LS-REF
manifests and experiments, SRMD records)."""

from __future__ import annotations

from typing import Any

__all__ = ["first_problem"]


def first_problem(checker: Any, root: Any) -> str | None:
    """None if `root` is valid against the lxml `XMLSchema` `checker`, else its first error as
    `line N: message` on one line."""
    if checker.validate(root):
        return None
    entry = checker.error_log[0]
    return f"line {entry.line}: {' '.join(entry.message.split())}"

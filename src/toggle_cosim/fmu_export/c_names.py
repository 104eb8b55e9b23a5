"""Which Modelica variable names the generated C can spell.

The Modelica compiler names each variable's C local after the variable (`x`, `body.v` ->
`body_v`, `'a b'` -> `_a_b_`), avoiding Python's keywords and its own workspace names but not
C's: a variable called `int`, `double` or `default`, or one that shadows a C function the
generated code calls (`sqrt`), breaks the C, and a quoted identifier with letters outside
ASCII (`'Café'`) is never declared. Such a model is refused before the C compiler runs, in one
line naming the variable and the fix.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

# C99/C11 keywords, and the names <stdbool.h> and <math.h> define as macros.
C_RESERVED = frozenset(
    """auto break case char const continue default do double else enum extern float for goto if
    inline int long register restrict return short signed sizeof static struct switch typedef union
    unsigned void volatile while _Alignas _Alignof _Atomic _Bool _Complex _Generic _Imaginary
    _Noreturn _Static_assert _Thread_local bool true false NAN INFINITY HUGE_VAL""".split()
)
_ASCII_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_CALLED = re.compile(r"\b([A-Za-z_]\w*)\s*\(")


def c_name_problem(symbol: str, called: frozenset[str] | set[str]) -> str | None:
    """Why the C local `symbol` cannot be used (None if it can); `called`: the functions the C calls."""
    if not _ASCII_IDENTIFIER.match(symbol):
        return f"its C name {symbol} has characters outside ASCII letters, digits and _"
    if symbol in C_RESERVED:
        return f"its name is the C keyword or macro {symbol}"
    if symbol in called:
        return f"its name is the C function {symbol}() the generated code calls"
    return None


def check_c_names(symbols: Mapping[str, str], c_source: str) -> None:
    """ValueError naming the first variable (of `symbols`: Modelica name -> C local) whose C
    name the generated `c_source` cannot use."""
    called = set(_CALLED.findall(c_source))
    for name, symbol in symbols.items():
        problem = c_name_problem(symbol, called)
        if problem:
            raise ValueError(
                f"variable {name!r}: {problem}, so the generated C cannot use it; rename the variable "
                "(ASCII letters, digits and _, not a C keyword)"
            )


__all__ = ["C_RESERVED", "c_name_problem", "check_c_names"]

"""`checked_command`, the check the Python loop makes of every step's result: its fast path (a
ControlStep holding a float command and a tuple of floats) accepts exactly what the full check
accepts, and returns the same values; every result the protocol refuses is still refused with
the same one-line reason (a command that is not a finite float fails the controller)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from toggle_cosim.control import protocol
from toggle_cosim.control.protocol import ControllerError, ControlStep, checked_command


class _Float(float):
    pass


@pytest.mark.parametrize(
    ("result", "expected"),
    [
        (ControlStep(1.5, (), "s"), (1.5, (), "s")),
        (ControlStep(-0.0, (2.0, math.nan), None), (-0.0, (2.0, math.nan), None)),  # diagnostics may be nan
        (ControlStep(np.float64(0.25), [np.float64(1.0), 3], 7), (0.25, (1.0, 3.0), 7)),  # converted to floats
        (ControlStep(_Float(2.0), (_Float(4.0), 1.0), None), (2.0, (4.0, 1.0), None)),
        (ControlStep(3, (1.0, 2.0), None), (3.0, (1.0, 2.0), None)),
    ],
)
def test_accepted_results_give_floats(result, expected) -> None:  # noqa: ANN001
    u, diagnostics, state = checked_command(result, len(expected[1]), 0.05)
    assert type(u) is float and all(type(value) is float for value in diagnostics)
    assert np.array_equal((u, *diagnostics), (expected[0], *expected[1]), equal_nan=True)
    assert math.copysign(1.0, u) == math.copysign(1.0, expected[0]) and state == expected[2]


@pytest.mark.parametrize(
    ("result", "n", "message"),
    [
        (ControlStep(math.nan, (), None), 0, "the controller's command at t = 0.05 s is nan, not a finite float"),
        (ControlStep(math.inf, (1.0,), None), 1, "is inf, not a finite float"),
        (ControlStep(-math.inf, (), None), 0, "is -inf, not a finite float"),
        (ControlStep(True, (), None), 0, "is True, not a finite float"),
        (ControlStep("1.0", (), None), 0, "is '1.0', not a finite float"),
        (ControlStep(1.0, (1.0,), None), 0, "returned 1 diagnostics at t = 0.05 s, its diagnostics attribute names 0"),
        (ControlStep(1.0, (), None), 1, "returned 0 diagnostics"),
        (ControlStep(1.0, ("x",), None), 1, "are ('x',), not a tuple of floats"),
        ((1.0, (), None), 0, "returned tuple at t = 0.05 s, not a ControlStep"),
    ],
)
def test_refused_results_fail_with_the_reason(result, n, message) -> None:  # noqa: ANN001
    with pytest.raises(ControllerError, match=re.escape(message)):
        checked_command(result, n, 0.05)


def test_the_fast_path_is_taken_for_plain_floats(monkeypatch) -> None:  # noqa: ANN001
    """A ControlStep of a float and a tuple of floats returns before the full check (which
    would call `numbers`' isinstance): the loop's per-sample cost."""
    calls = []
    monkeypatch.setattr(protocol, "isinstance", lambda *a: calls.append(a) or isinstance(*a), raising=False)
    result = ControlStep(1.0, (2.0,), None)
    assert checked_command(result, 1, 0.0) == (1.0, (2.0,), None)
    assert calls == []
    checked_command(ControlStep(np.float64(1.0), (2.0,), None), 1, 0.0)
    assert calls  # the full check ran for a numpy float

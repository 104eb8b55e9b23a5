"""Numerical derivatives of a vector function along chosen directions (pure functions).

`directional_derivatives(f, x0, directions, steps)` takes, for each direction d_j with step h_j,
three central differences, D(h) = (f(x0 + h d) − f(x0 − h d)) / 2h, D(h/2) and D(h/4), and two
Richardson extrapolations, R(h) = (4 D(h/2) − D(h)) / 3 and R(h/2) = (4 D(h/4) − D(h/2)) / 3,
whose errors are O(h⁴) where D's is O(h²). The value is R(h/2); |R(h/2) − R(h)| estimates the
error of R(h), 16 times R(h/2)'s (for h where truncation, not rounding, dominates), so it is an
upper bound of the value's error: it is reported as the error estimate.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

__all__ = ["Derivatives", "directional_derivatives", "step_for"]

RELATIVE_STEP = 2e-3  # h = RELATIVE_STEP * max(|x|, scale); the smallest step used, h/4, is about eps^(1/5)


@dataclass(frozen=True)
class Derivatives:
    """Columns j = derivatives of f along direction j: value (Richardson) and error estimate."""

    value: FloatArray  # (len(f), n_directions)
    error: FloatArray  # |R(h/2) − R(h)|, same shape
    steps: FloatArray  # h_j


def step_for(value: float, scale: float) -> float:
    """The step of a central difference in a variable of size `value` whose natural scale is
    `scale` (the FMU's nominal value of a state, 1 for an input): RELATIVE_STEP times the larger."""
    return RELATIVE_STEP * max(abs(value), abs(scale), 1e-12)


def directional_derivatives(
    f: Callable[[FloatArray], FloatArray], x0: FloatArray, directions: FloatArray, steps: FloatArray
) -> Derivatives:
    """df/dx · d_j for each column d_j of `directions`, by Richardson-extrapolated central
    differences with step steps[j] (see the module's docstring)."""
    x0 = np.asarray(x0, dtype=float)
    columns, errors = [], []
    for j in range(directions.shape[1]):
        d, h = directions[:, j], float(steps[j])
        central = [(f(x0 + s * d) - f(x0 - s * d)) / (2.0 * s) for s in (h, 0.5 * h, 0.25 * h)]
        coarse = (4.0 * central[1] - central[0]) / 3.0
        fine = (4.0 * central[2] - central[1]) / 3.0
        columns.append(fine)
        errors.append(np.abs(fine - coarse))
    return Derivatives(np.column_stack(columns), np.column_stack(errors), np.asarray(steps, dtype=float))

"""Where the funnel is checked: a verdict that does not depend on how the two traces were sampled.

The funnel of `toggle_cosim.analysis.compare` is built from the reference's samples, joined by straight
lines. A reference that keeps only every 10th sample of a run therefore cannot show a peak that
falls between two of its samples, while a result written at every sample does show it: checked
at the result's own samples, the same run would fail against its own decimated copy.

The rule (`check_points`): the funnel is checked at the samples of the SPARSER of the two traces.

* Result denser than the reference: the result is evaluated on the reference's time grid (linear
  interpolation between its samples; exact where the grids coincide, as for a decimated copy).
  Only what the reference can show is compared, and the result's extra detail is not held
  against a reference that never saw it.
* Result as sparse as the reference, or sparser: the result is checked at its own samples. Its
  samples are points of its own curve, and the funnel of the denser reference holds every point
  of an unchanged curve, so nothing is interpolated on the result's side.

A real change still fails: it moves the result away from the reference at the points both traces
show, whatever the ratio (the tests run ratios 3, 7 and 10 both ways across the reaching/sliding
switch and the friction sign events, with μ raised from 0.2 to 0.25 and a gain raised by 5 %).

Grids that do not coincide (say a result every 3.5 ms against a reference every 5 ms): a check
point that is not a sample of a trace falls between two of its samples, and between them that
trace may have taken any value from one sample's to the other's (a jump at an event can lie
anywhere in the interval). So there, and only there, the trace counts with that whole interval:
the result passes at such a point when some value between its two neighbouring samples lies in
the funnel (`CheckPoints.low`/`high`), and the funnel there also holds the values between the
reference's two neighbouring samples, ± the value tube (`reference_range`). At points that are
samples of both traces (any decimated copy) nothing is widened.

Time spans: the result may start or stop up to the time tolerance (the funnel's half-width)
away from the reference. Result samples outside the reference's span are dropped and the
result's value at the reference's first and last time is taken by interpolation, or held from
its nearest sample when the result stops short; that hold lasts less than the half-width, so
it stays inside the funnel of an unchanged curve.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CheckPoints", "SpanMismatch", "check_points", "reference_range"]

RESULT_GRID = "result samples"
REFERENCE_GRID = "reference samples"


class SpanMismatch(ValueError):
    """The result's time span differs from the reference's by more than the time tolerance."""

    def __init__(self, word: str, result_time: float, reference_time: float, tolerance: float) -> None:
        self.word, self.result_time, self.reference_time, self.tolerance = word, result_time, reference_time, tolerance
        super().__init__(f"time {word} at {result_time:.17g} s, {reference_time:.17g} s in the reference")


@dataclass(frozen=True)
class CheckPoints:
    """The times at which the funnel is checked, and the result's values there (one column per variable)."""

    time: np.ndarray
    values: np.ndarray  # shape (len(time), number of variables)
    grid: str  # RESULT_GRID or REFERENCE_GRID
    low: np.ndarray  # the smallest value the result may take there (= values at its own samples)
    high: np.ndarray  # the largest


def _neighbours(times: np.ndarray, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each of `times`: the indices of the samples of `grid` before and after it, and whether
    it is a sample of `grid` (to rounding)."""
    slack = _slack(grid)
    right = np.clip(np.searchsorted(grid, times), 0, grid.size - 1)
    left = np.clip(right - 1, 0, grid.size - 1)
    exact = (np.abs(grid[right] - times) <= slack) | (np.abs(grid[left] - times) <= slack)
    return left, right, exact


def _range_between(times: np.ndarray, grid: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) of the values a sampled signal may take at `times`: its value at its own
    samples, anything between the two neighbouring samples elsewhere (held beyond its ends)."""
    left, right, exact = _neighbours(times, grid)
    inside = (times > grid[0]) & (times < grid[-1])
    widen = (~exact & inside)[:, None]
    exact_value = np.column_stack([np.interp(times, grid, y[:, j]) for j in range(y.shape[1])])
    low = np.where(widen, np.minimum(y[left], y[right]), exact_value)
    high = np.where(widen, np.maximum(y[left], y[right]), exact_value)
    return low, high


def reference_range(times: np.ndarray, t_ref: np.ndarray, y_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where a check point falls between two reference samples: the smallest and largest of the
    two (NaN at the reference's own samples, where the funnel is not widened)."""
    times = np.asarray(times, dtype=float)
    y = np.asarray(y_ref, dtype=float).reshape(-1, 1)
    low, high = _range_between(times, np.asarray(t_ref, dtype=float), y)
    _, _, exact = _neighbours(times, np.asarray(t_ref, dtype=float))
    keep = ~exact & (times > t_ref[0]) & (times < t_ref[-1])
    return np.where(keep, low[:, 0], np.nan), np.where(keep, high[:, 0], np.nan)


def _slack(t_ref: np.ndarray) -> float:
    """Rounding slack for comparing times: 1e-9 of the span (or of the end time)."""
    return 1e-9 * max(float(t_ref[-1] - t_ref[0]), abs(float(t_ref[-1])), 1e-300)


def check_points(t_res: np.ndarray, y_res: np.ndarray, t_ref: np.ndarray, span_tolerance: float) -> CheckPoints:
    """Where and with which result values to check the funnel of the reference (see the module text).

    t_res: the result's times (strictly increasing); y_res: its values, shape (len(t_res), m);
    t_ref: the reference's times; span_tolerance: how far (s) the result may start or stop away
    from the reference (the smallest time half-width of the compared variables). Raises
    SpanMismatch when it starts or stops farther away.
    """
    t_res = np.asarray(t_res, dtype=float)
    y_res = np.asarray(y_res, dtype=float).reshape(t_res.size, -1)
    t_ref = np.asarray(t_ref, dtype=float)
    allowed = span_tolerance + _slack(t_ref)
    for index, word in ((0, "starts"), (-1, "ends")):
        if abs(float(t_res[index] - t_ref[index])) > allowed:
            raise SpanMismatch(word, float(t_res[index]), float(t_ref[index]), span_tolerance)

    def at(times: np.ndarray) -> np.ndarray:
        """The result at `times`: linear between its samples, held beyond its ends."""
        return np.column_stack([np.interp(times, t_res, y_res[:, j]) for j in range(y_res.shape[1])])

    inside = (t_res > t_ref[0] + _slack(t_ref)) & (t_res < t_ref[-1] - _slack(t_ref))
    if np.count_nonzero(inside) + 2 > t_ref.size:  # the result is denser: look only where the reference looks
        low, high = _range_between(t_ref, t_res, y_res)
        return CheckPoints(t_ref.copy(), at(t_ref), REFERENCE_GRID, low, high)
    # the result's own samples, with its values at the reference's first and last time as end points
    time = np.concatenate([t_ref[:1], t_res[inside], t_ref[-1:]])
    values = np.vstack([at(t_ref[:1]), y_res[inside], at(t_ref[-1:])])
    return CheckPoints(time, values, RESULT_GRID, values.copy(), values.copy())

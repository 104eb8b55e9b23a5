"""Checkpoint retries of a system's run, for every component: an execution option
(`CheckpointOptions`) that the Python execution and the compiled system loop use alike.

Every `interval` samples the state of every component is saved (an FMU's by fmi2GetFMUstate /
fmi3GetFMUState, a native controller's by a deep copy of its protocol state). When a
component's doStep at sample k returns Discard or Error, every component is put back to the
checkpoint, the samples from the checkpoint to k are run again (the same inputs: the run is
deterministic, so they give the same values and rows), and sample k is run with the failing
component stepping in `substeps` steps of T_s / substeps, its inputs held; then the run goes on
(the next checkpoint at k + 1). A retry that fails as well ends the run: its reason tells both
failures, with what the FMU logged, and the trace holds the samples up to k. Fatal is never
retried, nor is anything when a component cannot save its state: then `off` says why, in
run.json, and no checkpoint is kept.

The caller gives the two ways to run samples (`drive`): `forward`, the run's loop (the compiled
system loop returns to Python at every checkpoint, and at a failed call), and `retake`, the
retried sample, always in the Python execution (`Execution.advance` with `split`), whose calls
and values are the compiled loop's; the compiled loop then goes on from the next sample.

Each retry goes into run.json's `retries`: {"component", "t" (the failed step's start),
"error" (its failure), "outcome" ("passed" or "failed")}.

doStep's noSetFMUStatePriorToCurrentPoint (FMI 2.0 section 4.2.2, 3.0 section 4.2.1) is false
whenever a checkpoint may be restored and true only when none is kept;
`configure` sets it on every FMU component and on the compiled loop.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from toggle_cosim.cosim.execution.slaves import Slave, SlaveError

__all__ = [
    "CHECKPOINT_SAMPLES",
    "RETRIED_STATUSES",
    "RETRY_SUBSTEPS",
    "CheckpointOptions",
    "ComponentWords",
    "FailureWords",
    "SystemCheckpoints",
    "failure_text",
    "retried_words",
]

CHECKPOINT_SAMPLES = 200  # every component's state is saved every this many samples (where it can be)
RETRY_SUBSTEPS = 10  # a failed step is retried from the checkpoint in this many smaller steps
RETRIED_STATUSES = (2, 3)  # discard, error; fatal is not retried

# Samples k .. stop - 1 of the run, the next sample; a failed call raises SlaveError with its `k`.
Forward = Callable[[int, int], int]
# Sample k with component c stepping in m substeps: (k, c, m).
Retake = Callable[[int, int, int], None]


@dataclass(frozen=True)
class CheckpointOptions:
    """How a system's run keeps checkpoints and retries a refused step (module docstring):
    every `interval` samples, a failed step retried in `substeps` substeps; `enabled` False
    keeps none (and a refused step ends the run). `lead` (0: none): the samples run as a stretch
    of their own before the first full one (the plain pair runs its first sample, which starts
    the controller, alone, so its checkpoints and work-budget counts fall at 1 + m * interval)."""

    interval: int = CHECKPOINT_SAMPLES
    substeps: int = RETRY_SUBSTEPS
    enabled: bool = True
    lead: int = 0

    def __post_init__(self) -> None:
        if self.interval < 1 or self.substeps < 1 or self.lead < 0:
            raise ValueError(
                f"interval and substeps must be at least 1 and lead at least 0, not {self.interval}, "
                f"{self.substeps} and {self.lead}"
            )


class FailureWords(Protocol):
    """How a run says its components' failures: a failed call (`step`; `before`: a failure
    already said, e.g. the first of a retry that failed too), the retries that passed
    (`retried`, None for none) and the run's reason (`reason`; t the failed sample's time)."""

    def step(self, error: SlaveError, before: str | None = None) -> str: ...
    def retried(self, passed: Sequence[dict[str, Any]]) -> str | None: ...
    def reason(self, error: SlaveError, t: float) -> str: ...


class ComponentWords:
    """A system's words: every failure names its component (`SlaveError`'s own text)."""

    def step(self, error: SlaveError, before: str | None = None) -> str:
        said = str(error)
        prefix = f"component {error.component!r}"
        if before is not None and said.startswith(prefix) and ": " in said:  # the component is named already
            said = said.split(": ", 1)[1]
        return said

    def retried(self, passed: Sequence[dict[str, Any]]) -> str | None:
        return retried_words(passed)

    def reason(self, error: SlaveError, t: float) -> str:
        return str(error)


def _retried(error: SlaveError) -> bool:
    """A doStep that returned Discard or Error (Fatal and every other call end the run)."""
    return bool(error.function and error.function.endswith("DoStep") and error.status in RETRIED_STATUSES)


@dataclass
class SystemCheckpoints:
    """The checkpoints of one run over `slaves` (in plan order), its retries and, when none is
    kept, why (`off`)."""

    options: CheckpointOptions
    slaves: Sequence[Slave]
    T_s: float
    off: str | None = None
    retries: list[dict[str, Any]] = field(default_factory=list)
    calling: Any = None  # an int64 array: element 0 gets the id of the component being saved or restored
    ids: Sequence[int] = ()
    words: FailureWords = field(default_factory=ComponentWords)

    @classmethod
    def of(
        cls,
        options: CheckpointOptions,
        slaves: Sequence[Slave],
        T_s: float,
        calling: Any = None,
        ids: Sequence[int] | None = None,
        words: FailureWords | None = None,
    ) -> SystemCheckpoints:
        """The checkpoints of a run, off when the options say so or a component cannot save its
        state. `calling`, `ids`: as the execution's, so a supervising process knows whose save or
        restore ended the process. `words`: how failures are said (default `ComponentWords`)."""
        off = None if options.enabled else "checkpoints are off in this run's options"
        for slave in slaves:
            if off is not None:
                break
            off = getattr(slave, "cannot_save_state", f"component {slave.name!r} cannot save its state")
        ids = tuple(ids) if ids is not None else tuple(range(1, len(slaves) + 1))
        return cls(options, tuple(slaves), float(T_s), off, calling=calling, ids=ids, words=words or ComponentWords())

    def _each(self) -> Any:
        """The components in order, each noted in `calling` before it is called."""
        for slave, id_ in zip(self.slaves, self.ids, strict=True):
            if self.calling is not None:
                self.calling[0] = id_
            yield slave

    @property
    def no_set_state_prior_to_current_point(self) -> bool:
        """True only when no checkpoint can ever be restored."""
        return self.off is not None

    def configure(self, *targets: Any) -> None:
        """Set doStep's flag on everything that calls doStep (the FMU components, the compiled loop)."""
        for target in targets:
            if hasattr(target, "no_set_state_prior_to_current_point"):
                target.no_set_state_prior_to_current_point = self.no_set_state_prior_to_current_point

    def record(self) -> dict[str, Any]:
        """What run.json says of them (`system.checkpoints`)."""
        return {
            "interval": self.options.interval,
            "substeps": self.options.substeps,
            "retries": "off" if self.off is not None else "on",
            **({"reason": self.off} if self.off is not None else {}),
        }

    def passed(self) -> list[dict[str, Any]]:
        """The retries that passed (the run went on after them)."""
        return [entry for entry in self.retries if entry["outcome"] == "passed"]

    def _save(self, k: int) -> bool:
        """Save every component's state at sample k; False (and `off` says why) if one cannot."""
        if self.off is not None:
            return False
        try:
            for slave in self._each():
                slave.save_state()
        except SlaveError as error:
            self.off = f"{error} at t = {k * self.T_s:.6g} s; no checkpoint is kept from then on"
            return False
        return True

    def drive(
        self, forward: Forward, retake: Retake, k: int, n: int, after: Callable[[int], None] | None = None
    ) -> int:
        """Samples k .. n by `forward`, in stretches of `interval` that start at a checkpoint,
        a refused step retried (module docstring); the next sample (n + 1). Raises the
        SlaveError that ends the run. `after(k)` is called after every full stretch (not the
        lead), k the next sample, e.g. to count the plant's work (`budget`), and may raise to end the run."""
        lead = self.options.lead
        while k <= n:
            leading = k < lead
            stop = min(lead if leading else k + self.options.interval, n + 1)
            checkpoint, saved = k, self._save(k)
            try:
                k = forward(k, stop)
            except SlaveError as failure:
                if not saved or failure.k is None or not _retried(failure):
                    raise
                entry = {"component": failure.component, "t": failure.k * self.T_s, "error": self.words.step(failure)}
                entry["outcome"] = "failed"
                self.retries.append(entry)
                self._retry(forward, retake, checkpoint, failure)
                entry["outcome"] = "passed"
                k = failure.k + 1
            if after is not None and not leading:
                after(k)
        return k

    def _retry(self, forward: Forward, retake: Retake, checkpoint: int, failure: SlaveError) -> None:
        """Every component back to the checkpoint, the samples to the failed one again, and that
        one with the failing component in substeps; a SlaveError telling both failures if it fails."""
        k, substeps = int(failure.k or 0), self.options.substeps
        c = next(i for i, slave in enumerate(self.slaves) if slave.name == failure.component)
        try:
            for slave in self._each():
                slave.restore_state()
            if forward(checkpoint, k) != k:
                raise SlaveError(f"the samples from t = {checkpoint * self.T_s:.6g} s did not run again")
            retake(k, c, substeps)
        except SlaveError as again:
            first = self.words.step(failure)
            both = SlaveError(
                f"{first.rstrip('.')}. Retried from the checkpoint at t = {checkpoint * self.T_s:.6g} s in "
                f"{substeps} substeps: {self.words.step(again, before=first)}",
                failure.component,
                failure.function,
                failure.status,
            )
            both.k, both.retried = failure.k, True
            raise both from None


def retried_words(passed: Sequence[dict[str, Any]]) -> str | None:
    """The steps that failed and passed when retried from a checkpoint, in words (a run's
    warning; a failure reason's note), or None."""
    if not passed:
        return None
    if len(passed) == 1:
        first = passed[0]
        return (
            f"component {first['component']!r}'s step at t = {first['t']:.6g} s failed and passed when retried"
            " from a checkpoint"
        )
    names = ", ".join(dict.fromkeys(repr(entry["component"]) for entry in passed))
    return (
        f"{len(passed)} steps of component {names} from t = {passed[0]['t']:.6g} s to {passed[-1]['t']:.6g} s "
        "failed and passed when retried from a checkpoint"
    )


def failure_text(error: BaseException, logged: str | None) -> str:
    """A failed FMI call's message followed by what the FMU logged about it, if anything:
    "fmi2DoStep failed with status 3 (error): more than 10000 events in one communication step..."."""
    text = str(error)
    if not logged:
        return text
    return f"{text.rstrip('.')}: {logged}"

"""The checkpoint/retry policy: where the FMU can save its state, save it every `every`
samples; when a doStep fails with Discard or Error, put the FMU back to the checkpoint, replay
the recorded inputs up to the failed sample, and take its step again in `substeps` smaller
steps. Fatal is never retried (the FMU is beyond recovery), nor is anything without a checkpoint.
Every retry is kept for run.json (`retries`: its time, the failure with what the FMU logged, and
whether the retry passed); a run whose retry passed goes on, and if it fails later it is reported
failed at that later step, its trace kept up to it (`pair`).

FMI (2.0 section 4.2.2, 3.0 section 4.2.1): doStep's noSetFMUStatePriorToCurrentPoint = true
lets the FMU drop its history, after which restoring an earlier state is not allowed. So the
policy passes false whenever it may restore, and true only when it never restores (no
checkpoints); `configure` sets the flag on the session and on the compiled loop alike.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

from fmpy.fmi1 import FMICallException

from toggle_cosim.cosim.budget import BudgetExceeded, WorkBudget
from toggle_cosim.cosim.stepper import StepFailed, Stepper
from toggle_cosim.messages import said_in

CHECKPOINT_SAMPLES = 200  # the FMU state is saved every this many samples (where it can be)
RETRY_SUBSTEPS = 10  # a failed step is retried from the checkpoint in this many smaller steps
RETRIED_STATUSES = (2, 3)  # discard, error; fatal is not retried


class RetryFailed(Exception):
    """The retry from the checkpoint failed as well; the message tells both failures."""


class PlantStepFailed(Exception):
    """A doStep failed and was not retried; the message tells the call, its status and what the
    FMU logged (`failure_text`)."""


def failure_text(error: BaseException, logged: str | None) -> str:
    """A failed FMI call's message followed by what the FMU logged about it, if anything:
    "fmi2DoStep failed with status 3 (error): more than 10000 events in one communication step..."."""
    text = str(error)
    if not logged:
        return text
    return f"{text.rstrip('.')}: {logged}"


class Restorable(Protocol):
    """What the policy needs of a plant session (`PlantSession` has it)."""

    no_set_state_prior_to_current_point: bool

    def save_state(self) -> None: ...
    def restore_state(self) -> None: ...
    def write_inputs(self, values: tuple[float, ...]) -> None: ...
    def do_step(self, t: float, h: float) -> None: ...
    def logged_error(self) -> str | None: ...
    def solver_statistics(self) -> dict[str, int] | str: ...


class RecordedInputs(Protocol):
    def inputs(self, k: int) -> tuple[float, ...]: ...


@dataclass
class CheckpointPolicy:
    """Checkpoints every `every` samples when `saving`; the retries made, for run.json: each
    {"t": the failed step's start, "error": what failed, "outcome": "passed" or "failed"}. With a
    `budget`, the plant's work is counted after every stretch of `every` samples (`budget`)."""

    saving: bool
    every: int = CHECKPOINT_SAMPLES
    substeps: int = RETRY_SUBSTEPS
    retries: list[dict[str, Any]] = field(default_factory=list)
    budget: WorkBudget | None = None

    @property
    def no_set_state_prior_to_current_point(self) -> bool:
        """True only when no checkpoint can ever be restored."""
        return not self.saving

    def configure(self, *targets: Any) -> None:
        """Set doStep's flag on everything that calls doStep (the session, the compiled loop)."""
        for target in targets:
            target.no_set_state_prior_to_current_point = self.no_set_state_prior_to_current_point

    def drive(self, stepper: Stepper, session: Restorable, recorder: RecordedInputs, k: int, n: int, T_s: float) -> int:
        """Samples k .. n through `stepper`, in stretches that start at a checkpoint; the next
        sample (n + 1 when done), or -1 when the stepper ended the run. Raises BudgetExceeded
        when the plant's work after a stretch is past the budget."""
        while 0 < k <= n:
            stop = min(k + self.every, n + 1)
            if self.saving:
                session.save_state()
            checkpoint = k
            try:
                k = stepper.advance(k, stop)
            except StepFailed as failure:
                text = failure_text(failure.error, session.logged_error())
                if not self.saving or failure.error.status not in RETRIED_STATUSES:
                    raise PlantStepFailed(text) from None
                entry = {"t": failure.k * T_s, "error": text, "outcome": "failed"}
                self.retries.append(entry)
                self.retry(session, recorder, checkpoint, failure.k, text, T_s)
                entry["outcome"] = "passed"
                k = failure.k + 1
            if self.budget is not None and k > 0:
                exceeded = self.budget.exceeded(session.solver_statistics(), (k - 1) * T_s)
                if exceeded is not None:
                    raise BudgetExceeded(exceeded)
        return k

    def passed(self) -> list[dict[str, Any]]:
        """The retries that passed (the run went on after them)."""
        return [entry for entry in self.retries if entry["outcome"] == "passed"]

    def retry(
        self,
        session: Restorable,
        recorder: RecordedInputs,
        checkpoint: int,
        failed: int,
        error: str,
        T_s: float,
    ) -> None:
        """Back to the checkpoint, the recorded inputs replayed up to the failed sample, and its
        step again in `substeps` smaller steps; raises RetryFailed if that fails too (`error`:
        the first failure's text)."""
        try:
            session.restore_state()
            for j in range(checkpoint, failed):
                session.write_inputs(recorder.inputs(j))
                session.do_step(j * T_s, T_s)
            session.write_inputs(recorder.inputs(failed))
            h = T_s / self.substeps
            for m in range(self.substeps):
                session.do_step(failed * T_s + m * h, h)
        except FMICallException as again:
            logged = session.logged_error()
            said = failure_text(again, None if logged is not None and said_in(logged, error) else logged)
            raise RetryFailed(
                f"{error.rstrip('.')}. Retried from the checkpoint at t = {checkpoint * T_s:.6g} s in "
                f"{self.substeps} substeps: {said}"
            ) from again

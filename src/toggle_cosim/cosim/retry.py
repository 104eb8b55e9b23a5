"""The checkpoint/retry policy: where the FMU can save its state, save it every `every`
samples; when a doStep fails with Discard or Error, put the FMU back to the checkpoint, replay
the recorded inputs up to the failed sample, and take its step again in `substeps` smaller
steps. Fatal is never retried (the FMU is beyond recovery), nor is anything without a checkpoint.
`first_failure` is the first sample whose step failed (retried or not): a run that fails after
retries is reported failed there, its trace cut after that sample (`master`).

FMI (2.0 section 4.2.2, 3.0 section 4.2.1): doStep's noSetFMUStatePriorToCurrentPoint = true
lets the FMU drop its history, after which restoring an earlier state is not allowed. So the
policy passes false whenever it may restore, and true only when it never restores (no
checkpoints); `configure` sets the flag on the session and on the compiled loop alike.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

from fmpy.fmi1 import FMICallException

from toggle_cosim.cosim.stepper import StepFailed, Stepper

CHECKPOINT_SAMPLES = 200  # the FMU state is saved every this many samples (where it can be)
RETRY_SUBSTEPS = 10  # a failed step is retried from the checkpoint in this many smaller steps
RETRIED_STATUSES = (2, 3)  # discard, error; fatal is not retried


class RetryFailed(Exception):
    """The retry from the checkpoint failed as well; the message tells both failures."""


class Restorable(Protocol):
    """What the policy needs of a plant session (`PlantSession` has it)."""

    no_set_state_prior_to_current_point: bool

    def save_state(self) -> None: ...
    def restore_state(self) -> None: ...
    def write_inputs(self, values: tuple[float, ...]) -> None: ...
    def do_step(self, t: float, h: float) -> None: ...


class RecordedInputs(Protocol):
    def inputs(self, k: int) -> tuple[float, ...]: ...


@dataclass
class CheckpointPolicy:
    """Checkpoints every `every` samples when `saving`; the retries made, for run.json."""

    saving: bool
    every: int = CHECKPOINT_SAMPLES
    substeps: int = RETRY_SUBSTEPS
    retries: list[dict[str, Any]] = field(default_factory=list)
    first_failure: int | None = None  # the first sample k whose step (k -> k + 1) failed

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
        sample (n + 1 when done), or -1 when the stepper ended the run."""
        while 0 < k <= n:
            stop = min(k + self.every, n + 1)
            if self.saving:
                session.save_state()
            checkpoint = k
            try:
                k = stepper.advance(k, stop)
            except StepFailed as failure:
                if self.first_failure is None:
                    self.first_failure = failure.k
                if not self.saving or failure.error.status not in RETRIED_STATUSES:
                    raise failure.error from None
                self.retry(session, recorder, checkpoint, failure.k, failure.error, T_s)
                self.retries.append({"t": failure.k * T_s, "error": str(failure.error)})
                k = failure.k + 1
        return k

    def retry(
        self,
        session: Restorable,
        recorder: RecordedInputs,
        checkpoint: int,
        failed: int,
        error: FMICallException,
        T_s: float,
    ) -> None:
        """Back to the checkpoint, the recorded inputs replayed up to the failed sample, and its
        step again in `substeps` smaller steps; raises RetryFailed if that fails too."""
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
            raise RetryFailed(
                f"{error} Retried from the checkpoint at t = {checkpoint * T_s:.6g} s in {self.substeps} "
                f"substeps: {again}"
            ) from again

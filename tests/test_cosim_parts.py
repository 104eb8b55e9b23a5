"""The master's parts, each alone, over a mock plant session: the recorder, the Python stepper,
the hand-over from the compiled stepper to the Python one, and the checkpoint/retry policy
(Discard at a given step: restore, replay, substeps; doStep's noSetFMUStatePriorToCurrentPoint
false while checkpoints are in use, true only without them)."""

from __future__ import annotations

import re

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from toggle_cosim.control.controller import ControllerGains, VSCController
from toggle_cosim.cosim import compiled_loop
from toggle_cosim.cosim.recorder import ProgressHook, Recorder
from toggle_cosim.cosim.retry import RETRY_SUBSTEPS, CheckpointPolicy, PlantStepFailed, RetryFailed
from toggle_cosim.cosim.session import FunctionNames
from toggle_cosim.cosim.stepper import CompiledStepper, HandOver, LoopState, PythonStepper, StepFailed, Timing
from toggle_cosim.physics.parameters import MechanismParameters

T_S, N, F_E = 0.001, 30, 5.0
NAMES = ("time", "x_B", "v_B", "iq_ref", "F_E", *VSCController.diagnostics)


class MockSession:
    """A plant whose slider moves at v = iq_ref * 1e-3 m/s per A: x_B(t + h) = x_B + v h.
    The state is (x, v); save/restore copy it. `fail_at` makes the doStep from that time fail
    once with the given status (and log `logged`, as an FMU's logger keeps it); every doStep
    notes the flag it was called with."""

    function_names = FunctionNames("fmi2GetReal", "fmi2SetReal", "fmi2DoStep")

    def __init__(
        self, fail_at: float | None = None, status: int = 2, fail_again: bool = False, logged: str | None = None
    ) -> None:
        self.x, self.v, self.u = 0.2, 0.0, 0.0
        self.logged, self.last_logged = logged, None
        self.fail_at, self.status, self.fail_again = fail_at, status, fail_again
        self.no_set_state_prior_to_current_point = False
        self.flags: list[bool] = []
        self.steps: list[tuple[float, float]] = []
        self.saved: tuple[float, float] | None = None
        self.saves = self.restores = self.reads = 0
        self.written: list[tuple[float, ...]] = []  # every write_inputs, in order

    def read_outputs(self, into: np.ndarray) -> None:
        self.reads += 1
        into[:] = (self.x, self.v)

    def write_inputs(self, values: tuple[float, ...]) -> None:
        self.written.append(tuple(values))
        self.u = float(values[0])

    def do_step(self, t: float, h: float) -> None:
        self.flags.append(self.no_set_state_prior_to_current_point)
        self.steps.append((t, h))
        if self.fail_at is not None and abs(t - self.fail_at) < 1e-12 and (h == T_S or self.fail_again):
            if not self.fail_again:
                self.fail_at = None
            self.x = float("nan")  # the failed step leaves the FMU in a state the policy must undo
            self.last_logged = self.logged.format(t + h) if self.logged else None  # "{}": the step's end
            raise FMICallException(function="fmi2DoStep", status=self.status)
        self.v = self.u * 1e-3
        self.x += self.v * h

    def logged_error(self) -> str | None:
        said, self.last_logged = self.last_logged, None
        return said

    def save_state(self) -> None:
        self.saves += 1
        self.saved = (self.x, self.v)

    def restore_state(self) -> None:
        self.restores += 1
        self.x, self.v = self.saved


def _controller() -> VSCController:
    return VSCController(gains=ControllerGains(C=5.0), nominal=MechanismParameters(mu=0.0), target=0.25, T_s=T_S)


def _python(
    session: MockSession, hooks=(), load: np.ndarray | None = None
) -> tuple[PythonStepper, Recorder, LoopState]:
    recorder, state = Recorder(NAMES, N), LoopState()
    load = np.full((N + 1, 1), F_E) if load is None else load
    return (
        PythonStepper(session, _controller(), recorder, Timing(N, T_S, load), state, hooks),
        recorder,
        state,
    )


def _run(session: MockSession, policy: CheckpointPolicy, load: np.ndarray | None = None) -> tuple[int, Recorder]:
    python, recorder, _ = _python(session, load=load)
    policy.configure(session)
    k = python.advance(0, 1)
    return policy.drive(python, session, recorder, k, N, T_S), recorder


def test_the_recorder_keeps_a_given_buffer_and_copies_its_own() -> None:
    own = Recorder(NAMES, 4)
    assert own.data.shape == (5, len(NAMES)) and np.isnan(own.data).all()
    assert (own.n_out, own.i_x, own.i_v, own.col_u) == (2, 1, 2, 3)
    own.outputs(0)[:] = (0.2, 0.1)
    own.data[0, own.col_u : own.col_u + 2] = (1.5, F_E)
    own.rows = 1
    assert own.inputs(0) == (1.5, F_E)
    trace = own.trace()
    assert trace.data.shape == (1, len(NAMES)) and not np.shares_memory(trace.data, own.data)
    shared = np.full((5, len(NAMES)), np.nan)
    given = Recorder(NAMES, 4, shared)
    given.rows = 3
    assert np.shares_memory(given.trace().data, shared)  # the supervised child writes the parent's map
    with pytest.raises(ValueError, match="shape"):
        Recorder(NAMES, 5, shared)


def test_the_python_stepper_records_every_sample_and_calls_its_hook() -> None:
    seen: list[float] = []
    session = MockSession()
    python, recorder, state = _python(session, [ProgressHook(seen.append, N, T_S, N * T_S)])
    assert python.advance(0, N + 1) == N + 1
    assert recorder.rows == N + 1 and not np.isnan(recorder.data).any()
    assert np.array_equal(recorder.data[:, 0], np.arange(N + 1) * T_S)
    assert len(session.steps) == N  # no doStep after the last sample
    # the slider moves as the recorded current says: v(k+1) = 1e-3 iq_ref(k)
    assert np.allclose(recorder.data[1:, 2], 1e-3 * recorder.data[:-1, 3], rtol=0, atol=1e-15)
    assert seen == pytest.approx([k / N for k in range(N)])  # every sample (n < 100), after its doStep
    assert state.controller is not None and state.reason is None


def test_the_python_stepper_stops_at_non_finite_outputs() -> None:
    session = MockSession()
    python, recorder, state = _python(session)
    assert python.advance(0, 5) == 5
    session.x = float("inf")
    assert python.advance(5, N + 1) == -1
    assert recorder.rows == 5 and "non-finite at t = 0.005" in state.reason


def test_a_discard_is_retried_from_the_checkpoint_and_the_run_recovers() -> None:
    """Discard at t = 12 T_s: back to the checkpoint at sample 1, samples 1 .. 11 replayed with
    their recorded inputs, the failed step taken in RETRY_SUBSTEPS substeps; the trace is the
    undisturbed one to rounding, and every doStep had the flag false (the FMU kept its history)."""
    clean, clean_recorder = _run(MockSession(), CheckpointPolicy(saving=True))
    session = MockSession(fail_at=12 * T_S, status=2)
    policy = CheckpointPolicy(saving=True)
    k, recorder = _run(session, policy)
    assert k == clean == N + 1 and recorder.rows == N + 1
    assert session.restores == 1 and session.saves == 2  # at sample 1, and at 13 after the retry
    assert policy.retries == [
        {"t": pytest.approx(12 * T_S), "error": "fmi2DoStep failed with status 2 (discard).", "outcome": "passed"}
    ]
    failed = session.steps.index((pytest.approx(12 * T_S), T_S))
    replay = session.steps[failed + 1 : failed + 1 + 11 + RETRY_SUBSTEPS]
    assert [t for t, _ in replay[:11]] == pytest.approx([j * T_S for j in range(1, 12)])
    assert [h for _, h in replay[11:]] == pytest.approx([T_S / RETRY_SUBSTEPS] * RETRY_SUBSTEPS)
    assert np.allclose(recorder.data, clean_recorder.data, rtol=0, atol=1e-12)
    assert session.flags and not any(session.flags)
    assert not policy.no_set_state_prior_to_current_point


def test_a_load_that_varies_is_sent_and_recorded_per_sample_and_replayed_as_recorded() -> None:
    """Sample k sends (iq_ref_k, load[k]) and records load[k] in its F_E column; a retry replays
    samples 1 .. 12 with the loads they sent, not one value for all."""
    load = (10.0 + np.arange(N + 1) * 0.5)[:, None]
    session = MockSession(fail_at=12 * T_S, status=2)
    k, recorder = _run(session, CheckpointPolicy(saving=True), load)
    assert k == N + 1
    assert np.array_equal(recorder.data[:, recorder.col_u + 1], load[:, 0])
    sent = [F for _, F in session.written]
    first = [F for _, F in session.written[:12]]
    assert first == list(load[:12, 0])  # samples 0 .. 11 before the failed step from sample 12
    replay = sent[13 : 13 + 12]  # after the failed step's own write: the replay from the checkpoint at 1
    assert replay == list(load[1:13, 0])
    assert sent[-1] == load[N - 1, 0]  # no write after the last sample


def test_a_retry_that_fails_again_ends_the_run_with_both_failures() -> None:
    session = MockSession(fail_at=12 * T_S, status=3, fail_again=True)
    with pytest.raises(RetryFailed, match=r"status 3 \(error\)\. Retried from the checkpoint at t = 0.001 s"):
        _run(session, CheckpointPolicy(saving=True))


def test_a_failed_step_says_what_the_fmu_logged_and_a_retry_notes_its_outcome() -> None:
    """The FMU's last failing-status message ends the failure's text, in the retry's entry and
    in a retry that fails again, where it is not said twice; an entry says whether it passed."""
    zeno = "more than 10000 events in one communication step: the model is chattering (Zeno behaviour)"
    policy = CheckpointPolicy(saving=True)
    _run(MockSession(fail_at=12 * T_S, status=3, logged=zeno), policy)
    at = f"{zeno} at t={{}} s"  # the retry's substep fails at another time: the same failure, said once
    with pytest.raises(RetryFailed) as failed:
        _run(MockSession(fail_at=12 * T_S, status=3, fail_again=True, logged=at), CheckpointPolicy(saving=True))
    assert str(failed.value).count("Zeno") == 1 and str(failed.value).startswith(
        f"fmi2DoStep failed with status 3 (error): {at.format(13 * T_S)}. Retried"
    )
    assert policy.retries == [
        {"t": pytest.approx(12 * T_S), "error": f"fmi2DoStep failed with status 3 (error): {zeno}", "outcome": "passed"}
    ]
    policy = CheckpointPolicy(saving=True)
    with pytest.raises(RetryFailed) as failed:
        _run(MockSession(fail_at=12 * T_S, status=3, fail_again=True, logged=zeno), policy)
    assert str(failed.value) == (
        f"fmi2DoStep failed with status 3 (error): {zeno}. Retried from the checkpoint at t = 0.001 s in "
        f"{RETRY_SUBSTEPS} substeps: fmi2DoStep failed with status 3 (error)."
    )
    assert [entry["outcome"] for entry in policy.retries] == ["failed"]
    with pytest.raises(PlantStepFailed, match=re.escape(f"status 4 (fatal): {zeno}")):
        _run(MockSession(fail_at=3 * T_S, status=4, logged=zeno), CheckpointPolicy(saving=True))


def test_without_checkpoints_nothing_is_restored_and_the_flag_is_true() -> None:
    """No saved state: doStep may be told the FMU need keep no history; a Discard ends the run."""
    policy = CheckpointPolicy(saving=False)
    session = MockSession()
    assert _run(session, policy)[0] == N + 1 and all(session.flags) and session.saves == 0
    session = MockSession(fail_at=12 * T_S, status=2)
    with pytest.raises(PlantStepFailed, match="status 2"):
        _run(session, policy)
    assert session.restores == 0 and policy.retries == []


def test_fatal_is_never_retried() -> None:
    session = MockSession(fail_at=3 * T_S, status=4)
    with pytest.raises(PlantStepFailed, match="fatal"):
        _run(session, CheckpointPolicy(saving=True))
    assert session.restores == 0


class FakeCompiledLoop:
    """Stands in for the C loop: runs the Python stepper's arithmetic over a second recorder-
    less session, and hands sample `back_at` back after reading its outputs, as the C does."""

    def __init__(self, python: PythonStepper, back_at: int) -> None:
        self.python, self.back_at, self.z = python, back_at, 0.0
        self.fault_function, self.fault_status = None, 0
        self.calls: list[tuple[int, int]] = []

    def run(self, k: int, k_end: int) -> tuple[int, int]:
        self.calls.append((k, k_end))
        if k <= self.back_at < k_end:
            self.python.advance(k, self.back_at)
            self.python.session.read_outputs(self.python.recorder.outputs(self.back_at))
            self.z = self.python.state.controller.z
            return compiled_loop.HAND_BACK, self.back_at
        self.python.advance(k, k_end)
        self.z = self.python.state.controller.z
        return compiled_loop.DONE, k_end


def test_the_compiled_stepper_hands_a_sample_back_to_python() -> None:
    """The C stops at sample 17 with its outputs read; Python takes sample 17 without reading
    again and runs to the end: the trace is the all-Python one, and the loop record says so."""
    reference, reference_recorder = _run(MockSession(), CheckpointPolicy(saving=True))
    session = MockSession()
    python, recorder, state = _python(session)
    hooked: list[float] = []
    hook = ProgressHook(hooked.append, N, T_S, N * T_S)
    fake = FakeCompiledLoop(PythonStepper(session, python.controller, recorder, python.timing, state), back_at=17)
    compiled = CompiledStepper(fake, session, recorder, python.timing, state, [hook])
    stepper = HandOver(python, compiled)
    assert stepper.loop["kind"] == "compiled"
    assert HandOver(python, "no C compiler").loop == {"kind": "python", "reason": "no C compiler"}
    policy = CheckpointPolicy(saving=True)
    assert python.advance(0, 1) == 1
    reads_before = session.reads
    assert policy.drive(stepper, session, recorder, 1, N, T_S) == N + 1
    assert stepper.loop["kind"] == "compiled, then python" and "sample 17 (t = 0.017 s)" in stepper.loop["reason"]
    assert session.reads - reads_before == N  # samples 1 .. N, each read once: 17 is not read twice
    assert np.array_equal(recorder.data, reference_recorder.data)
    assert all(end - start == 1 for start, end in fake.calls)  # the hook wants every sample: stretches of one
    assert hooked[:16] == pytest.approx([k / N for k in range(1, 17)])


def test_the_compiled_stepper_reports_a_failed_step_for_the_policy() -> None:
    session = MockSession()
    python, recorder, state = _python(session)

    class Failing:
        z, fault_function, fault_status = 0.0, "fmi2DoStep", 2

        def run(self, k: int, k_end: int) -> tuple[int, int]:
            return compiled_loop.FMI_FAILED, 4

    stepper = CompiledStepper(Failing(), session, recorder, python.timing, state)
    with pytest.raises(StepFailed) as failure:
        stepper.advance(1, 10)
    assert failure.value.k == 4 and failure.value.error.status == 2 and recorder.rows == 5


def test_the_policy_sets_the_flag_in_the_compiled_loop_and_the_skeleton_passes_it() -> None:
    """The C loop's struct carries the flag; the skeleton passes it to the plant's doStep, under
    FMI 2.0 and 3.0 alike (a controller FMU's deferred doStep passes false, as its Python does)."""
    from importlib import resources

    skeleton = resources.files("toggle_cosim.control").joinpath("loop_skeleton.c").read_text()
    assert skeleton.count("fmu_step(&s->plant, t, s->T_s, s->no_prior != 0)") == 1
    assert skeleton.count("f->component, t, h, no_prior") == 2
    library = compiled_loop.kernel_library()
    if library is None:
        pytest.skip(f"no compiled loop: {compiled_loop.kernel_reason()}")
    from toggle_cosim.cosim.session import CFunctions

    functions = CFunctions(0, 0, 0, 0, 0, 0, False, MockSession.function_names, None)
    loop = compiled_loop.CompiledLoop(
        library,
        functions,
        np.zeros((N + 1, len(NAMES))),
        2,
        1,
        2,
        3,
        N,
        T_S,
        np.full((N + 1, 1), F_E),
        _controller().law_parameters(),
    )
    assert loop.no_set_state_prior_to_current_point is False  # the safe default
    CheckpointPolicy(saving=False).configure(loop)
    assert loop.no_set_state_prior_to_current_point is True
    CheckpointPolicy(saving=True).configure(loop)
    assert loop.no_set_state_prior_to_current_point is False

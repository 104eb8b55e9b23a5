"""The Python loop's plant exchange (`compiled_loop.PlantExchange`): the plant's set, doStep and
the next sample's get in one C call. It makes the calls `PlantSession.write_inputs`, `do_step`
and `read_outputs` make, with the same values, so a run through it has the three-call path's
trace bit for bit, and a failed call is reported as they report it: the same function, status
and sample, the same rows kept, the same retries."""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from toggle_cosim.control.protocol import ControlStep
from toggle_cosim.cosim import compiled_loop, master, stepper
from toggle_cosim.cosim.compiled_loop import PlantExchange
from toggle_cosim.cosim.session import CFunctions, FunctionNames
from toggle_cosim.plant.contract import check_plant

pytestmark = pytest.mark.skipif(not compiled_loop.kernel_available(), reason="no compiled loop library (no C compiler)")


class Proportional:
    """A protocol controller the compiled loop cannot run: i_q* = 40 (x* - x_B), so the command
    depends on every output read (a wrong or missed read changes the trace)."""

    diagnostics = ()

    def start(self, t0, measurement):
        return None

    def step(self, state, t, measurement):
        return ControlStep(40.0 * (0.3199 - measurement["x_B"]), (), state)


def _run(plant, monkeypatch: pytest.MonkeyPatch, exchange: bool):
    """simulate() with the Python loop, through the exchange or (TOGGLE_COSIM_KERNEL=0) the session's
    three calls; asserts which path ran."""
    used: list[object] = []
    original = stepper.PythonStepper.exchange

    def spy(self):
        found = original(self)
        used.append(found)
        return found

    with monkeypatch.context() as patch:
        patch.setattr(stepper.PythonStepper, "exchange", spy)
        if not exchange:
            patch.setenv("TOGGLE_COSIM_KERNEL", "0")
        from test_faults import _nominal

        outcome = master.simulate(_nominal(), plant, controller=Proportional())
    assert used and all((found is not None) == exchange for found in used)
    return outcome


def _same(a, b) -> None:
    assert a.complete == b.complete and a.reason == b.reason
    assert a.record["retries"] == b.record["retries"] and a.record["samples"] == b.record["samples"]
    assert a.record["loop"]["kind"] == b.record["loop"]["kind"] == "python"
    assert a.trace.data.shape == b.trace.data.shape
    assert np.array_equal(a.trace.data, b.trace.data, equal_nan=True)  # bit for bit


def test_the_exchange_gives_the_three_calls_trace(plant_fmu: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    plant = check_plant(plant_fmu)
    through, three = _run(plant, monkeypatch, True), _run(plant, monkeypatch, False)
    assert through.complete and through.record["samples"] == 1001
    _same(through, three)


@pytest.mark.parametrize(
    ("kind", "status", "retried"),
    [("status", "4", False), ("status", "5", False), ("error", "3", True), ("nan", "0", False)],
)
def test_a_failing_plant_fails_alike_on_both_paths(
    shim_fmu: Path, monkeypatch: pytest.MonkeyPatch, kind: str, status: str, retried: bool
) -> None:
    """doStep answering Fatal (4), an undefined status (5) or Error (3, retried from the checkpoint,
    failing again), or the outputs turning NaN, from t = 0.1 s: the same reason (function,
    status, sample), rows and retries on both paths."""
    from fault_plants import fault_environment

    plant = check_plant(shim_fmu)
    for name, value in fault_environment(kind, 0.1, plant.references).items():
        if name.startswith("TOGGLE_FAULT"):
            monkeypatch.setenv(name, value)
    monkeypatch.setenv("TOGGLE_FAULT_STATUS", status)
    through, three = _run(plant, monkeypatch, True), _run(plant, monkeypatch, False)
    assert not through.complete
    if kind == "nan":
        assert through.reason.startswith("plant outputs became non-finite at t = 0.1005 s")
    else:
        assert "fmi2DoStep" in through.reason and through.reason.startswith("plant FMU failed at t = 0.1 s")
        assert ("Retried from the checkpoint" in through.reason) == retried
    _same(through, three)


# -- the exchange alone, over C callbacks that fail a chosen call at a chosen sample ----------
_VR, _DOUBLES = ctypes.POINTER(ctypes.c_uint32), ctypes.POINTER(ctypes.c_double)
_GET = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, _VR, ctypes.c_size_t, _DOUBLES)
_STEP = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int)
NAMES = FunctionNames(get="fmi2GetReal", set="fmi2SetReal", step="fmi2DoStep")


class FakePlant:
    """Two outputs (t, sum of inputs set) behind C function pointers; `fail` = (call, sample, status)."""

    def __init__(self, fail: tuple[str, int, int] | None) -> None:
        self.fail, self.t, self.sent, self.calls = fail, 0.0, 0.0, []
        self.get, self.set, self.step = _GET(self._get), _GET(self._set), _STEP(self._step)
        self.vr = (ctypes.c_uint32 * 3)(0, 1, 2)

    def _status(self, call: str, sample: int) -> int:
        self.calls.append((call, sample))
        return self.fail[2] if self.fail is not None and self.fail[:2] == (call, sample) else 0

    def _get(self, component, vr, n, values) -> int:
        status = self._status("get", round(self.t / 0.1))
        values[0], values[1] = self.t, self.sent
        return status

    def _set(self, component, vr, n, values) -> int:
        status = self._status("set", round(self.t / 0.1))
        if status == 0:
            self.sent = sum(values[j] for j in range(n))
        return status

    def _step(self, component, t, h, no_prior) -> int:
        status = self._status("step", round(t / 0.1))
        if status == 0:
            self.t = t + h
        return status

    def functions(self) -> CFunctions:
        pointers = (self.get, self.set, self.step)
        return CFunctions.of(pointers, 0, self.vr, self.vr, False, NAMES, self)


@pytest.mark.parametrize(
    ("call", "code", "function"),
    [
        ("set", PlantExchange.SET, "fmi2SetReal"),
        ("step", PlantExchange.STEP, "fmi2DoStep"),
        ("get", PlantExchange.GET, "fmi2GetReal"),
    ],
)
@pytest.mark.parametrize("status", [2, 3, 4, 5, -1])
def test_a_failed_call_is_named_with_its_status_and_nothing_after_it_is_made(
    call: str, code: int, function: str, status: int
) -> None:
    """Sample 3's call fails (get: the read of sample 4, made after sample 3's step): the
    exchange returns which call, `failure` is the session's FMICallException for it, no call
    follows it, and the row of sample 4 holds the outputs only if the read succeeded."""
    n = 6
    plant = FakePlant((call, 4 if call == "get" else 3, status))
    data = np.full((n + 1, 5), np.nan)
    load = np.arange(n + 1, dtype=np.float64).reshape(n + 1, 1) * 10.0
    exchange = PlantExchange(compiled_loop.kernel_library(), plant.functions(), data, 2, 3, n, 0.1, load)
    for k in range(n):
        result = exchange.call(exchange.pointer, k, 1.5, True)
        if result:
            break
    assert (k, result) == (3, code)
    failure = exchange.failure(result)
    assert str(failure) == str(FMICallException(function=function, status=status)) and failure.status == status
    assert plant.calls[-1][0] == call  # nothing after the failed call
    assert np.array_equal(data[1:4, 1:3], [[0.1 * j, 1.5 + 10.0 * (j - 1)] for j in (1, 2, 3)])
    assert np.all(np.isnan(data[4:, 1:3])) == (call != "get")  # a failed get writes what the FMU wrote

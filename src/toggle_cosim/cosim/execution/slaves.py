"""The components of a system as the master steps them (after libcosim's slaves): one small
interface, `Slave`, for an FMU (`FmuSlave`, FMI 2.0 or 3.0 Co-Simulation, whatever it models)
and for a controller of the protocol run natively (`ControllerSlave`: the built-in law, a
user's Python controller, a python-control system).

    instantiate(t_end) -> enter_initialization() -> [set, get]* -> exit_initialization()
    per sample t_k:  set(positions, values) -> get(values) -> set(...) -> do_step(t_k, T_s)
    at a checkpoint: save_state(); on a retry: restore_state()   (`cannot_save_state`: why not)
    close()

`set` takes positions in the slave's fed inputs (`Interface.inputs`, the plan's order) and their
values, `get` fills its outputs. An FMU's call that fails raises `SlaveError` naming the
component, the FMI function, the time and the FMU's last log line; after a fatal status the
FMU is not called again (FMI 2.0, 2.1.3). An FMU's outputs of other types than Real/Float64 (a
recorded Integer, Boolean, Enumeration: `Interface.typed`) are read by their own getters and
given as numbers (`fmi_pointers.typed_reads`).
"""

from __future__ import annotations

import contextlib
import copy
import ctypes
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple, NoReturn, Protocol

from toggle_cosim import interrupts
from toggle_cosim.control.protocol import Controller, ControllerError, Measurement, checked_command
from toggle_cosim.cosim.execution.fmi_pointers import (
    FMI2_NAMES,
    FMI3_NAMES,
    CFunctions,
    bound_function,
    fmu_functions,
    read_typed,
    typed_reads,
)
from toggle_cosim.cosim.execution.instance_pool import InstancePool, Kept
from toggle_cosim.cosim.execution.unzipped import release, unzipped
from toggle_cosim.messages import error_text
from toggle_cosim.plant.fmi_calls import (
    FATAL,
    FMU2SlaveChecked,
    FMU3SlaveChecked,
    failed,
    last_error_message,
    last_log_line,
    logger3,
    quiet,
    typed_setter,
)
from toggle_cosim.system.interfaces import FLOAT64_TYPES, fmu_interface
from toggle_cosim.system.model import Interface, Value

__all__ = ["ControllerSlave", "FmuSlave", "SampleState", "Slave", "SlaveError", "measured_not_finite"]


class SlaveError(Exception):
    """A component's call failed; str() names the component, the call and why. Where known:
    `component` (its name), `function` (the FMI call), `status` (what it returned) and `k` (the
    sample, set by the execution), which the checkpoint retries read (`system_retry`); `logged`
    what an FMU logged with a failing status about it (no label, one line), `retried` that it is
    a retry's failure, its message telling both, `not_finite` that a controller was refused a
    value it measures that is not finite (`measured_not_finite`)."""

    def __init__(
        self, message: str, component: str | None = None, function: str | None = None, status: object = None
    ) -> None:
        super().__init__(message)
        self.component, self.function, self.status = component, function, status
        self.k: int | None = None
        self.logged: str | None = None
        self.retried = False
        self.not_finite = False


def measured_not_finite(source: str, value: float, t: float, name: str, kind: str) -> SlaveError:
    """The error of a value that is not finite, from `source` (in words), which the controller
    `name` (a "native controller", a "controller FMU") would measure at t: it takes finite
    values only, so the run ends before it sees it (`not_finite`)."""
    error = SlaveError(
        f"{source} is {value} at t = {t:.6g} s, measured by the {kind} {name!r}, which takes finite values only", name
    )
    error.not_finite = True
    return error


class Slave(Protocol):
    name: str
    interface: Interface

    def instantiate(self, t_end: float) -> None: ...
    def enter_initialization(self) -> None: ...
    def exit_initialization(self) -> None: ...
    def set(self, positions: Sequence[int], values: Sequence[float], t: float) -> None: ...
    def get(self, values: Any, t: float) -> None: ...
    def do_step(self, t: float, h: float) -> None: ...
    def close(self) -> None: ...
    @property
    def cannot_save_state(self) -> str | None: ...
    def save_state(self) -> None: ...
    def restore_state(self) -> None: ...


class FmuSlave:
    """An FMU component (module docstring). `fmu` is the FMU as its check gave it: the plant's
    `PlantInterface`, a controller FMU's `ControllerFmu`, a part's `FmuArchive`
    (`plant.contract.read_fmu`), each a Co-Simulation FMU with its path, model description and
    SHA-256. `values` are set before initialisation, in order; `fed` are the inputs the plan
    feeds (`Plan.input_names`), `outputs` the variables it reads every sample
    (`Plan.output_names`), both set by `bind` before `instantiate`. `pool`: where its instance
    comes from and goes back to (`instance_pool`: kept loaded from run to run); None: loaded
    for this run and unloaded by `close`. `interface`: its connectors as the run's check found
    them (`checked.FmuComponent`); None: read from its model description here."""

    def __init__(
        self,
        name: str,
        fmu: Any,
        values: Sequence[tuple[str, Value]] = (),
        observed: Sequence[str] = (),
        pool: InstancePool | None = None,
        interface: Interface | None = None,
    ):
        self.name, self.path, self.values = name, Path(fmu.path), tuple(values)
        self.description, self.sha256 = fmu.model_description, fmu.sha256
        self.variables = {v.name: v for v in self.description.modelVariables}
        self.interface = interface if interface is not None else fmu_interface(self.description, observed)
        self.fmi3 = self.description.fmiVersion.startswith("3")
        self._slave: Any = None
        self._unzipped: Path | None = None
        self._fatal = False
        self._stepping = False
        self._reads: tuple = ()
        self._calls: CFunctions | None = None  # `c_functions`, bound once per instance
        self._instance = f"{name}"
        self._saved: Any = None  # the checkpoint: an fmi2FMUstate / fmi3FMUState (`save_state`)
        self.no_set_state_prior_to_current_point = False  # doStep's flag (`system_retry`)
        self.pool = pool
        self.bind(self.interface.inputs, self.interface.outputs)

    def bind(self, fed: Sequence[str], outputs: Sequence[str]) -> None:
        """The inputs the plan sets (by position) and the outputs it reads, in its order: those
        read by getReal / getFloat64 first, then those of other types (`fmu_interface`'s order)."""
        self._fed = tuple(fed)
        kinds = [self.variables[n].type for n in outputs]
        n_real = next((i for i, kind in enumerate(kinds) if kind not in FLOAT64_TYPES), len(kinds))
        if any(kind in FLOAT64_TYPES for kind in kinds[n_real:]):
            raise ValueError(f"component {self.name!r}: its Real outputs must come before those of other types")
        self._read = tuple(outputs[:n_real])
        self._typed = tuple(
            (i, self.variables[n].valueReference, kinds[i]) for i, n in enumerate(outputs) if i >= n_real
        )
        if self._slave is not None:
            self._reads = self._typed_reads()
        self._in_refs = tuple(self.variables[n].valueReference for n in fed)
        self._out_refs = tuple(self.variables[n].valueReference for n in self._read)
        self._in_vr = (ctypes.c_uint32 * max(len(fed), 1))(*self._in_refs)
        self._out_vr = (ctypes.c_uint32 * max(len(outputs), 1))(*self._out_refs)
        self._buffer = (ctypes.c_double * max(len(fed), 1))()
        self._vr_buffer = (ctypes.c_uint32 * max(len(fed), 1))()

    # -- life cycle ---------------------------------------------------------------------------
    def failure(self, function: str, t: float, status: int) -> SlaveError:
        """The error of the call `function` that returned `status` at t (a C loop's call too)."""
        return self._fail(function, t, status)

    def _fail(self, function: str, t: float | None, status: object) -> SlaveError:
        if status == FATAL:
            self._fatal = True
        line = last_log_line(self._instance)
        said = f"; it logged {' '.join(line.split())}" if line else ""
        at = f" at t = {t:.6g} s" if t is not None else ""
        error = SlaveError(
            f"component {self.name!r} ({self.path.name}): {function}{at} returned status {status}{said}",
            self.name,
            function,
            status,
        )
        error.logged = last_error_message(self._instance, forget=True)
        return error

    def _call(self, function: str, call: Any) -> None:
        try:
            call()
        except SlaveError:
            raise
        except Exception as error:  # noqa: BLE001 - fmpy's FMICallException, or a bad value
            raise self._fail(function, None, getattr(error, "status", error_text(error))) from None

    def instantiate(self, t_end: float) -> None:
        """Unzip (once for every instance of the FMU in this process: `unzipped`), load,
        instantiate, (FMI 2.0: setupExperiment) and set `values`. From a pool: its kept instance
        (reset after the last run: only the experiment and the values are set) or its loaded
        binary (instantiated anew), else loaded here."""
        kept = self.pool.take(self.sha256, self.name) if self.pool is not None else None
        slave = kept.slave if kept is not None else self._load()
        if kept is not None:
            self._unzipped = kept.folder
        self._slave = slave
        last_log_line(self._instance, forget=True)
        quiet(self._instance)
        if kept is not None and kept.instantiated:
            self.pool.counts.reset += 1
        else:
            if kept is not None:
                self.pool.counts.renewed += 1
            self._instantiate(slave)
        self._quiet_logging(slave)
        self.names = names = FMI3_NAMES if self.fmi3 else FMI2_NAMES
        self._set, self._get, self._step = (bound_function(slave.dll, n) for n in (names.set, names.get, names.step))
        if None in (self._set, self._get, self._step):
            raise SlaveError(
                f"component {self.name!r}: {self.path.name} does not export {names.set}, {names.get}, {names.step}"
            )
        self._reads = self._typed_reads()
        if self.fmi3:
            self._step_outputs = tuple(ctypes.byref(ctypes.c_bool()) for _ in range(3)) + (
                ctypes.byref(ctypes.c_double()),
            )
        self._t_end = t_end
        if not self.fmi3:
            self._call("fmi2SetupExperiment", lambda: slave.setupExperiment(startTime=0.0, stopTime=t_end))
        for name, value in self.values:
            self._set_value(name, value)

    def _load(self) -> Any:
        """fmpy's slave of this FMU: unzipped (`unzipped`), its binary loaded, no instance yet."""
        description = self.description
        self._unzipped = unzipped(self.path, self.sha256, description)
        kwargs = dict(
            unzipDirectory=str(self._unzipped),
            modelIdentifier=description.coSimulation.modelIdentifier,
            instanceName=self._instance,
            guid=description.guid if not self.fmi3 else description.instantiationToken,
        )
        try:  # fmpy loads the binary and binds every FMI function here
            slave = (FMU3SlaveChecked if self.fmi3 else FMU2SlaveChecked)(**kwargs)
        except Exception as error:  # noqa: BLE001 - a binary that does not load, or lacks a function
            raise SlaveError(
                f"component {self.name!r} ({self.path.name}): its binary could not be loaded ({error_text(error, 200)})"
            ) from None
        if self.pool is not None:
            self.pool.counts.loaded += 1
        return slave

    def _instantiate(self, slave: Any) -> None:
        """A new instance from the loaded binary."""
        if self.fmi3:
            self._call(
                "fmi3InstantiateCoSimulation",
                lambda: slave.instantiate(visible=False, loggingOn=True, logMessage=logger3(self._instance)),
            )
        else:
            self._call("fmi2Instantiate", lambda: slave.instantiate(visible=False, loggingOn=True))

    def _typed_reads(self) -> tuple:
        """The getters of the outputs of other types than Real (`fmi_pointers.typed_reads`)."""
        try:
            return typed_reads(self._slave, self._typed)
        except ValueError as error:
            raise SlaveError(f"component {self.name!r} ({self.path.name}): {error}") from None

    def _quiet_logging(self, slave: Any) -> None:
        """Logging stays on for what a failure's reason needs: where the FMU declares log
        categories, only those of non-OK statuses (the standard's logStatus*, or a name with
        Error or Warning in it), so an FMU that logs every step does not call back every step. A
        PythonFMU keeps its own logging (it logs only what its code logs, and the exception that
        fails a call under no category, which choosing categories would drop)."""
        categories = [c.name for c in getattr(self.description, "logCategories", None) or ()]
        chosen = [c for c in categories if c.startswith("logStatus") or "Error" in c or "Warning" in c]
        tool = str(getattr(self.description, "generationTool", "") or "")
        if tool.startswith("PythonFMU"):  # it logs a failure's cause under no category, which chosen ones drop
            return
        if categories and chosen:
            try:  # the others off by name, then those on (a shell may add to the categories it has)
                unwanted = [c for c in categories if c not in chosen]
                if unwanted:
                    slave.setDebugLogging(False, unwanted)
                slave.setDebugLogging(True, chosen)
            except Exception:  # noqa: BLE001, S110 - an FMU that refuses keeps its own logging
                pass

    def _set_value(self, name: str, value: Value) -> None:
        variable = self.variables.get(name)
        if variable is None:
            raise SlaveError(f"component {self.name!r}: {self.path.name} has no variable {name!r}")
        found = typed_setter(self._slave, variable.type, value)
        if found is None:
            raise SlaveError(f"component {self.name!r}: {name!r} is of type {variable.type}, which cannot be set")
        setter, value = found
        try:
            setter([variable.valueReference], [value])
        except Exception as error:  # noqa: BLE001 - name the variable and the value
            line = last_log_line(self._instance)
            said = f"; it logged {' '.join(line.split())}" if line else ""
            raise SlaveError(f"component {self.name!r}: setting {name} = {value!r} failed ({error}){said}") from None

    def enter_initialization(self) -> None:
        slave = self._slave
        if self.fmi3:
            self._call(
                "fmi3EnterInitializationMode",
                lambda: slave.enterInitializationMode(startTime=0.0, stopTime=self._t_end),
            )
        else:
            self._call("fmi2EnterInitializationMode", slave.enterInitializationMode)

    def exit_initialization(self) -> None:
        self._call(f"{'fmi3' if self.fmi3 else 'fmi2'}ExitInitializationMode", self._slave.exitInitializationMode)
        self._stepping = True
        self._calls = None
        with contextlib.suppress(ValueError):  # a library that lacks one: said when a C loop asks
            self.c_functions()

    def close(self, reuse: bool = False) -> None:
        """Terminate and free the instance (not after a fatal status), give back the unzipped
        copy (removed with its last user). With a pool: the instance goes back to it, reset
        when `reuse` (a complete run) and the FMU accepts terminate and reset, else freed with
        its binary kept loaded (`instance_pool`)."""
        slave, self._slave, self._calls = self._slave, None, None
        folder, self._unzipped = self._unzipped, None
        try:
            if slave is not None and not self._fatal and self.pool is not None and folder is not None:
                self._free_state(slave)
                instantiated = reuse and self._reset(slave)
                if not instantiated:
                    self._free_instance(slave)
                if not self._fatal:
                    self.pool.give_back(self.sha256, self.name, Kept(slave, folder, instantiated))
                    folder = None  # the pool holds it now
            elif slave is not None and not self._fatal:
                self._free_state(slave)
                if self._stepping:  # terminate is not allowed before initialisation has ended
                    try:
                        slave.terminate()
                    except Exception:  # noqa: BLE001, S110 - an FMU in error state may refuse terminate
                        pass
                slave.freeInstance()
        except Exception:  # noqa: BLE001, S110 - freeing never changes a run's outcome
            pass
        finally:
            if self._fatal and self.pool is not None:  # FMI: no further call to that binary
                self.pool.fatal = True
            if folder is not None:
                release(folder)
            last_log_line(self._instance, forget=True)
            quiet(self._instance, on=False)

    def _reset(self, slave: Any) -> bool:
        """Terminate and reset the instance for the next run (True), or False: not initialised,
        or the FMU refused either call (a Fatal answer marks the FMU fatal)."""
        if not self._stepping:
            return False
        try:
            slave.terminate()
            slave.reset()
        except Exception as error:  # noqa: BLE001 - an FMU that cannot reset gets a new instance
            self._fatal = getattr(error, "status", None) == FATAL
            return False
        return True

    def _free_instance(self, slave: Any) -> None:
        """Terminate (when initialised) and free the instance; the binary stays loaded. Never raises."""
        if self._fatal or slave.component is None:
            return
        if self._stepping:
            try:
                slave.terminate()
            except Exception:  # noqa: BLE001, S110 - an FMU in error state may refuse terminate
                pass
        try:
            (slave.fmi3FreeInstance if self.fmi3 else slave.fmi2FreeInstance)(slave.component)
        except Exception:  # noqa: BLE001, S110 - freeing never changes a run's outcome
            pass
        slave.component = None

    def solver_statistics(self) -> dict[str, int] | str:
        """The FMU's solver counts read now (`plant.solver_statistics`: the plant's integrator's,
        what a work budget counts), or why there are none; run.json's `solver_statistics`."""
        from toggle_cosim.plant.solver_statistics import NOT_EXPOSED, read_solver_statistics

        if self._slave is None:
            return NOT_EXPOSED
        try:
            return read_solver_statistics(self._slave, self.description)
        except Exception as error:  # noqa: BLE001 - a run's record never fails for its statistics
            return f"unreadable ({error})"

    # -- checkpoints (FMI "get/set FMU state") --------------------------------------------------
    @property
    def cannot_save_state(self) -> str | None:
        """None when the FMU can save and restore its state, else why not (run.json)."""
        if self.description.coSimulation.canGetAndSetFMUstate:
            return None
        flag = "canGetAndSetFMUState" if self.fmi3 else "canGetAndSetFMUstate"
        return f"component {self.name!r} ({self.path.name}) cannot save its state (its FMU does not declare {flag})"

    def save_state(self) -> None:
        """Keep the FMU's whole state as the checkpoint (one state, updated in place)."""
        slave, saved = self._slave, self._saved
        if saved is None:
            saved = self._saved = ctypes.c_void_p()
        name = "fmi3GetFMUState" if self.fmi3 else "fmi2GetFMUstate"
        self._call(name, lambda: getattr(slave, name)(slave.component, ctypes.byref(saved)))

    def restore_state(self) -> None:
        """Put the FMU back to the checkpoint (also out of a Discard or Error state)."""
        slave, saved = self._slave, self._saved
        if saved is None:
            raise SlaveError(f"component {self.name!r}: no checkpoint to restore", self.name)
        name = "fmi3SetFMUState" if self.fmi3 else "fmi2SetFMUstate"
        self._call(name, lambda: getattr(slave, name)(slave.component, saved))

    def _free_state(self, slave: Any) -> None:
        saved, self._saved = self._saved, None
        if saved is not None and saved.value is not None:
            try:
                (slave.fmi3FreeFMUState if self.fmi3 else slave.fmi2FreeFMUstate)(slave.component, ctypes.byref(saved))
            except Exception:  # noqa: BLE001, S110 - freeInstance releases it in any case
                pass

    # -- the hot calls --------------------------------------------------------------------------
    def set(self, positions: Sequence[int], values: Sequence[float], t: float) -> None:
        n = len(positions)
        if not n:
            return
        vr, buffer, own = self._vr_buffer, self._buffer, self._in_vr
        for j, (i, value) in enumerate(zip(positions, values, strict=True)):
            vr[j], buffer[j] = own[i], value
        status = (
            self._set(self._slave.component, vr, n, buffer, n)
            if self.fmi3
            else self._set(self._slave.component, vr, n, buffer)
        )
        if failed(status):
            raise self._fail(self.names.set, t, status)

    def get(self, values: Any, t: float) -> None:
        """Read the outputs into `values` (a ctypes double array of len(outputs)): the Real ones
        in one getReal / getFloat64, then each of another type by its getter, as a number."""
        n = len(self._read)
        component = self._slave.component
        if n:
            status = (
                self._get(component, self._out_vr, n, values, n)
                if self.fmi3
                else self._get(component, self._out_vr, n, values)
            )
            if failed(status):
                raise self._fail(self.names.get, t, status)
        for read in self._reads:
            status, value = read_typed(read, component, self.fmi3)
            if failed(status):
                raise self._fail(read.name, t, status)
            values[read.position] = value

    def do_step(self, t: float, h: float) -> None:
        component = self._slave.component
        status = (
            self._step(component, t, h, self.no_set_state_prior_to_current_point, *self._step_outputs)
            if self.fmi3
            else self._step(component, t, h, 1 if self.no_set_state_prior_to_current_point else 0)
        )
        if failed(status):
            raise self._fail(self.names.step, t, status)

    def c_functions(self) -> CFunctions:
        """What a C loop calls (`fmi_pointers.fmu_functions`): the three functions, the instance,
        the value references of its outputs and fed inputs, in the plan's order; bound once per
        instance (as it leaves initialisation, `exit_initialization`), so a C loop that runs
        it finds them ready."""
        if self._calls is None:
            self._calls = fmu_functions(
                self._slave, self._out_refs, self._in_refs, self._reads, (self._get, self._set, self._step)
            )
        return self._calls


class SampleState(NamedTuple):
    """What a `ControllerSlave` holds between two calls: the controller's state and the state its
    last computation gave (`next`, committed by the next doStep), its outputs held (the command,
    then the diagnostics), its fed inputs as set (`row`, in the plan's order), whether they were
    set since that computation (`dirty`) and whether its start has run. The compiled system loop
    (`cosim.execution.system_natives`) takes it over to run the controller natively in C and gives
    it back, at every checkpoint: a named tuple, the cheapest immutable record to make."""

    state: Any
    next: Any
    held: tuple[float, ...]
    row: tuple[float, ...]
    dirty: bool
    started: bool


class ControllerSlave:
    """A controller of the protocol (`control.protocol`) as a component: its inputs are the
    variables it measures (`controller.measured`), its outputs the command and its diagnostics,
    each depending directly on every input. It samples as a sampled-data controller FMU does: the
    step is computed from the inputs as set, at the time they were last used (`get` after a
    `set`, else `do_step` at its start), and `get` without a new `set` returns the held outputs;
    `do_step` keeps the state that step returned. Its start runs at the first computation.

    What it measures must be finite: a value that is not (NaN, an infinity) ends the run naming
    the output it came from (`fed_from`) and the time, as the pair ends a run whose x_B or v_B is
    not finite. Its checkpoint is the protocol's state and what it holds (a deep copy), so it can
    be put back like an FMU; a state that cannot be copied stops the checkpoints."""

    def __init__(
        self,
        name: str,
        controller: Controller,
        diagnostics: Sequence[str],
        interface: Interface,
    ):
        """`interface`: its connectors as the run's check found them (`checked.NativeComponent`):
        its inputs the names it declares it measures (`measured`), else the plant's outputs
        (which its measurement holds in the plant + controller loop), its outputs the command
        and `diagnostics`, in the units of the plant's variables of their names; its measurement
        holds those fed."""
        self.name, self.controller = name, controller
        self.interface = interface
        measured, outputs = interface.inputs, interface.outputs
        self.bind(measured, outputs)
        self._state: Any = None
        self._next: Any = None
        self._held: tuple[float, ...] = (0.0,) * len(outputs)
        self._started = False
        self._dirty = True
        self._n_diagnostics = len(diagnostics)
        self._sources = tuple(f"input {name}" for name in measured)
        self._saved: tuple | None = None
        self._changes = 0  # how many times what it holds has changed (`changes`)

    @property
    def changes(self) -> int:
        """A count that moves whenever what it holds changes: equal counts, the same holding."""
        return self._changes

    def bind(self, fed: Sequence[str], outputs: Sequence[str]) -> None:
        """Its measurement holds the fed inputs only, in the plan's order: reading another raises KeyError."""
        self._index = {name: i for i, name in enumerate(fed)}
        self._row = [0.0] * len(fed)
        self._every = tuple(range(len(fed)))  # positions that set every fed input, in order
        self._measurement = Measurement(self._index, self._row)  # the view the controller is given, over `_row`
        self._sources = tuple(f"input {name}" for name in fed)
        self._changes = getattr(self, "_changes", 0) + 1

    def fed_from(self, sources: Sequence[str]) -> None:
        """What feeds each fed input, in words (e.g. "component 'plant': its output x_B"), for
        the error of a value that is not finite."""
        self._sources = tuple(sources)

    def instantiate(self, t_end: float) -> None:
        pass

    def enter_initialization(self) -> None:
        pass

    def exit_initialization(self) -> None:
        pass

    def set(self, positions: Sequence[int], values: Sequence[float], t: float) -> None:
        """Set the fed inputs at `positions` to `values`; a value that is not finite is refused
        (SlaveError naming its source, `not_finite`), the first in the positions' order. Every
        input at once (a Python controller's sample) is one check and one copy: their sum is
        finite only when every one is (a NaN or an infinity makes it NaN or infinite), and only a
        sum that is not (one of them is not finite, or finite ones overflowed) looks at each."""
        row, isfinite = self._row, math.isfinite
        if len(values) == len(row) and positions == self._every:
            total = sum(values)
            if total - total != 0.0 and not all(map(isfinite, values)):
                self._refuse(positions, values, t)
            row[:] = values
        else:
            for i, value in zip(positions, values, strict=True):
                if not isfinite(value):
                    self._refuse(positions, values, t)
                row[i] = value
        self._dirty = True
        self._changes += 1

    def _refuse(self, positions: Sequence[int], values: Sequence[float], t: float) -> NoReturn:
        """Raise the error of the first value that is not finite, naming its source."""
        i, value = next((i, v) for i, v in zip(positions, values, strict=True) if not math.isfinite(v))
        raise measured_not_finite(self._sources[i], value, t, self.name, "native controller")

    @property
    def cannot_save_state(self) -> str | None:
        """None: its state can be kept (`save_state` may still find it cannot be copied)."""
        return None

    def save_state(self) -> None:
        """Keep a deep copy of the controller's state, with its held outputs and its inputs as set
        (numbers, copied as they are)."""
        try:
            states = copy.deepcopy((self._state, self._next))
            self._saved = (*states, tuple(self._held), self._started, self._dirty, tuple(self._row))
        except Exception as error:  # noqa: BLE001 - a state that cannot be copied: no checkpoint
            raise SlaveError(
                f"component {self.name!r} cannot save its state (its controller's state cannot be copied:"
                f" {error_text(error, 200)})",
                self.name,
            ) from None

    def restore_state(self) -> None:
        if self._saved is None:
            raise SlaveError(f"component {self.name!r}: no checkpoint to restore", self.name)
        state, following, held, started, dirty, row = self._saved
        self._state, self._next = copy.deepcopy((state, following))
        self._held, self._started, self._dirty = held, started, dirty
        self._row[:] = row
        self._changes += 1

    def _fail(self, what: str, t: float, error: BaseException) -> SlaveError:
        if not interrupts.raised_by_code(error):
            raise error
        return SlaveError(
            f"component {self.name!r}: the controller's {what} raised at t = {t:.6g} s: {error_text(error, 300)}"
        )

    def _compute(self, t: float) -> None:
        """The step at t from the inputs as set: the held outputs and the pending state."""
        self._changes += 1
        measurement = self._measurement
        if not self._started:
            try:
                self._state = self.controller.start(t, measurement)
            except BaseException as error:  # noqa: BLE001 - the user's code: its failure ends the run
                raise self._fail("start", t, error) from None
            self._started = True
        try:
            result = self.controller.step(self._state, t, measurement)
        except BaseException as error:  # noqa: BLE001 - the user's code
            raise self._fail("step", t, error) from None
        try:
            u, diagnostics, self._next = checked_command(result, self._n_diagnostics, t)
        except ControllerError as error:
            raise SlaveError(f"component {self.name!r}: {error}") from None
        self._held = (u, *diagnostics)
        self._dirty = False

    def sample_state(self) -> SampleState:
        """What it holds now (`SampleState`)."""
        return SampleState(self._state, self._next, self._held, tuple(self._row), self._dirty, self._started)

    def resume(self, held: SampleState) -> None:
        """Hold `held` from now on (the compiled loop's controller given back, `SampleState`)."""
        self._state, self._next, self._held = held.state, held.next, tuple(held.held)
        self._row[:] = held.row
        self._dirty, self._started = held.dirty, held.started
        self._changes += 1

    def get(self, values: Any, t: float) -> None:
        if self._dirty:
            self._compute(t)
        held = self._held
        values[: len(held)] = held

    def do_step(self, t: float, h: float) -> None:
        if self._dirty:
            self._compute(t)
        self._state = self._next
        self._changes += 1

    def close(self) -> None:
        close = getattr(self.controller, "close", None)
        if callable(close):
            try:
                close()
            except BaseException as error:  # noqa: BLE001 - freeing never changes the outcome
                if not interrupts.raised_by_code(error):
                    raise


def values_of(mapping: Mapping[str, Value]) -> tuple[tuple[str, Value], ...]:
    return tuple(mapping.items())

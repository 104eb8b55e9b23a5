"""What the master asks of every FMI call, beyond what fmpy checks.

* A status is a success only when it is OK (0) or Warning (1). fmpy raises for a status above
  Warning; a value the standard does not define (a negative one, or 5 from an FMI 3.0 FMU or a
  Co-Simulation FMU that was not asked to run asynchronously) would pass as success. Here it
  fails, in the hot calls (`failed`), in every other call fmpy makes (`FMU2SlaveChecked`,
  `FMU3SlaveChecked`) and in the compiled system loop (`cosim/execution/system_skeleton.c`, the same rule in C).
* An FMU's log message is printed `[LABEL] message` as fmpy prints it, but decoded with
  replacement (a message that is not UTF-8 is still shown) and with a label for any status
  (`[STATUS 7]`): fmpy's own logger raises inside the callback for both, and the message is lost.
  The last line each instance logged is kept (`last_log_line`), and the text of the last one it
  logged with a failing status (Discard, Error, Fatal: `last_error_message`), for a failure's reason.
"""

from __future__ import annotations

import ctypes
import functools
import inspect
import sys
from typing import Any

from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi3 import FMU3Slave

SUCCESS = (0, 1)  # fmi2OK/fmi3OK, fmi2Warning/fmi3Warning
LABELS = ("OK", "WARNING", "DISCARD", "ERROR", "FATAL", "PENDING")
FATAL = LABELS.index("FATAL")  # fmi2Fatal, fmi3Fatal: no further call to any instance of the FMU


SETTERS = {  # fmpy's setter per FMI type, FMI 2.0 then 3.0
    "Real": "setReal",
    "Float64": "setFloat64",
    "Float32": "setFloat32",
    "Integer": "setInteger",
    "Int32": "setInt32",
    "Int64": "setInt64",
    "Enumeration": "setInteger",
    "Boolean": "setBoolean",
    "String": "setString",
}


def typed_setter(slave: Any, kind: str, value: Any) -> tuple[Any, Any] | None:
    """fmpy's setter on `slave` for a variable of FMI type `kind`, and `value` as that type takes
    it (bool, int, float, or UTF-8 bytes); None when the type cannot be set."""
    setter = getattr(slave, SETTERS.get(kind, ""), None)
    if setter is None:
        return None
    if kind == "Boolean":
        return setter, bool(value)
    if kind == "String":
        return setter, str(value).encode("utf-8")
    if kind in ("Integer", "Int32", "Int64", "Enumeration"):
        return setter, int(value)
    return setter, float(value)


def failed(status: int) -> bool:
    """True for every status but OK and Warning, including values the standard does not define."""
    return status not in SUCCESS


def log_line(status: int, message: bytes | str | None) -> str:
    """`[LABEL] message`, whatever the status and the bytes of the message."""
    label = LABELS[status] if isinstance(status, int) and 0 <= status < len(LABELS) else f"STATUS {status}"
    if isinstance(message, bytes):
        text = message.decode("utf-8", errors="replace")
    else:
        text = "" if message is None else str(message)
    return f"[{label}] {text}"


_LAST: dict[str, str] = {}  # instance name -> the last line it logged
_QUIET: set[str] = set()  # instance names whose OK-status messages are dropped
_LAST_ERROR: dict[str, str] = {}  # instance name -> the text of the last failing-status line it logged


def quiet(instance: str, on: bool = True) -> None:
    """Drop (on) or keep (off) the OK-status messages of the instance named `instance`: an FMU
    instantiated with logging on to learn a failure's cause may report every step."""
    if on:
        _QUIET.add(instance)
    else:
        _QUIET.discard(instance)


def _print(status: int, message: bytes | str | None, instance: Any = None) -> None:
    try:
        name = None
        if instance is not None:
            name = instance.decode("utf-8", errors="replace") if isinstance(instance, bytes) else str(instance)
            if status == 0 and name in _QUIET:
                return
        line = log_line(status, message)
        if name is not None:
            if len(_LAST) > 64 and name not in _LAST:
                _LAST.clear()  # names of instances long gone
                _LAST_ERROR.clear()
            _LAST[name] = line
            if failed(status) and status != 5:  # not Pending (an asynchronous call still running)
                _LAST_ERROR[name] = " ".join(line.split("] ", 1)[-1].split())
        sys.stdout.write(line + "\n")
    except Exception:  # noqa: BLE001, S110 - a log line never fails the FMU's call
        pass


def last_log_line(instance: str, forget: bool = False) -> str | None:
    """The last line the FMU instance named `instance` logged (FMI 2.0, or FMI 3.0 instantiated
    with `logger3(instance)`), or None; `forget` drops it (and its `last_error_message`)."""
    if forget:
        _LAST_ERROR.pop(instance, None)
        return _LAST.pop(instance, None)
    return _LAST.get(instance)


def last_error_message(instance: str, forget: bool = False) -> str | None:
    """The text (no label, on one line) of the last message the instance named `instance` logged
    with a failing status (Discard, Error, Fatal), or None; `forget` drops it. A plant's failure
    reason ends with it: what the FMU said went wrong, not only its status."""
    return _LAST_ERROR.pop(instance, None) if forget else _LAST_ERROR.get(instance)


def _log2(_environment: Any, instance: Any, status: int, _category: Any, message: Any) -> None:
    _print(status, message, instance)


def _log3(_environment: Any, status: int, _category: Any, message: Any) -> None:
    _print(status, message)


def logger3(instance: str) -> Any:
    """An FMI 3.0 log-message callback (for fmpy's instantiate) that prints as `_log3` does and
    keeps the last line under `instance` (FMI 3.0 callbacks do not get the instance's name)."""

    def log(_environment: Any, status: int, _category: Any, message: Any) -> None:
        _print(status, message, instance)

    return log


@functools.cache
def _logger2() -> Any:
    """Our FMI 2.0 logger as a C function pointer, made once per process and kept: the C proxy
    that formats a message keeps a pointer to it, so it must outlive every FMU that may log."""
    return fmi2CallbackLoggerTYPE(_log2)


def fmi2_callbacks() -> fmi2CallbackFunctions:
    """fmpy's default FMI 2.0 callbacks (its allocator, its formatting proxy) with our logger, for
    one instance (which keeps them). fmpy's formatting proxy keeps one process-wide pointer to
    the logger behind it, which any FMU instantiated with fmpy's own callbacks re-points: making
    the callbacks anew at each instantiation points it at ours again, so an FMU's messages are
    never lost to a logger set up by other code in the process."""
    from fmpy.fmi2 import defaultCallbacks
    from fmpy.logging import addLoggerProxy

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = _logger2()
    callbacks.allocateMemory = defaultCallbacks.allocateMemory
    callbacks.freeMemory = defaultCallbacks.freeMemory
    addLoggerProxy(ctypes.byref(callbacks))  # formats the variadic message in C, then calls _log2
    return callbacks


def _checking(method: Any) -> Any:
    """fmpy's method for one FMI function, raising for every status but OK and Warning."""

    @functools.wraps(method)  # fmpy reads the C prototype from the signature: wraps keeps it
    def call(self: Any, *args: Any) -> Any:
        status = method(self, *args)  # fmpy has raised already for a status above Warning
        if isinstance(status, int) and failed(status):
            raise FMICallException(function=method.__name__, status=status)
        return status

    return call


def _checked(base: type) -> dict[str, Any]:
    """Checking versions of `base`'s methods for the FMI functions that return a status."""
    prefix = "fmi" + base.__name__[3]  # FMU2Slave: "fmi2", FMU3Slave: "fmi3"
    methods = {}
    for name in dir(base):
        method = getattr(base, name)
        if name.startswith(prefix) and callable(method) and inspect.signature(method).return_annotation is int:
            methods[name] = _checking(method)
    return methods


def _instantiate2(self: Any, visible: bool = False, callbacks: Any = None, loggingOn: bool = False) -> None:  # noqa: N803
    chosen = callbacks if callbacks is not None else fmi2_callbacks()
    FMU2Slave.instantiate(self, visible=visible, callbacks=chosen, loggingOn=loggingOn)


def _instantiate3(self: Any, *args: Any, logMessage: Any = None, **kwargs: Any) -> None:  # noqa: N803
    FMU3Slave.instantiate(self, *args, logMessage=logMessage or _log3, **kwargs)


# fmpy finds an FMU class's functions by the class name's prefix: these names start "FMU2"/"FMU3".
FMU2SlaveChecked = type("FMU2SlaveChecked", (FMU2Slave,), {**_checked(FMU2Slave), "instantiate": _instantiate2})
FMU3SlaveChecked = type("FMU3SlaveChecked", (FMU3Slave,), {**_checked(FMU3Slave), "instantiate": _instantiate3})


__all__ = [
    "FMU2SlaveChecked",
    "FMU3SlaveChecked",
    "failed",
    "last_error_message",
    "last_log_line",
    "log_line",
    "logger3",
    "quiet",
]

"""What C needs to call an FMU loaded by fmpy: its getReal / setReal / doStep functions (FMI 2.0)
or getFloat64 / setFloat64 / doStep (FMI 3.0) with their FMI prototypes, its instance, and the
value references of the variables the caller reads and sets (`CFunctions`), each function bound
from the FMU's library with its FMI prototype (`bound_function`) and called directly, without
fmpy's wrapper.

`fmu_functions` makes one from any instantiated fmpy `FMU2Slave` or `FMU3Slave` (fmpy's checked
subclasses of `plant.fmi_calls` included): a system's FMU components (`slaves.FmuSlave`) hand
themselves to the compiled system loop (`system_loop`) this way, and take the FMI function names
from here.

A variable of another type that a system records (`record:` an Integer, a Boolean, an
Enumeration; FMI 3.0 also the sized integers and Float32) is read by its own getter, one value
at a time (`TypedRead`, `typed_reads`): fmi2GetInteger / fmi2GetBoolean, fmi3GetInt8 ...
fmi3GetBoolean, fmi3GetFloat32. Its value is recorded as a number, the C conversion of that
type to double (a Boolean as 0 or 1), the same in the Python execution (`read_typed`) and the
compiled loop (`system_skeleton.c`, whose kind codes are `KINDS`' here).
"""

from __future__ import annotations

import ctypes
import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from fmpy.fmi3 import FMU3Slave

__all__ = [
    "CFunctions",
    "FunctionNames",
    "FMI2_NAMES",
    "FMI3_NAMES",
    "RECORDED_TYPES",
    "TypedRead",
    "bound_function",
    "fmu_functions",
    "is_fmi3",
    "read_typed",
    "typed_reads",
]

_VR, _DOUBLES = ctypes.POINTER(ctypes.c_uint32), ctypes.POINTER(ctypes.c_double)
_BOOL_OUT = ctypes.POINTER(ctypes.c_bool)
# The FMI prototypes of the three hot functions (fmi2FunctionTypes.h, fmi3FunctionTypes.h).
_PROTOTYPES = {
    "fmi2GetReal": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, _VR, ctypes.c_size_t, _DOUBLES),
    "fmi2SetReal": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, _VR, ctypes.c_size_t, _DOUBLES),
    "fmi2DoStep": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int),
    "fmi3GetFloat64": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, _VR, ctypes.c_size_t, _DOUBLES, ctypes.c_size_t),
    "fmi3SetFloat64": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, _VR, ctypes.c_size_t, _DOUBLES, ctypes.c_size_t),
    "fmi3DoStep": ctypes.CFUNCTYPE(
        ctypes.c_int,
        ctypes.c_void_p,
        ctypes.c_double,
        ctypes.c_double,
        ctypes.c_bool,
        _BOOL_OUT,
        _BOOL_OUT,
        _BOOL_OUT,
        _DOUBLES,
    ),
}


def bound_function(dll: Any, name: str):  # noqa: ANN201 - a ctypes function pointer, or None
    """The FMU library's exported C function `name` (fmi2GetReal, fmi3DoStep, ...) with its FMI
    prototype, called directly (no fmpy wrapper), or None if the library does not export it."""
    try:
        return _PROTOTYPES[name]((name, dll))
    except (AttributeError, TypeError):
        return None


@dataclass(frozen=True)
class FunctionNames:
    """The FMI names of the hot functions, for error messages (fmi2GetReal / fmi3GetFloat64, ...)."""

    get: str
    set: str
    step: str


@dataclass(frozen=True)
class CFunctions:
    """What the compiled loop needs to call the FMU from C: addresses of the three functions,
    the instance, and the value-reference arrays (kept alive by `owner`)."""

    get: int
    set: int
    step: int
    component: int
    out_vr: int
    in_vr: int
    fmi3: bool
    names: FunctionNames
    owner: Any
    reads: tuple[Any, ...] = ()  # a system's typed reads after the Real outputs (`fmi_pointers.TypedRead`)

    @classmethod
    def of(
        cls,
        functions: tuple[Any, Any, Any],
        component: int,
        out_vr: Any,
        in_vr: Any,
        fmi3: bool,
        names: FunctionNames,
        holder: object = None,
    ) -> CFunctions:
        """From the bound (get, set, step) functions (`bound_function`), the instance and the
        value-reference arrays (ctypes arrays), all kept alive by the result (and `holder`, the
        object that owns them)."""
        get, set_, step = (ctypes.cast(f, ctypes.c_void_p).value for f in functions)
        return cls(
            get=get,
            set=set_,
            step=step,
            component=component,
            out_vr=ctypes.addressof(out_vr),
            in_vr=ctypes.addressof(in_vr),
            fmi3=fmi3,
            names=names,
            owner=(holder, functions, out_vr, in_vr),
        )


FMI2_NAMES = FunctionNames(get="fmi2GetReal", set="fmi2SetReal", step="fmi2DoStep")
FMI3_NAMES = FunctionNames(get="fmi3GetFloat64", set="fmi3SetFloat64", step="fmi3DoStep")


# (FMI version's first digit, the variable's type) -> (the getter, the kind code of
# system_skeleton.c's get_typed, the C type of its values)
KINDS: dict[tuple[str, str], tuple[str, int, Any]] = {
    ("2", "Integer"): ("fmi2GetInteger", 0, ctypes.c_int),
    ("2", "Enumeration"): ("fmi2GetInteger", 0, ctypes.c_int),
    ("2", "Boolean"): ("fmi2GetBoolean", 0, ctypes.c_int),  # fmi2Boolean is an int
    ("3", "Int8"): ("fmi3GetInt8", 1, ctypes.c_int8),
    ("3", "UInt8"): ("fmi3GetUInt8", 2, ctypes.c_uint8),
    ("3", "Int16"): ("fmi3GetInt16", 3, ctypes.c_int16),
    ("3", "UInt16"): ("fmi3GetUInt16", 4, ctypes.c_uint16),
    ("3", "Int32"): ("fmi3GetInt32", 5, ctypes.c_int32),
    ("3", "UInt32"): ("fmi3GetUInt32", 6, ctypes.c_uint32),
    ("3", "Int64"): ("fmi3GetInt64", 7, ctypes.c_int64),
    ("3", "Enumeration"): ("fmi3GetInt64", 7, ctypes.c_int64),
    ("3", "UInt64"): ("fmi3GetUInt64", 8, ctypes.c_uint64),
    ("3", "Boolean"): ("fmi3GetBoolean", 9, ctypes.c_bool),
    ("3", "Float32"): ("fmi3GetFloat32", 10, ctypes.c_float),
}
RECORDED_TYPES = frozenset(kind for _, kind in KINDS) | {"Real", "Float64"}  # what `record:` can take


@dataclass(frozen=True)
class TypedRead:
    """One recorded variable of another type than Real/Float64: its getter (name, address and a
    ctypes function to call it from Python), its value reference, the kind code the C loop
    switches on, its position among the component's outputs, and one-value buffers for the
    value reference and the value."""

    name: str
    address: int
    function: Any
    vr: int
    kind: int
    position: int
    vrs: Any
    value: Any


def typed_reads(slave: Any, variables: Sequence[tuple[int, int, str]]) -> tuple[TypedRead, ...]:
    """The typed reads of the instantiated fmpy slave for `variables`, each (position among the
    outputs, value reference, FMI type). ValueError (one line) for a type no getter reads, or a
    library that does not export the getter."""
    version = "3" if is_fmi3(slave) else "2"
    found = []
    for position, vr, kind in variables:
        known = KINDS.get((version, kind))
        if known is None:
            raise ValueError(
                f"a variable of type {kind} is not recorded (record Real, Integer, Boolean or Enumeration)"
            )
        name, code, c_type = known
        arguments = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_uint32), ctypes.c_size_t, ctypes.POINTER(c_type)]
        if version == "3":
            arguments.append(ctypes.c_size_t)
        try:
            raw = getattr(slave.dll, name)
        except AttributeError:
            raise ValueError(f"its library does not export {name}") from None
        address = ctypes.cast(raw, ctypes.c_void_p).value
        function = ctypes.CFUNCTYPE(ctypes.c_int, *arguments)(address)
        found.append(TypedRead(name, address, function, vr, code, position, (ctypes.c_uint32 * 1)(vr), (c_type * 1)()))
    return tuple(found)


def read_typed(read: TypedRead, component: Any, fmi3: bool) -> tuple[int, float]:
    """Call `read`'s getter for its one value on the instance `component`: (status, the value as
    a float: C's conversion of its type to double)."""
    vrs, value = read.vrs, read.value
    status = read.function(component, vrs, 1, value, 1) if fmi3 else read.function(component, vrs, 1, value)
    return status, float(read.value[0])


def is_fmi3(slave: Any) -> bool:
    """Whether the fmpy slave is an FMI 3.0 one (else FMI 2.0)."""
    return isinstance(slave, FMU3Slave)


def fmu_functions(
    slave: Any,
    outputs: Sequence[int],
    inputs: Sequence[int],
    reads: Sequence[TypedRead] = (),
    bound: tuple[Any, Any, Any] | None = None,
) -> CFunctions:
    """The C calls of an instantiated fmpy FMU2Slave / FMU3Slave that reads the Real (Float64)
    variables of value references `outputs` and sets those of `inputs`, in those orders, and
    makes the typed `reads` (`typed_reads`: other types, after the Real outputs); `bound`: its
    (get, set, step) already bound (`bound_function`), else bound here.
    ValueError (one line) when it is not instantiated or its library lacks one of the three
    functions. The result keeps the slave and its arrays alive."""
    names = FMI3_NAMES if is_fmi3(slave) else FMI2_NAMES
    component = getattr(slave, "component", None)
    if component is None:
        raise ValueError(f"{getattr(slave, 'instanceName', 'the FMU')}: not instantiated, so it has no C calls yet")
    functions = bound or tuple(bound_function(slave.dll, name) for name in (names.get, names.set, names.step))
    missing = [name for name, f in zip((names.get, names.set, names.step), functions, strict=True) if f is None]
    if missing:
        raise ValueError(
            f"{getattr(slave, 'instanceName', 'the FMU')}: its library does not export {', '.join(missing)}"
        )
    out_vr = (ctypes.c_uint32 * max(len(outputs), 1))(*outputs)
    in_vr = (ctypes.c_uint32 * max(len(inputs), 1))(*inputs)
    address = component if isinstance(component, int) else ctypes.cast(component, ctypes.c_void_p).value
    calls = CFunctions.of(functions, address, out_vr, in_vr, is_fmi3(slave), names, slave)  # type: ignore[arg-type]
    return dataclasses.replace(calls, reads=tuple(reads))

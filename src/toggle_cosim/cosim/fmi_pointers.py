"""What C needs to call an FMU loaded by fmpy: its getReal / setReal / doStep functions (FMI 2.0)
or getFloat64 / setFloat64 / doStep (FMI 3.0) with their FMI prototypes, its instance, and the
value references of the variables the caller reads and sets (`CFunctions`).

`fmu_functions` makes one from any instantiated fmpy `FMU2Slave` or `FMU3Slave` (fmpy's checked
subclasses of `plant.fmi_calls` included): a system's FMU components (`slaves.FmuSlave`) hand
themselves to the compiled system loop (`system_loop`) this way, and take the FMI function names
from here.
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence
from typing import Any

from fmpy.fmi3 import FMU3Slave

from toggle_cosim.cosim.session import CFunctions, FunctionNames, bound_function

__all__ = ["FMI2_NAMES", "FMI3_NAMES", "fmu_functions", "is_fmi3"]

FMI2_NAMES = FunctionNames(get="fmi2GetReal", set="fmi2SetReal", step="fmi2DoStep")
FMI3_NAMES = FunctionNames(get="fmi3GetFloat64", set="fmi3SetFloat64", step="fmi3DoStep")


def is_fmi3(slave: Any) -> bool:
    """Whether the fmpy slave is an FMI 3.0 one (else FMI 2.0)."""
    return isinstance(slave, FMU3Slave)


def fmu_functions(slave: Any, outputs: Sequence[int], inputs: Sequence[int]) -> CFunctions:
    """The C calls of an instantiated fmpy FMU2Slave / FMU3Slave that reads the Real (Float64)
    variables of value references `outputs` and sets those of `inputs`, in those orders.
    ValueError (one line) when it is not instantiated or its library lacks one of the three
    functions. The result keeps the slave and its arrays alive."""
    names = FMI3_NAMES if is_fmi3(slave) else FMI2_NAMES
    component = getattr(slave, "component", None)
    if component is None:
        raise ValueError(f"{getattr(slave, 'instanceName', 'the FMU')}: not instantiated, so it has no C calls yet")
    functions = tuple(bound_function(slave.dll, name) for name in (names.get, names.set, names.step))
    missing = [name for name, f in zip((names.get, names.set, names.step), functions, strict=True) if f is None]
    if missing:
        raise ValueError(
            f"{getattr(slave, 'instanceName', 'the FMU')}: its library does not export {', '.join(missing)}"
        )
    out_vr = (ctypes.c_uint32 * max(len(outputs), 1))(*outputs)
    in_vr = (ctypes.c_uint32 * max(len(inputs), 1))(*inputs)
    address = component if isinstance(component, int) else ctypes.cast(component, ctypes.c_void_p).value
    return CFunctions.of(functions, address, out_vr, in_vr, is_fmi3(slave), names, slave)  # type: ignore[arg-type]

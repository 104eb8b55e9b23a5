"""Fault injection: misbehaving plant FMUs made from a working one, without LD_PRELOAD.

`make_faulty_fmu(plant, out)` copies the FMU and puts a small C shim in place of its binary;
the real binary travels beside it as `real_<identifier>.so`. The shim forwards every fmi2
call to the real binary and, once the communication point reaches TOGGLE_FAULT_TIME (s) in a
run whose input F_E is at least TOGGLE_FAULT_MIN_FE (N), misbehaves as TOGGLE_FAULT_KIND says:

    segfault  write through a null pointer in fmi2DoStep
    abort     abort() in fmi2DoStep
    loop      spin forever in fmi2DoStep (ignores every signal it can)
    alloc     allocate and touch memory in fmi2DoStep until malloc fails, then abort()
    nan       fmi2GetReal answers NaN for every output
    discard   fmi2DoStep returns fmi2Discard
    error     fmi2DoStep returns fmi2Error

The settings come from the environment, so a command started with them passes them to every
process that loads the plant (pool workers, supervised children).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import zipfile
from pathlib import Path

import fmpy

HEADERS = Path(fmpy.__file__).parent / "c-code"

# name, return type, parameters (type name pairs as C text); the fmi2 functions fmpy loads
_FUNCTIONS = [
    ("fmi2GetTypesPlatform", "const char*", ""),
    ("fmi2GetVersion", "const char*", ""),
    ("fmi2SetDebugLogging", "fmi2Status", "fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]"),
    (
        "fmi2Instantiate",
        "fmi2Component",
        "fmi2String name, fmi2Type type, fmi2String guid, fmi2String location, "
        "const fmi2CallbackFunctions* functions, fmi2Boolean visible, fmi2Boolean logging",
    ),
    ("fmi2FreeInstance", "void", "fmi2Component c"),
    ("fmi2EnterInitializationMode", "fmi2Status", "fmi2Component c"),
    ("fmi2ExitInitializationMode", "fmi2Status", "fmi2Component c"),
    ("fmi2Terminate", "fmi2Status", "fmi2Component c"),
    ("fmi2Reset", "fmi2Status", "fmi2Component c"),
    ("fmi2GetInteger", "fmi2Status", "fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]"),
    ("fmi2GetBoolean", "fmi2Status", "fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]"),
    ("fmi2GetString", "fmi2Status", "fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]"),
    ("fmi2SetInteger", "fmi2Status", "fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]"),
    ("fmi2SetBoolean", "fmi2Status", "fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]"),
    ("fmi2SetString", "fmi2Status", "fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]"),
    ("fmi2GetFMUstate", "fmi2Status", "fmi2Component c, fmi2FMUstate* s"),
    ("fmi2SetFMUstate", "fmi2Status", "fmi2Component c, fmi2FMUstate s"),
    ("fmi2FreeFMUstate", "fmi2Status", "fmi2Component c, fmi2FMUstate* s"),
    ("fmi2SerializedFMUstateSize", "fmi2Status", "fmi2Component c, fmi2FMUstate s, size_t* size"),
    ("fmi2SerializeFMUstate", "fmi2Status", "fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t size"),
    ("fmi2DeSerializeFMUstate", "fmi2Status", "fmi2Component c, const fmi2Byte b[], size_t size, fmi2FMUstate* s"),
    (
        "fmi2GetDirectionalDerivative",
        "fmi2Status",
        "fmi2Component c, const fmi2ValueReference u[], size_t nu, "
        "const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real df[]",
    ),
    (
        "fmi2SetRealInputDerivatives",
        "fmi2Status",
        "fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer order[], const fmi2Real v[]",
    ),
    (
        "fmi2GetRealOutputDerivatives",
        "fmi2Status",
        "fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer order[], fmi2Real v[]",
    ),
    ("fmi2CancelStep", "fmi2Status", "fmi2Component c"),
    ("fmi2GetStatus", "fmi2Status", "fmi2Component c, const fmi2StatusKind k, fmi2Status* v"),
    ("fmi2GetRealStatus", "fmi2Status", "fmi2Component c, const fmi2StatusKind k, fmi2Real* v"),
    ("fmi2GetIntegerStatus", "fmi2Status", "fmi2Component c, const fmi2StatusKind k, fmi2Integer* v"),
    ("fmi2GetBooleanStatus", "fmi2Status", "fmi2Component c, const fmi2StatusKind k, fmi2Boolean* v"),
    ("fmi2GetStringStatus", "fmi2Status", "fmi2Component c, const fmi2StatusKind k, fmi2String* v"),
]

_PROLOGUE = r"""
#define _GNU_SOURCE
#include <dlfcn.h>
#include <math.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

static void *real_library;
static int kind; /* 0 none, 1 segfault, 2 abort, 3 loop, 4 alloc, 5 nan, 6 discard, 7 error */
static double fault_time = 1e300, fault_min_FE = -1e300, last_time, F_E;
static unsigned int F_E_vr = 0xffffffffu;

static void *real(const char *name) {
    if (!real_library) {
        Dl_info info;
        char path[4096];
        dladdr((void *)real, &info);
        strncpy(path, info.dli_fname, sizeof path - 64);
        path[sizeof path - 64] = 0;
        char *slash = strrchr(path, '/');
        const char *base = slash ? slash + 1 : path;
        char file[256];
        strncpy(file, base, sizeof file - 8);
        file[sizeof file - 8] = 0;
        strcpy(slash ? slash + 1 : path, "real_");
        strcat(path, file);
        real_library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
        if (!real_library) abort();
        const char *k = getenv("TOGGLE_FAULT_KIND");
        const char *names[] = {"", "segfault", "abort", "loop", "alloc", "nan", "discard", "error"};
        for (int i = 1; k && i < 8; i++) if (strcmp(k, names[i]) == 0) kind = i;
        if (getenv("TOGGLE_FAULT_TIME")) fault_time = atof(getenv("TOGGLE_FAULT_TIME"));
        if (getenv("TOGGLE_FAULT_MIN_FE")) fault_min_FE = atof(getenv("TOGGLE_FAULT_MIN_FE"));
        if (getenv("TOGGLE_FAULT_FE_VR")) F_E_vr = (unsigned int)atol(getenv("TOGGLE_FAULT_FE_VR"));
    }
    return dlsym(real_library, name);
}

static int faulting(void) { return kind && last_time >= fault_time - 1e-12 && F_E >= fault_min_FE; }

/* Every run sets up its experiment (a new instance, or one reset after the last run): the
   shim's time and force start again, as the instance's own state does. */
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDef, fmi2Real stop) {
    last_time = start;
    F_E = 0;
    return ((fmi2SetupExperimentTYPE *)real("fmi2SetupExperiment"))(c, tolDef, tol, start, stopDef, stop);
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    for (size_t i = 0; i < n; i++) if (vr[i] == F_E_vr) F_E = v[i];
    return ((fmi2SetRealTYPE *)real("fmi2SetReal"))(c, vr, n, v);
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    fmi2Status status = ((fmi2GetRealTYPE *)real("fmi2GetReal"))(c, vr, n, v);
    if (faulting() && kind == 5) for (size_t i = 0; i < n; i++) v[i] = NAN;
    return status;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    last_time = t;
    if (faulting()) {
        switch (kind) {
        case 1: *(volatile int *)0 = 1; break;
        case 2: abort();
        case 3: {
            sigset_t all;
            sigfillset(&all);
            sigprocmask(SIG_BLOCK, &all, NULL);
            for (volatile unsigned long i = 0;; i++) {}
        }
        case 4:
            for (;;) {
                char *block = malloc(64u << 20);
                if (!block) abort();
                memset(block, 1, 64u << 20);
            }
        case 6: return fmi2Discard;
        case 7: return fmi2Error;
        }
    }
    return ((fmi2DoStepTYPE *)real("fmi2DoStep"))(c, t, h, noSetPrior);
}
"""


def _argument_names(parameters: str) -> str:
    names = []
    for part in parameters.split(","):
        part = part.strip()
        if part:
            names.append(part.replace("[]", "").split()[-1].lstrip("*"))
    return ", ".join(names)


def shim_source() -> str:
    lines = [_PROLOGUE]
    for name, result, parameters in _FUNCTIONS:
        call = f'(({name}TYPE *)real("{name}"))({_argument_names(parameters)})'
        body = f"{call};" if result == "void" else f"return {call};"
        lines.append(f"{result} {name}({parameters or 'void'}) {{ {body} }}")
    return "\n".join(lines) + "\n"


def make_faulty_fmu(plant: Path, out: Path) -> Path:
    """A copy of the FMI 2.0 `plant` whose binary is the fault shim (see the module doc)."""
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        raise RuntimeError("no C compiler for the fault shim")
    with zipfile.ZipFile(plant) as archive:
        members = {info.filename: archive.read(info) for info in archive.infolist()}
    binary = next(name for name in members if name.startswith("binaries/linux64/") and name.endswith(".so"))
    folder, file = binary.rsplit("/", 1)
    with tempfile.TemporaryDirectory() as scratch:
        source = Path(scratch) / "shim.c"
        source.write_text(shim_source())
        library = Path(scratch) / file
        subprocess.run(
            [compiler, "-shared", "-fPIC", "-O1", "-I", str(HEADERS), "-o", str(library), str(source), "-ldl", "-lm"],
            check=True,
            capture_output=True,
            text=True,
        )
        shim = library.read_bytes()
    out.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(f"{folder}/real_{file}" if name == binary else name, data)
        archive.writestr(binary, shim)
    return out


def fault_environment(
    kind: str, time: float, plant_references: dict[str, int], min_F_E: float = -1e300
) -> dict[str, str]:
    """The environment that makes the shim misbehave (merged into os.environ)."""
    return {
        **os.environ,
        "TOGGLE_FAULT_KIND": kind,
        "TOGGLE_FAULT_TIME": repr(time),
        "TOGGLE_FAULT_MIN_FE": repr(min_F_E),
        "TOGGLE_FAULT_FE_VR": str(plant_references["F_E"]),
        # small enough that the alloc fault reaches it well inside the tests' 2 s time limit:
        # touching fresh pages costs about 1-2 s per GiB on these machines (0.5-1.3 s for 576 MiB)
        "TOGGLE_COSIM_PLANT_MEMORY": "128M",
    }

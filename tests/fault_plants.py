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
    status    fmi2DoStep returns TOGGLE_FAULT_STATUS (any integer, e.g. -1 or 5) and does not step
    log       fmi2DoStep logs a message in invalid UTF-8 with status TOGGLE_FAULT_STATUS, then steps
    resetfatal  fmi2Reset returns fmi2Fatal; any later call to the binary aborts (FMI allows none)
    chatter   fmi2DoStep returns fmi2Discard for a full step, while smaller steps (a retry's
              substeps) pass until TOGGLE_FAULT_END (s); from then on every step is discarded
    zeno      fmi2DoStep fails once (fmi2Error, logging ZENO_ONCE as an error): a retry passes;
              from TOGGLE_FAULT_END (s) on every step fails, logging ZENO_LATER as an error

and, whatever the time and F_E (the helper processes live TOGGLE_FAULT_SLEEP s, default 40):

    fork      fmi2Instantiate forks a helper (no exec: it holds every descriptor the plant has)
    daemon    the library's constructor starts `sleep N &` through system() (at load: the probe too)
    chdir     fmi2Instantiate changes the working directory to TOGGLE_FAULT_DIR
    orphan    fmi2Instantiate starts a daemon (double fork, setsid: it leaves the plant's group
              and tree), then fmi2DoStep segfaults at the fault time

and, with any kind (or none), from the fault time in a run whose F_E is at least TOGGLE_FAULT_MIN_FE:

    TOGGLE_FAULT_HOLD=<path>  fmi2DoStep waits until the file <path> exists, then steps on
                              (a file never made: the run cannot finish, it is killed)
    TOGGLE_FAULT_MARK=<path>  the first fmi2DoStep of a run that meets the fault (or the hold)
                              appends "<pid>" and a newline to <path> before it misbehaves: the
                              event a test waits on before it interrupts, kills or releases

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
# What the zeno kind logs (as the plant's solver words its failures), with the time in "%g"
ZENO_ONCE = "event iteration did not converge at t={} s: indicator 10 (zero crossing) still changes"
ZENO_LATER = "more than 10000 events in one communication step: the model is chattering (Zeno behaviour) at t={} s"
# A scenario for the shim: the "hit" run (F_E = 60 N) meets the fault, the "clean" one (0 N) not.
SCENARIO = {
    "name": "faulty",
    "t_end": 0.3,
    "T_s": 0.0005,
    "stroke": {"x_start": 0.2329, "x_target": 0.3199},
    "plant": {"F_E": 0.0, "m_B": 4.43, "mu": 0.2},
    "controller": {"objective": "x_B", "gains": {"C": 5, "Q": 4, "P": 50, "delta": 0.25, "beta": 65}},
    "variants": {"hit": {"plant": {"F_E": 60.0}}, "clean": {"plant": {"F_E": 0.0}}},
}

# name, return type, parameters (type name pairs as C text); the fmi2 functions fmpy loads
_FUNCTIONS = [
    ("fmi2GetTypesPlatform", "const char*", ""),
    ("fmi2GetVersion", "const char*", ""),
    ("fmi2SetDebugLogging", "fmi2Status", "fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]"),
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
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>
#include "fmi2Functions.h"

static void *real_library;
/* 0 none, 1 segfault, 2 abort, 3 loop, 4 alloc, 5 nan, 6 discard, 7 error, 8 status, 9 log,
   10 fork, 11 daemon, 12 chdir, 13 orphan, 14 chatter, 15 resetfatal, 16 zeno */
static int kind;
static double fault_time = 1e300, fault_min_FE = -1e300, last_time, F_E;
static double fault_end = 1e300, full_step; /* chatter: substeps pass until fault_end */
static unsigned int F_E_vr = 0xffffffffu;
static int fault_status;
static fmi2CallbackFunctions callbacks;
static const char *hold_path, *mark_path; /* TOGGLE_FAULT_HOLD, TOGGLE_FAULT_MARK */
static int marked;                        /* this run has appended its line to mark_path */
static char instance_name[256]; /* the name the instance logs under */
static int failed_once;         /* zeno: its one failure before fault_end is behind it */

static double sleep_seconds(void) {
    const char *text = getenv("TOGGLE_FAULT_SLEEP");
    return text ? atof(text) : 40.0;
}

__attribute__((constructor)) static void on_load(void) {
    const char *k = getenv("TOGGLE_FAULT_KIND");
    if (k && strcmp(k, "daemon") == 0) {
        char command[64];
        snprintf(command, sizeof command, "sleep %g &", sleep_seconds());
        if (system(command) != 0) abort();
    }
}

static int dead; /* set once fmi2Reset answered Fatal (resetfatal): any later call aborts */

static void *real(const char *name) {
    if (dead) abort();
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
        const char *names[] = {"", "segfault", "abort", "loop", "alloc", "nan", "discard", "error",
                               "status", "log", "fork", "daemon", "chdir", "orphan", "chatter", "resetfatal", "zeno"};
        for (int i = 1; k && i < 17; i++) if (strcmp(k, names[i]) == 0) kind = i;
        if (getenv("TOGGLE_FAULT_STATUS")) fault_status = atoi(getenv("TOGGLE_FAULT_STATUS"));
        if (getenv("TOGGLE_FAULT_END")) fault_end = atof(getenv("TOGGLE_FAULT_END"));
        if (getenv("TOGGLE_FAULT_TIME")) fault_time = atof(getenv("TOGGLE_FAULT_TIME"));
        if (getenv("TOGGLE_FAULT_MIN_FE")) fault_min_FE = atof(getenv("TOGGLE_FAULT_MIN_FE"));
        if (getenv("TOGGLE_FAULT_FE_VR")) F_E_vr = (unsigned int)atol(getenv("TOGGLE_FAULT_FE_VR"));
        hold_path = getenv("TOGGLE_FAULT_HOLD");
        mark_path = getenv("TOGGLE_FAULT_MARK");
    }
    return dlsym(real_library, name);
}

static int at_fault(void) { return last_time >= fault_time - 1e-12 && F_E >= fault_min_FE; }

static int faulting(void) { return kind && at_fault(); }

/* Once a run: "<pid>\n" appended to TOGGLE_FAULT_MARK (one write, O_APPEND: lines never mix). */
static void mark(void) {
    if (marked || !mark_path) return;
    marked = 1;
    int fd = open(mark_path, O_WRONLY | O_CREAT | O_APPEND, 0644);
    if (fd < 0) return;
    char line[32];
    int n = snprintf(line, sizeof line, "%ld\n", (long)getpid());
    if (write(fd, line, (size_t)n) != n) abort();
    close(fd);
}

/* TOGGLE_FAULT_HOLD: wait (1 ms naps) until the file exists; a signal ends the wait as it ends the process. */
static void hold(void) {
    while (access(hold_path, F_OK) != 0) usleep(1000);
}

/* Every run sets up its experiment (a new instance, or one reset after the last run): the
   shim's time and force start again, as the instance's own state does. */
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDef, fmi2Real stop) {
    last_time = start;
    F_E = 0;
    marked = 0;
    failed_once = 0;
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

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible, fmi2Boolean logging) {
    fmi2InstantiateTYPE *instantiate = (fmi2InstantiateTYPE *)real("fmi2Instantiate");
    if (functions) callbacks = *functions;
    snprintf(instance_name, sizeof instance_name, "%s", name ? name : "");
    if (kind == 10 && fork() == 0) {
        usleep((useconds_t)(sleep_seconds() * 1e6));
        _exit(0);
    }
    if (kind == 13 && fork() == 0) {
        setsid();
        if (fork() == 0) {
            usleep((useconds_t)(sleep_seconds() * 1e6));
        }
        _exit(0);
    }
    if (kind == 12 && chdir(getenv("TOGGLE_FAULT_DIR") ? getenv("TOGGLE_FAULT_DIR") : "/") != 0) abort();
    return instantiate(name, type, guid, location, functions, visible, logging);
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    last_time = t;
    if (h > full_step) full_step = h;
    if (at_fault() && (kind || hold_path)) mark();
    if (hold_path && at_fault()) hold();
    if (faulting()) {
        switch (kind) {
        case 1:
        case 13: *(volatile int *)0 = 1; break;
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
        case 8: return (fmi2Status)fault_status;
        case 9:
            if (callbacks.logger)
                callbacks.logger(callbacks.componentEnvironment, "shim", (fmi2Status)fault_status, "logAll",
                                 "bad bytes \xff\xfe\x80 at %g s", t);
            break;
        case 14:
            if (h < 0.5 * full_step && t < fault_end) break;
            return fmi2Discard;
        case 16:
            if (t >= fault_end - 1e-12) {
                if (callbacks.logger)
                    callbacks.logger(callbacks.componentEnvironment, instance_name, fmi2Error, "logStatusError",
                                     ZENO_LATER, t);
                return fmi2Error;
            }
            if (failed_once) break;
            failed_once = 1;
            if (callbacks.logger)
                callbacks.logger(callbacks.componentEnvironment, instance_name, fmi2Error, "logStatusError",
                                 ZENO_ONCE, t);
            return fmi2Error;
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
    said = {"ZENO_ONCE": ZENO_ONCE, "ZENO_LATER": ZENO_LATER}
    lines = [f'#define {name} "{text.format("%g")}"' for name, text in said.items()] + [_PROLOGUE]
    for name, result, parameters in _FUNCTIONS:
        call = f'(({name}TYPE *)real("{name}"))({_argument_names(parameters)})'
        body = f"{call};" if result == "void" else f"return {call};"
        if name == "fmi2Reset":  # resetfatal: Fatal, and the binary may not be called again
            body = f'real("fmi2Reset"); if (kind == 15) {{ dead = 1; return fmi2Fatal; }} {body}'

        lines.append(f"{result} {name}({parameters or 'void'}) {{ {body} }}")
    return "\n".join(lines) + "\n"


HELPER_LIBRARY = "libtoggle_helper.so"
_HELPER_SOURCE = "int toggle_helper_answer(void) { return 42; }\n"
_NEEDS_HELPER = """
int toggle_helper_answer(void);
__attribute__((constructor)) static void needs_helper(void) { if (toggle_helper_answer() != 42) abort(); }
"""


def make_faulty_fmu(plant: Path, out: Path, needs_library: bool = False) -> Path:
    """A copy of the FMI 2.0 `plant` whose binary is the fault shim (see the module doc). With
    `needs_library` the shim is linked against HELPER_LIBRARY, shipped beside it in the FMU's
    binaries/linux64/ and found there through the run path $ORIGIN (as vendors ship
    dependencies): the binary loads only from the whole extracted platform folder."""
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        raise RuntimeError("no C compiler for the fault shim")
    with zipfile.ZipFile(plant) as archive:
        members = {info.filename: archive.read(info) for info in archive.infolist()}
    binary = next(name for name in members if name.startswith("binaries/linux64/") and name.endswith(".so"))
    folder, file = binary.rsplit("/", 1)
    with tempfile.TemporaryDirectory() as scratch:
        source = Path(scratch) / "shim.c"
        source.write_text(shim_source() + (_NEEDS_HELPER if needs_library else ""))
        library = Path(scratch) / file
        extra: list[str] = []
        if needs_library:
            (Path(scratch) / "helper.c").write_text(_HELPER_SOURCE)
            helper = Path(scratch) / HELPER_LIBRARY
            subprocess.run(
                [compiler, "-shared", "-fPIC", "-o", str(helper), str(Path(scratch) / "helper.c")],
                check=True,
                capture_output=True,
            )
            members[f"{folder}/{HELPER_LIBRARY}"] = helper.read_bytes()
            extra = [f"-L{scratch}", "-ltoggle_helper", "-Wl,-rpath,$ORIGIN"]
        subprocess.run(
            [compiler, "-shared", "-fPIC", "-O1", "-I", str(HEADERS), "-o", str(library), str(source), *extra]
            + ["-ldl", "-lm"],
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
    kind: str,
    time: float,
    plant_references: dict[str, int],
    min_F_E: float = -1e300,
    *,
    hold: Path | None = None,
    mark: Path | None = None,
) -> dict[str, str]:
    """The environment that makes the shim misbehave (merged into os.environ); `hold` and
    `mark`: TOGGLE_FAULT_HOLD and TOGGLE_FAULT_MARK (module doc), unset if None. `kind` "" is
    no kind: the plant steps as it should, held where `hold` says."""
    files = {"TOGGLE_FAULT_HOLD": hold, "TOGGLE_FAULT_MARK": mark}
    return {
        **{key: value for key, value in os.environ.items() if key not in files},
        **{key: str(path) for key, path in files.items() if path is not None},
        "TOGGLE_FAULT_KIND": kind,
        "TOGGLE_FAULT_TIME": repr(time),
        "TOGGLE_FAULT_MIN_FE": repr(min_F_E),
        "TOGGLE_FAULT_FE_VR": str(plant_references["F_E"]),
        # small enough that the alloc fault reaches it soon (touching fresh pages costs about
        # 1-2 s per GiB); its run ends by itself there (abort), under no time limit
        "TOGGLE_COSIM_PLANT_MEMORY": "128M",
    }

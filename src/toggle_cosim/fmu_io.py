"""A thin, allocation-free wrapper over an FMI 2.0 or 3.0 Co-Simulation FMU for the master loop,
and the compiled step loop that the master runs it with.

fmpy's `FMU2Slave.getReal([..])` builds ctypes arrays on every call, and each of its `fmi2*`
methods goes through a Python `_call` that looks the function up, optionally logs, and checks
the status. Here the value-reference arrays and value buffers are built once, and each call
goes straight to the FMU's C function (the ctypes function fmpy loaded, with its argument
types), checking the status as fmpy does: anything worse than a warning raises fmpy's
`FMICallException` naming the function.

The compiled loop
-----------------
Even so, a step in Python (read outputs, controller, set inputs, doStep, record) costs several
times the FMU's own doStep, and most of that is the controller's nominal model (~3 us of
scalar Python per sample). `CompiledLoop` runs whole stretches of the loop in C: it calls the
FMU's functions through their pointers, evaluates the controller (the nominal model of
`mechanism.nominal_fG` / `nominal_fG_theta1` and the control law of `controller.VSCController.step`,
transcribed operation for operation, compiled without contraction or reassociation so that
every result is bit-identical to the Python) and writes each sample into the master's
preallocated trace. It never decides anything the Python would decide differently: a sample
with non-finite outputs, or one where the Python controller would raise or produce a
non-finite value (a domain error, a division by zero), is handed back to the Python loop
before anything of it is sent to the FMU. An FMI error status is reported with the function's
name and status, and the master raises the same exception the Python path raises.

The C source is compiled once per machine with the C compiler the FMU build uses and cached
(``$XDG_CACHE_HOME/toggle-cosim`` or ``~/.cache/toggle-cosim``; ``TOGGLE_COSIM_CACHE`` overrides).
Without a C compiler, or with ``TOGGLE_COSIM_KERNEL=0``, the master runs the Python loop.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from fmpy import extract
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

from toggle_cosim.plant import PlantInterface

_WARNING = 1  # fmi2Warning == fmi3Warning: a status above it is a failure, as fmpy's _call says


class PlantFMU:
    """One instance of a plant FMU: set parameters, initialise, then read/write/step."""

    def __init__(self, plant: PlantInterface, instance_name: str, outputs: list[str], inputs: list[str]) -> None:
        self.plant = plant
        self._unzipped = Path(extract(str(plant.path)))
        md = plant.model_description
        self.is_fmi3 = plant.fmi_version.startswith("3")
        kwargs = dict(unzipDirectory=str(self._unzipped), modelIdentifier=plant.model_identifier, instanceName=instance_name)
        try:
            if self.is_fmi3:
                # fmpy passes the instantiationToken of FMI 3.0 under the name guid
                self.fmu = FMU3Slave(guid=md.instantiationToken, **kwargs)
            else:
                self.fmu = FMU2Slave(guid=md.guid, **kwargs)
        except BaseException:
            shutil.rmtree(self._unzipped, ignore_errors=True)
            raise
        self._instantiated = False
        ref = plant.references
        self._out_vr = (ctypes.c_uint32 * len(outputs))(*(ref[n] for n in outputs))
        self._out_val = (ctypes.c_double * len(outputs))()
        self._out_view = np.frombuffer(self._out_val, dtype=np.float64)
        self._n_out = len(outputs)
        self._in_vr = (ctypes.c_uint32 * len(inputs))(*(ref[n] for n in inputs))
        self._in_val = (ctypes.c_double * len(inputs))()
        self._n_in = len(inputs)
        prefix = "fmi3" if self.is_fmi3 else "fmi2"
        self._get_name = f"{prefix}GetFloat64" if self.is_fmi3 else "fmi2GetReal"
        self._set_name = f"{prefix}SetFloat64" if self.is_fmi3 else "fmi2SetReal"
        self._step_name = f"{prefix}DoStep"
        self._get = self._c_function(self._get_name)
        self._set = self._c_function(self._set_name)
        self._step = self._c_function(self._step_name)
        if self.is_fmi3:  # doStep's output arguments, built once
            self._event = ctypes.c_bool()
            self._terminate = ctypes.c_bool()
            self._early = ctypes.c_bool()
            self._last_time = ctypes.c_double()
            self._step_outputs = (ctypes.byref(self._event), ctypes.byref(self._terminate),
                                  ctypes.byref(self._early), ctypes.byref(self._last_time))
        self._component = None

    def _c_function(self, name: str):  # noqa: ANN202 - a ctypes function pointer
        """The FMU's C function as fmpy loaded it (argument and result types set), or the
        fmpy method of that name if this fmpy keeps them elsewhere."""
        found = getattr(self.fmu, "_functions", {}).get(name)
        return found if found is not None else getattr(self.fmu, name)

    # -- life cycle ---------------------------------------------------------------------------
    def instantiate(self, start: float, stop: float) -> None:
        if self.is_fmi3:
            self.fmu.instantiate(visible=False, loggingOn=False)
        else:
            self.fmu.instantiate(visible=False, loggingOn=False)
            self.fmu.setupExperiment(startTime=start, stopTime=stop)
        self._instantiated = True
        self._component = self.fmu.component
        self._start, self._stop = start, stop

    def enter_initialization(self) -> None:
        if self.is_fmi3:
            self.fmu.enterInitializationMode(startTime=self._start, stopTime=self._stop)
        else:
            self.fmu.enterInitializationMode()

    def exit_initialization(self) -> None:
        self.fmu.exitInitializationMode()

    def set_value(self, name: str, value: float | bool) -> None:
        vr = [self.plant.references[name]]
        kind = self.plant.types[name]
        if kind == "Boolean":
            self.fmu.setBoolean(vr, [bool(value)])
        elif kind in ("Real", "Float64"):
            self.fmu.setReal(vr, [float(value)]) if not self.is_fmi3 else self.fmu.setFloat64(vr, [float(value)])
        else:
            raise TypeError(f"variable {name!r} is of type {kind}; only Real/Float64 and Boolean can be set")

    def close(self) -> None:
        """Terminate and free the instance, whatever state it is in, and delete the unzipped copy."""
        try:
            if self._instantiated:
                try:
                    self.fmu.terminate()
                except Exception:  # noqa: BLE001 - an FMU in error state may refuse terminate
                    pass
                self.fmu.freeInstance()
                self._instantiated = False
                self._component = None
        finally:
            shutil.rmtree(self._unzipped, ignore_errors=True)

    # -- the hot path -------------------------------------------------------------------------
    def read_outputs(self, into: np.ndarray) -> None:
        """Copy the outputs (in the order given at construction) into `into`."""
        if self.is_fmi3:
            status = self._get(self._component, self._out_vr, self._n_out, self._out_val, self._n_out)
        else:
            status = self._get(self._component, self._out_vr, self._n_out, self._out_val)
        if status is not None and status > _WARNING:
            raise FMICallException(function=self._get_name, status=status)
        into[:] = self._out_view

    def write_inputs(self, values: tuple[float, ...]) -> None:
        buffer = self._in_val
        for k, v in enumerate(values):
            buffer[k] = v
        if self.is_fmi3:
            status = self._set(self._component, self._in_vr, self._n_in, buffer, self._n_in)
        else:
            status = self._set(self._component, self._in_vr, self._n_in, buffer)
        if status is not None and status > _WARNING:
            raise FMICallException(function=self._set_name, status=status)

    def do_step(self, t: float, h: float) -> None:
        if self.is_fmi3:
            status = self._step(self._component, t, h, True, *self._step_outputs)
        else:
            status = self._step(self._component, t, h, 1)
        if status is not None and status > _WARNING:
            raise FMICallException(function=self._step_name, status=status)

    # -- the compiled loop --------------------------------------------------------------------
    def compiled_loop(self, data: np.ndarray, n_out: int, i_x: int, i_v: int, col_u: int, n: int,
                      T_s: float, F_E: float, law: dict[str, float]) -> CompiledLoop | None:
        """The loop in C over this instance, or None when it cannot be had (no compiler, the
        FMU's C functions not reachable, TOGGLE_COSIM_KERNEL=0). See `CompiledLoop`."""
        library = kernel_library()
        functions = getattr(self.fmu, "_functions", {})
        names = (self._get_name, self._set_name, self._step_name)
        if library is None or self._component is None or any(name not in functions for name in names):
            return None
        return CompiledLoop(library, self, [functions[name] for name in names], data, n_out, i_x, i_v, col_u,
                            n, T_s, F_E, law)


# ----------------------------------------------------------------------------------------------
# The loop in C
# ----------------------------------------------------------------------------------------------

KERNEL_SOURCE = r"""
/* toggle-cosim: the co-simulation loop in C (see fmu_io.py). Compile with -ffp-contract=off
   and no -ffast-math: every expression is evaluated in the order Python evaluates it. */
#include <math.h>
#include <stdbool.h>
#include <stddef.h>

typedef int (*get2_t)(void *, const unsigned int *, size_t, double *);
typedef int (*set2_t)(void *, const unsigned int *, size_t, const double *);
typedef int (*step2_t)(void *, double, double, int);
typedef int (*get3_t)(void *, const unsigned int *, size_t, double *, size_t);
typedef int (*set3_t)(void *, const unsigned int *, size_t, const double *, size_t);
typedef int (*step3_t)(void *, double, double, bool, bool *, bool *, bool *, double *);

/* Keep in step with class _Kernel in fmu_io.py: pointers, then longs, then doubles. */
typedef struct {
    void *get, *set, *step, *component;
    const unsigned int *out_vr, *in_vr;
    double *data;
    long fmi3, n_out, ncols, i_x, i_v, col_u, n, objective;
    long k, fault, status;  /* next sample; the failed FMI function (1 get, 2 set, 3 step), its status */
    double T_s, F_E;
    double target, C, Q, P, delta, beta, K_f, t0, T_h;
    double r1, r3, r4, r5, f, h, phi, m3, m5, mB, mC, J2, g;
} kernel_t;

enum { DONE = 0, HAND_BACK = 1, FMI_FAILED = 2 };

/* mechanism._theta1_omega1_from_slider, for f == 0 (then math.hypot(x_B, f) == |x_B| exactly;
   the master uses this kernel only then). Returns 0, or 1 where Python would raise or go
   non-finite. */
static int theta1_omega1(const kernel_t *s, double x_B, double v_B, double *t1, double *w1) {
    double rho = fabs(x_B), den, arg, s1, c1, s2, q, c2, dxB;
    den = 2.0 * s->r1 * rho;
    if (den == 0.0) { return 1; }
    arg = (x_B * x_B + s->r1 * s->r1 + s->f * s->f - s->r3 * s->r3) / den;
    if (!(arg >= -1.0 && arg <= 1.0)) { return 1; }
    *t1 = asin(arg) - atan2(x_B, s->f);
    s1 = sin(*t1);
    c1 = cos(*t1);
    s2 = (s->f - s->r1 * s1) / s->r3;
    q = 1.0 - s2 * s2;
    if (!(q >= 0.0)) { return 1; }
    c2 = sqrt(q);
    den = s->r3 * c2;
    if (den == 0.0) { return 1; }
    dxB = -s->r1 * s1 + s->r3 * s2 * s->r1 * c1 / den;
    if (dxB == 0.0) { return 1; }
    *w1 = v_B / dxB;
    return 0;
}

/* mechanism._nominal_reduced: out = (acc0, dacc, dxB, bB). */
static int nominal_reduced(const kernel_t *s, double t1, double w1, double out[4]) {
    const double r1 = s->r1, r3 = s->r3, r4 = s->r4, r5 = s->r5;
    double s1, c1, sp, cp, s2, c2, s5, c5, q, rho2, rho5, w2, w5, w1s, w2s, w5s, g1, g2, sv2, sv5;
    double a3, a5, m3, m5, mB, mC, c12, s12, cp5, sp5, M11, M12, M15, M22, M55;
    double d11_1, d12_1, d12_2, d15_1, d15_5, N1, N2, N5, g, V1, V2, V5;
    double m_eff, RMs, RQ0, dxB, dxC, den2, den5;
    s1 = sin(t1);
    c1 = cos(t1);
    sp = sin(t1 + s->phi);
    cp = cos(t1 + s->phi);
    s2 = (s->f - r1 * s1) / r3;
    q = 1.0 - s2 * s2;
    if (!(q >= 0.0)) { return 1; }
    c2 = sqrt(q);
    s5 = (s->h - r4 * sp) / r5;
    q = 1.0 - s5 * s5;
    if (!(q >= 0.0)) { return 1; }
    c5 = sqrt(q);
    den2 = r3 * c2;
    den5 = r5 * c5;
    if (den2 == 0.0 || den5 == 0.0) { return 1; }
    rho2 = -r1 * c1 / den2;
    rho5 = -r4 * cp / den5;
    w2 = rho2 * w1;
    w5 = rho5 * w1;
    w1s = w1 * w1;
    w2s = w2 * w2;
    w5s = w5 * w5;
    g1 = r1 * s1 * w1s + r3 * s2 * w2s;
    g2 = -r4 * sp * w1s - r5 * s5 * w5s;
    sv2 = g1 / den2;
    sv5 = -g2 / den5;

    a3 = 0.5 * r3;
    a5 = 0.5 * r5;
    m3 = s->m3; m5 = s->m5; mB = s->mB; mC = s->mC;
    c12 = c1 * c2 + s1 * s2;
    s12 = s1 * c2 - c1 * s2;
    cp5 = cp * c5 + sp * s5;
    sp5 = sp * c5 - cp * s5;
    M11 = s->J2 + m3 * r1 * r1 + m5 * r4 * r4 + mB * r1 * r1 * s1 * s1 + mC * r4 * r4 * sp * sp;
    M12 = m3 * r1 * a3 * c12 + mB * r1 * r3 * s1 * s2;
    M15 = m5 * r4 * a5 * cp5 + mC * r4 * r5 * sp * s5;
    M22 = m3 * r3 * r3 / 12.0 + m3 * a3 * a3 + mB * r3 * r3 * s2 * s2;
    M55 = m5 * r5 * r5 / 12.0 + m5 * a5 * a5 + mC * r5 * r5 * s5 * s5;
    d11_1 = 2.0 * (mB * r1 * r1 * s1 * c1 + mC * r4 * r4 * sp * cp);
    d12_1 = -m3 * r1 * a3 * s12 + mB * r1 * r3 * c1 * s2;
    d12_2 = m3 * r1 * a3 * s12 + mB * r1 * r3 * s1 * c2;
    d15_1 = -m5 * r4 * a5 * sp5 + mC * r4 * r5 * cp * s5;
    d15_5 = m5 * r4 * a5 * sp5 + mC * r4 * r5 * sp * c5;
    N1 = 0.5 * d11_1 * w1s + d12_2 * w2s + d15_5 * w5s;
    N2 = d12_1 * w1s + mB * r3 * r3 * s2 * c2 * w2s;
    N5 = d15_1 * w1s + mC * r5 * r5 * s5 * c5 * w5s;
    g = s->g;
    V1 = g * (m3 * r1 * c1 + m5 * r4 * cp);
    V2 = g * m3 * a3 * c2;
    V5 = g * m5 * a5 * c5;

    m_eff = M11 + 2.0 * (M12 * rho2 + M15 * rho5) + M22 * rho2 * rho2 + M55 * rho5 * rho5;
    RMs = sv2 * (M12 + M22 * rho2) + sv5 * (M15 + M55 * rho5);
    RQ0 = -(N1 + V1) - rho2 * (N2 + V2) - rho5 * (N5 + V5);
    dxB = -r1 * s1 - r3 * s2 * rho2;
    dxC = -r4 * sp - r5 * s5 * rho5;
    if (m_eff == 0.0) { return 1; }
    out[0] = (RQ0 - RMs) / m_eff;
    out[1] = -dxC / m_eff;
    out[2] = dxB;
    out[3] = -r1 * c1 * w1s - r3 * (s2 * sv2 + c2 * w2s);
    return 0;
}

/* controller.VSCController.step: out = (u, S, phase, e), phase 0 reaching, 1 sliding.
   Returns 0, or 1 where the Python must evaluate this sample itself. */
int kernel_control(const kernel_t *s, double t, double x_B, double v_B, double out[4]) {
    double t1, w1, red[4], e, edot, f, G, S, u, sg, den;
    int reaching;
    if (theta1_omega1(s, x_B, v_B, &t1, &w1) || nominal_reduced(s, t1, w1, red)) { return 1; }
    if (s->objective == 0) {               /* x_B: mechanism.nominal_fG */
        f = red[2] * red[0] + red[3];
        G = s->K_f * red[2] * red[1];
        e = s->target - x_B;
        edot = -v_B;
    } else {                               /* theta1: mechanism.nominal_fG_theta1 */
        f = red[0];
        G = s->K_f * red[1];
        e = s->target - t1;
        edot = -w1;
    }
    S = s->C * e + edot;
    reaching = t - s->t0 < s->T_h;
    if (G == 0.0) { return 1; }
    if (reaching) {
        sg = S > 0.0 ? 1.0 : (S < 0.0 ? -1.0 : 0.0);
        u = (s->C * edot + s->P * S + s->Q * sg - f) / G;
    } else {
        den = fabs(S) + s->delta;
        if (den == 0.0) { return 1; }
        u = (s->C * edot + s->beta * S / den - f) / G;
    }
    if (!(isfinite(u) && isfinite(S) && isfinite(e) && isfinite(f) && isfinite(G))) { return 1; }
    out[0] = u;
    out[1] = S;
    out[2] = reaching ? 0.0 : 1.0;
    out[3] = e;
    return 0;
}

/* Samples s->k .. k_end - 1: read outputs into the trace row, control, record, then (except
   after the last sample n) set the inputs and doStep. Stops early with HAND_BACK at a sample
   the Python must take (nothing of it sent to the FMU) or FMI_FAILED. s->k is the next
   sample on return (the failed one for FMI_FAILED). */
int kernel_run(kernel_t *s, long k_end) {
    double in[2], c[4], t, x_B, v_B, *row;
    long k;
    int status;
    bool event, terminate, early;
    double last;
    for (k = s->k; k < k_end; k++) {
        t = (double)k * s->T_s;
        row = s->data + k * s->ncols;
        status = s->fmi3 ? ((get3_t)s->get)(s->component, s->out_vr, (size_t)s->n_out, row + 1, (size_t)s->n_out)
                         : ((get2_t)s->get)(s->component, s->out_vr, (size_t)s->n_out, row + 1);
        if (status > 1) { s->k = k; s->fault = 1; s->status = status; return FMI_FAILED; }
        x_B = row[s->i_x];
        v_B = row[s->i_v];
        if (!(isfinite(x_B) && isfinite(v_B)) || kernel_control(s, t, x_B, v_B, c)) {
            s->k = k;
            return HAND_BACK;
        }
        row[0] = t;
        row[s->col_u] = c[0];
        row[s->col_u + 1] = s->F_E;
        row[s->col_u + 2] = c[1];
        row[s->col_u + 3] = c[2];
        row[s->col_u + 4] = c[3];
        if (k == s->n) { s->k = k + 1; return DONE; }
        in[0] = c[0];
        in[1] = s->F_E;
        status = s->fmi3 ? ((set3_t)s->set)(s->component, s->in_vr, 2, in, 2)
                         : ((set2_t)s->set)(s->component, s->in_vr, 2, in);
        if (status > 1) { s->k = k; s->fault = 2; s->status = status; return FMI_FAILED; }
        status = s->fmi3 ? ((step3_t)s->step)(s->component, t, s->T_s, true, &event, &terminate, &early, &last)
                         : ((step2_t)s->step)(s->component, t, s->T_s, 1);
        if (status > 1) { s->k = k; s->fault = 3; s->status = status; return FMI_FAILED; }
    }
    s->k = k_end;
    return DONE;
}
"""

KERNEL_FLAGS = ("-std=c99", "-O2", "-fPIC", "-shared", "-ffp-contract=off", "-fno-fast-math", "-fno-builtin")

_LAW_FIELDS = ("target", "C", "Q", "P", "delta", "beta", "K_f", "t0", "T_h",
               "r1", "r3", "r4", "r5", "f", "h", "phi", "m3", "m5", "mB", "mC", "J2", "g")


class _Kernel(ctypes.Structure):
    _fields_ = [
        *((name, ctypes.c_void_p) for name in ("get", "set", "step", "component", "out_vr", "in_vr", "data")),
        *((name, ctypes.c_long) for name in ("fmi3", "n_out", "ncols", "i_x", "i_v", "col_u", "n", "objective",
                                             "k", "fault", "status")),
        *((name, ctypes.c_double) for name in ("T_s", "F_E", *_LAW_FIELDS)),
    ]


DONE, HAND_BACK, FMI_FAILED = 0, 1, 2

_library: ctypes.CDLL | None = None
_library_reason: str | None = None


def _cache_folder() -> Path:
    if os.environ.get("TOGGLE_COSIM_CACHE"):
        return Path(os.environ["TOGGLE_COSIM_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "toggle-cosim"


def _compiler() -> str | None:
    for name in (os.environ.get("CC", ""), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return name
    return None


def _build_kernel() -> Path:
    compiler = _compiler()
    if compiler is None:
        raise RuntimeError("no C compiler (set CC or install gcc)")
    suffix = {"Windows": ".dll", "Darwin": ".dylib"}.get(platform.system(), ".so")
    key = hashlib.sha256("\0".join((KERNEL_SOURCE, *KERNEL_FLAGS, shutil.which(compiler) or compiler,
                                    platform.machine(), sys.platform)).encode()).hexdigest()[:16]
    for folder in (_cache_folder(), Path(tempfile.gettempdir()) / f"toggle-cosim-{os.getuid() if hasattr(os, 'getuid') else 'user'}"):
        library = folder / f"loop-kernel-{key}{suffix}"
        if library.is_file():
            return library
        try:
            folder.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryDirectory(dir=folder) as work:
                source = Path(work) / "kernel.c"
                source.write_text(KERNEL_SOURCE, encoding="utf-8")
                built = Path(work) / f"kernel{suffix}"
                result = subprocess.run([compiler, *KERNEL_FLAGS, "-o", str(built), str(source), "-lm"],
                                        capture_output=True, text=True, check=False)
                if result.returncode != 0:
                    raise RuntimeError(f"the C compiler failed: {result.stderr.strip()[:500]}")
                os.replace(built, library)  # atomic: a concurrent build just wins or loses the race
            return library
        except OSError:
            continue
    raise RuntimeError("no writable cache folder for the compiled loop")


def kernel_library() -> ctypes.CDLL | None:
    """The compiled loop (built and cached on first use), or None; `kernel_reason()` says why not."""
    global _library, _library_reason
    if os.environ.get("TOGGLE_COSIM_KERNEL", "1") == "0":
        return None
    if _library is None and _library_reason is None:
        try:
            library = ctypes.CDLL(str(_build_kernel()))
            library.kernel_run.argtypes = [ctypes.POINTER(_Kernel), ctypes.c_long]
            library.kernel_run.restype = ctypes.c_int
            library.kernel_control.argtypes = [ctypes.POINTER(_Kernel), ctypes.c_double, ctypes.c_double,
                                               ctypes.c_double, ctypes.POINTER(ctypes.c_double)]
            library.kernel_control.restype = ctypes.c_int
            _library = library
        except Exception as error:  # noqa: BLE001 - no kernel: the Python loop runs instead
            _library_reason = str(error)
    return _library


def kernel_available() -> bool:
    return kernel_library() is not None


def kernel_reason() -> str | None:
    """Why the compiled loop is not used (None when it is)."""
    if os.environ.get("TOGGLE_COSIM_KERNEL", "1") == "0":
        return "disabled by TOGGLE_COSIM_KERNEL=0"
    kernel_library()
    return _library_reason


class CompiledLoop:
    """Samples k .. k_end - 1 of the master loop in one C call (see the module docstring).

    `data` is the master's preallocated (n + 1, ncols) float64 trace: column 0 time, columns
    1 .. n_out the FMU outputs, col_u .. col_u + 4 (iq_ref, F_E, S, phase, e). `law` holds the
    controller: objective (0 x_B, 1 theta1), target (x_B* or theta1*), gains C Q P delta beta,
    K_f, t0 and T_h of the ControllerState, and the nominal mechanism r1 .. g.
    """

    def __init__(self, library: ctypes.CDLL, fmu: PlantFMU, functions: list, data: np.ndarray, n_out: int,
                 i_x: int, i_v: int, col_u: int, n: int, T_s: float, F_E: float, law: dict[str, float]) -> None:
        if data.dtype != np.float64 or not data.flags.c_contiguous or data.shape[0] < n + 1:
            raise ValueError("the trace must be a C-contiguous float64 array of n + 1 rows")
        self._library = library
        self._keep = (fmu, data, functions)  # everything the C side points into stays alive
        k = _Kernel()
        k.get, k.set, k.step = (ctypes.cast(f, ctypes.c_void_p).value for f in functions)
        k.component = fmu._component
        k.out_vr = ctypes.addressof(fmu._out_vr)
        k.in_vr = ctypes.addressof(fmu._in_vr)
        k.data = data.ctypes.data
        k.fmi3 = 1 if fmu.is_fmi3 else 0
        k.n_out, k.ncols, k.i_x, k.i_v, k.col_u, k.n = n_out, data.shape[1], i_x, i_v, col_u, n
        k.objective = int(law["objective"])
        k.T_s, k.F_E = float(T_s), float(F_E)
        for name in _LAW_FIELDS:
            setattr(k, name, float(law[name]))
        self._state = k
        self._pointer = ctypes.pointer(k)
        self._out = (ctypes.c_double * 4)()
        self.fault_function = None
        self.fault_status = 0
        self._names = (None, fmu._get_name, fmu._set_name, fmu._step_name)

    def control(self, t: float, x_B: float, v_B: float) -> tuple[float, float, float, float] | None:
        """(u, S, phase, e) of the compiled controller, or None where it defers to Python."""
        if self._library.kernel_control(self._pointer, t, x_B, v_B, self._out):
            return None
        return tuple(self._out)

    def run(self, k: int, k_end: int) -> tuple[int, int]:
        """Run samples k .. k_end - 1; returns (DONE | HAND_BACK | FMI_FAILED, next sample).
        On FMI_FAILED the sample is the failed one and fault_function/fault_status say what failed."""
        state = self._state
        state.k = k
        code = self._library.kernel_run(self._pointer, k_end)
        if code == FMI_FAILED:
            self.fault_function = self._names[state.fault]
            self.fault_status = int(state.status)
        return code, int(state.k)

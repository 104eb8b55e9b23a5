"""The generic FMI 2.0 Co-Simulation shell (src/toggle_cosim/fmu_export/shell), on its own.

Nothing here uses toggle_cosim's build code. Each test model is written in Modelica below,
compiled by `modelica.sim.cgen` exactly as the build does it (inputs turned into parameter
slots), and given the `md_model.h` tables by hand -- for that one small model only. The
shell is compiled with the strict flags it promises to pass, linked with the model into a
minimal FMU, and driven through `fmpy.fmi2.FMU2Slave`.

Every numerical check has a tolerance that a wrong integrator, a sloppy event locator or a
lost restart would fail.
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
import re
import shutil
import subprocess
import sys
import tempfile
import time
import uuid
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
pytest.importorskip("modelica")

from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import (  # noqa: E402
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2LastSuccessfulTime,
)
from fmpy.logging import addLoggerProxy  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

from toggle_cosim.fmu_export.shell_settings import HEADER_NAME, settings_header  # noqa: E402

SHELL = Path(__file__).resolve().parents[1] / "src" / "toggle_cosim" / "fmu_export" / "shell"
FMI_HEADERS = Path(__file__).resolve().parents[1] / "src" / "toggle_cosim" / "fmu_export" / "fmi_headers"
CC = shutil.which("gcc")

pytestmark = pytest.mark.skipif(CC is None or not sys.platform.startswith("linux"), reason="needs gcc on Linux")

STRICT = ["-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror"]
# md_settings.h is written from toggle_cosim.fmu_export.shell_settings (as the build does)
GENERATED = Path(tempfile.mkdtemp(prefix="md-settings-"))
(GENERATED / HEADER_NAME).write_text(settings_header())
COMMON = ["-fPIC", "-O2", "-fvisibility=hidden", f"-I{FMI_HEADERS}", f"-I{SHELL}", f"-I{GENERATED}"]
SETTINGS = ("solver.relTol", "solver.absTol", "solver.maxStep")  # vr nvars + 0, 1, 2
SETTING_DEFAULTS = (1e-8, 1e-10, 0.0)


# ---------------------------------------------------------------------------------------
# The test models, and their md_model.h tables (written by hand, checked against the C)
# ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Var:
    name: str
    kind: str  # parameter | calculated | input | state | discrete | output | local
    obs: int  # slot in observe()'s output; the value reference is the position in `variables`
    par: int = -1
    start: float | None = None
    type: str = "Real"  # or "Boolean" (held as 0.0 / 1.0 in the same arrays)


@dataclass(frozen=True)
class Spec:
    name: str
    source: str
    ny: int
    np: int
    nw: int
    nz: int
    direction: tuple[float, ...]
    latch: tuple[int, ...]
    variables: tuple[Var, ...]
    parameters_c: str  # body of md_parameters(double *p)
    start_c: str  # body of md_start(const double *p, double *y, double *w)
    defaults_c: str  # body of md_defaults(double *p)
    expect: tuple[str, ...] = ()  # lines the generated C must contain for the tables to hold

    @property
    def nobs(self) -> int:
        return len(self.variables)

    def vr(self, name: str) -> int:
        return next(i for i, v in enumerate(self.variables) if v.name == name)


MASS = Spec(
    name="Mass",
    source="""
model Mass "mass-spring with an input force and a when-latched friction sign"
  parameter Real k = 2 "stiffness";
  parameter Real k2 = 2*k "calculated from k";
  parameter Real mu = 0.1 "friction";
  parameter Boolean friction = true "friction on";
  input Real u(start = 0) "force";
  Real x(start = 1.0, fixed = true) "position";
  Real v(start = 0.0, fixed = true) "velocity";
  discrete Real s(start = 0.0) "friction sign";
  output Real y "twice x";
equation
  der(x) = v;
  der(v) = -k2*x - (if friction then mu*s else 0) + u;
  y = 2*x;
  when v > 0 then
    s = 1;
  elsewhen v < 0 then
    s = -1;
  end when;
end Mass;
""",
    ny=2,
    np=5,
    nw=11,
    nz=2,
    direction=(1.0, 1.0),
    latch=(-1, -1),
    variables=(
        Var("k", "parameter", 0, 0, 2.0),
        Var("k2", "calculated", 1, 1),
        Var("mu", "parameter", 2, 2, 0.1),
        Var("friction", "parameter", 3, 3, 1.0, "Boolean"),
        Var("u", "input", 4, 4, 0.0),
        Var("x", "state", 5, start=1.0),
        Var("v", "state", 6, start=0.0),
        Var("s", "discrete", 7, start=0.0),
        Var("y", "output", 8),
        Var("der(v)", "local", 9),
        Var("der(x)", "local", 10),
    ),
    parameters_c="p[1] = 2.0 * p[0];",
    start_c="(void)p; y[0] = 1.0; y[1] = 0.0; w[7] = 0.0;",
    defaults_c="p[0] = 2.0; p[2] = 0.1; p[3] = 1.0; p[4] = 0.0;",
    expect=(
        "k2 = p[1];",
        "friction = p[3];",
        "u = p[4];",
        "s = w[7];",
        "out[5] = x;",
        "out[8] = y_;",
        "(friction ? mu * s : 0.0)",
        "z[0] = v;",
        "z[1] = -v;",
        "w[7] = 1.0;",
        "w[7] = -1.0;",
    ),
)

REL = Spec(
    name="Rel",
    source="""
model Rel "time spent with x above an input threshold: a relation latched in w"
  input Real a(start = 0.5) "threshold";
  Real x(start = 1.0, fixed = true);
  Real v(start = 0.0, fixed = true);
  Real e(start = 0.0, fixed = true);
equation
  der(x) = v;
  der(v) = -x;
  der(e) = if x > a then 1 else 0;
end Rel;
""",
    ny=3,
    np=1,
    nw=8,
    nz=1,
    direction=(0.0,),
    latch=(7,),
    variables=(
        Var("a", "input", 0, 0, 0.5),
        Var("x", "state", 1, start=1.0),
        Var("v", "state", 2, start=0.0),
        Var("e", "state", 3, start=0.0),
        Var("der(v)", "local", 4),
        Var("der(e)", "local", 5),
        Var("der(x)", "local", 6),
    ),
    parameters_c="(void)p;",
    start_c="(void)p; (void)w; y[0] = 1.0; y[1] = 0.0; y[2] = 0.0;",
    defaults_c="p[0] = 0.5;",
    expect=("z[0] = x - a;", "der_e = w[7] > 0.5 ? 1.0 : 0.0;", "w[7] = 1.0 - w[7];", "out[3] = e;", "out[5] = der_e;"),
)

ZENO = Spec(
    name="Zeno",
    source="""
model Zeno "a sliding mode: chatters at x = 0.5"
  Real x(start = 0.0, fixed = true);
equation
  der(x) = if x > 0.5 then -1 else 1;
end Zeno;
""",
    ny=1,
    np=0,
    nw=3,
    nz=1,
    direction=(0.0,),
    latch=(2,),
    variables=(Var("x", "state", 0, start=0.0), Var("der(x)", "local", 1)),
    parameters_c="(void)p;",
    start_c="(void)p; (void)w; y[0] = 0.0;",
    defaults_c="(void)p;",
    expect=("z[0] = x - 0.5;", "w[2] = 1.0 - w[2];"),
)

BAD = Spec(
    name="Bad",
    source="""
model Bad "a right-hand side that stops being finite at t = 1"
  Real x(start = 0.0, fixed = true);
equation
  der(x) = sqrt(1 - time);
end Bad;
""",
    ny=1,
    np=0,
    nw=2,
    nz=0,
    direction=(),
    latch=(),
    variables=(Var("x", "state", 0, start=0.0), Var("der(x)", "local", 1)),
    parameters_c="(void)p;",
    start_c="(void)p; (void)w; y[0] = 0.0;",
    defaults_c="(void)p;",
    expect=("der_x = sqrt(1.0 - t);", "out[0] = x;"),
)

BALL = Spec(
    name="Ball",
    source="""
model Ball "a bouncing ball: a when branch that reinitialises a state"
  parameter Real e = 0.8 "restitution";
  parameter Real g = 9.81;
  Real h(start = 1.0, fixed = true);
  Real v(start = 0.0, fixed = true);
equation
  der(h) = v;
  der(v) = -g;
  when h < 0 then
    reinit(v, -e*pre(v));
  end when;
end Ball;
""",
    ny=2,
    np=2,
    nw=6,
    nz=1,
    direction=(1.0,),
    latch=(-1,),
    variables=(
        Var("e", "parameter", 0, 0, 0.8),
        Var("g", "parameter", 1, 1, 9.81),
        Var("h", "state", 2, start=1.0),
        Var("v", "state", 3, start=0.0),
        Var("der(v)", "local", 4),
        Var("der(h)", "local", 5),
    ),
    parameters_c="(void)p;",
    start_c="(void)p; (void)w; y[0] = 1.0; y[1] = 0.0;",
    defaults_c="p[0] = 0.8; p[1] = 9.81;",
    expect=("z[0] = -h;", "out[1] = -e * v;", "out[2] = h;"),
)

CASCADE = Spec(
    name="Cascade",
    source="""
model Cascade "an event whose action turns another condition: event iteration"
  Real x(start = 0.0, fixed = true);
  discrete Real d(start = 0.0);
equation
  der(x) = if d > 0.5 then -1 else 1;
  when x > 0.5 then
    d = 1;
  end when;
end Cascade;
""",
    ny=1,
    np=0,
    nw=4,
    nz=2,
    direction=(1.0, 0.0),
    latch=(-1, 3),
    variables=(
        Var("x", "state", 0, start=0.0),
        Var("d", "discrete", 1, start=0.0),
        Var("der(x)", "local", 2),
    ),
    parameters_c="(void)p;",
    start_c="(void)p; y[0] = 0.0; w[1] = 0.0;",
    defaults_c="(void)p;",
    expect=("z[0] = x - 0.5;", "z[1] = d - 0.5;", "w[1] = 1.0;", "w[3] = 1.0 - w[3];"),
)

MODELS = {spec.name: spec for spec in (MASS, REL, BALL, CASCADE, ZENO, BAD)}


def generate_c(spec: Spec) -> str:
    """cgen's translation unit for `spec.source`, as the build makes it."""
    from modelica.sim import cgen

    from modelica import lang, sim

    flat = sim.flatten(lang.parse(spec.source), spec.name)
    variables = tuple(
        dataclasses.replace(v, variability="parameter", causality="none") if v.causality == "input" else v
        for v in flat.variables
    )
    system = sim.causalize(dataclasses.replace(flat, variables=variables))
    return cgen.unit(system)


_MD_KIND = {"parameter": "MD_PARAMETER", "input": "MD_INPUT", "calculated": "MD_CALCULATED"}


def _array(ctype: str, name: str, values: list[str]) -> str:
    body = ", ".join(values) if values else "0"
    return f"static const {ctype} {name}[{max(1, len(values))}] = {{{body}}};"


def tables_c(spec: Spec, guid: str) -> str:
    """The md_model.h tables for `spec`: what toggle_cosim.fmu_export generates for real models."""
    vs = spec.variables
    names = ", ".join(f'"{v.name}"' for v in vs)
    return "\n".join(
        [
            "",
            "/* ---- md_model.h tables, written by tests/test_shell.py for this model ---- */",
            _array("double", "md_direction", [repr(d) for d in spec.direction]),
            _array("int", "md_latch", [str(k) for k in spec.latch]),
            _array("int", "md_kinds", [_MD_KIND.get(v.kind, "MD_COMPUTED") for v in vs]),
            _array("int", "md_obs", [str(v.obs) for v in vs]),
            _array("int", "md_par", [str(v.par) for v in vs]),
            f"static const char *const md_names[{len(vs)}] = {{{names}}};",
            f'const md_info MD_INFO = {{"{spec.name}", "{guid}", {spec.ny}, {spec.np}, '
            f"{spec.nw}, {spec.nobs}, {spec.nz}, md_direction, md_latch, {len(vs)}, md_kinds, "
            "md_obs, md_par, md_names};",
            f"void md_parameters(double *p) {{ {spec.parameters_c} }}",
            f"void md_start(const double *p, double *y, double *w) {{ {spec.start_c} }}",
            f"void md_defaults(double *p) {{ {spec.defaults_c} }}",
            "",
        ]
    )


# ---------------------------------------------------------------------------------------
# modelDescription.xml for a test model (the real one is toggle_cosim.fmu_export's business)
# ---------------------------------------------------------------------------------------

_MD_ATTRS = {
    "parameter": ('causality="parameter" variability="fixed" initial="exact"', True),
    "calculated": ('causality="calculatedParameter" variability="fixed" initial="calculated"', False),
    "input": ('causality="input" variability="continuous"', True),
    "state": ('causality="local" variability="continuous" initial="exact"', True),
    "discrete": ('causality="local" variability="discrete" initial="exact"', True),
    "output": ('causality="output" variability="continuous" initial="calculated"', False),
    "local": ('causality="local" variability="continuous" initial="calculated"', False),
}


def model_description(spec: Spec, guid: str) -> str:
    rows, outputs, initial = [], [], []
    for vr, v in enumerate(spec.variables):
        attrs, has_start = _MD_ATTRS[v.kind]
        value = ("true" if v.start else "false") if v.type == "Boolean" else repr(v.start)
        start = f' start="{value}"' if has_start else ""
        rows.append(
            f'    <ScalarVariable name="{v.name}" valueReference="{vr}" {attrs}><{v.type}{start}/></ScalarVariable>'
        )
        if v.kind == "output":
            outputs.append(vr + 1)
        if v.kind in ("output", "calculated"):
            initial.append(vr + 1)
    for i, (name, default) in enumerate(zip(SETTINGS, SETTING_DEFAULTS, strict=True)):
        unit = ' unit="s"' if name == "solver.maxStep" else ""
        rows.append(
            f'    <ScalarVariable name="{name}" valueReference="{len(spec.variables) + i}" '
            f'causality="parameter" variability="fixed" initial="exact">'
            f'<Real start="{default!r}"{unit}/></ScalarVariable>'
        )

    def unknowns(tag: str, indices: list[int]) -> str:
        """The schema refuses an empty list: leave the element out instead."""
        if not indices:
            return ""
        return f"    <{tag}>" + "".join(f'<Unknown index="{i}"/>' for i in indices) + f"</{tag}>"

    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="{spec.name}" guid="{guid}"
    generationTool="tests/test_shell.py" variableNamingConvention="structured">
  <CoSimulation modelIdentifier="{spec.name}" canHandleVariableCommunicationStepSize="true"
      canGetAndSetFMUstate="true" canSerializeFMUstate="true"
      providesDirectionalDerivative="false" canInterpolateInputs="false"
      maxOutputDerivativeOrder="0" canNotUseMemoryManagementFunctions="false">
    <SourceFiles><File name="solver.c"/><File name="instance.c"/><File name="fmi2.c"/><File name="model.c"/></SourceFiles>
  </CoSimulation>
  <UnitDefinitions><Unit name="s"><BaseUnit s="1"/></Unit></UnitDefinitions>
  <LogCategories>
    <Category name="logEvents" description="each state event: time and indicator"/>
    <Category name="logStatusError" description="every non-OK status, with the reason"/>
    <Category name="logAll" description="everything, including step statistics"/>
  </LogCategories>
  <DefaultExperiment startTime="0" stopTime="10"/>
  <ModelVariables>
{chr(10).join(rows)}
  </ModelVariables>
  <ModelStructure>
{unknowns("Outputs", outputs)}
{unknowns("InitialUnknowns", initial)}
  </ModelStructure>
</fmiModelDescription>
"""


# ---------------------------------------------------------------------------------------
# Building
# ---------------------------------------------------------------------------------------


@dataclass
class Built:
    spec: Spec
    guid: str
    fmu: Path
    unzipped: Path
    library: Path
    model_c: str


def _run(command: list[str]) -> None:
    result = subprocess.run(command, capture_output=True, text=True, check=False)
    assert result.returncode == 0, f"{' '.join(command)}\n{result.stderr}"


@pytest.fixture(scope="session")
def shell_objects(tmp_path_factory) -> list[Path]:
    """solver.c, instance.c and fmi2.c, compiled with the strict flags the shell promises to pass."""
    out = tmp_path_factory.mktemp("shell")
    objects = []
    for name in ("solver", "instance", "fmi2"):
        obj = out / f"{name}.o"
        _run([CC, "-c", *STRICT, *COMMON, str(SHELL / f"{name}.c"), "-o", str(obj)])
        objects.append(obj)
    return objects


@pytest.fixture(scope="session")
def build(tmp_path_factory, shell_objects):
    """build(name) -> Built, one FMU per test model, made once per session."""
    cache: dict[str, Built] = {}

    def make(name: str) -> Built:
        if name in cache:
            return cache[name]
        spec = MODELS[name]
        guid = "{" + str(uuid.uuid4()) + "}"
        work = tmp_path_factory.mktemp(name)
        generated = generate_c(spec)
        for line in spec.expect:  # the hand-written tables describe this very code
            assert line in generated, f"cgen output changed: {line!r} not found"
        model_c = '#include "md_model.h"\n' + generated + tables_c(spec, guid)
        (work / "model.c").write_text(model_c)
        model_o = work / "model.o"
        # generated code: looser flags (unused parameters, __attribute__((unused)))
        _run([CC, "-c", "-std=c99", *COMMON, str(work / "model.c"), "-o", str(model_o)])
        library = work / f"{name}{fmpy.sharedLibraryExtension}"
        _run([CC, "-shared", *(str(o) for o in shell_objects), str(model_o), "-lm", "-o", str(library)])
        fmu = work / f"{name}.fmu"
        with zipfile.ZipFile(fmu, "w") as zf:
            zf.writestr("modelDescription.xml", model_description(spec, guid))
            zf.write(library, f"binaries/{fmpy.platform}/{library.name}")
            for source in ("md_model.h", "solver.h", "solver.c", "instance.h", "instance.c", "fmi2.c"):
                zf.write(SHELL / source, f"sources/{source}")
            zf.write(GENERATED / HEADER_NAME, f"sources/{HEADER_NAME}")
            zf.writestr("sources/model.c", model_c)
        unzipped = Path(fmpy.extract(str(fmu), str(work / "unzipped")))
        cache[name] = Built(spec, guid, fmu, unzipped, library, model_c)
        return cache[name]

    return make


# ---------------------------------------------------------------------------------------
# Driving
# ---------------------------------------------------------------------------------------

_libc = ctypes.CDLL(None)
_libc.calloc.restype = ctypes.c_void_p
_libc.calloc.argtypes = [ctypes.c_size_t, ctypes.c_size_t]
_libc.free.argtypes = [ctypes.c_void_p]
_libc.free.restype = None

EVENT = re.compile(r"event at t=(\S+) s: indicator (\d+)")

# fmpy's logger proxy (which formats the variadic message) keeps ONE Python logger for the
# whole process, whichever callbacks struct registered it last. So all slaves share this
# logger, and it routes each message by instance name.
_SLAVES: dict[str, Slave] = {}


def _route(env, name, status, category, message) -> None:
    slave = _SLAVES.get(name.decode())
    if slave is not None:
        slave.messages.append((status, category.decode(), message.decode()))


_LOGGER = fmi2CallbackLoggerTYPE(_route)


@dataclass
class Slave:
    """An FMU2Slave with callbacks that record the log and count live allocations."""

    built: Built
    logging: bool = False
    guid: str | None = None
    messages: list[tuple[int, str, str]] = field(default_factory=list)
    live: set[int] = field(default_factory=set)

    def __post_init__(self) -> None:
        self.name = f"test{len(_SLAVES)}"
        _SLAVES[self.name] = self

        def allocate(n, size):
            pointer = _libc.calloc(n, size)
            if pointer:
                self.live.add(pointer)
            return pointer

        def release(pointer):
            if pointer:
                self.live.discard(pointer)
                _libc.free(pointer)

        self.callbacks = fmi2CallbackFunctions()
        self._keep = (
            _LOGGER,
            fmi2CallbackAllocateMemoryTYPE(allocate),
            fmi2CallbackFreeMemoryTYPE(release),
        )
        self.callbacks.logger, self.callbacks.allocateMemory, self.callbacks.freeMemory = self._keep
        addLoggerProxy(ctypes.byref(self.callbacks))  # formats the variadic message
        self.fmu = FMU2Slave(
            guid=self.guid or self.built.guid,
            modelIdentifier=self.built.spec.name,
            unzipDirectory=str(self.built.unzipped),
            instanceName=self.name,
        )
        self.fmu.instantiate(callbacks=self.callbacks, loggingOn=self.logging)
        self.t = 0.0

    def vr(self, *names: str) -> list[int]:
        spec = self.built.spec
        return [len(spec.variables) + SETTINGS.index(n) if n in SETTINGS else spec.vr(n) for n in names]

    def get(self, *names: str) -> list[float]:
        return self.fmu.getReal(self.vr(*names))

    def set(self, **values: float) -> None:
        names = list(values)
        self.fmu.setReal(self.vr(*names), [values[n] for n in names])

    def start(self, stop: float | None = None, **values: float) -> Slave:
        self.fmu.setupExperiment(startTime=0.0, stopTime=stop)
        if values:
            self.set(**values)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        return self

    def step(self, h: float) -> None:
        self.fmu.doStep(self.t, h)
        self.t += h

    def run(self, t_end: float, h: float, *names: str) -> np.ndarray:
        """Step to t_end with step h, sampling `names` after each step."""
        n = round((t_end - self.t) / h)
        t0 = self.t
        rows = []
        for i in range(n):
            self.fmu.doStep(t0 + i * h, h)
            rows.append(self.get(*names))
        self.t = t0 + n * h
        return np.array(rows)

    def events(self) -> list[tuple[float, int]]:
        return [
            (float(m.group(1)), int(m.group(2)))
            for _, category, text in self.messages
            if category == "logEvents" and (m := EVENT.search(text))
        ]

    def errors(self) -> str:
        return "\n".join(text for status, _, text in self.messages if status >= 3)

    def free(self) -> None:
        self.fmu.freeInstance()
        assert not self.live, f"{len(self.live)} allocations leaked"


def mass_analytic(t: float, k2: float = 4.0, mu: float = 0.1, x0: float = 1.0):
    """x, v of the Mass model with u = 0 and s switching at every velocity reversal.

    v starts at 0 and goes negative at once, so s = -1 from t = 0+; every half period
    pi/omega the velocity reverses, s flips, and the centre of the oscillation moves to
    -mu*s/k2. Each segment is an exact cosine about its centre."""
    omega = math.sqrt(k2)
    half = math.pi / omega
    n = int(t // half)
    xn = x0
    for i in range(n):
        centre = -mu * (-1.0 if i % 2 == 0 else 1.0) / k2
        xn = 2.0 * centre - xn
    centre = -mu * (-1.0 if n % 2 == 0 else 1.0) / k2
    tau = t - n * half
    return centre + (xn - centre) * math.cos(omega * tau), -(xn - centre) * omega * math.sin(omega * tau)


# ---------------------------------------------------------------------------------------
# Tests
# ---------------------------------------------------------------------------------------


def test_only_fmi2_functions_are_exported(build):
    """Only the fmi2 entry points leave the binary: Co-Simulation and Model Exchange (the
    modelDescription decides which of them an importer may use), never the model's symbols."""
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("needs nm")
    library = build("Mass").library
    out = subprocess.run([nm, "-D", "--defined-only", str(library)], capture_output=True, text=True, check=True).stdout
    exported = {line.split()[-1] for line in out.splitlines() if line.strip()}
    assert exported, out
    assert all(name.startswith("fmi2") for name in exported), exported
    for required in (
        "fmi2Instantiate",
        "fmi2DoStep",
        "fmi2GetFMUstate",
        "fmi2CancelStep",
        "fmi2GetRealStatus",
        "fmi2DeSerializeFMUstate",
        "fmi2EnterEventMode",
        "fmi2GetDerivatives",
        "fmi2SetTime",
        "fmi2GetEventIndicators",
        "fmi2SetContinuousStates",
        "fmi2NewDiscreteStates",
        "fmi2CompletedIntegratorStep",
        "fmi2GetNominalsOfContinuousStates",
    ):
        assert required in exported
    assert "MD_INFO" not in exported and "rhs" not in exported


def test_model_exchange_refused_when_the_description_offers_co_simulation_only(build):
    """These hand-made tables leave MD_INFO.interfaces at 0 (Co-Simulation only), and their
    modelDescription has no <ModelExchange>: fmi2Instantiate(fmi2ModelExchange) says no."""
    from fmpy.fmi2 import FMU2Model

    built = build("Mass")
    model = FMU2Model(
        guid=built.guid, unzipDirectory=str(built.unzipped), modelIdentifier=built.spec.name, instanceName="me"
    )
    with pytest.raises(Exception, match="Failed to instantiate"):
        model.instantiate(loggingOn=True)
    model.freeLibrary()


@pytest.mark.parametrize("name", sorted(MODELS))
def test_validate_fmu_reports_no_problems(build, name):
    assert validate_fmu(str(build(name).fmu)) == []


def test_undamped_oscillator_matches_cosine(build):
    """mu = 0: x = cos(sqrt(k2) t), with k2 = 2k computed from k = 1 set before init."""
    slave = Slave(build("Mass")).start(k=1.0, mu=0.0)
    assert slave.get("k2") == [2.0]
    h = 1e-3
    x = slave.run(10.0, h, "x")[:, 0]
    t = h * np.arange(1, len(x) + 1)
    error = np.max(np.abs(x - np.cos(math.sqrt(2.0) * t)))
    print(f"oscillator, h=1e-3: max |x - cos(sqrt(2) t)| = {error:.3g}")
    assert error < 1e-7
    slave.free()

    # long communication steps (many adaptive internal steps); friction off by its switch
    slave = Slave(build("Mass"))
    slave.fmu.setBoolean(slave.vr("friction"), [False])
    slave.start(k=1.0)
    assert slave.fmu.getBoolean(slave.vr("friction")) == [False]
    x = slave.run(10.0, 0.5, "x")[:, 0]
    t = 0.5 * np.arange(1, len(x) + 1)
    error = np.max(np.abs(x - np.cos(math.sqrt(2.0) * t)))
    print(f"oscillator, h=0.5: max |x - cos(sqrt(2) t)| = {error:.3g}")
    assert error < 1e-7
    slave.free()


def test_friction_sign_events_are_located(build):
    """Velocity reversals every pi/2 s (k2 = 4); each flips s and moves the centre."""
    slave = Slave(build("Mass"), logging=False)
    slave.fmu.setDebugLogging(True, ["logEvents"])  # events only
    slave.start()
    data = slave.run(10.0, 0.01, "x", "v", "s")
    events = slave.events()
    # first: v < 0 becomes true at t = 0+ (v starts at 0 and falls)
    assert events[0][1] == 1 and 0.0 < events[0][0] < 1e-9
    later = events[1:]
    assert [k for _, k in later] == [0, 1, 0, 1, 0, 1]
    times = np.array([t for t, _ in later])
    expected = math.pi / 2 * np.arange(1, 7)
    error = np.max(np.abs(times - expected))
    print(f"event location: max |t_event - n pi/2| = {error:.3g} s")
    assert error < 1e-9
    # and the dynamics the events switch between
    x_end, v_end = mass_analytic(10.0)
    assert abs(data[-1, 0] - x_end) < 1e-7 and abs(data[-1, 1] - v_end) < 1e-7
    assert data[-1, 2] == (1.0 if (10.0 // (math.pi / 2)) % 2 else -1.0)
    assert {category for _, category, _ in slave.messages} == {"logEvents"}
    # outputs are sampled right: s at each sample matches the segment it is in
    t = 0.01 * np.arange(1, len(data) + 1)
    segment = np.floor(t / (math.pi / 2)).astype(int)
    assert np.array_equal(data[:, 2], np.where(segment % 2 == 0, -1.0, 1.0))
    slave.free()


def test_relation_latch_events_both_ways(build):
    """der(e) = if x > a then 1 else 0 with x = cos t: e(10) = pi, crossings at
    pi/3 (falling), 5pi/3 (rising), 7pi/3 (falling). The latch starts true (x(0) = 1)."""
    # tight tolerances, so that what is measured is the event location and not the
    # integration error in x (about 1e-9 at the default relTol)
    slave = Slave(build("Rel"), logging=True).start(**{"solver.relTol": 1e-11, "solver.absTol": 1e-13})
    assert slave.get("der(e)") == [1.0]
    data = slave.run(10.0, 0.05, "e", "x", "der(e)")
    times = np.array([t for t, _ in slave.events()])
    expected = np.array([1, 5, 7]) * math.pi / 3
    assert len(times) == 3
    error = np.max(np.abs(times - expected))
    print(f"relation latch: max event time error {error:.3g} s, e(10) - pi = {data[-1, 0] - math.pi:.3g}")
    assert error < 1e-10
    assert abs(data[-1, 0] - math.pi) < 1e-9
    assert abs(data[-1, 1] - math.cos(10.0)) < 1e-9
    assert data[-1, 2] == 0.0
    slave.free()


def test_reinit_moves_the_state_at_the_event(build):
    """Bouncing ball: impact k at t1 (1 + 2 sum_{j<k} e^j), v jumps from -v to e v."""
    slave = Slave(build("Ball"), logging=True).start()
    data = slave.run(3.0, 0.01, "h", "v")
    e, g = 0.8, 9.81
    t1 = math.sqrt(2.0 / g)
    impacts = [t1 * (1 + 2 * sum(e**j for j in range(1, k))) for k in range(1, 7)]
    times = np.array([t for t, _ in slave.events()])
    assert len(times) == 6
    error = np.max(np.abs(times - impacts))
    print(f"bouncing ball: max impact time error {error:.3g} s")
    assert error < 1e-9
    v6 = e**6 * g * t1
    tau = 3.0 - impacts[-1]
    assert abs(data[-1, 0] - (v6 * tau - g / 2 * tau**2)) < 1e-8
    assert abs(data[-1, 1] - (v6 - g * tau)) < 1e-8
    assert np.all(data[:, 0] > -1e-9)  # never (visibly) below the floor
    slave.free()


def test_event_iteration_at_one_instant(build):
    """`when x > 0.5 then d = 1` turns the relation d > 0.5, which reverses der(x): both
    events act at the same instant, and x comes back down as 1 - t."""
    slave = Slave(build("Cascade"), logging=True).start()
    data = slave.run(1.0, 0.125, "x", "d", "der(x)")
    (t0, k0), (t1, k1) = slave.events()
    assert (k0, k1) == (0, 1) and t0 == t1 and abs(t0 - 0.5) < 1e-12
    assert abs(data[-1, 0]) < 1e-11 and data[-1, 1] == 1.0 and data[-1, 2] == -1.0
    slave.free()


def test_inputs_and_parameters(build):
    """Parameters set in initialisation mode, inputs before exit and in step mode."""
    slave = Slave(build("Mass"))
    slave.fmu.setupExperiment(startTime=0.0)
    slave.fmu.enterInitializationMode()
    slave.set(k=4.0, mu=0.0, u=0.4, **{"solver.relTol": 1e-10, "solver.absTol": 1e-12})
    assert slave.get("k2") == [8.0]  # calculated parameters follow, in initialisation mode
    slave.fmu.exitInitializationMode()
    assert slave.get("k2", "u") == [8.0, 0.4]
    omega, centre = math.sqrt(8.0), 0.4 / 8.0
    slave.run(1.0, 0.01, "x")
    x1, v1 = slave.get("x", "v")
    assert abs(x1 - (centre + (1 - centre) * math.cos(omega))) < 1e-10
    # an input change in step mode: the integrator restarts with the new right-hand side
    slave.set(u=-0.8)
    assert slave.get("u", "der(v)") == [-0.8, pytest.approx(-8.0 * x1 - 0.8, abs=1e-14)]
    slave.run(2.0, 0.25, "x")
    centre2 = -0.8 / 8.0
    x2 = centre2 + (x1 - centre2) * math.cos(omega) + v1 / omega * math.sin(omega)
    # (without the restart the stale first stage costs about 1e-9 here, even with the error
    # control catching most of it)
    assert abs(slave.get("x")[0] - x2) < 2e-10
    # parameters are fixed once running
    with pytest.raises(FMICallException):
        slave.set(k=1.0)
    slave.free()


def test_input_change_fires_relation_at_the_communication_point(build):
    """Raising the threshold above x mid-run turns the relation false at once."""
    slave = Slave(build("Rel"), logging=True).start()
    slave.run(0.5, 0.05, "e")
    slave.set(a=0.9)  # x = cos(0.5) = 0.878 < 0.9
    slave.run(1.0, 0.05, "e")
    assert slave.events()[0][0] == 0.5  # exactly at the communication point
    e, de = slave.get("e", "der(e)")
    assert abs(e - 0.5) < 1e-9 and de == 0.0
    slave.free()

    # and a threshold set before the start initialises the latch false: e stays 0
    slave = Slave(build("Rel")).start(a=1.5)
    assert slave.get("der(e)") == [0.0]
    slave.run(1.0, 0.1, "e")
    assert slave.get("e") == [0.0]
    slave.free()


def test_get_set_and_serialise_fmu_state(build):
    slave = Slave(build("Mass"))
    slave.start()
    slave.run(1.0, 0.01, "x")
    at_save = slave.get("x", "v", "s")
    state = slave.fmu.getFMUstate()
    first = slave.run(2.0, 0.01, "x", "v", "s", "y")  # an event at pi/2 on the way
    assert set(first[:, 2]) == {-1.0, 1.0}

    slave.fmu.setFMUstate(state)
    slave.t = 1.0
    assert slave.get("x", "v", "s") == at_save  # the outputs come back too
    second = slave.run(2.0, 0.01, "x", "v", "s", "y")
    assert first.tobytes() == second.tobytes()

    blob = slave.fmu.serializeFMUstate(state)
    restored = slave.fmu.deSerializeFMUstate(blob)
    slave.fmu.setFMUstate(restored)
    slave.t = 1.0
    third = slave.run(2.0, 0.01, "x", "v", "s", "y")
    assert first.tobytes() == third.tobytes()

    # damaged, truncated, or another model's: refused, and the instance carries on
    damaged = bytearray(blob)
    damaged[len(blob) // 2] ^= 0x10
    for bad in (bytes(damaged), blob[:-8], blob[:10], b"\0" * len(blob)):
        with pytest.raises(FMICallException):
            slave.fmu.deSerializeFMUstate(bad)
    assert "corrupted" in slave.errors() and "another" not in slave.errors()
    other = Slave(build("Rel")).start()
    foreign = other.fmu.serializeFMUstate(other.fmu.getFMUstate())
    with pytest.raises(FMICallException):
        slave.fmu.deSerializeFMUstate(foreign)
    assert "another model" in slave.errors()
    other.free()

    slave.fmu.freeFMUstate(state)
    slave.fmu.freeFMUstate(restored)
    slave.run(2.5, 0.01, "x")
    slave.free()  # asserts nothing leaked, FMU states included


def test_several_instances_are_independent(build):
    alone = Slave(build("Mass")).start(k=3.0)
    reference = alone.run(2.0, 0.01, "x", "s")
    alone.free()
    a = Slave(build("Mass")).start(k=3.0)
    b = Slave(build("Mass")).start(k=0.5, u=0.2)
    rows = []
    for i in range(200):  # the same communication points as `alone` used
        a.fmu.doStep(i * 0.01, 0.01)
        rows.append(a.get("x", "s"))
        b.fmu.doStep(i * 0.01, 0.01)
    assert np.array(rows).tobytes() == reference.tobytes()
    a.free()
    b.free()


def test_non_finite_derivative_is_an_error_not_a_crash(build):
    """der(x) = sqrt(1 - t): NaN past t = 1. The step fails cleanly and stays failed."""
    slave = Slave(build("Bad")).start()
    slave.run(0.5, 0.25, "x")
    x_half = slave.get("x")[0]
    assert abs(x_half - 2 / 3 * (1 - 0.5**1.5)) < 1e-9
    saved = slave.fmu.getFMUstate()
    with pytest.raises(FMICallException):
        slave.fmu.doStep(0.5, 1.0)
    assert "non-finite derivative" in slave.errors()
    assert "integrator failed at t=" in slave.errors()
    last = slave.fmu.getRealStatus(fmi2LastSuccessfulTime)
    assert 0.999 < last <= 1.0
    x = slave.get("x")[0]
    assert math.isfinite(x) and abs(x - 2 / 3 * (1 - (1 - last) ** 1.5)) < 1e-6
    with pytest.raises(FMICallException):  # further steps: error
        slave.fmu.doStep(last, 0.1)
    # FMI 2.0 sec. 2.1.3: a state saved before the error brings the instance back
    slave.fmu.setFMUstate(saved)
    slave.fmu.doStep(0.5, 0.25)
    assert abs(slave.get("x")[0] - 2 / 3 * (1 - 0.25**1.5)) < 1e-9
    slave.fmu.freeFMUstate(saved)
    slave.fmu.terminate()
    slave.free()


def test_chattering_is_stopped_with_a_message(build):
    """A sliding mode at x = 0.5: the Zeno guard stops it, naming indicator and time."""
    slave = Slave(build("Zeno"), logging=True).start()
    with pytest.raises(FMICallException):
        slave.fmu.doStep(0.0, 1.0)  # without the guard: an endless sequence of events, never returns
    events = slave.events()
    assert len(events) == 10001 and {k for _, k in events} == {0}
    assert abs(events[0][0] - 0.5) < 1e-12  # x = t reaches 0.5
    message = slave.errors()
    assert "chattering" in message and "indicator 0" in message
    # each chatter costs at least half the location tolerance, so time creeps on a little
    match = re.search(r"at t=(\S+) s", message)
    assert match and 0.5 < float(match.group(1)) < 0.5 + 1e-7
    assert abs(slave.fmu.getRealStatus(fmi2LastSuccessfulTime) - 0.5) < 1e-7
    assert abs(slave.get("x")[0] - 0.5) < 1e-9
    with pytest.raises(FMICallException):
        slave.fmu.doStep(0.5, 0.1)
    slave.free()


def test_step_budget_is_enforced(build):
    """solver.maxStep = 1e-7 over a 1 s step needs 1e7 steps: more than MD_MAX_STEPS."""
    slave = Slave(build("Mass")).start(**{"solver.maxStep": 1e-7})
    with pytest.raises(FMICallException):
        slave.fmu.doStep(0.0, 1.0)
    assert "more than 1000000 internal steps" in slave.errors()
    last = slave.fmu.getRealStatus(fmi2LastSuccessfulTime)
    assert 0.09 < last < 0.11
    x, v = slave.get("x", "v")
    assert (x, v) == pytest.approx(mass_analytic(last), abs=1e-7)
    slave.free()


def test_misuse_is_refused_without_damage(build):
    built = build("Mass")
    slave = Slave(built)
    # wrong state: before initialisation
    for call in (
        lambda: slave.fmu.doStep(0.0, 0.1),
        lambda: slave.get("x"),
        slave.fmu.exitInitializationMode,
        slave.fmu.terminate,
    ):
        with pytest.raises(FMICallException):
            call()
    assert "not allowed in instantiated" in slave.errors()
    # solver settings: validated, readable, tunable (settable before and during the run)
    for name, bad in (("solver.relTol", 0.5), ("solver.relTol", 0.0), ("solver.absTol", 0.0), ("solver.maxStep", -1.0)):
        with pytest.raises(FMICallException):
            slave.set(**{name: bad})
    slave.set(**{"solver.maxStep": 0.05})
    slave.start(stop=1.0)
    assert slave.get(*SETTINGS) == [1e-8, 1e-10, 0.05]
    for call in (
        slave.fmu.enterInitializationMode,
        slave.fmu.exitInitializationMode,
        lambda: slave.fmu.setupExperiment(startTime=0.0),
    ):
        with pytest.raises(FMICallException):
            call()
    # not settable, not finite, unknown, not provided
    refused = {
        "x": 0.3,
        "k2": 1.0,
        "y": 1.0,
        "k": 1.0,
        "solver.relTol": 0.5,  # k: fixed when running
        "u": float("nan"),
    }
    for name, value in refused.items():
        with pytest.raises(FMICallException):
            slave.set(**{name: value})
    slave.set(**{"solver.relTol": 1e-6})  # tunable: accepted in step mode
    assert slave.get("solver.relTol") == [1e-6]
    assert "variable x is not settable" in slave.errors()
    assert "variable k2 is not settable" in slave.errors()
    assert "non-finite value nan for u" in slave.errors()
    assert slave.get("u") == [0.0]
    assert slave.fmu.getBoolean(slave.vr("friction")) == [True]
    for vrs, values in ((slave.vr("friction"), [False]), (slave.vr("solver.relTol"), [True])):
        with pytest.raises(FMICallException):  # a parameter when running; a Real setting
            slave.fmu.setBoolean(vrs, values)
    assert "solver.relTol is a Real variable" in slave.errors()
    with pytest.raises(FMICallException):
        slave.fmu.getInteger([0])
    with pytest.raises(FMICallException):
        slave.fmu.getReal([999])
    with pytest.raises(FMICallException):
        slave.fmu.setReal([999], [1.0])
    with pytest.raises(FMICallException):
        slave.fmu.getDirectionalDerivative([7], [3], [1.0])
    assert "not provided" in slave.errors()
    with pytest.raises(FMICallException):
        slave.fmu.doStep(0.3, 0.1)  # not the FMU's time
    # none of that hurt: the run goes on and matches the analytic solution
    slave.run(1.0, 0.1, "x")
    assert abs(slave.get("x")[0] - mass_analytic(1.0)[0]) < 1e-7
    with pytest.raises(FMICallException):
        slave.fmu.doStep(1.0, 0.1)  # past stopTime
    slave.fmu.terminate()
    slave.free()

    # wrong GUID
    with pytest.raises(Exception, match="instantiate"):
        Slave(built, guid="{00000000-0000-0000-0000-000000000000}")

    # Model Exchange, a wrong GUID, missing callbacks: called directly (FMU2Model would need
    # the ME functions), with a probe slave's callbacks and name so that the log is ours
    probe = Slave(built)
    instantiate = probe.fmu.dll.fmi2Instantiate
    instantiate.restype = ctypes.c_void_p
    instantiate.argtypes = [
        ctypes.c_char_p,
        ctypes.c_int,
        ctypes.c_char_p,
        ctypes.c_char_p,
        ctypes.c_void_p,
        ctypes.c_int,
        ctypes.c_int,
    ]
    callbacks = ctypes.addressof(probe.callbacks)
    name = probe.name.encode()
    for fmu_type, guid, functions, reason in (
        (0, built.guid, callbacks, "Co-Simulation only"),
        (1, "{nope}", callbacks, "GUID {nope} does not match"),
        (1, built.guid, None, None),
    ):
        assert instantiate(name, fmu_type, guid.encode(), b"", functions, 0, 0) is None
        if reason is not None:
            assert reason in probe.errors()
    # the right arguments work, and a second instance on the same callbacks frees cleanly
    component = instantiate(name, 1, built.guid.encode(), b"", callbacks, 0, 0)
    assert component is not None
    free_instance = probe.fmu.dll.fmi2FreeInstance
    free_instance.argtypes = [ctypes.c_void_p]
    free_instance.restype = None
    free_instance(component)
    probe.free()  # asserts that nothing allocated through the probe's callbacks is left


def test_time_per_step(build):
    """Not a benchmark, a sanity bound: a doStep of the Mass model at h = 0.5 ms."""
    slave = Slave(build("Mass")).start()
    do_step = slave.fmu.dll.fmi2DoStep
    do_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
    do_step.restype = ctypes.c_int
    component, h, n = slave.fmu.component, 5e-4, 20000
    started = time.perf_counter()
    for i in range(n):
        assert do_step(component, i * h, h, 1) == 0
    per_step = (time.perf_counter() - started) / n * 1e6
    print(f"doStep, h=0.5 ms, via ctypes: {per_step:.2f} us")
    assert per_step < 200.0
    slave.t = n * h
    assert abs(slave.get("x")[0] - mass_analytic(n * h)[0]) < 1e-7
    slave.free()

"""The compiled system loop and the Python execution give the same bits over whole runs.

The law is defined once (`control/laws.py`, `control/nominal.py`); the compiled system loop runs
its C translation (`control.law_c`). Every shipped scenario (every variant), plus the θ1
objective and the integral law on the paper's strokes, is run twice through `simulate`, once
compiled and once in Python (TOGGLE_COSIM_KERNEL=0), and every column of the two traces must be
equal bit for bit; the generated law alone matches the Python at every sample point.
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from toggle_cosim import native
from toggle_cosim.control import law_c, laws, nominal, translate
from toggle_cosim.control.controller import VSCController
from toggle_cosim.control.parameters import LawParameters
from toggle_cosim.cosim.execution import system_loop
from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.physics.parameters import ControllerGains, MechanismParameters
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = sorted(p for p in (ROOT / "scenarios").glob("*.yaml") if not p.name.startswith(("sweep", "tune_")))


def _runs() -> list:
    runs = [run for path in SCENARIOS for run in load_scenario(path)]
    fig5 = load_scenario(ROOT / "scenarios" / "fig5_external_force.yaml")[0]
    theta1 = dataclasses.replace(
        fig5, variant="theta1_objective", controller=dataclasses.replace(fig5.controller, objective="theta1")
    )
    return [*runs, theta1]


RUNS = _runs()


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a).view(np.int64)  # -0.0 and 0.0 differ here, as do NaN payloads


@pytest.mark.parametrize("run", RUNS, ids=lambda run: run.label)
def test_compiled_and_python_loops_agree_bit_for_bit(
    run, plant_fmu: Path, no_gravity_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    plant = check_plant(no_gravity_fmu if "NoGravity" in str(run.fmu) else plant_fmu)
    compiled = check_and_simulate(run, plant)
    monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "0")
    python = check_and_simulate(run, plant)
    assert compiled.record["loop"]["kind"] == "compiled", compiled.record["loop"]
    assert python.record["loop"]["kind"] == "python"
    assert python.record["loop"]["reason"].endswith(
        "in Python (no compiled system loop: disabled by TOGGLE_COSIM_KERNEL=0)"
    )
    # the θ1 case with friction stops at the plant's Zeno guard (t = 1.0845 s): both loops alike
    assert (compiled.complete, compiled.reason) == (python.complete, python.reason)
    assert compiled.trace.names == python.trace.names
    for j, name in enumerate(compiled.trace.names):
        a, b = compiled.trace.data[:, j], python.trace.data[:, j]
        assert np.array_equal(a, b), name
        assert np.array_equal(_bits(a), _bits(b)), name


HARNESS = """
int law_sample(double t, double q, double qd, double z, double r, double rd, double rdd, const law_t *p,
               double *out) {
    int i;
    if (!(isfinite(q) && isfinite(qd))) { return 1; }
    if (law_step(t, q, qd, z, r, rd, rdd, p, &out[0], &out[1], &out[2], &out[3], &out[4])) { return 1; }
    for (i = 0; i < 5; i++) { if (!isfinite(out[i])) { return 1; } }
    return 0;
}
"""


def _law_library() -> ctypes.CDLL:
    """The generated law with a harness that calls it as system_skeleton.c does (a hand-back,
    1, where a measurement or an output is not finite or the law refuses), built like the loop."""
    if system_loop.system_library() is None:
        pytest.skip(f"no compiled loop: {system_loop.system_library_reason()}")
    source = law_c.law_source() + HARNESS
    library = native.load_library(native.cached_library(source, "law-harness", native.KERNEL_FLAGS, ("-lm",)))
    library.law_sample.restype = ctypes.c_int
    library.law_sample.argtypes = [ctypes.c_double] * 7 + [ctypes.c_void_p, ctypes.POINTER(ctypes.c_double)]
    return library


def _law(law: float, objective: float) -> LawParameters:
    controller = VSCController(
        gains=ControllerGains(C=5.0),
        nominal=MechanismParameters(mu=0.0),
        objective="x_B" if objective == 0.0 else "theta1",
        law="paper" if law == 0.0 else "integral",
        C_I=12.0,
        K_I=40.0,
        i_max=6.0,
    )
    return controller.law_parameters(t0=0.0, T_h=0.03)


@pytest.mark.parametrize("law", [0.0, 1.0], ids=["paper", "integral"])
@pytest.mark.parametrize("objective", [0.0, 1.0], ids=["x_B", "theta1"])
def test_generated_law_matches_the_python_at_every_sample_point(law: float, objective: float) -> None:
    """The generated C law (`law_c`, as the system loop calls it, its outputs checked finite)
    against laws.law_step at states across and beyond the
    stroke (x_B beyond the reach at both ends; θ1 over a turn and a half, past the folded
    position at −180°), both phases, moving both ways, with the integrator positive and
    negative, and at non-finite measurements: the same bits where the Python returns finite
    values, a hand-back (None) where it raises or returns a non-finite value."""
    library = _law_library()
    p = _law(law, objective)
    parameters = translate.ctypes_struct(LawParameters)(
        *(getattr(p, name) for name in LawParameters.__dataclass_fields__)
    )
    out = (ctypes.c_double * 5)()

    def control(t: float, q: float, qd: float, z: float, ref: tuple[float, float, float]) -> tuple | None:
        code = library.law_sample(t, q, qd, z, *ref, ctypes.byref(parameters), out)
        return None if code else tuple(out)

    if objective == 0.0:  # the measured (q, q̇): (x_B [m], v_B [m/s]) or (θ1 [rad], ω1 [rad/s])
        coordinates, rates = np.linspace(0.05, 0.40, 36), (-0.9, -0.2, 0.0, 0.3, 1.1)
    else:
        coordinates, rates = np.linspace(-2.0 * math.pi, math.pi, 36), (-9.0, -2.0, 0.0, 3.0, 11.0)
    # the reference: the constant target, and a moving one (q*, q̇*, q̈*) of a trajectory
    scale = 1.0 if objective == 0.0 else 10.0
    references = ((p.target, 0.0, 0.0), (p.target - 0.01 * scale, 0.15 * scale, -1.5 * scale), (p.target, 0.0, 2.0))
    checked = deferred = 0
    for q in [*coordinates, math.nan, math.inf]:
        for qd in rates:
            for t in (0.0, 0.05, 1.0):
                for z, ref in zip((-0.02, 0.0, 0.01), references, strict=True):
                    try:
                        expected = laws.law_step(t, float(q), qd, z, *ref, p)
                        if not all(math.isfinite(v) for v in expected):
                            expected = None
                    except (ArithmeticError, ValueError):
                        expected = None
                    got = control(t, float(q), qd, z, ref)
                    if expected is None:
                        assert got is None, (q, qd, t, z)
                        deferred += 1
                    else:
                        assert got is not None, (q, qd, t, z)
                        assert _bits(np.array(got)).tolist() == _bits(np.array(expected)).tolist(), (q, qd, t, z)
                        checked += 1
    assert checked > 500 and deferred > 0  # both kinds of sample were exercised


def test_the_integral_law_clips_at_i_max_and_holds_its_integrator() -> None:
    """Anti-windup: far from the target the integral law asks for more than i_max; u is i_max
    exactly, and z does not integrate the error that would push u further out."""
    p = _law(1.0, 0.0)
    u, S, phase, e, z_next = laws.law_step(1.0, 0.2329, 0.0, 0.0, p.target, 0.0, 0.0, p)
    assert u == p.i_max and e > 0
    assert z_next == 0.0
    u_free, _, _, e_in, z_in = laws.law_step(
        1.0, p.target - 1e-4, 0.0, 0.0, p.target, 0.0, 0.0, p
    )  # near the target: not clipped
    assert abs(u_free) < p.i_max and z_in == p.T_s * e_in and e_in > 0


def test_translator_rejects_what_it_cannot_translate_exactly() -> None:
    def with_a_loop(x: float, p: LawParameters) -> float:
        for _ in range(3):
            x = x * 2.0
        return x

    def with_power(x: float, p: LawParameters) -> float:
        return x**2

    for function in (with_a_loop, with_power):
        with pytest.raises(translate.TranslationError, match=function.__name__):
            translate.translate_functions([function], LawParameters)


def test_the_generated_source_has_the_law_once_and_no_hand_written_physics() -> None:
    """The system loop's skeleton holds no law (no mass-matrix term, no gain); the generated source
    holds the mass terms exactly once, and the struct has the dataclass's fields in order."""
    skeleton = (ROOT / "src" / "toggle_cosim" / "cosim" / "execution" / "system_skeleton.c").read_text()
    for word in ("M11", "beta", "delta", "sin(", "K_f"):
        assert word not in skeleton
    source = system_loop.system_source()
    assert source.count("static int mass_terms(") == 2  # the prototype and the definition
    fields = [line.split()[1].rstrip(";") for line in translate.c_struct(LawParameters).splitlines()[1:-1]]
    assert fields == list(LawParameters.__dataclass_fields__)
    assert [n for n, _ in translate.ctypes_struct(LawParameters)._fields_] == fields
    # the nominal mass terms exist once in the sources: control/nominal.py
    hits = [p.name for p in (ROOT / "src").rglob("*.py") if "M11 = J2 +" in p.read_text()] + [
        p.name for p in (ROOT / "src").rglob("*.c") if "M11" in p.read_text()
    ]
    assert hits == ["nominal.py"]
    assert nominal.mass_terms.__module__ == "toggle_cosim.control.nominal"

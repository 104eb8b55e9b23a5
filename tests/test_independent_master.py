"""An independent check of the co-simulation master: the same plant FMU under a master that
does not use fmpy.

`toggle_cosim.cosim.master.simulate` runs a paper run closed loop (plant FMU through fmpy, the VSC in
Python) and records the input sequence it applied: iq_ref (the controller's output) and F_E,
one value per communication point t_k = k T_s. That sequence is then replayed *open loop* into
the same FMU under ecos (`ecospy`, Python bindings of the C++ co-simulation engine ecos; its own
FMI import, fmilibcpp, unzips, loads, initialises and steps the FMU -- no fmpy code is involved),
and the two traces are compared with the project's funnel (`compare_traces`, default tolerances).

Input timing convention (the one the master uses, and the one the replay must match):
the input u_k recorded in the row of t_k is set on the FMU *before* the doStep from t_k to
t_k + T_s, i.e. it is held constant (zero-order hold) over [t_k, t_{k+1}); the outputs in the
row of t_k are read before that input is set, so u_k depends on y_k and acts on y_{k+1}.
Under ecos this is `sim.set_real("plant::iq_ref", u_k)` then `sim.step()`: ecos caches a set
value and its fixed-step algorithm writes the cached values to the FMU (fmi2SetReal) right before
it calls fmi2DoStep, so the value set before step() acts on that step. At initialisation both
masters hold iq_ref = 0 and F_E = the scenario's value (ecos: in the parameter set, which it
applies in initialisation mode, together with m_B, mu, x_B0 and idealCurrentLoop).
A replay one step late (u_{k-1} over [t_k, t_{k+1}), what a master that sets inputs after the
step would do) leaves the funnel: the controller chatters in the sliding phase, so a one-sample
shift is far from harmless; `test_the_funnel_catches_a_one_step_input_delay` keeps that check
honest.

Measured on the reference machine (ecospy 0.7.2, ecos v0.7.2): every output agrees to rounding
(x_B to 4e-16 m in fig4_nominal/friction and 3e-15 m in fig5_external_force/no_friction; the
largest difference of any output is 6e-13 N, in lambda1); ecos's communication times, which it
accumulates as t + T_s, differ from k T_s by 1.1e-13 s at t = 1.5 s. The one-step-late replay
differs by 1.7e-2 m and 2.3e-2 m in x_B.

ecospy loads its native library (libecosc.so) on import, and that library needs Debian's
libtbb12 (`scripts/install-system-deps`). When that system library is missing the tests are
skipped with the reason (shown by pytest's -ra summary); when ecospy itself is not installed
they fail, since it is a test dependency of the project (`pip install -e '.[test]'`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from toggle_cosim.analysis.compare import DEFAULT_TOLERANCE, compare_traces, format_table
from toggle_cosim.cosim.master import RunOutcome, check_and_simulate, plant_settings
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.files.traces import Trace
from toggle_cosim.plant.contract import PlantInterface, check_plant
from toggle_cosim.runs.definition import Run

pytestmark = pytest.mark.slow  # Ecos and FMPy replays of the paper's runs

ROOT = Path(__file__).resolve().parent.parent
RUNS = ("fig4_nominal/friction", "fig5_external_force/no_friction")
# The outputs the check must cover at least (every recorded output of the plant is compared).
REQUIRED = ("x_B", "v_B", "lambda1", "lambda2", "N12", "E_in", "F_C", "i_q")
INSTANCE = "plant"


def _load_ecospy():
    """Import ecospy; skip the module only when its native library cannot find a system library.

    Returns the module, or the message to fail with when ecospy is not installed at all.
    """
    try:
        import ecospy
    except ModuleNotFoundError as error:  # a setup fault: the tests fail (in the `ecospy` fixture), not skip
        return (
            f"ecospy is not installed ({error}); it is a test dependency of toggle-cosim: "
            "pip install -e '.[test]' (scripts/setup does it)"
        )
    except OSError as error:  # raised by ctypes.CDLL(libecosc.so) inside `import ecospy`
        if "cannot open shared object file" not in str(error):
            return f"ecospy is installed but its native library cannot be loaded ({error})"
        pytest.skip(
            f"ecospy's native library cannot be loaded: a system library is missing ({error}); "
            "install it with scripts/install-system-deps (Debian: apt-get install libtbb12)",
            allow_module_level=True,
        )
    return ecospy


ECOSPY = _load_ecospy()  # skips the whole module (before the FMU is built) when libtbb12 is missing


def ecospy_version() -> str:
    from importlib import metadata

    try:
        return metadata.version("ecospy")
    except metadata.PackageNotFoundError:
        return "?"


@pytest.fixture(scope="module")
def ecospy():
    if isinstance(ECOSPY, str):
        pytest.fail(ECOSPY, pytrace=False)
    return ECOSPY


@pytest.fixture(scope="module")
def plant(plant_fmu: Path) -> PlantInterface:
    return check_plant(plant_fmu)


@pytest.fixture(scope="module")
def closed_loop(plant: PlantInterface) -> dict[str, RunOutcome]:
    """The two paper runs under the project's master (fmpy), closed loop."""
    found = {}
    for label in RUNS:
        scenario, variant = label.split("/")
        run = next(r for r in load_scenario(ROOT / "scenarios" / f"{scenario}.yaml") if r.variant == variant)
        outcome = check_and_simulate(run, plant)
        assert outcome.complete, (label, outcome.reason)
        found[label] = outcome
    return found


def replay_under_ecos(
    ecospy, plant: PlantInterface, run: Run, iq_ref: np.ndarray, F_E: np.ndarray, delay: int = 0
) -> Trace:
    """Drive the plant FMU open loop under ecos with the input sequence of a closed-loop trace.

    iq_ref[k], F_E[k] are held over [t_k, t_k + T_s) (delay = 0, the master's convention);
    delay = 1 applies them one step late. Returns the outputs at every communication point,
    with ecos's own time.
    """
    outputs = list(plant.recorded_outputs)
    n = run.steps
    assert len(iq_ref) == len(F_E) == n + 1
    settings: dict[str, float | bool] = {}
    for name, value in plant_settings(run, plant):  # m_B, mu, x_B0, idealCurrentLoop, ... as the master sets them
        settings[f"{INSTANCE}::{name}"] = value if isinstance(value, bool) else float(value)
    settings[f"{INSTANCE}::iq_ref"] = 0.0  # the master's inputs during initialisation
    settings[f"{INSTANCE}::F_E"] = float(run.plant.F_E)
    ids = [f"{INSTANCE}::{name}" for name in outputs]
    data = np.full((n + 1, 1 + len(outputs)), np.nan)
    with ecospy.EcosSimulationStructure() as structure:
        structure.add_model(INSTANCE, str(plant.path))
        structure.add_parameter_set("run", settings)
        with ecospy.EcosSimulation(structure=structure, step_size=run.T_s) as sim:
            if not sim.init(0.0, "run"):
                raise RuntimeError(f"ecos could not initialise {plant.path}: {ecospy.EcosLib.get_last_error()}")
            try:
                for k in range(n + 1):
                    row = data[k]
                    row[0] = sim.get_time()
                    for j, identifier in enumerate(ids, start=1):
                        row[j] = sim.get_real(identifier)
                    if k == n:
                        break
                    source = max(k - delay, 0)
                    sim.set_real(f"{INSTANCE}::iq_ref", float(iq_ref[source]))
                    sim.set_real(f"{INSTANCE}::F_E", float(F_E[source]))
                    sim.step()
            finally:
                sim.terminate()
    return Trace(("time", *outputs), data)


def _reference(outcome: RunOutcome, names: list[str]) -> Trace:
    trace = outcome.trace
    return Trace(("time", *names), np.column_stack([trace.time, *(trace.column(name) for name in names)]))


@pytest.mark.parametrize("label", RUNS)
def test_ecos_replay_agrees_with_the_fmpy_master(ecospy, plant: PlantInterface, closed_loop: dict, label: str) -> None:
    outcome = closed_loop[label]
    run, trace = outcome.run, outcome.trace
    replay = replay_under_ecos(ecospy, plant, run, trace.column("iq_ref"), trace.column("F_E"))

    # Same communication points (ecos accumulates t + T_s; the master uses k T_s).
    assert replay.data.shape == (run.steps + 1, len(replay.names))
    assert np.all(np.isfinite(replay.data))
    assert np.max(np.abs(replay.time - trace.time)) < 1e-9

    names = list(replay.names[1:])
    assert set(REQUIRED) <= set(names)
    reference = _reference(outcome, names)
    comparison = compare_traces(
        replay,
        reference,
        {},
        DEFAULT_TOLERANCE,
        result_label=f"ecos replay of {label}",
        reference_label=f"fmpy master {label}",
    )
    differences = {name: float(np.max(np.abs(replay.column(name) - reference.column(name)))) for name in names}
    print(f"\n{label}: ecospy {ecospy_version()} vs fmpy master, max |difference| per variable:")
    print("  " + ", ".join(f"{name} {value:.1e}" for name, value in differences.items()))
    assert comparison.passed, f"{label}: outside the funnel: {comparison.failed}\n{format_table(comparison)}"
    # Same deterministic FMU, same inputs: the agreement is to rounding, not just within the funnel.
    assert differences["x_B"] < 1e-10, differences
    for name in REQUIRED:
        scale = max(float(np.ptp(reference.column(name))), 1.0)
        assert differences[name] < 1e-9 * scale, (name, differences[name])


def test_the_funnel_catches_a_one_step_input_delay(ecospy, plant: PlantInterface, closed_loop: dict) -> None:
    """The check has teeth: the same replay with every input one step late leaves the funnel."""
    outcome = closed_loop[RUNS[0]]
    run, trace = outcome.run, outcome.trace
    late = replay_under_ecos(ecospy, plant, run, trace.column("iq_ref"), trace.column("F_E"), delay=1)
    names = list(REQUIRED)
    comparison = compare_traces(late, _reference(outcome, names), {}, DEFAULT_TOLERANCE, names)
    assert not comparison["x_B"].passed
    assert math.isfinite(comparison["x_B"].max_error) and comparison["x_B"].max_error > 1e-3

"""Model Exchange from the generic shell (issue 14), checked by tools other than our own.

The same model is built as Co-Simulation (the shell's Dormand-Prince 5(4) at relTol 1e-8,
events located to 1e-12 s) and as Model Exchange, integrated by FMPy's CVODE wrapper at
relTol 1e-10 (BDF, its own root finder). The two are independent integrators and event
locators of the same equations, so they agree to their tolerances or not at all: a wrong
derivative, a lost event or a wrong event mode shows up as millimetres, not micrometres.

Tolerances: x_B within 1e-6 m over 0.3 s (the issue's proposal; measured: 3.3e-8 m with
friction, 1.3e-9 m without, at 1 A), closed loop within 1e-6 m, and the small models within
1e-6 of their analytic / scipy references.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Model, FMU2Slave
from fmpy.validation import validate_fmu
from me_driver import ModelExchangeRun
from scipy.integrate import solve_ivp

from toggle_cosim import __version__
from toggle_cosim.fmu_export import build_fmu
from toggle_cosim.fmu_export.package import write_fmu

pytestmark = pytest.mark.slow  # builds the plant for Model Exchange and FMI 3.0, runs the FMI checkers

ROOT = Path(__file__).resolve().parent.parent
SMALL = ROOT / "tests" / "models" / "ExchangeModels.mo"
TOOL = f"toggle-cosim {__version__} (tests)"


@pytest.fixture(scope="session")
def plant_variants(plant_model, tmp_path_factory):
    """The plant as FMI 2.0 and 3.0, offering CS, ME and both: one compile, six packages."""
    folder = tmp_path_factory.mktemp("variants")
    built = {}
    for version in ("2.0", "3.0"):
        for interfaces in ("cs", "me", "both"):
            path = folder / f"Plant{version[0]}{interfaces}.fmu"
            write_fmu(plant_model, path, TOOL, fmi_version=version, interfaces=interfaces)
            built[version, interfaces] = path
    return built


@pytest.mark.parametrize("version", ["2.0", "3.0"])
@pytest.mark.parametrize("interfaces", ["cs", "me", "both"])
def test_validate_fmu_is_clean(plant_model, plant_variants, version, interfaces):
    path = plant_variants[version, interfaces]
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    assert (md.coSimulation is not None) == (interfaces in ("cs", "both"))
    assert (md.modelExchange is not None) == (interfaces in ("me", "both"))
    assert md.numberOfContinuousStates == 10
    # FMI 3.0 lists event indicators only for Model Exchange (ModelStructure/EventIndicator); the
    # plant has one per `when` condition: the six joint-velocity sign latches of eq. (17) and those
    # of the friction models
    assert plant_model.event_count >= 6
    expected = 0 if (version, interfaces) == ("3.0", "cs") else plant_model.event_count
    assert md.numberOfEventIndicators == expected


@pytest.mark.parametrize("interfaces, refused", [("cs", "ModelExchange"), ("me", "CoSimulation")])
def test_binary_refuses_the_interface_the_description_does_not_offer(plant_variants, interfaces, refused):
    path = str(plant_variants["2.0", interfaces])
    md = read_model_description(path)
    unzipped = extract(path)
    try:
        identifier = (md.coSimulation or md.modelExchange).modelIdentifier
        cls = FMU2Slave if refused == "CoSimulation" else FMU2Model
        fmu = cls(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=identifier, instanceName="x")
        with pytest.raises(Exception, match="Failed to instantiate"):
            fmu.instantiate()
        fmu.freeLibrary()
    finally:
        shutil.rmtree(unzipped, ignore_errors=True)


def test_model_structure_lists_states_derivatives_and_their_dependencies(plant_variants):
    """der(theta1) = omega1 depends on omega1 alone; x_B on the two angles that place it
    (eq. (18)); every state and der(x) is an initial unknown."""
    md = read_model_description(str(plant_variants["2.0", "both"]))
    derivatives = {u.variable.name: u for u in md.derivatives}
    assert list(derivatives) == [
        f"der({s})"
        for s in (
            "motor.i_lag",
            "mechanism.theta1",
            "mechanism.theta2",
            "mechanism.theta5",
            "mechanism.omega1",
            "mechanism.omega2",
            "mechanism.omega5",
            "mechanism.E_in",
            "mechanism.E_load",
            "mechanism.E_fric",
        )
    ]
    assert [v.name for v in derivatives["der(mechanism.theta1)"].dependencies] == ["mechanism.omega1"]
    assert sorted(v.name for v in derivatives["der(motor.i_lag)"].dependencies) == ["iq_ref", "motor.i_lag"]
    (x_b,) = [u for u in md.outputs if u.variable.name == "x_B"]
    assert sorted(v.name for v in x_b.dependencies) == ["mechanism.theta1", "mechanism.theta2"]
    initial = {u.variable.name for u in md.initialUnknowns}
    assert set(derivatives) <= initial and "mechanism.theta1" in initial


def test_declared_dependencies_are_truthful(plant_variants):
    """Perturb each state in turn through fmi2SetContinuousStates: only the derivatives that
    declare a dependency on it may move (over-reporting is allowed, under-reporting not)."""
    md = read_model_description(str(plant_variants["2.0", "me"]))
    states = [u.variable.derivative.name for u in md.derivatives]
    declared = [{v.name for v in u.dependencies} for u in md.derivatives]
    run = ModelExchangeRun(str(plant_variants["2.0", "me"]), {"iq_ref": 1.0})
    try:
        run.advance(0.05)  # away from rest, so velocities and friction terms are non-zero
        x0 = np.array(_states(run))
        base = np.array(_derivatives(run))
        for j, state in enumerate(states):
            x = x0.copy()
            x[j] += 1e-6 * max(1.0, abs(x[j]))
            _set_states(run, x)
            moved = np.abs(np.array(_derivatives(run)) - base) > 0
            for i in np.flatnonzero(moved):
                assert state in declared[i], f"der({states[i]}) moves with {state} but does not declare it"
        _set_states(run, x0)
    finally:
        run.close()


def _states(run: ModelExchangeRun) -> list[float]:
    n = run.description.numberOfContinuousStates
    x = np.zeros(n)
    run.model.fmi2GetContinuousStates(run.model.component, x.ctypes.data_as(_double_p()), n)
    return list(x)


def _derivatives(run: ModelExchangeRun) -> list[float]:
    n = run.description.numberOfContinuousStates
    dx = np.zeros(n)
    run.model.fmi2GetDerivatives(run.model.component, dx.ctypes.data_as(_double_p()), n)
    return list(dx)


def _set_states(run: ModelExchangeRun, x: np.ndarray) -> None:
    x = np.ascontiguousarray(x, dtype=float)
    run.model.fmi2SetContinuousStates(run.model.component, x.ctypes.data_as(_double_p()), len(x))


def _double_p():
    import ctypes

    return ctypes.POINTER(ctypes.c_double)


# ---------------------------------------------------------------------------------------
# The plant: Model Exchange under CVODE against Co-Simulation
# ---------------------------------------------------------------------------------------

INPUT = np.array([(0.0, 1.0, 0.0), (0.3, 1.0, 0.0)], dtype=[("time", float), ("iq_ref", float), ("F_E", float)])
OUTPUTS = ["x_B", "v_B", "solver.events"]


@pytest.mark.parametrize("version", ["2.0", "3.0"])
@pytest.mark.parametrize("mu", [0.2, 0.0], ids=["friction", "frictionless"])
def test_open_loop_model_exchange_matches_co_simulation(plant_variants, version, mu):
    """1 A for 0.3 s from rest, input from a table: FMPy's simulate_fmu as ModelExchange with
    CVode against the same FMU as CoSimulation. With friction (mu = 0.2) the joint-friction
    sign events go through ME event handling (fmi2NewDiscreteStates / fmi3UpdateDiscreteStates)."""
    path = str(plant_variants[version, "both"])
    common = dict(stop_time=0.3, output_interval=5e-4, input=INPUT, start_values={"mu": mu}, output=OUTPUTS)
    cs = simulate_fmu(path, fmi_type="CoSimulation", **common)
    me = simulate_fmu(path, fmi_type="ModelExchange", solver="CVode", relative_tolerance=1e-10, **common)
    assert me["time"][-1] == pytest.approx(0.3)
    x_me = np.interp(cs["time"], me["time"], me["x_B"])
    assert np.max(np.abs(x_me - cs["x_B"])) < 1e-6
    assert abs(cs["x_B"][-1] - 0.2329) > 0.02  # it moved: 27 mm at 1 A (a dead model would pass)
    assert me["solver.events"][-1] > 0 and cs["solver.events"][-1] > 0


X_REF, KP, KD, LIMIT, DT, T_END = 0.215, 300.0, 30.0, 3.0, 5e-4, 0.4


def _pd(x_b: float, v_b: float) -> float:
    """A saturated PD position loop (not the paper's VSC: smooth, so both runs see the same
    law); positive current drives slider B towards smaller x_B."""
    return float(np.clip(KP * (x_b - X_REF) + KD * v_b, -LIMIT, LIMIT))


def test_closed_loop_model_exchange_matches_co_simulation(plant_variants):
    """Closed loop, inputs changing every 0.5 ms: a CS master (fmi2DoStep) and an ME master
    (CVODE restarted at every communication point, state events in event mode) under the
    same sampled controller, with friction. x_B within 1e-6 m over 0.4 s (measured 1.7e-8 m)."""
    path = str(plant_variants["2.0", "both"])
    md = read_model_description(path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzipped = extract(path)
    slave = FMU2Slave(
        guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="cs"
    )
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    steps = int(round(T_END / DT))
    cs = []
    for k in range(steps):
        x_b, v_b = slave.getReal([vr["x_B"], vr["v_B"]])
        cs.append(x_b)
        slave.setReal([vr["iq_ref"]], [_pd(x_b, v_b)])
        slave.doStep(k * DT, DT)
    cs.append(slave.getReal([vr["x_B"]])[0])
    cs_events = slave.getInteger([vr["solver.events"]])[0]
    slave.terminate()
    slave.freeInstance()
    shutil.rmtree(unzipped, ignore_errors=True)

    run = ModelExchangeRun(path)
    me = []
    try:
        for k in range(steps):
            x_b, v_b = run.get(["x_B", "v_B"])
            me.append(x_b)
            run.set_inputs({"iq_ref": _pd(x_b, v_b)})
            run.advance((k + 1) * DT)
        me.append(run.get(["x_B"])[0])
        me_events = run.statistic("solver.events")
    finally:
        run.close()
    cs, me = np.array(cs), np.array(me)
    assert np.max(np.abs(cs - me)) < 1e-6
    assert np.ptp(cs) > 0.05  # the loop really moves the slider (saturated swings of ~10 cm)
    assert cs_events > 5 and me_events > 5


# ---------------------------------------------------------------------------------------
# Small models: bouncing ball (reinit) and Van der Pol, as ME and CS
# ---------------------------------------------------------------------------------------


@pytest.fixture(scope="session")
def small_fmus(tmp_path_factory):
    folder = tmp_path_factory.mktemp("small")
    return {
        name: build_fmu(SMALL, f"ExchangeModels.{name}", folder / f"{name}.fmu").fmu.path
        for name in ("BouncingBall", "VanDerPol")
    }


def _ball(t: np.ndarray, g: float = 9.81, e: float = 0.8, h0: float = 1.0) -> np.ndarray:
    """Analytic height: free fall from rest, each impact reverses v scaled by e."""
    h = np.empty_like(t)
    t_bounce, v_up = np.sqrt(2 * h0 / g), e * np.sqrt(2 * g * h0)
    for i, ti in enumerate(t):
        if ti <= t_bounce:
            h[i] = h0 - 0.5 * g * ti**2
            continue
        start, v = t_bounce, v_up
        while ti > start + 2 * v / g:
            start, v = start + 2 * v / g, e * v
        s = ti - start
        h[i] = v * s - 0.5 * g * s**2
    return h


@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
def test_bouncing_ball_matches_the_analytic_flight(small_fmus, fmi_type):
    """Three impacts in 2 s (t = 0.4515, 1.1741, 1.7521 s); h within 1e-6 m of the analytic
    parabolas at every output point, for CS and for ME under CVODE; the CS FMU counts the
    three reinit events in solver.events."""
    result = simulate_fmu(
        str(small_fmus["BouncingBall"]),
        fmi_type=fmi_type,
        relative_tolerance=1e-10,
        output=["h", "v", "solver.events"],
        record_events=False,
    )
    assert result["time"][-1] == pytest.approx(2.0)
    assert np.max(np.abs(result["h"] - _ball(result["time"]))) < 1e-6
    assert result["solver.events"][-1] == 3


@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
def test_van_der_pol_matches_scipy(small_fmus, fmi_type):
    """mu = 1 from (2, 0) over 10 s (the default experiment): x within 1e-6 of scipy's DOP853
    at rtol 1e-12."""
    result = simulate_fmu(str(small_fmus["VanDerPol"]), fmi_type=fmi_type, relative_tolerance=1e-10, output=["x", "y"])
    reference = solve_ivp(
        lambda t, z: [z[1], (1 - z[0] ** 2) * z[1] - z[0]],
        (0.0, 10.0),
        [2.0, 0.0],
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        t_eval=result["time"],
    )
    assert np.max(np.abs(result["x"] - reference.y[0])) < 1e-6
    assert np.max(np.abs(result["y"] - reference.y[1])) < 1e-6


def test_small_model_default_experiment_comes_from_the_annotation(small_fmus):
    ball = read_model_description(str(small_fmus["BouncingBall"])).defaultExperiment
    assert (float(ball.stopTime), float(ball.stepSize)) == (2.0, 0.001)
    vdp = read_model_description(str(small_fmus["VanDerPol"])).defaultExperiment
    assert (float(vdp.stopTime), float(vdp.stepSize)) == (10.0, 0.01)


def test_without_an_experiment_annotation_there_is_no_stop_time():
    """Nothing model-specific in the generic build: a model without the annotation gets only
    the shell's tolerance (solver.relTol's default) in <DefaultExperiment>."""
    from modelica import lang
    from toggle_cosim.fmu_export.experiment import ExperimentError, experiment_of

    plain = lang.parse("model M Real x(start = 1); equation der(x) = -x; end M;").find("M")
    assert experiment_of(plain, "M").attributes(default_tolerance=1e-8) == {"tolerance": "1e-08"}
    annotated = lang.parse(
        "model M Real x(start = 1); equation der(x) = -x; "
        "annotation(experiment(StartTime = 0, StopTime = 3, Tolerance = 1e-6, Interval = 0.1)); end M;"
    ).find("M")
    assert experiment_of(annotated, "M").attributes(default_tolerance=1e-8) == {
        "startTime": "0.0",
        "stopTime": "3.0",
        "tolerance": "1e-06",
        "stepSize": "0.1",
    }
    bad = lang.parse('model M Real x; equation der(x) = -x; annotation(experiment(StopTime = "x")); end M;').find("M")
    with pytest.raises(ExperimentError, match="StopTime"):
        experiment_of(bad, "M")


@pytest.mark.parametrize("name, variable", [("BouncingBall", "h"), ("VanDerPol", "x")])
def test_small_models_agree_as_model_exchange_and_co_simulation(small_fmus, name, variable):
    """The same FMU, both interfaces, on the default experiment's output grid: within 1e-6."""
    runs = {
        kind: simulate_fmu(
            str(small_fmus[name]), fmi_type=kind, relative_tolerance=1e-10, output=[variable], record_events=False
        )
        for kind in ("CoSimulation", "ModelExchange")
    }
    cs, me = runs["CoSimulation"], runs["ModelExchange"]
    np.testing.assert_allclose(me["time"], cs["time"], rtol=0, atol=1e-12)
    assert np.max(np.abs(me[variable] - cs[variable])) < 1e-6


def test_model_exchange_fmu_state_round_trip(plant_variants):
    """fmi2GetFMUstate / fmi2SetFMUstate in continuous-time mode restore time, states and the
    event conditions: integrating on from the restored state repeats the first continuation
    (CVODE restarted at the same point both times) bit for bit."""
    run = ModelExchangeRun(str(plant_variants["2.0", "me"]), {"iq_ref": 1.0})
    try:
        run.advance(0.05)
        saved, t_saved = run.model.getFMUstate(), run.time
        x_saved = _states(run)
        run.solver.reset(run.time)
        run.advance(0.1)
        first = (_states(run), run.get(["x_B", "v_B"]), run.statistic("solver.events"))
        run.model.setFMUstate(saved)
        run.time = t_saved
        assert _states(run) == x_saved
        run.solver.reset(run.time)
        run.advance(0.1)
        second = (_states(run), run.get(["x_B", "v_B"]), run.statistic("solver.events"))
        assert second == first
        run.model.freeFMUstate(saved)
    finally:
        run.close()

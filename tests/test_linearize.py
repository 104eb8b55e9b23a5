"""Trim and linearise the plant FMU (issue 28, item 1), checked against the model's own equations.

The reference is `reference_dynamics.py` (independent of toggle_cosim: eq. (18) from point
Jacobians, solved by the Schur complement), reduced to the mechanism's one degree of freedom
exactly as docs/model.md states it: q(θ1) from the two loop closures, q̇ = t(θ1) ω1 with
Φ_q t = 0, θ̈1 from eq. (18) with F_C = K_f i_q, and the current loop di_q/dt = K (i_q* − i_q).
The test trims it (brentq on θ̈1 = 0) and differentiates it with a five-point stencil
(truncation ~h⁴, about 1e-12 here), then compares with `linearize` of the FMU at points along
the stroke, near both ends of the working range and on both sides of each fold: under
F_E = 100 N the holding current i_q*(x_B) has a minimum near x_B = 0.23 m and a maximum near
0.297 m, the folds of the family of equilibria, where the held mechanism's stiffness changes
sign and the open-loop pole pair passes through 0 (an imaginary pair between the folds, a real
pair outside them; without F_E the pair is real over the whole stroke):

* the holding current within 1e-9 relative;
* the eigenvalues within 1e-6 relative;
* the frequency response iq_ref → x_B over 0.1 to 1000 rad/s within 1e-6 relative.

A linearisation with a wrong sign, a missed dependent rate (δq̇ off the manifold) or the
Baumgarte modes mixed in fails these by orders of magnitude (the constraint modes sit at
−20 1/s, the mechanical ones at a few rad/s).
"""

from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
import pytest
from reference_dynamics import reference_accelerations
from scipy.optimize import brentq

import toggle_cosim as tc
from toggle_cosim.api.simulation import checked_plant
from toggle_cosim.design.linearize import linearize
from toggle_cosim.design.trim import TrimError, trim
from toggle_cosim.physics.motor import thrust_constant
from toggle_cosim.physics.parameters import MechanismParameters, MotorParameters

ROOT = Path(__file__).resolve().parent.parent
K_F = thrust_constant(MotorParameters())
FREQUENCIES = np.logspace(-1, 3, 41)  # rad/s


@pytest.fixture(scope="module")
def plant(plant_fmu):
    return checked_plant(plant_fmu)


@pytest.fixture(scope="module")
def base_run():
    return tc.load_scenario(ROOT / "scenarios" / "fig5_external_force.yaml")["friction"]


def with_load(run, F_E: float, m_B: float, current_loop: str = "first_order"):
    return dataclasses.replace(run, plant=dataclasses.replace(run.plant, F_E=F_E, m_B=m_B, current_loop=current_loop))


class Reduced:
    """The reference model on the constraint manifold: z = (θ1, ω1, i_q), u = (i_q*, F_E)."""

    def __init__(self, F_E: float, m_B: float, K: float = 350.0, ideal: bool = False) -> None:
        self.p = dataclasses.replace(MechanismParameters(), mB=m_B, mu=0.0)
        self.params = self.p.as_dict()
        self.F_E, self.K, self.ideal = F_E, K, ideal

    def q(self, theta1: float) -> np.ndarray:
        p = self.p
        theta2 = math.asin((p.f - p.r1 * math.sin(theta1)) / p.r3)
        theta5 = math.asin((p.h - p.r4 * math.sin(theta1 + p.phi)) / p.r5)
        return np.array([theta1, theta2, theta5])

    def tangent(self, q: np.ndarray) -> np.ndarray:
        p = self.p
        return np.array(
            [
                1.0,
                -p.r1 * math.cos(q[0]) / (p.r3 * math.cos(q[1])),
                -p.r4 * math.cos(q[0] + p.phi) / (p.r5 * math.cos(q[2])),
            ]
        )

    def x_B(self, theta1: float) -> float:
        q = self.q(theta1)
        return self.p.r1 * math.cos(q[0]) + self.p.r3 * math.cos(q[1])

    def alpha1(self, theta1: float, omega1: float, current: float, F_E: float) -> float:
        q = self.q(theta1)
        qdd, _ = reference_accelerations(q, self.tangent(q) * omega1, K_F * current, F_E, self.params, np.zeros(3))
        return float(qdd[0])

    def f(self, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        theta1, omega1, current = z
        drive = u[0] if self.ideal else current
        return np.array([omega1, self.alpha1(theta1, omega1, drive, u[1]), self.K * (u[0] - current)])

    def g(self, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        h = 1e-7
        dxB = (self.x_B(z[0] + h) - self.x_B(z[0] - h)) / (2 * h)  # only v_B uses it: not compared
        return np.array([self.x_B(z[0]), dxB * z[1], z[0]])

    def trim(self, x_B: float) -> tuple[np.ndarray, float]:
        theta1 = brentq(lambda t: self.x_B(t) - x_B, -math.pi + 1e-3, -1e-3, xtol=1e-15)
        current = brentq(lambda i: self.alpha1(theta1, 0.0, i, self.F_E), -100.0, 100.0, xtol=1e-14)
        return np.array([theta1, 0.0, current]), current

    def jacobian(self, fun, x0: np.ndarray, steps: np.ndarray) -> np.ndarray:
        columns = []
        for k, h in enumerate(steps):
            e = np.zeros(len(x0))
            e[k] = h
            columns.append((-fun(x0 + 2 * e) + 8 * fun(x0 + e) - 8 * fun(x0 - e) + fun(x0 - 2 * e)) / (12 * h))
        return np.column_stack(columns)

    def linear(self, x_B: float):
        z0, current = self.trim(x_B)
        u0 = np.array([current, self.F_E])
        zs, us = np.array([1e-3, 1e-3, 1e-3]), np.array([1e-3, 1e-2])
        A = self.jacobian(lambda z: self.f(z, u0), z0, zs)
        B = self.jacobian(lambda u: self.f(z0, u), u0, us)
        C = self.jacobian(lambda z: self.g(z, u0), z0, zs)
        if self.ideal:
            A, B, C = A[:2, :2], B[:2], C[:, :2]
        return A, B, C, current


def frequency_response(A, B, C, w):
    n = A.shape[0]
    return np.array([(C[0] @ np.linalg.solve(1j * wk * np.eye(n) - A, B[:, 0])) for wk in w])


def relative(a, b):
    return np.max(np.abs(a - b) / np.abs(b))


POINTS = [0.19, 0.2329, 0.25, 0.27, 0.2864, 0.30, 0.3199, 0.35]


@pytest.mark.parametrize("F_E, m_B", [(0.0, 4.43), (100.0, 4.43), (0.0, 8.86)])
def test_linearize_matches_the_model_equations_along_the_stroke(plant, base_run, F_E, m_B):
    run = with_load(base_run, F_E, m_B)
    reference = Reduced(F_E, m_B)
    kinds = set()
    for x_B in POINTS:
        point = trim(run, x_B, plant)
        A, B, C, current = reference.linear(x_B)
        assert point.iq_ref == pytest.approx(current, rel=1e-9, abs=1e-12), x_B
        model = linearize(run, point, plant)
        assert model.states == ("theta1", "omega1", "i_lag") and model.inputs == ("iq_ref", "F_E")
        assert model.outputs == ("x_B", "v_B", "theta1")
        ours, theirs = np.sort_complex(model.eigenvalues()), np.sort_complex(np.linalg.eigvals(A))
        assert relative(ours, theirs) < 1e-6, (x_B, ours, theirs)
        assert (
            relative(
                frequency_response(model.A, model.B, model.C, FREQUENCIES), frequency_response(A, B, C, FREQUENCIES)
            )
            < 1e-6
        ), x_B
        assert model.relative_error < 1e-6  # the reported estimate is small where the agreement is
        kinds.add("oscillating" if A[1, 0] < 0 else "diverging")
    assert kinds == ({"oscillating", "diverging"} if F_E == 100.0 else {"diverging"})


def test_the_folds_are_where_the_holding_current_turns(plant, base_run):
    """Under F_E = 100 N. On the manifold θ̈1 = F(θ1, i) and at a trimmed point F(θ1(x), i*(x)) = 0,
    so di*/dx_B = −F_θ (dθ1/dx_B) / F_i: the holding current turns exactly where the stiffness
    A[1, 0] = F_θ changes sign, the pole pair passing through 0 from real to imaginary. Both from
    the FMU: the trimmed currents on a 3 mm grid and the linear models there."""
    run = with_load(base_run, 100.0, 4.43)
    grid = np.arange(0.200, 0.3401, 0.003)
    points = [trim(run, x, plant) for x in grid]
    current = np.array([point.iq_ref for point in points])
    stiffness = np.array([linearize(run, point, plant).A[1, 0] for point in points[1:-1]])
    slope = (current[2:] - current[:-2]) / (grid[2:] - grid[:-2])
    turns = grid[1:-1][np.nonzero(np.diff(np.sign(slope)))[0]]
    folds = grid[1:-1][np.nonzero(np.diff(np.sign(stiffness)))[0]]
    assert len(turns) == 2 and len(folds) == 2
    assert np.allclose(turns, folds, atol=0.0031)  # the same place, to the grid
    assert 0.226 < folds[0] < 0.234 and 0.292 < folds[1] < 0.300
    inside = (grid[1:-1] > folds[0] + 0.003) & (grid[1:-1] < folds[1] - 0.003)
    assert np.all(stiffness[inside] < 0) and np.all(
        stiffness[(grid[1:-1] < folds[0] - 0.003) | (grid[1:-1] > folds[1] + 0.003)] > 0
    )


def test_ideal_current_loop_drops_the_current_state(plant, base_run):
    run = with_load(base_run, 100.0, 4.43, current_loop="ideal")
    model = linearize(run, trim(run, 0.28, plant), plant)
    A, B, C, _ = Reduced(100.0, 4.43, ideal=True).linear(0.28)
    assert model.states == ("theta1", "omega1")
    assert relative(np.sort_complex(model.eigenvalues()), np.sort_complex(np.linalg.eigvals(A))) < 1e-6
    assert (
        relative(frequency_response(model.A, model.B, model.C, FREQUENCIES), frequency_response(A, B, C, FREQUENCIES))
        < 1e-6
    )


def test_fmu_coordinates_hold_the_same_mechanics_and_the_constraint_modes(plant, base_run):
    """All ten FMU states: the mechanical poles and -K as on the manifold, four constraint modes at
    -baumgarte (20 1/s, a double root per closure: known to ~sqrt(eps)), three integrators at 0."""
    run = with_load(base_run, 100.0, 4.43)
    point = trim(run, 0.28, plant)
    full = linearize(run, point, plant, coordinates="fmu")
    reduced = linearize(run, point, plant)
    assert len(full.states) == 10
    poles = full.eigenvalues()
    for p in reduced.eigenvalues():
        assert np.min(np.abs(poles - p)) < 1e-6 * abs(p)
    assert np.sum(np.abs(poles + 20.0) < 1e-3) == 4
    assert np.sum(np.abs(poles) < 1e-9) == 3
    assert (
        relative(
            frequency_response(full.A, full.B, full.C, FREQUENCIES),
            frequency_response(reduced.A, reduced.B, reduced.C, FREQUENCIES),
        )
        < 1e-6
    )


def test_trim_reports_friction_and_refuses_points_outside_the_working_range(plant, base_run):
    point = trim(base_run, 0.28, plant)
    assert base_run.plant.mu == 0.2 and point.friction_free and "friction-free" in point.warnings[0]
    assert point.outputs["x_B"] == pytest.approx(0.28, abs=1e-12) and point.residual < 1e-9
    assert not trim(
        dataclasses.replace(base_run, plant=dataclasses.replace(base_run.plant, mu=0.0)), 0.28, plant
    ).warnings
    for x_B in (0.1, 0.4, math.nan):
        with pytest.raises(TrimError, match="x_B"):
            trim(base_run, x_B, plant)
    with pytest.raises(TrimError, match="not a recorded output"):
        linearize(base_run, point, plant, outputs=("nope",))
    with pytest.raises(TrimError, match="'E_in' depends on mechanism.E_in"):
        linearize(base_run, point, plant, outputs=("E_in",))
    full = linearize(base_run, point, plant, outputs=("E_in",), coordinates="fmu")
    assert full.C[full.outputs.index("E_in"), full.states.index("E_in")] == pytest.approx(1.0)


def test_linearize_at_one_point_takes_under_a_second(plant, base_run):
    started = time.perf_counter()
    model = linearize(base_run, trim(base_run, 0.28, plant), plant, outputs=("i_q", "F_C"))
    assert time.perf_counter() - started < 1.0
    assert model.units["F_C"] == "N" and model.units["theta1"] == "rad" and model.units["iq_ref"] == "A"
    assert model.system.nstates == 3  # python-control's StateSpace, named
    assert model.system.input_labels == ["iq_ref", "F_E"]
    assert "no directional derivatives" in model.method  # the shipped FMU does not provide them


def test_a_plant_without_model_exchange_or_in_fmi3_is_refused_in_one_line(plant, base_run):
    import copy

    from toggle_cosim.design.model_exchange import ModelExchangeError

    cs_only = copy.copy(plant.model_description)
    cs_only.modelExchange = None
    with pytest.raises(ModelExchangeError, match="offers no Model Exchange interface"):
        trim(base_run, 0.28, dataclasses.replace(plant, model_description=cs_only))
    fmi3 = copy.copy(plant.model_description)
    fmi3.fmiVersion = "3.0"
    with pytest.raises(ModelExchangeError, match="FMI 2.0 plants"):
        trim(base_run, 0.28, dataclasses.replace(plant, model_description=fmi3))


def test_the_command_writes_npz_and_mat_and_refuses_bad_input(plant_fmu, tmp_path):
    from click.testing import CliRunner
    from scipy.io import loadmat

    from toggle_cosim.cli import main

    scenario = ROOT / "scenarios" / "fig5_external_force.yaml"
    common = [str(scenario), "--fmu", str(plant_fmu), "--variant", "friction", "--x-B", "0.28"]
    npz, mat = tmp_path / "lin.npz", tmp_path / "lin.mat"
    result = CliRunner().invoke(main, ["linearize", *common, "--out", str(npz), "--output", "i_q"])
    assert result.exit_code == 0, result.output
    assert "friction-free" in result.output and "i_q* = 1.87955 A" in result.output
    saved = np.load(npz)
    assert list(saved["states"]) == ["theta1", "omega1", "i_lag"] and list(saved["inputs"]) == ["iq_ref", "F_E"]
    assert list(saved["outputs"]) == ["x_B", "v_B", "theta1", "i_q"] and list(saved["output_units"])[0] == "m"
    assert saved["u0"][0] == pytest.approx(1.87955, abs=1e-5) and float(saved["x_B"]) == pytest.approx(0.28)
    result = CliRunner().invoke(main, ["linearize", *common, "--out", str(mat)])
    assert result.exit_code == 0, result.output
    assert np.array_equal(loadmat(mat)["A"], saved["A"])
    for args, message in [
        ([*common[:-1], "0.5", "--out", str(tmp_path / "far.npz")], "outside the working range"),
        ([*common, "--out", str(tmp_path / "lin.txt")], "must end in .npz or .mat"),
        ([*common[:3], "--variant", "nope", "--x-B", "0.28", "--out", str(tmp_path / "v.npz")], "no variant 'nope'"),
        ([*common, "--out", str(tmp_path / "o.npz"), "--output", "nope"], "not a recorded output"),
    ]:
        result = CliRunner().invoke(main, ["linearize", *args])
        assert result.exit_code == 2 and message in result.output, result.output
        assert len(result.output.strip().splitlines()) <= 2  # a warning line at most, then the error
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lin.mat", "lin.npz"]  # nothing half-written
    first = tmp_path / "first.npz"  # without --variant: the scenario's first variant (friction), named
    result = CliRunner().invoke(main, ["linearize", *common[:3], "--x-B", "0.28", "--out", str(first)])
    assert result.exit_code == 0 and "fig5_external_force/friction at x_B = 0.28 m" in result.output, result.output
    assert np.array_equal(np.load(first)["A"], saved["A"])


def test_without_python_control_the_model_names_the_extra(plant, base_run, monkeypatch):
    import sys

    model = linearize(base_run, trim(base_run, 0.28, plant), plant)
    monkeypatch.setitem(sys.modules, "control", None)  # as if python-control were not installed
    with pytest.raises(ModuleNotFoundError, match=r"pip install 'toggle-cosim\[design\]'"):
        _ = model.system
    assert model.A.shape == (3, 3)  # the matrices need no extra


@pytest.mark.parametrize("x_B", [0.5, 0.05])
def test_a_point_beyond_the_linkages_reach_is_one_line(plant_fmu, tmp_path, x_B):
    """A plant.working_range may reach past the toggle's dead points; a point beyond them (where
    the plant cannot be initialised) is refused naming the value and the reach, nothing written."""
    import yaml
    from click.testing import CliRunner

    from toggle_cosim.cli import main

    document = yaml.safe_load((ROOT / "scenarios" / "fig5_external_force.yaml").read_text())
    document["plant"]["working_range"] = [0.01, 0.9]
    scenario = tmp_path / "wide.yaml"
    scenario.write_text(yaml.safe_dump({**document, "fmu": str(plant_fmu)}))
    out = tmp_path / "far.npz"
    result = CliRunner().invoke(main, ["linearize", str(scenario), "--x-B", str(x_B), "--out", str(out)])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2 and "Traceback" not in result.output and not out.exists(), result.output
    assert lines[-1].startswith(f"error: {scenario}: x_B = {x_B:g} m is beyond the linkage's reach, 0.17 m (folded)")
    assert len(lines) <= 2  # the friction-free warning at most, then the error


def test_a_system_is_refused_naming_what_linearize_would_drop(plant_fmu, press_parts, tmp_path):
    """The press example (a sensor, and a die whose force feeds plant.F_E): `linearize` would take
    the plant alone at F_E = 0, so it refuses in one line naming the parts and the connection into
    the plant, exit 2, nothing written; tc.trim and tc.linearize raise the same TrimError. The
    pair with a `record:` list alone is still the plant's run."""
    from click.testing import CliRunner

    from toggle_cosim.cli import main
    from toggle_cosim.system.model import Port, Wiring

    source = (ROOT / "examples" / "press_system" / "press.yaml").read_text(encoding="utf-8")
    for name, path in press_parts.items():
        source = source.replace(f"../../fmus/{name}.fmu", str(path))
    scenario = tmp_path / "press.yaml"
    scenario.write_text(source.replace("../../fmus/ToggleLSM.fmu", str(plant_fmu)), encoding="utf-8")
    out = tmp_path / "press.npz"
    result = CliRunner().invoke(main, ["linearize", str(scenario), "--x-B", "0.3", "--out", str(out)])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1, result.output
    assert lines[0].startswith(f"error: {scenario}: keys components:/connections: press_system/paper is a system")
    assert "components sensor, die; connections die.F -> plant.F_E" in lines[0]
    assert not out.exists()
    run = tc.load_scenario(scenario)["paper"]
    with pytest.raises(TrimError, match="would drop them"):
        tc.trim(run, 0.3)
    point = trim(
        plant=checked_plant(plant_fmu),
        run=tc.load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")["friction"],
        x_B=0.3,
    )
    with pytest.raises(TrimError, match="would drop them"):
        tc.linearize(run, point)
    recorded = dataclasses.replace(run, system=Wiring(record=(Port("plant", "x_B"),)))
    assert tc.trim(recorded, 0.3, fmu=plant_fmu).x_B == pytest.approx(0.3)

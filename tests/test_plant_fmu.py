"""The plant FMU built from the Modelica source, checked against the physics it must obey.

Each test names what it checks: the FMI validation, the thrust constant of eq. (16), the two
loop-closure constraints, the energy balance, an independent numpy evaluation of eq. (18),
the initial angles of eq. (26), the integrator's convergence, and a clean error status where
the model cannot proceed.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu
from reference_dynamics import reference_accelerations, reference_joint_forces

MECHANISM = dict(
    r1=0.10,
    r3=0.27,
    r4=0.10,
    r5=0.27,
    f=0.0,
    h=0.10,
    phi=math.radians(166.0),
    m2=0.8,
    J2=0.003,
    m3=0.3,
    m5=0.3,
    mC=1.5,
    g=9.81,
)


class Plant:
    """The FMU under a tiny test master: parameters by name, outputs by name."""

    def __init__(self, path: Path, **parameters: float | bool) -> None:
        self.md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.types = {v.name: v.type for v in self.md.modelVariables}
        self.dir = extract(str(path))
        self.fmu = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=self.dir,
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName="test",
        )
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0)
        for name, value in parameters.items():
            self.set(name, value)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        self.t = 0.0

    def set(self, name: str, value: float | bool) -> None:
        if self.types[name] == "Boolean":
            self.fmu.setBoolean([self.vr[name]], [bool(value)])
        else:
            self.fmu.setReal([self.vr[name]], [float(value)])

    def get(self, *names: str) -> list[float]:
        return self.fmu.getReal([self.vr[n] for n in names])

    def step(self, h: float) -> None:
        self.fmu.doStep(self.t, h)
        self.t += h

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.dir, ignore_errors=True)


def test_fmu_validates_and_steps(plant_fmu: Path) -> None:
    """fmpy's validator finds no problem; FMU2Slave instantiates, initialises and steps it."""
    assert validate_fmu(str(plant_fmu)) == []
    plant = Plant(plant_fmu)
    plant.set("iq_ref", 1.0)
    for _ in range(10):
        plant.step(1e-3)
    assert plant.get("x_B")[0] > 0.2329
    plant.close()


def test_thrust_constant_from_field_model(plant_fmu: Path) -> None:
    """Eq. (16): with i_q* = 1 A and an ideal current loop, F_C = K_f * 1 A = 56.959 N."""
    mu0 = 4e-7 * math.pi
    tau, P_m, B_r, L_m, alpha, K_C, G, L_A, K_w1, W, p = 0.1143, 2, 0.86, 0.00635, 0.67, 1, 0.002, 0.1016, 0.955, 96, 1
    F1 = 6 * math.sqrt(2) / (K_C * math.pi) * K_w1 * W / p
    B_x = mu0 * math.pi / tau * F1 * math.sinh(math.pi * L_m / tau) / math.sinh(math.pi * (G + L_m) / tau)
    K_f = 2 * tau / (mu0 * math.pi) * B_r * P_m * L_A * B_x * math.sin(alpha * math.pi / 2)
    plant = Plant(plant_fmu, idealCurrentLoop=True)
    plant.set("iq_ref", 1.0)
    plant.step(1e-4)
    F_C, i_q = plant.get("F_C", "i_q")
    plant.close()
    assert i_q == 1.0
    assert abs(F_C - K_f) / K_f < 1e-12
    assert abs(F_C - 56.959) / 56.959 < 1e-5  # the spec's value, given to five digits


def test_initial_angles_of_eq_26(plant_fmu: Path) -> None:
    """Eq. (26): theta1 = -100.71 deg at x_B = 0.2329 m and -51.95 deg at 0.3199 m."""
    for x_B0, expected in ((0.2329, -100.71), (0.3199, -51.95)):
        plant = Plant(plant_fmu, x_B0=x_B0)
        theta1, x_B, phi1, phi2 = plant.get("theta1", "x_B", "Phi1", "Phi2")
        plant.close()
        assert abs(math.degrees(theta1) - expected) < 0.005
        assert abs(x_B - x_B0) < 1e-12
        assert abs(phi1) < 1e-14 and abs(phi2) < 1e-14


def _open_loop(
    plant_fmu: Path, t_end: float = 0.3, h: float = 5e-4, **parameters: float | bool
) -> dict[str, np.ndarray]:
    """A 0.3 s open-loop run: a current command that accelerates, then brakes the mechanism."""
    plant = Plant(plant_fmu, **parameters)
    names = ("x_B", "Phi1", "Phi2", "E_in", "E_mech", "E_fric", "E_load", "v_B")
    rows = []
    n = int(round(t_end / h))
    for k in range(n):
        t = k * h
        plant.set("iq_ref", 4.0 if t < 0.15 else -2.5)
        rows.append(plant.get(*names))
        plant.step(h)
    rows.append(plant.get(*names))
    plant.close()
    data = np.array(rows)
    return {name: data[:, i] for i, name in enumerate(names)}


def test_constraints_and_energy_balance_with_friction(plant_fmu: Path) -> None:
    """Over 0.3 s open loop with mu = 0.2 and F_E = 50 N: |Phi| < 1e-8 m, and
    E_in = (E_mech - E_mech(0)) + E_fric + E_load to 1e-4 of E_in."""
    run = _open_loop(plant_fmu, mu=0.2, F_E=50.0)
    assert run["x_B"][-1] - run["x_B"][0] > 0.01  # the mechanism really moved
    assert np.max(np.abs(run["Phi1"])) < 1e-8
    assert np.max(np.abs(run["Phi2"])) < 1e-8
    balance = run["E_in"] - (run["E_mech"] - run["E_mech"][0]) - run["E_fric"] - run["E_load"]
    assert np.max(np.abs(balance)) < 1e-4 * np.max(np.abs(run["E_in"]))
    assert np.max(np.abs(run["E_fric"])) > 1e-3 * np.max(np.abs(run["E_in"]))  # friction took part


def test_halving_the_internal_step_changes_x_B_by_less_than_1e_7(plant_fmu: Path) -> None:
    """Convergence: the FMU's integrator with its maximum step halved (and its tolerance
    tightened tenfold) moves x_B over a 0.3 s run by less than 1e-7 m."""
    coarse = _open_loop(plant_fmu, mu=0.2, **{"solver.maxStep": 1e-4})
    fine = _open_loop(plant_fmu, mu=0.2, **{"solver.maxStep": 5e-5})
    tight = _open_loop(plant_fmu, mu=0.2, **{"solver.relTol": 1e-9})
    default = _open_loop(plant_fmu, mu=0.2)
    assert np.max(np.abs(coarse["x_B"] - fine["x_B"])) < 1e-7
    assert np.max(np.abs(default["x_B"] - tight["x_B"])) < 1e-7


def test_fmu_matches_independent_numpy_evaluation(plant_fmu: Path) -> None:
    """Accelerations and multipliers of eq. (18) from the FMU agree with tests/reference_dynamics.py
    (built from body Jacobians and solved by a Schur complement) to 1e-8 relative, at states the
    FMU reaches under random inputs, masses, friction and loads."""
    rng = np.random.default_rng(2001)
    names = (
        "mechanism.theta1",
        "mechanism.theta2",
        "mechanism.theta5",
        "mechanism.omega1",
        "mechanism.omega2",
        "mechanism.omega5",
        "mechanism.alpha1",
        "mechanism.alpha2",
        "mechanism.alpha5",
        "lambda1",
        "lambda2",
        "F_C",
        "mechanism.sgn1",
        "mechanism.sgn2",
        "mechanism.sgn5",
        "N12",
        "N23",
        "N34",
        "N25",
        "N56",
    )
    checked = 0
    for trial in range(6):
        m_B = rng.uniform(3.0, 9.0)
        mu = (0.0, 0.2)[trial % 2]
        F_E = rng.uniform(0.0, 150.0)
        plant = Plant(plant_fmu, m_B=m_B, mu=mu, x_B0=rng.uniform(0.24, 0.30))
        plant.set("F_E", F_E)
        for _ in range(8):
            plant.set("iq_ref", rng.uniform(-6.0, 8.0))
            plant.step(rng.uniform(0.002, 0.01))
            values = dict(zip(names, plant.get(*names), strict=True))
            q = [values["mechanism.theta1"], values["mechanism.theta2"], values["mechanism.theta5"]]
            qd = [values["mechanism.omega1"], values["mechanism.omega2"], values["mechanism.omega5"]]
            sgn = [values["mechanism.sgn1"], values["mechanism.sgn2"], values["mechanism.sgn5"]]
            params = {**MECHANISM, "mB": m_B, "mu": mu}
            qdd, lam = reference_accelerations(q, qd, values["F_C"], F_E, params, sgn)
            fmu_qdd = np.array([values["mechanism.alpha1"], values["mechanism.alpha2"], values["mechanism.alpha5"]])
            fmu_lam = np.array([values["lambda1"], values["lambda2"]])
            assert np.allclose(fmu_qdd, qdd, rtol=1e-8, atol=1e-8 * np.max(np.abs(qdd)))
            assert np.allclose(fmu_lam, lam, rtol=1e-8, atol=1e-8 * np.max(np.abs(lam)))
            forces = reference_joint_forces(q, qd, values["F_C"], F_E, params, sgn)["normal"]
            for joint in ("12", "23", "34", "25", "56"):
                assert values[f"N{joint}"] == pytest.approx(forces[joint], rel=1e-7, abs=1e-9)
            checked += 1
        plant.close()
    assert checked == 48


def test_unreachable_start_is_an_error_status_not_a_crash(plant_fmu: Path) -> None:
    """x_B0 beyond the toggle position (0.37 m) has no initial angles: initialisation must
    report an error status, and the instance must still be freed cleanly."""
    md = read_model_description(str(plant_fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzipped = extract(str(plant_fmu))
    fmu = FMU2Slave(
        guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bad"
    )
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.setReal([vr["x_B0"]], [0.5])
    with pytest.raises(FMICallException):
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        fmu.doStep(0.0, 1e-3)
    fmu.freeInstance()
    shutil.rmtree(unzipped, ignore_errors=True)

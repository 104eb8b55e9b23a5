"""Reference trajectories (control/trajectory.py) and the built-in laws tracking them.

* The profiles themselves: the velocity, acceleration and jerk limits hold, the target is
  reached at rest, position and velocity (and an S-curve's acceleration) are continuous, the
  rate and acceleration are the derivatives of the position, the durations are the closed
  forms', a cycle extends and retracts `repeat` times with its dwells.
* The scenario keys (stroke.trajectory): one-line errors for what cannot be tracked; a sweep
  axis stroke.trajectory.v_max.
* Tracking on the plant with joint friction (μ = 0.2), both laws: the error during a
  trapezoidal move and at its end is reported and bounded, and the feed-forward q̈*/G of the
  equivalent control is what keeps it small (without it the error is many times larger).
* The same bits in the Python loop and the compiled loop on a trajectory run.
(The constant target's traces are the stored references, unchanged: test_references.py; the
shipped press cycle runs in both loops in test_compiled_loop.py.)
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from toggle_cosim.cli import main
from toggle_cosim.control.trajectory import ProfileSpec, SampledReference, build, evaluate, sample
from toggle_cosim.cosim.controllers import builtin_controller
from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments.scenario import ScenarioError, runs_from_document
from toggle_cosim.experiments.sweep import load_sweep
from toggle_cosim.plant.contract import check_plant

X0, X1 = 0.2329, 0.3199  # the paper's stroke [m]
T_S = 0.0005

PROFILES = {
    "trapezoid": ProfileSpec("trapezoid", X0, X1, v_max=0.2, a_max=2.0),
    "triangle": ProfileSpec("trapezoid", X1, X0, v_max=0.5, a_max=2.0),  # short: v_max not reached
    "scurve": ProfileSpec("scurve", X0, X1, v_max=0.2, a_max=2.0, j_max=40.0),
    "scurve_no_a_max": ProfileSpec("scurve", X1, X0, v_max=0.2, a_max=2.0, j_max=5.0),  # a_max not reached
    "scurve_short": ProfileSpec("scurve", X0, X0 + 0.002, v_max=0.2, a_max=2.0, j_max=40.0),  # neither
    "cycle": ProfileSpec("cycle", X0, X1, v_max=0.2, a_max=2.0, dwell=0.2, repeat=3, t_start=0.05),
    "cycle_scurve": ProfileSpec("cycle", X0, X1, v_max=0.2, a_max=2.0, j_max=40.0, dwell=0.1, repeat=2),
}


@pytest.mark.parametrize("name", PROFILES)
def test_the_profile_respects_its_limits_reaches_its_target_and_is_continuous(name: str) -> None:
    spec = PROFILES[name]
    trajectory = build(spec)
    end = trajectory.end
    t = np.linspace(0.0, end + 0.1, 20001)
    values = np.array([evaluate(trajectory, float(time)) for time in t])
    x, v, a = values.T
    assert np.max(np.abs(v)) <= spec.v_max * (1 + 1e-12)
    assert np.max(np.abs(a)) <= spec.a_max * (1 + 1e-12)
    if spec.j_max is not None:
        assert max(abs(s.jerk) for s in trajectory.segments) <= spec.j_max
    # never beyond the stroke's ends; at rest at the end point after the profile
    assert np.min(x) >= min(spec.x_start, spec.x_target) - 1e-12
    assert np.max(x) <= max(spec.x_start, spec.x_target) + 1e-12
    final = spec.x_start if spec.kind == "cycle" else spec.x_target
    assert evaluate(trajectory, end) == (final, 0.0, 0.0)
    assert evaluate(trajectory, -1.0) == (spec.x_start, 0.0, 0.0)
    # continuity: each segment ends where the next starts (x, v; and a for jerk-limited profiles)
    pieces = [*trajectory.segments]
    for before, after in zip(pieces, pieces[1:], strict=False):
        tau = before.duration
        x_end = before.x0 + before.v0 * tau + before.a0 * tau**2 / 2 + before.jerk * tau**3 / 6
        v_end = before.v0 + before.a0 * tau + before.jerk * tau**2 / 2
        assert abs(x_end - after.x0) < 1e-12 and abs(v_end - after.v0) < 1e-12
        if spec.j_max is not None:
            assert abs(before.a0 + before.jerk * tau - after.a0) < 1e-9
    last = pieces[-1]
    tau = last.duration
    assert abs(last.x0 + last.v0 * tau + last.a0 * tau**2 / 2 + last.jerk * tau**3 / 6 - final) < 1e-12
    assert abs(last.v0 + last.a0 * tau + last.jerk * tau**2 / 2) < 1e-12
    # the rate and acceleration are the position's derivatives (central differences)
    h = 1e-6
    for time in np.linspace(0.001, end - 0.001, 97):
        xm, vm, _ = evaluate(trajectory, float(time) - h)
        xp, vp, _ = evaluate(trajectory, float(time) + h)
        _, v0, a0 = evaluate(trajectory, float(time))
        assert (xp - xm) / (2 * h) == pytest.approx(v0, abs=1e-6)
        if spec.j_max is not None or not any(abs(float(time) - s.t0) < 2 * h for s in pieces):
            assert (vp - vm) / (2 * h) == pytest.approx(a0, abs=1e-4 * max(spec.a_max, 1.0))


def test_the_durations_are_the_closed_forms() -> None:
    """Trapezoid: D/v + v/a; triangle: 2 sqrt(D/a); S-curve: D/v + v/a + a/j; a cycle: 2 repeat
    moves and 2 repeat - 1 dwells after t_start."""
    D = X1 - X0
    assert build(PROFILES["trapezoid"]).end == pytest.approx(D / 0.2 + 0.2 / 2.0, rel=1e-12)
    assert build(PROFILES["triangle"]).end == pytest.approx(2 * math.sqrt(D / 2.0), rel=1e-12)
    assert build(PROFILES["scurve"]).end == pytest.approx(D / 0.2 + 0.2 / 2.0 + 2.0 / 40.0, rel=1e-12)
    move = D / 0.2 + 0.2 / 2.0
    assert build(PROFILES["cycle"]).end == pytest.approx(0.05 + 6 * move + 5 * 0.2, rel=1e-12)
    # the cycle is at the target through each dwell there, at the start through each dwell there
    cycle = build(PROFILES["cycle"])
    for i in range(3):
        at_target = 0.05 + (2 * i + 1) * move + 2 * i * 0.2
        assert evaluate(cycle, at_target + 0.1) == pytest.approx((X1, 0.0, 0.0), abs=1e-12)
        if i < 2:
            assert evaluate(cycle, at_target + 0.2 + move + 0.1) == pytest.approx((X0, 0.0, 0.0), abs=1e-12)


def test_the_sampled_reference_gives_the_python_loop_the_rows_the_compiled_loop_reads() -> None:
    trajectory = build(PROFILES["scurve"])
    reference = SampledReference.of(trajectory, 1600, T_S)
    assert reference.values.shape == (1601, 3) and reference.values.flags.c_contiguous
    for k in (0, 1, 17, 400, 1100, 1600):
        row = reference.at(k * T_S)
        assert np.array(row).view(np.int64).tolist() == reference.values[k].view(np.int64).tolist()
        assert row == evaluate(trajectory, k * T_S)
    assert reference.at(0.123456) == evaluate(trajectory, 0.123456)  # off the grid: the profile itself
    assert np.array_equal(sample(trajectory, 1600, T_S), reference.values)


def _document(trajectory: dict | None = None, **controller) -> dict:
    return {
        "name": "tracking",
        "t_end": 0.8,
        "T_s": T_S,
        "stroke": {"x_start": X0, "x_target": X1, **({"trajectory": trajectory} if trajectory else {})},
        "plant": {"mu": 0.2, "friction_model": "stick_slip"},
        "controller": controller,
    }


TRAPEZOID = {"kind": "trapezoid", "v_max": 0.2, "a_max": 2.0}


@pytest.mark.parametrize(
    ("trajectory", "controller", "t_end", "message"),
    [
        (
            {**TRAPEZOID, "v_max": 0.05},
            {},
            0.8,
            r"^key stroke\.trajectory: the profile ends at t = 1\.765 s, after t_end = 0\.8 s \(raise v_max or a_max",
        ),
        (
            {"kind": "cycle", "v_max": 0.2, "a_max": 2.0, "dwell": 0.5, "repeat": 3},
            {},
            3.0,
            r"^key stroke\.trajectory: the profile ends at .* after t_end = 3 s \(raise .*shorten dwell or repeat",
        ),
        (TRAPEZOID, {"objective": "theta1"}, 0.8, r"^key stroke\.trajectory: the theta1 objective tracks a constant"),
        ({**TRAPEZOID, "j_max": 40.0}, {}, 0.8, r"^key stroke\.trajectory\.j_max: only for kind scurve or cycle"),
        ({**TRAPEZOID, "repeat": 2}, {}, 0.8, r"^key stroke\.trajectory\.repeat: only for kind cycle"),
        ({**TRAPEZOID, "kind": "scurve"}, {}, 0.8, r"^key stroke\.trajectory: an S-curve needs a jerk limit"),
        (
            TRAPEZOID,
            {"python": "mod:make"},
            0.8,
            r"^key stroke\.trajectory: only the built-in law, its controller FMU or a python-control system",
        ),
        (
            TRAPEZOID,
            {"python": "mod:make", "error": {"output": "theta1"}},
            0.8,
            r"^key controller\.error\.output: stroke\.trajectory is a profile of x_B, not of 'theta1'",
        ),
        (
            TRAPEZOID,
            {"python": "mod:make", "error": {"output": "x_B", "target": 0.3}},
            0.8,
            r"^key controller\.error\.target: the reference is stroke\.trajectory",
        ),
        (
            {"kind": "ramp", "v_max": 0.2, "a_max": 2.0},
            {},
            0.8,
            r"^key stroke\.trajectory\.kind: 'ramp' is not allowed",
        ),
        ({"kind": "trapezoid", "v_max": 0.2}, {}, 0.8, r"^missing key: 'a_max' is a required property"),
    ],
)
def test_a_profile_that_cannot_be_tracked_is_one_line_naming_the_key(trajectory, controller, t_end, message) -> None:
    document = {**_document(trajectory, **controller), "t_end": t_end}
    with pytest.raises(ScenarioError, match=message) as error:
        runs_from_document(document)
    assert "\n" not in str(error.value)


def test_the_command_line_refuses_it_with_exit_2_and_writes_nothing(tmp_path: Path) -> None:
    path = tmp_path / "slow.yaml"
    path.write_text(yaml.safe_dump(_document({**TRAPEZOID, "v_max": 0.05})), encoding="utf-8")
    result = CliRunner().invoke(main, ["run", str(path), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2, result.output
    assert "slow.yaml: key stroke.trajectory: the profile ends at t = 1.765 s" in result.output
    assert not (tmp_path / "out").exists()


def test_a_sweep_varies_the_profile(tmp_path: Path) -> None:
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(_document(TRAPEZOID)), encoding="utf-8")
    axes = {"stroke.trajectory.v_max": {"values": [0.15, 0.2, 0.3]}, "stroke.trajectory.a_max": {"values": [1.5, 3.0]}}
    (tmp_path / "sweep.yaml").write_text(
        yaml.safe_dump({"base": "base.yaml", "axes": axes, "output": "out"}, sort_keys=False), encoding="utf-8"
    )
    sweep = load_sweep(tmp_path / "sweep.yaml")
    limits = [
        (run.trajectory.v_max, run.trajectory.a_max)
        for case in sweep.cases
        for run in runs_from_document(case.document)
    ]
    assert limits == [(v, a) for v in (0.15, 0.2, 0.3) for a in (1.5, 3.0)]


@pytest.fixture(scope="module")
def tracking(plant_fmu: Path) -> dict:
    """Both laws on a trapezoidal move with joint friction, with the feed-forward q̈*/G and
    without it (the same reference with its q̈* column zeroed): the outcomes and the profile's end."""
    plant = check_plant(plant_fmu)
    outcomes = {}
    for law in ("paper", "integral"):
        run = runs_from_document(_document(TRAPEZOID, law=law))[0]
        controller = builtin_controller(run)
        values = controller.reference.values.copy()
        values[:, 2] = 0.0
        without = dataclasses.replace(
            controller, reference=SampledReference(controller.reference.trajectory, T_S, values)
        )
        outcomes[law] = (
            check_and_simulate(run, plant, controller=controller),
            check_and_simulate(run, plant, controller=without),
        )
    return {"outcomes": outcomes, "end": build(ProfileSpec("trapezoid", X0, X1, 0.2, 2.0)).end}


def _errors(outcome, end: float) -> tuple[float, float]:
    """max |e| over the move (t ≤ its end) and |e| at its end [m]."""
    t, e = outcome.trace.time, outcome.trace.column("e")
    move = t <= end + 1e-12
    return float(np.max(np.abs(e[move]))), float(abs(e[move][-1]))


@pytest.mark.parametrize("law", ["paper", "integral"])
def test_the_laws_track_a_trapezoid_and_the_feed_forward_is_what_keeps_the_error_small(tracking, law) -> None:
    """Measured (μ = 0.2, stick-slip friction, the paper's gains; C_I = 16, K_I = 64): max |e|
    during the 87 mm move 0.044 mm (paper) and 0.027 mm (integral), |e| at its end 0.011 and
    0.007 mm; without q̈* 0.66 and 0.40 mm. A law without the feed-forward, or with its sign
    wrong, fails the bounds."""
    with_ff, without_ff = tracking["outcomes"][law]
    assert with_ff.complete and without_ff.complete
    assert with_ff.record["loop"]["kind"] == "compiled"
    during, at_end = _errors(with_ff, tracking["end"])
    during_without, _ = _errors(without_ff, tracking["end"])
    print(
        f"{law}: max|e| during the move {during * 1e3:.4f} mm, at its end {at_end * 1e3:.4f} mm;"
        f" without the feed-forward {during_without * 1e3:.4f} mm"
    )
    assert during < 1e-4 and at_end < 5e-5  # 0.1 mm, 0.05 mm on an 87 mm stroke
    assert during_without > 5 * during
    assert abs(with_ff.summary.final_error_m) < 5e-5  # at rest on the target at t_end
    assert with_ff.summary.peak_iq_ref_A < 1.0  # a 2 m/s² profile asks for little current


def test_python_and_compiled_loops_agree_bit_for_bit_on_a_trajectory(
    plant_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    plant = check_plant(plant_fmu)
    spec = {"kind": "scurve", "v_max": 0.2, "a_max": 2.0, "j_max": 40.0}
    run = runs_from_document({**_document(spec, law="integral"), "t_end": 0.7})[0]
    compiled = check_and_simulate(run, plant)
    monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "0")
    python = check_and_simulate(run, plant)
    assert compiled.record["loop"]["kind"] == "compiled" and python.record["loop"]["kind"] == "python"
    assert compiled.complete and python.complete
    bits = np.ascontiguousarray(compiled.trace.data).view(np.int64)
    assert np.array_equal(bits, np.ascontiguousarray(python.trace.data).view(np.int64))


@pytest.fixture(scope="module")
def toggle_vsc(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from toggle_cosim.controller_fmu import build_controller_fmu

    return build_controller_fmu(tmp_path_factory.mktemp("vsc") / "ToggleVSC.fmu", "2.0").path


@pytest.mark.parametrize(
    ("law", "coupling"), [("paper", "gauss-seidel"), ("integral", "gauss-seidel"), ("integral", "jacobi")]
)
def test_the_controller_fmu_tracks_the_trajectory_with_the_built_in_laws_bits_in_both_loops(
    toggle_vsc: Path, plant_fmu: Path, monkeypatch: pytest.MonkeyPatch, law: str, coupling: str
) -> None:
    """controller.fmu: ToggleVSC.fmu on a trajectory run: the execution feeds its inputs x_ref,
    v_ref, a_ref from the run's sampled reference (signal columns, set with its measurements: the
    compiled loop from C, the Python execution from Python); iq_ref, S, phase, e and x_B are the
    built-in law's bits, under either coupling."""
    plant = check_plant(plant_fmu)
    spec = {"kind": "trapezoid", "v_max": 0.2, "a_max": 2.0}
    document = {**_document(spec, law=law), "t_end": 0.7, "coupling": coupling}
    builtin = check_and_simulate(runs_from_document(document)[0], plant)
    with_fmu = {**document, "controller": {"law": law, "fmu": str(toggle_vsc)}}
    compiled = check_and_simulate(runs_from_document(with_fmu)[0], plant)
    monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "0")
    python = check_and_simulate(runs_from_document(with_fmu)[0], plant)
    assert compiled.record["loop"]["kind"] == "compiled" and python.record["loop"]["kind"] == "python"
    assert builtin.complete and compiled.complete and python.complete
    for name in ("x_B", "v_B", "iq_ref", "S", "phase", "e"):
        expected = builtin.trace.column(name).view(np.int64)
        assert np.array_equal(compiled.trace.column(name).view(np.int64), expected), name
        assert np.array_equal(python.trace.column(name).view(np.int64), expected), name
    assert np.max(np.abs(builtin.trace.column("e"))) < 1e-4


def test_a_controller_fmu_without_the_reference_inputs_is_refused(tmp_path: Path) -> None:
    """An FMU of the built-in law with no x_ref, v_ref, a_ref (the SSP tests' stand-in) cannot
    track: one line naming controller.fmu."""
    from toggle_cosim.control.protocol import ControllerError
    from toggle_cosim.cosim.controllers import controller_for
    from toggle_cosim.plant.controller_contract import ControllerFmu

    run = runs_from_document({**_document(TRAPEZOID), "controller": {"fmu": str(tmp_path / "Old.fmu")}})[0]
    old = ControllerFmu(
        tmp_path / "Old.fmu", None, "2.0", "", ("x_B", "v_B"), ("S",), {}, {}, ("C", "target"), True, (), ()
    )
    import toggle_cosim.cosim.controllers as controllers

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(controllers, "_checked_fmu", lambda run, outputs: old)
        with pytest.raises(ControllerError, match=r"^key controller\.fmu: Old\.fmu has no inputs x_ref, v_ref, a_ref"):
            controller_for(run, ("x_B", "v_B"))


def test_a_connection_to_a_tracking_controller_fmus_reference_is_refused(toggle_vsc: Path, plant_fmu: Path) -> None:
    """A system whose controller FMU tracks stroke.trajectory takes x_ref, v_ref, a_ref from the
    run's reference: a connection to one is refused in one line naming it and the fix."""
    from toggle_cosim.cosim.checked import SystemError_, check_run

    connections = ["plant.x_B -> controller.x_B", "plant.v_B -> controller.v_B", "plant.x_B -> controller.x_ref"]
    document = {
        **_document(TRAPEZOID),
        "t_end": 0.7,
        "controller": {"fmu": str(toggle_vsc)},
        "connections": [*connections, "controller.iq_ref -> plant.iq_ref"],
    }
    with pytest.raises(SystemError_, match=r"^scenario tracking: a connection feeds controller\.x_ref, which the"):
        check_run(runs_from_document(document)[0], check_plant(plant_fmu))

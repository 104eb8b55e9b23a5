"""Tuning a controller over a robustness map (`toggle-cosim tune`, `tc.tune`): the tuning file's
errors, a tiny tuning whose best scenario, re-run through the sweep engine, gives the figures
the tuner reported, resuming a study (an interrupted batch included), infeasible trials, the
scores' arithmetic and the Pareto front."""

from __future__ import annotations

import math
from pathlib import Path

import optuna
import pytest
import yaml
from click.testing import CliRunner

import toggle_cosim as tc
from toggle_cosim.cli import main
from toggle_cosim.cosim.plausibility import plausibility_warnings
from toggle_cosim.experiments.sweep import load_sweep, read_results, run_sweep
from toggle_cosim.experiments.tune_run import pareto_front
from toggle_cosim.experiments.tune_score import PENALTY, WORKING_RANGE_FLAG, score
from toggle_cosim.experiments.tune_spec import Constraints, Objective, TuneError, load_tuning

pytestmark = pytest.mark.slow  # tunings: many trials of whole runs each

ROOT = Path(__file__).resolve().parent.parent

# the integral law (integral_load.yaml's), shortened: 0.6 s is enough for the final error to differ
BASE = {
    "name": "small_integral",
    "t_end": 0.6,
    "T_s": 0.0005,
    "stroke": {"x_start": 0.2329, "x_target": 0.3199},
    "plant": {"F_E": 0.0, "m_B": 4.43, "mu": 0.2, "current_loop": "first_order"},
    "controller": {
        "law": "integral",
        "objective": "x_B",
        "nominal_m_B": 4.43,
        "gains": {"C": 5, "Q": 4, "P": 50, "delta": 0.25, "beta": 65},
        "C_I": 16,
        "K_I": 64,
    },
    "variants": {"friction": {"plant": {"mu": 0.2}}, "no_friction": {"plant": {"mu": 0.0}}},
}
SWEEP = {
    "base": "base.yaml",
    "variant": "friction",
    "axes": {
        "controller.law": {"values": ["paper", "integral"]},
        "plant.F_E": {"values": [0, 150]},
        "plant.m_B": {"values": [4.43, 8.86]},
    },
    "heatmap": {"x": "plant.F_E", "y": "plant.m_B"},
}
TUNE = {
    "name": "tiny",
    "sweep": "sweep.yaml",
    "fix": {"controller.law": "integral"},
    "parameters": {"controller.C_I": {"low": 8, "high": 40}, "controller.K_I": {"low": 16, "high": 400, "log": True}},
    "objective": {"metric": "final_error", "over": "worst"},
    "constraints": {"rated_current": True, "working_range": True},
    "optimiser": {"sampler": "tpe", "trials": 6, "batch": 3, "seed": 3},
    "output": "out",
}


def write_tuning(folder: Path, plant_fmu: Path | None = None, **changes) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    base = dict(BASE, fmu=str(plant_fmu)) if plant_fmu is not None else BASE
    (folder / "base.yaml").write_text(yaml.safe_dump(base, sort_keys=False), encoding="utf-8")
    (folder / "sweep.yaml").write_text(yaml.safe_dump(SWEEP, sort_keys=False), encoding="utf-8")
    document = {**TUNE, **changes}
    document = {k: v for k, v in document.items() if v is not None}
    path = folder / "tune.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    return path


# -- the tuning file's errors: one line naming the file and the key, nothing run ----------------


@pytest.mark.parametrize(
    ("changes", "expected"),
    [
        ({"budget": 3}, "unknown key budget"),
        (
            {"parameters": {"controller.C_I": {"low": 40, "high": 8}}},
            "key parameters.controller.C_I: low 40 is not below high 8",
        ),
        (
            {"parameters": {"controller.gains.Z": {"low": 1, "high": 2}}},
            "key parameters.controller.gains.Z: unknown scenario key 'Z'",
        ),
        ({"parameters": {"plant.F_E": {"low": 1, "high": 2}}}, "key parameters.plant.F_E: an axis of the sweep"),
        (
            {"parameters": {"controller.C_I": {"low": -5, "high": 8}}},
            "key parameters.controller.C_I: the bound -5 is not a valid value",
        ),
        ({"parameters": {"controller.K_I": {"low": 0, "high": 8, "log": True}}}, "log: true needs low > 0"),
        (
            {"objective": {"metric": "speed"}},
            "key objective.metric: unknown metric 'speed' (choose one of settling_time",
        ),
        ({"objective": {"metric": "final_error", "over": "median"}}, "key objective.over: 'median' is not allowed"),
        ({"fix": {"controller.law": "pid"}}, "key fix.controller.law: 'pid' is not a value of that axis"),
        ({"fix": {"controller.colour": 1}}, "key fix.controller.colour: unknown scenario key 'colour'"),
        ({"optimiser": {"sampler": "grid"}}, "key optimiser.sampler: 'grid' is not a sampler"),
        (
            {"objective": [{"metric": "final_error"}, {"metric": "peak_command"}], "optimiser": {"sampler": "cmaes"}},
            "cmaes minimises one objective",
        ),
        ({"sweep": "nowhere.yaml"}, "key sweep:"),
    ],
)
def test_a_bad_tuning_file_is_one_line_naming_the_key(tmp_path: Path, changes: dict, expected: str) -> None:
    path = write_tuning(tmp_path, **changes)
    with pytest.raises(TuneError) as error:
        load_tuning(path)
    message = str(error.value)
    assert message.startswith(f"{path}: ") and expected in message, message
    assert "\n" not in message


def test_the_command_refuses_a_bad_file_with_exit_2_and_writes_nothing(tmp_path: Path) -> None:
    path = write_tuning(tmp_path, parameters={"controller.K_I": {"low": 9, "high": 9}})
    done = CliRunner().invoke(main, ["tune", str(path), "--out", str(tmp_path / "never")])
    assert done.exit_code == 2
    lines = done.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "low 9 is not below high 9" in lines[0]
    assert not (tmp_path / "never").exists()


# -- the scores (pure) ----------------------------------------------------------------------------


def _row(settling: float | None, error: float, peak: float, warnings: str | None = None, status: str = "ok") -> dict:
    return {
        "status": status,
        "t_end": 1.5,
        "settling_time_s": settling,
        "final_error_m": error,
        "peak_iq_ref_A": peak,
        "warnings": warnings,
        "overshoot_percent": 0.0,
        "E_in_J": 1.0,
        "iq_total_variation_A_per_s": 2.0,
        "S_sign_changes_per_s": None,
    }


def test_a_score_is_the_worst_or_the_mean_and_a_case_that_never_settles_counts_t_end() -> None:
    rows = [_row(0.5, -2e-5, 3.0), _row(None, 4e-5, 5.0)]
    settle = [Objective("settling_time", "worst"), Objective("final_error", "mean")]
    result = score(rows, [10.0, 10.0], settle, Constraints(rated_current=True))
    assert result.feasible and result.objectives == [1.5, pytest.approx(3e-5, rel=1e-12)]
    assert result.told == result.objectives and result.figures["settled"] == 1.0
    assert result.figures["worst_peak_command"] == 5.0 and result.figures["mean_peak_command"] == 4.0
    assert math.isnan(result.figures["worst_S_sign_changes"])  # no S: no value, not zero


def test_each_constraint_counts_the_cases_that_break_it_and_infeasible_is_penalised() -> None:
    rows = [
        _row(None, 2e-4, 11.0),
        _row(0.4, 1e-5, 3.0, warnings=f"slider B leaves its working range {WORKING_RANGE_FLAG} at t = 1 s"),
        _row(None, math.nan, math.nan, status="failed"),
        _row(0.3, 1e-5, 9.0),
    ]
    all_of_them = Constraints(settles=True, final_error_below=1e-4, rated_current=True, working_range=True)
    result = score(rows, [10.0] * 4, [Objective("final_error", "worst")], all_of_them)
    assert result.violations == {
        "failed": 1,
        "settles": 1,
        "final_error_below": 1,
        "rated_current": 1,
        "working_range": 1,
    }
    assert not result.feasible and result.told == [PENALTY * (1 + 5 / 4)]
    assert result.objectives == [2e-4]  # the true figure, over the cases that ran
    assert score(rows[3:], [10.0], [Objective("final_error", "worst")], all_of_them).feasible


def test_the_working_range_flag_is_the_one_the_plausibility_check_writes() -> None:
    import numpy as np

    lines = plausibility_warnings(np.array([0.0, 1.0]), np.array([0.25, 0.40]), np.array([1.0, 1.0]), 10.0, (0.2, 0.35))
    assert len(lines) == 1 and WORKING_RANGE_FLAG in lines[0]


def test_the_pareto_front_keeps_the_points_no_other_dominates() -> None:
    points = [(1.0, 5.0), (2.0, 2.0), (3.0, 3.0), (5.0, 1.0), (2.0, 2.0), (1.0, 6.0)]
    assert pareto_front(points) == [True, True, False, True, True, False]


# -- a tiny tuning, end to end ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory, plant_fmu: Path):
    """2 parameters, the 4 integral-law cases of a 2 x 2 map, 6 trials in batches of 3, t_end 0.6 s."""
    folder = tmp_path_factory.mktemp("tune")
    path = write_tuning(folder, plant_fmu)
    result = tc.tune(path, workers=2)
    return path, result


def test_the_tiny_tuning_reports_its_start_best_and_history(tiny) -> None:
    path, result = tiny
    tuning = load_tuning(path)
    assert len(tuning.cases) == 4 and {c.values["controller.law"] for c in tuning.cases} == {"integral"}
    history = result.history
    assert list(history["trial"]) == list(range(7)) and history["origin"].tolist() == ["start"] + ["optimiser"] * 6
    assert result.trials == 6 and (history["state"] == "complete").all()
    assert history.loc[0, "controller.C_I"] == 16 and history.loc[0, "controller.K_I"] == 64
    feasible = history[history["feasible"]]
    best = feasible.loc[feasible["worst_final_error"].idxmin()]
    assert result.best["trial"] == best["trial"]
    assert result.best["objectives"] == [best["worst_final_error"]]
    assert result.best["objectives"][0] <= result.start["objectives"][0]  # the start is a trial too
    for name in ("trials.csv", "tiny_best.yaml", "tuned_sweep.yaml", "start_sweep.yaml", "maps.png", "tune.json"):
        assert (result.output / name).is_file(), name
    assert (result.output / "maps.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    from toggle_cosim.provenance import srmd

    record = srmd.read_record(result.output / "provenance.srmd")  # the tuning's, and each map's
    assert [item.role for item in record.resources][:2] == ["tuning", "sweep"] and record.data.uri == "trials.csv"
    assert "plant" in {item.role for item in record.resources}
    for folder in (result.output, result.output / "map_start", result.output / "map_tuned"):
        assert srmd.verify_record(folder / "provenance.srmd") == [], folder


def test_the_best_scenario_rerun_by_sweep_gives_the_tuners_figures_exactly(tiny, plant_fmu, tmp_path) -> None:
    """The written sweep file of the tuned map, run again by `toggle-cosim sweep` into a new
    folder: the same cases (ids) and the objective and every metric equal, to the last bit."""
    path, result = tiny
    tuning = load_tuning(path)
    sweep_file = result.output / "tuned_sweep.yaml"
    assert run_sweep(sweep_file, None, 2, plant_fmu, output=tmp_path / "again", progress=False) == 0
    table = read_results(tmp_path / "again")
    best = result.best["parameters"]
    assert sorted(table["case_id"]) == sorted(c.case_id for c in tuning.trial_cases(best))
    rows = table.astype(object).where(table.notna(), None).to_dict("records")
    again = score(rows, tuning.rated_currents, tuning.objectives, tuning.constraints)
    assert again.objectives == result.best["objectives"]
    figures = {k: (None if math.isnan(v) else v) for k, v in again.figures.items()}
    assert figures == result.best["figures"]
    assert result.rerun["equal"] is True


def test_the_best_scenario_loads_and_runs_with_the_tuned_values(tiny, plant_fmu) -> None:
    path, result = tiny
    runs = tc.load_scenario(result.output / "tiny_best.yaml")
    run = runs["friction"]
    assert run.controller.C_I == result.best["parameters"]["controller.C_I"]
    assert run.controller.K_I == result.best["parameters"]["controller.K_I"]
    assert run.controller.law == "integral" and run.t_end == 0.6
    done = tc.simulate(run, plant_fmu)
    assert done.status == "complete"
    table = read_results(result.output / "map_tuned")
    row = table[(table["plant.F_E"] == 0.0) & (table["plant.m_B"] == 4.43)].iloc[0]
    assert done.summary.final_error_m == row["final_error_m"]


def test_resume_goes_on_with_the_same_study_and_asks_an_interrupted_batch_again(tiny, tmp_path, plant_fmu) -> None:
    """A copy of the tiny tuning's study with one trial asked and never told (a batch cut short):
    resumed with a budget of 8, the first trials stay as they were, the stale one is failed and
    its point asked again, and 2 more trials run (the start map is not run again)."""
    import shutil

    path, result = tiny
    folder = tmp_path / "resumed"
    shutil.copytree(path.parent, folder, ignore=shutil.ignore_patterns("again"))
    storage = f"sqlite:///{folder / 'out' / 'study.db'}"
    study = optuna.load_study(study_name="tiny", storage=storage)
    before = [(t.number, dict(t.params), t.values) for t in study.trials]
    stale = study.ask({"controller.C_I": optuna.distributions.FloatDistribution(8, 40)})
    stale.suggest_float("controller.K_I", 16, 400, log=True)
    stale_point = dict(stale.params)
    again = tc.tune(folder / "tune.yaml", workers=2, trials=8)
    assert again.trials == 8 and again.ran == 2
    study = optuna.load_study(study_name="tiny", storage=storage)
    trials = study.trials
    assert [(t.number, dict(t.params), t.values) for t in trials[: len(before)]] == before
    assert trials[len(before)].state == optuna.trial.TrialState.FAIL
    assert trials[len(before) + 1].params == stale_point  # asked again, first
    assert trials[len(before) + 1].state == optuna.trial.TrialState.COMPLETE
    table = read_results(folder / "out" / "map_start")
    assert len(table) == 4  # the start map's cases were found done


@pytest.mark.parametrize(
    ("changes", "words"),
    [
        ({"name": "other"}, "another tuning ('tiny')"),
        (
            {"parameters": {"controller.C_I": {"low": 8, "high": 30}, "controller.K_I": {"low": 16, "high": 400}}},
            "another tuning (its map, parameters, bounds",
        ),
    ],
)
def test_a_second_different_tuning_into_the_same_folder_is_refused(
    tiny, tmp_path, plant_fmu, changes: dict, words: str
) -> None:
    """A copy of the tiny tuning's folder, and a different tuning (another name; the same name
    with other bounds) with the same --out: refused in one line naming the folder's tune.json or
    study.db, exit 2, before any case runs; the study still holds the tiny tuning's trials alone
    and no file changed."""
    import shutil

    path, result = tiny
    folder = tmp_path / "second"
    shutil.copytree(path.parent, folder, ignore=shutil.ignore_patterns("again"))
    out = folder / "out"
    listing = {p: p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}
    other = write_tuning(folder, plant_fmu, **changes)
    done = CliRunner().invoke(main, ["tune", str(other), "--out", str(out), "-q"])
    assert done.exit_code == 2, done.output
    lines = done.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {out}/") and words in lines[0], lines
    assert {p: p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()} == listing
    assert optuna.study.get_all_study_names(f"sqlite:///{out / 'study.db'}") == ["tiny"]


def test_a_constraint_no_trial_meets_leaves_no_best_and_exit_1(tmp_path, plant_fmu) -> None:
    path = write_tuning(
        tmp_path,
        plant_fmu,
        constraints={"final_error_below": 1e-9},
        optimiser={"sampler": "random", "trials": 2, "batch": 2, "seed": 0},
    )
    done = CliRunner().invoke(main, ["tune", str(path), "--workers", "2", "-q"])
    assert done.exit_code == 1, done.output
    history = __import__("pandas").read_csv(tmp_path / "out" / "trials.csv")
    assert len(history) == 3 and not history["feasible"].any()
    # the start ran the whole map; a trial stops after its first wave (1 case of 4) breaks the constraint
    assert history["cases"].tolist() == [4, 1, 1]
    assert history["violations_final_error_below"].tolist() == [4, 1, 1]
    assert not (tmp_path / "out" / "tiny_best.yaml").exists()
    assert "best: none" in done.output


def test_the_start_map_is_a_sweep_file_of_the_same_cases(tiny) -> None:
    path, result = tiny
    tuning = load_tuning(path)
    sweep = load_sweep(result.output / "start_sweep.yaml")
    assert [c.case_id for c in sweep.cases] == [c.case_id for c in tuning.cases]


def test_two_objectives_give_a_pareto_front_and_its_plot(tmp_path, plant_fmu) -> None:
    """Final error against peak current (a trade-off): the history marks the front, which no
    other feasible trial dominates; `fix:` shortens every case (a key that is no axis)."""
    path = write_tuning(
        tmp_path,
        plant_fmu,
        fix={"controller.law": "integral", "t_end": 0.3},
        objective=[{"metric": "final_error", "over": "worst"}, {"metric": "peak_command", "over": "mean"}],
        optimiser={"sampler": "random", "trials": 4, "batch": 4, "seed": 5},
    )
    result = tc.tune(path, workers=2)
    history = result.history
    assert (history.loc[history["feasible"], "cases"] == 4).all()  # a feasible trial ran the whole map
    assert {c.parameters["t_end"] for c in load_tuning(path).cases} == {0.3}
    labels = ["worst_final_error", "mean_peak_command"]
    feasible = history[history["feasible"]]
    front = history[history["pareto"]]
    assert 1 <= len(front) and front["feasible"].all()
    for _, row in front.iterrows():
        others = feasible.drop(index=row.name)
        assert not ((others[labels] <= row[labels]).all(axis=1) & (others[labels] < row[labels]).any(axis=1)).any()
    best = front.loc[front["worst_final_error"].idxmin()]
    assert result.best["trial"] == best["trial"]
    assert (result.output / "pareto.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_plant_that_is_not_there_is_exit_2_and_leaves_no_folder(tmp_path) -> None:
    path = write_tuning(tmp_path)
    missing = tmp_path / "nowhere.fmu"
    done = CliRunner().invoke(main, ["tune", str(path), "--fmu", str(missing), "--out", str(tmp_path / "o"), "-q"])
    assert done.exit_code == 2, done.output
    lines = done.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and str(missing) in lines[0], lines
    assert not (tmp_path / "o").exists()


def test_a_python_factorys_parameters_are_tuned_as_scenario_keys(tmp_path, plant_fmu) -> None:
    """The PD controller of examples/controllers (a controller.python factory): its Kp and Kd
    tuned over a 2-case map of its variant; the written scenario keeps that variant only, with
    the tuned values where the variant sets them, and its map re-run gives the tuner's figures."""
    import shutil

    for name in ("my_controllers.py", "user_controllers.yaml"):
        shutil.copy(ROOT / "examples" / "controllers" / name, tmp_path / name)
    sweep = {"base": "user_controllers.yaml", "variant": "pd", "axes": {"plant.F_E": {"values": [0.0, 20.0]}}}
    (tmp_path / "pd_sweep.yaml").write_text(yaml.safe_dump(sweep), encoding="utf-8")
    tuning = {
        "name": "pd",
        "sweep": "pd_sweep.yaml",
        "fix": {"t_end": 0.3},
        "parameters": {
            "controller.parameters.Kp": {"low": 5, "high": 40},
            "controller.parameters.Kd": {"low": 1, "high": 5},
        },
        "objective": {"metric": "final_error", "over": "worst"},
        "optimiser": {"sampler": "random", "trials": 2, "batch": 2, "seed": 2},
    }
    (tmp_path / "pd_tune.yaml").write_text(yaml.safe_dump(tuning), encoding="utf-8")
    result = tc.tune(tmp_path / "pd_tune.yaml", fmu=plant_fmu, output=tmp_path / "out", workers=2)
    assert result.history.loc[0, "controller.parameters.Kp"] == 12.0  # the variant's own value, trial 0
    written = yaml.safe_load((tmp_path / "out" / "pd_best.yaml").read_text(encoding="utf-8"))
    assert list(written["variants"]) == ["pd"] and "parameters" not in written["controller"]
    assert written["variants"]["pd"]["controller"]["parameters"] == {
        "Kp": result.best["parameters"]["controller.parameters.Kp"],
        "Kd": result.best["parameters"]["controller.parameters.Kd"],
    }
    assert written["t_end"] == 0.3 and result.rerun["equal"] is True

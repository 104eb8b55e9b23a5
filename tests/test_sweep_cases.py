"""A sweep's cases checked per axis value (`sweep_spec`): the same cases, ids, documents, table
parameters and errors as checking every case's whole scenario.

The reference below is that per-case check, written out: each case's document a deep copy of the
variant's with the values set, checked by the scenario loader, its id hashed from the whole
document, its parameters read from its Run; the first bad or repeated case refused. The sweeps
are 3 × 3 grids (and zip, signal and sampling axes), with invalid values placed so that a check
reading two keys together (the stroke's ends, t_end and T_s) fails only in some combinations.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path

import pytest
import yaml

from toggle_cosim.experiments import sweep_spec
from toggle_cosim.experiments.scenario import ScenarioError, merge_documents, runs_from_document
from toggle_cosim.experiments.sweep import load_sweep, run_sweep
from toggle_cosim.experiments.sweep_spec import SweepError, case_id, check_group, with_values

BASE = {
    "name": "small",
    "t_end": 0.3,
    "T_s": 0.0005,
    "stroke": {"x_start": 0.2329, "x_target": 0.3199},
    "plant": {"F_E": 0.0, "m_B": 4.43, "mu": 0.2, "current_loop": "first_order"},
    "controller": {"objective": "x_B", "nominal_m_B": 4.43, "gains": {"C": 5, "Q": 4, "P": 50, "delta": 0.25}},
    "variants": {"fast": {"controller": {"gains": {"beta": 80}}}, "slow": {"controller": {"gains": {"beta": 40}}}},
}


def _write(folder: Path, axes: dict, **extra) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "base.yaml").write_text(yaml.safe_dump(BASE, sort_keys=False), encoding="utf-8")
    path = folder / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": "base.yaml", "axes": axes, "output": "out", **extra}), encoding="utf-8")
    return path


def _per_case(path: Path) -> list[tuple[str, str | None, dict, dict]]:
    """(id, variant, document, parameters) of every case by checking each whole case, or the
    SweepError message (without the file) of the first bad or repeated one."""
    document = yaml.safe_load(path.read_text(encoding="utf-8"))
    axes = {key: sweep_spec._axis_values(key, spec) for key, spec in document["axes"].items()}
    base = {k: v for k, v in BASE.items() if k != "variants"}
    combos = list(zip(*axes.values(), strict=True)) if document.get("mode") == "zip" else _grid(list(axes.values()))
    out, seen = [], {}
    for variant in BASE["variants"]:
        resolved = merge_documents(base, BASE["variants"][variant])
        for combo in combos:
            values = dict(zip(axes, combo, strict=True))
            document = copy.deepcopy(resolved)
            for key, value in values.items():
                sweep_spec.set_key(document, key, value)
            label = ", ".join(f"{k}={v!r}" for k, v in values.items())
            index = len(out)
            try:
                (run,) = runs_from_document(document, path.parent / "base.yaml")
            except ScenarioError as error:
                raise SweepError(f"case {index} (variant {variant}, {label}): {error}") from None
            identifier = case_id(document, variant)
            if identifier in seen:
                raise SweepError(f"cases {seen[identifier]} and {index} are the same co-simulation ({label})")
            seen[identifier] = index
            parameters = {
                "plant.F_E": run.plant.F_E if isinstance(run.plant.F_E, float) else math.nan,
                "plant.m_B": run.plant.m_B,
                "plant.mu": run.plant.mu,
                "T_s": run.T_s,
                "t_end": run.t_end,
                **{k: float(v) if isinstance(v, int) and not isinstance(v, bool) else v for k, v in values.items()},
            }
            out.append((identifier, variant, document, parameters))
    return out


def _grid(axes: list[list]) -> list[tuple]:
    import itertools

    return list(itertools.product(*axes))


def _same(a, b) -> bool:  # noqa: ANN001
    return (isinstance(a, float) and math.isnan(a) and isinstance(b, float) and math.isnan(b)) or (
        a == b and type(a) is type(b)
    )


GOOD = [
    {"plant.F_E": {"values": [0, 75, 150]}, "plant.m_B": {"linspace": [4.43, 8.86, 3]}},
    {
        "controller.law": {"values": ["paper", "integral"]},
        "plant.F_E": {"values": [0, 10.0, 20]},
        "plant.mu": {"values": [0.0, 0.2]},
    },
    {"T_s": {"values": [0.0005, 0.001, 0.0015]}, "t_end": {"values": [0.3, 0.03, 0.6]}},
    {
        "plant.F_E.kind": {"values": ["step"]},
        "plant.F_E.start_time": {"values": [0.1, 0.2, 0.25]},
        "plant.F_E.height": {"values": [5, 50, 100]},
    },
    {"stroke.x_start": {"values": [0.2329, 0.25, 0.26]}, "plant.parameters.mechanism.r3": {"values": [0.27, 0.28]}},
]


@pytest.mark.parametrize("axes", GOOD, ids=["FE_mB", "law_FE_mu", "sampling", "signal", "stroke_parameter"])
def test_cases_are_those_of_the_per_case_check(tmp_path: Path, axes: dict) -> None:
    path = _write(tmp_path, axes)
    expected = _per_case(path)
    cases = load_sweep(path).cases
    assert len(cases) == len(expected) >= 9
    for case, (identifier, variant, document, parameters) in zip(cases, expected, strict=True):
        assert (case.case_id, case.variant, case.document) == (identifier, variant, document)
        assert case.parameters.keys() == parameters.keys()
        assert all(_same(case.parameters[k], parameters[k]) for k in parameters), (case.parameters, parameters)
        assert case.payload()["document"] == document


def test_zip_mode_gives_the_per_case_cases(tmp_path: Path) -> None:
    path = _write(tmp_path, {"plant.F_E": {"values": [0, 10, 20]}, "plant.m_B": {"values": [4.43, 5, 6]}}, mode="zip")
    assert [c.case_id for c in load_sweep(path).cases] == [e[0] for e in _per_case(path)]


BAD = [
    # one bad value on the second axis: the first case holding it
    ({"plant.F_E": {"values": [0, 10, 20]}, "plant.m_B": {"values": [4.43, -1.0, 5.0]}}, "case 1 ("),
    # two bad values, in two groups (the file's axes in sorted order: C outermost): the first case holding either
    (
        {
            "plant.F_E": {"values": [0, 10, 20]},
            "plant.m_B": {"values": [4.43, 5.0, -2.0]},
            "controller.gains.C": {"values": [1.0, -5.0]},
        },
        "case 2 (",
    ),
    # the stroke's ends, each fine alone, too close together in one combination only
    (
        {"stroke.x_start": {"values": [0.2329, 0.25, 0.3]}, "stroke.x_target": {"values": [0.3199, 0.30005, 0.31]}},
        "within 0.1 mm of x_start",
    ),
    # t_end not a whole number of T_s in some combinations
    (
        {"T_s": {"values": [0.0005, 0.0007, 0.001]}, "t_end": {"values": [0.1, 0.2, 0.35]}},
        "is not a whole number of samples",
    ),
    # a repeated value (10 and 10.0 are the same case)
    (
        {"plant.F_E": {"values": [0, 10, 10.0]}, "plant.m_B": {"values": [4.43, 5.0, 6.0]}},
        "cases 3 and 6 are the same co-simulation",
    ),
    (
        {"controller.law": {"values": ["paper", "integral", "bogus"]}, "plant.F_E": {"values": [0, 10, 20]}},
        "'bogus' is not allowed",
    ),
]


@pytest.mark.parametrize(("axes", "part"), BAD)
def test_bad_values_are_refused_as_the_per_case_check_refuses_them(tmp_path, plant_fmu, capsys, axes, part) -> None:  # noqa: ANN001
    path = _write(tmp_path, axes)
    with pytest.raises(SweepError) as reference:
        _per_case(path)
    with pytest.raises(SweepError) as got:
        load_sweep(path)
    # the same message (the reference leaves off the hint after a repeated case's label)
    assert part in str(got.value) and str(got.value).startswith(f"{path}: {reference.value}")
    assert run_sweep(path, None, 1, plant_fmu, progress=False) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: {got.value}"]
    assert not (tmp_path / "out").exists()


def test_with_values_copies_only_the_paths_it_sets() -> None:
    document = {"plant": {"F_E": 0.0, "parameters": {"a": 1.0}}, "controller": {"gains": {"C": 5}}, "T_s": 0.1}
    result = with_values(document, {"plant.F_E": 9.0, "plant.parameters.mechanism.r3": 0.3, "stroke.x_start": 0.25})
    reference = copy.deepcopy(document)
    for key, value in {"plant.F_E": 9.0, "plant.parameters.mechanism.r3": 0.3, "stroke.x_start": 0.25}.items():
        sweep_spec.set_key(reference, key, value)
    assert result == reference and list(result) == list(reference)
    assert document["plant"] == {"F_E": 0.0, "parameters": {"a": 1.0}}  # the original is unchanged
    assert result["controller"] is document["controller"]  # shared: no axis passes through it
    assert check_group("plant.F_E.height") == check_group("t_end") == check_group("plant.inputs.u") == "sampling"
    assert check_group("stroke.x_start") == check_group("stroke.x_target") != check_group("plant.m_B")

"""Scenario files: the shipped ones load as expected, and every kind of bad file gives one clear line.

The contract of `load_scenario` (see `toggle_cosim.experiments.scenario`): a bad file raises `ScenarioError`
whose str() is ONE line that starts with the file path, names the offending key and says what is
allowed. The CLI prints that line after "error: " (see tests/test_scenario_fuzz.py).
"""

from __future__ import annotations

import copy
import math
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from toggle_cosim.experiments.scenario import ScenarioError, load_scenario, toggle_limit
from toggle_cosim.physics.parameters import MechanismParameters

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ROOT / "scenarios"
BASE: dict[str, Any] = yaml.safe_load((SCENARIOS / "fig4_nominal.yaml").read_text(encoding="utf-8"))

SHIPPED = {
    # file stem: (F_E [N], m_B [kg])
    "fig4_nominal": (0.0, 4.43),
    "fig5_external_force": (100.0, 4.43),
    "fig6_mass_variation": (0.0, 8.86),
}


# --------------------------------------------------------------------------------------------- helpers


def write_doc(tmp_path: Path, document: Any, name: str = "scenario.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(document, sort_keys=False, allow_unicode=True), encoding="utf-8")
    return path


def write_text(tmp_path: Path, text: str, name: str = "scenario.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def write_bytes(tmp_path: Path, data: bytes, name: str = "scenario.yaml") -> Path:
    path = tmp_path / name
    path.write_bytes(data)
    return path


def mutated(**changes: Any) -> dict[str, Any]:
    """BASE with dotted keys set (value DELETE removes the key)."""
    document = copy.deepcopy(BASE)
    for dotted, value in changes.items():
        *parents, last = dotted.split("__")
        node = document
        for part in parents:
            node = node.setdefault(part, {})
        if value is DELETE:
            del node[last]
        else:
            node[last] = value
    return document


DELETE = object()


def one_line_error(path: Path, *needles: str) -> str:
    """load_scenario(path) raises ScenarioError: one line, starting with the path, holding every needle."""
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert message.splitlines() == [message], f"not one line: {message!r}"
    assert "\n" not in message and "\r" not in message
    assert message.startswith(f"{path}: "), message
    for needle in needles:
        assert needle in message, f"{needle!r} not in {message!r}"
    return message


# ----------------------------------------------------------------------------------- shipped scenarios


@pytest.mark.parametrize("stem", sorted(SHIPPED))
def test_shipped_scenario_loads_into_friction_and_no_friction(stem: str) -> None:
    F_E, m_B = SHIPPED[stem]
    path = SCENARIOS / f"{stem}.yaml"
    runs = load_scenario(path)
    assert [run.variant for run in runs] == ["friction", "no_friction"]
    assert {run.variant: run.plant.mu for run in runs} == {"friction": 0.2, "no_friction": 0.0}
    for run in runs:
        assert run.scenario == stem
        assert run.label == f"{stem}/{run.variant}"
        assert run.source == path
        assert run.description
        assert run.fmu is not None and run.fmu.resolve() == (ROOT / "fmus" / "ToggleLSM.fmu").resolve()
        assert run.t_end == 1.5
        assert run.T_s == 0.0005
        assert run.steps == 3000
        assert (run.x_start, run.x_target) == (0.2329, 0.3199)
        assert run.plant.F_E == F_E
        assert run.plant.m_B == m_B
        assert run.plant.current_loop == "first_order"
        assert run.plant.K is None
        assert dict(run.plant.parameters) == {}
        assert run.controller.objective == "x_B"
        assert run.controller.nominal_m_B == 4.43
        gains = run.controller.gains
        assert (gains.C, gains.Q, gains.P, gains.delta, gains.beta) == (5.0, 4.0, 50.0, 0.25, 65.0)
        # the resolved document is what run.json records: the variant applied, no variants key
        assert "variants" not in run.resolved
        assert run.resolved["plant"]["mu"] == run.plant.mu
        assert run.resolved["plant"]["F_E"] == F_E


def test_shipped_scenarios_are_all_tested() -> None:
    assert {p.stem for p in SCENARIOS.glob("fig*.yaml")} == set(SHIPPED)


def test_the_swap_scenario_names_the_second_plant() -> None:
    (run,) = load_scenario(SCENARIOS / "swap_no_gravity.yaml")
    assert run.variant is None and run.label == "swap_no_gravity"
    assert run.fmu is not None and run.fmu.resolve() == (ROOT / "fmus" / "ToggleLSM_NoGravity.fmu").resolve()
    assert (run.plant.mu, run.plant.F_E, run.plant.m_B) == (0.2, 0.0, 4.43)


def test_stroke_lies_inside_the_reach() -> None:
    upper = toggle_limit(MechanismParameters())
    assert upper == pytest.approx(0.37)
    for stem in SHIPPED:
        for run in load_scenario(SCENARIOS / f"{stem}.yaml"):
            assert 0.17 < run.x_start < run.x_target < upper


def test_scenario_without_variants_gives_one_run(tmp_path: Path) -> None:
    path = write_doc(tmp_path, mutated(variants=DELETE))
    (run,) = load_scenario(path)
    assert run.variant is None and run.label == "fig4_nominal"
    assert run.plant.mu == 0.2  # the default


def test_variant_overrides_merge_into_the_base(tmp_path: Path) -> None:
    document = mutated(variants={"heavy": {"plant": {"m_B": 8.86}, "stroke": {"x_target": 0.3}, "t_end": 2.0}})
    (run,) = load_scenario(write_doc(tmp_path, document))
    assert run.plant.m_B == 8.86 and run.plant.F_E == 0.0  # F_E kept from the base plant
    assert (run.x_start, run.x_target) == (0.2329, 0.3)
    assert run.t_end == 2.0 and run.steps == 4000


def test_fmu_is_relative_to_the_file_and_absolute_is_kept(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    run = load_scenario(write_doc(tmp_path / "sub", mutated(fmu="plant.fmu")))[0]
    assert run.fmu == tmp_path / "sub" / "plant.fmu"
    run = load_scenario(write_doc(tmp_path, mutated(fmu="/opt/x.fmu")))[0]
    assert run.fmu == Path("/opt/x.fmu")
    run = load_scenario(write_doc(tmp_path, mutated(fmu=DELETE)))[0]
    assert run.fmu is None


# ------------------------------------------------------------------------------------- unknown keys


def test_unknown_top_level_key(tmp_path: Path) -> None:
    message = one_line_error(
        write_doc(tmp_path, mutated(speed=3)), "unknown key speed", "allowed here:", "t_end", "stroke"
    )
    assert "(top level)" not in message


@pytest.mark.parametrize(
    ("dotted", "key", "allowed"),
    [
        ("plant__muu", "plant.muu", "mu"),
        ("stroke__x_end", "stroke.x_end", "x_target"),
        ("controller__gain", "controller.gain", "gains"),
        ("controller__gains__K", "controller.gains.K", "beta"),
        ("variants__friction__plant__muu", "variants.friction.plant.muu", "m_B"),
        ("variants__friction__speed", "variants.friction.speed", "t_end"),
    ],
)
def test_unknown_nested_key(tmp_path: Path, dotted: str, key: str, allowed: str) -> None:
    one_line_error(write_doc(tmp_path, mutated(**{dotted: 1})), f"unknown key {key}", "allowed here:", allowed)


# --------------------------------------------------------------------------------------- wrong types


@pytest.mark.parametrize(
    ("dotted", "value", "key", "allowed"),
    [
        ("t_end", "fast", "t_end", "number"),
        ("T_s", True, "T_s", "number"),  # a YAML boolean is not a number
        ("stroke", [0.2329, 0.3199], "stroke", "object"),
        ("plant__m_B", "heavy", "plant.m_B", "number"),
        ("plant__parameters__J2", "big", "plant.parameters.J2", "number"),
        ("controller__gains", None, "controller.gains", "object"),
        ("name", 4, "name", "string"),
        ("description", ["a"], "description", "string"),
        ("variants__friction", "on", "variants.friction", "object"),
    ],
)
def test_wrong_type(tmp_path: Path, dotted: str, value: Any, key: str, allowed: str) -> None:
    one_line_error(write_doc(tmp_path, mutated(**{dotted: value})), f"key {key}:", "not of type", allowed)


def test_wrong_type_from_yaml_text(tmp_path: Path) -> None:
    text = (SCENARIOS / "fig4_nominal.yaml").read_text(encoding="utf-8").replace("t_end: 1.5", 't_end: "fast"')
    one_line_error(write_text(tmp_path, text), "key t_end:", "'fast'", "not of type number")


@pytest.mark.parametrize(
    ("dotted", "value", "key", "allowed"),
    [
        ("current_loop", "pid", "plant.current_loop", "first_order, ideal"),
        ("objective", "x_C", "controller.objective", "x_B, theta1"),
    ],
)
def test_value_not_in_the_choices(tmp_path: Path, dotted: str, value: str, key: str, allowed: str) -> None:
    parent = "plant" if dotted == "current_loop" else "controller"
    one_line_error(write_doc(tmp_path, mutated(**{f"{parent}__{dotted}": value})), f"key {key}:", repr(value), allowed)


# ------------------------------------------------------------------------------------------- ranges


@pytest.mark.parametrize(
    ("dotted", "value", "key", "allowed"),
    [
        ("plant__m_B", -1.0, "plant.m_B", "must be > 0"),
        ("plant__m_B", 0, "plant.m_B", "must be > 0"),
        ("controller__nominal_m_B", -4.43, "controller.nominal_m_B", "must be > 0"),
        ("plant__mu", -0.1, "plant.mu", "must be >= 0"),
        ("plant__mu", 1.5, "plant.mu", "must be <= 1"),
        ("variants__friction__plant__mu", 2, "variants.friction.plant.mu", "must be <= 1"),
        ("T_s", 0, "T_s", "must be >= 1e-06"),
        ("T_s", 0.5, "T_s", "must be <= 0.1"),
        ("t_end", 0, "t_end", "must be > 0"),
        ("t_end", -1.5, "t_end", "must be > 0"),
        ("t_end", 1000, "t_end", "must be <= 100"),
        ("plant__F_E", 1e9, "plant.F_E", "must be <= 10000"),
        ("controller__gains__C", 0, "controller.gains.C", "must be > 0"),
        ("controller__gains__delta", -0.25, "controller.gains.delta", "must be > 0"),
        ("stroke__x_start", -0.2, "stroke.x_start", "must be > 0"),
        ("plant__K", 10**40, "plant.K", "must be <= 1000000"),
    ],
)
def test_out_of_range(tmp_path: Path, dotted: str, value: Any, key: str, allowed: str) -> None:
    one_line_error(write_doc(tmp_path, mutated(**{dotted: value})), f"key {key}:", "out of range", allowed)


# ------------------------------------------------------------------------------------ missing keys


@pytest.mark.parametrize("dotted", ["name", "t_end", "T_s", "stroke", "stroke__x_start", "stroke__x_target"])
def test_missing_required_key(tmp_path: Path, dotted: str) -> None:
    key = dotted.split("__")[-1]
    one_line_error(write_doc(tmp_path, mutated(**{dotted: DELETE})), "missing key", f"'{key}'", "required")


def test_optional_keys_may_be_left_out(tmp_path: Path) -> None:
    document = {k: BASE[k] for k in ("name", "t_end", "T_s", "stroke")}
    (run,) = load_scenario(write_doc(tmp_path, document))
    assert run.plant.m_B == 4.43 and run.controller.gains.C == 5.0 and run.fmu is None


# --------------------------------------------------------------------------------- physical limits


def test_target_beyond_the_toggle_position(tmp_path: Path) -> None:
    path = write_doc(tmp_path, mutated(stroke__x_target=0.40))
    one_line_error(path, "key stroke.x_target", "0.4", "toggle position 0.3700 m", "between 0.1800 m")


def test_target_beyond_the_toggle_position_in_a_variant(tmp_path: Path) -> None:
    path = write_doc(tmp_path, mutated(variants__friction__stroke={"x_target": 0.40}))
    one_line_error(path, "key stroke.x_target (variant friction)", "toggle position")


@pytest.mark.parametrize("x_start", [0.1, 0.17, 0.1799, 0.3601, 0.37, 0.5, 10**6])
def test_start_outside_the_reach(tmp_path: Path, x_start: float) -> None:
    """The linkage is singular at the folded (x_B = r3 - r1 = 0.17 m) and the toggle position
    (r1 + r3 = 0.37 m): a start within 10 mm of either is refused, not run into huge currents."""
    path = write_doc(tmp_path, mutated(stroke__x_start=x_start))
    one_line_error(
        path,
        "key stroke.x_start",
        "outside the working range",
        "between 0.1800 m and 0.3600 m",
        "folded position 0.1700 m",
        "toggle position 0.3700 m",
    )


@pytest.mark.parametrize("x_start", [0.18, 0.36])
def test_start_at_the_margin_is_accepted(tmp_path: Path, x_start: float) -> None:
    (run, _) = load_scenario(write_doc(tmp_path, mutated(stroke__x_start=x_start)))
    assert run.x_start == x_start


def test_zero_length_stroke_is_refused(tmp_path: Path) -> None:
    path = write_doc(tmp_path, mutated(stroke__x_start=0.3199))
    one_line_error(path, "key stroke.x_target", "of x_start", "needs a length")


@pytest.mark.parametrize(
    ("name", "own"),
    [
        ("m_B", "plant.m_B"),
        ("mu", "plant.mu"),
        ("K", "plant.K"),
        ("idealCurrentLoop", "plant.current_loop"),
        ("x_B0", "stroke.x_start"),
    ],
)
def test_plant_parameters_may_not_bypass_their_own_keys(tmp_path: Path, name: str, own: str) -> None:
    path = write_doc(tmp_path, mutated(plant__parameters={name: True}))
    one_line_error(path, f"key plant.parameters.{name}", f"set {own} instead")


@pytest.mark.parametrize("text", ["5e-4", "5E-4", "+5e-4"])
def test_yaml_1_2_exponents_are_numbers(tmp_path: Path, text: str) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(BASE_TEXT_FOR_NUMBERS.replace("T_s: 0.0005", f"T_s: {text}"))
    (run,) = load_scenario(path)
    assert run.T_s == 5e-4


def test_duplicate_keys_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text(BASE_TEXT_FOR_NUMBERS + "t_end: 2.0\n")
    one_line_error(path, "duplicate key 't_end'", "line 5")


BASE_TEXT_FOR_NUMBERS = "name: fig\nt_end: 1.5\nT_s: 0.0005\nstroke: {x_start: 0.2329, x_target: 0.3199}\n"


def test_t_end_not_a_whole_number_of_samples(tmp_path: Path) -> None:
    path = write_doc(tmp_path, mutated(T_s=0.0007))
    one_line_error(path, "key t_end", "not a whole number of samples", "T_s = 0.0007")


def test_sample_time_longer_than_the_run(tmp_path: Path) -> None:
    path = write_doc(tmp_path, mutated(t_end=0.01, T_s=0.05))
    one_line_error(path, "key T_s", "longer than t_end", "T_s < t_end")


# ------------------------------------------------------------------------------------ non-finite


@pytest.mark.parametrize(
    ("line", "replacement", "key"),
    [
        ("t_end: 1.5", "t_end: .nan", "t_end"),
        ("t_end: 1.5", "t_end: .inf", "t_end"),
        ("T_s: 0.0005", "T_s: -.inf", "T_s"),
        ("  m_B: 4.43", "  m_B: .NaN", "plant.m_B"),
        ("  x_target: 0.3199", "  x_target: .Inf", "stroke.x_target"),
        ("  m_B: 4.43", "  m_B: 4.43\n  parameters: {J2: .nan}", "plant.parameters.J2"),
        ("    plant: {mu: 0.0}", "    plant: {mu: .nan}", "variants.no_friction.plant.mu"),
        ("    plant: {mu: 0.0}", "    plant: {mu: 0.0}\n    extra: [1, .inf]", "variants.no_friction.extra.1"),
        ("t_end: 1.5", "t_end: 1.0e+400", "t_end"),  # overflows to inf
    ],
)
def test_non_finite_numbers(tmp_path: Path, line: str, replacement: str, key: str) -> None:
    text = (SCENARIOS / "fig4_nominal.yaml").read_text(encoding="utf-8")
    assert line in text
    one_line_error(write_text(tmp_path, text.replace(line, replacement, 1)), f"key {key}:", "not a finite number")


# ----------------------------------------------------------------------------------- broken files


@pytest.mark.parametrize("text", ["", "\n\n", "   \n", "# only a comment\n", "---\n", "~\n"])
def test_empty_file(tmp_path: Path, text: str) -> None:
    one_line_error(write_text(tmp_path, text), "empty", "name, t_end, T_s and stroke")


def test_binary_junk(tmp_path: Path) -> None:
    data = bytes(range(256)) * 4 + b"PK\x03\x04\x00\x00\xff\xfe"
    one_line_error(write_bytes(tmp_path, data), "not UTF-8", "byte 128")


def test_control_characters_are_a_syntax_error_with_a_position(tmp_path: Path) -> None:
    path = write_bytes(tmp_path, b"name: fig\nt_end: 1\x00\x01\x02\n")
    one_line_error(path, "YAML", "line 2, column 9", "#x0000")


def test_latin1_text(tmp_path: Path) -> None:
    text = (SCENARIOS / "fig4_nominal.yaml").read_text(encoding="utf-8").replace("Nominal case", "Cas nominal é")
    path = write_bytes(tmp_path, text.encode("latin-1"))
    offset = text.encode("latin-1").index(b"\xe9")
    one_line_error(path, "not UTF-8", f"byte {offset}", "UTF-8")


@pytest.mark.parametrize(
    "text",
    [
        "- name: fig4\n- t_end: 1.5\n",
        "[1, 2, 3]\n",
        "just a sentence\n",
        "42\n",
        "!!binary aGVsbG8=\n",
        "!!set {name, t_end}\n",
    ],
)
def test_not_a_mapping(tmp_path: Path, text: str) -> None:
    one_line_error(write_text(tmp_path, text), "YAML mapping", "name, t_end, T_s, stroke")


@pytest.mark.parametrize(
    ("text", "where"),
    [
        ("name: fig\nt_end: 1.5\nT_s: a: b\n", "line 3, column 7"),
        ("name: fig\nstroke: {x_start: 0.2\n", "line 3, column 1"),
        ("name: fig\n  t_end: 1.5\n", "line 2, column 8"),
        ("name: fig\nt_end:\n\t- 1.5\n", "line 3, column 1"),
        ("name: 'unterminated\n", "line 2, column 1"),
        ("name: *nowhere\n", "line 1, column 7"),
        ("name: fig\n---\nname: other\n", "line 2, column 1"),
        ("name: !!python/object/apply:os.system [echo]\n", "line 1, column 7"),
        ("? [a, b]\n: 1\n", "line 1, column 3"),
    ],
)
def test_yaml_syntax_error_gives_line_and_column(tmp_path: Path, text: str, where: str) -> None:
    one_line_error(write_text(tmp_path, text), "YAML syntax error", where)


@pytest.mark.parametrize(
    "scalar",
    [
        "!!int abc",
        "!!float abc",
        "!!int '0b'",
        "!!int ':'",
        "!!int ''",
        "!!float ''",
        "!!int '_'",
        "!!bool maybe",
        "!!bool ''",
        "!!timestamp abc",
        "!!timestamp 2001-13-45",
        "!!timestamp 2001-02-30",
        "9" * 5000,
    ],
)
def test_unconvertible_tagged_scalar(tmp_path: Path, scalar: str) -> None:
    """PyYAML raises ValueError, KeyError, IndexError or AttributeError, not YAMLError, for these."""
    text = (SCENARIOS / "fig4_nominal.yaml").read_text(encoding="utf-8").replace("t_end: 1.5", f"t_end: {scalar}")
    one_line_error(write_text(tmp_path, text), "YAML value that cannot be converted")


def test_missing_file_and_directory(tmp_path: Path) -> None:
    one_line_error(tmp_path / "nowhere.yaml", "no such scenario file")
    one_line_error(tmp_path, "is a directory, not a scenario file")


# ----------------------------------------------------------------------------- names and patterns


@pytest.mark.parametrize("name", ["fig 4", "", "../escape", "fig/4", ".hidden", "fig4\n", "fig4\u2028"])
def test_bad_scenario_name(tmp_path: Path, name: str) -> None:
    one_line_error(write_doc(tmp_path, mutated(name=name)), "key name:", "does not match")


@pytest.mark.parametrize("variant", ["no friction", "a/b", "x\n", 1, True, None])
def test_bad_variant_name(tmp_path: Path, variant: Any) -> None:
    document = mutated()
    document["variants"][variant] = {"plant": {"mu": 0.1}}
    one_line_error(write_doc(tmp_path, document), "key variants:")


def test_no_variants_is_an_error_not_zero_runs(tmp_path: Path) -> None:
    one_line_error(write_doc(tmp_path, mutated(variants={})), "key variants:", "non-empty")


@pytest.mark.parametrize("parameter", ["9lives", "a b", "x\n", 3])
def test_bad_parameter_name(tmp_path: Path, parameter: Any) -> None:
    document = mutated()
    document["plant"]["parameters"] = {parameter: 1.0}
    one_line_error(write_doc(tmp_path, document), "key plant.parameters")


def test_parameters_accept_numbers_and_booleans(tmp_path: Path) -> None:
    document = mutated()
    document["plant"]["parameters"] = {"J2": 0.004, "link.r[1]": 2, "useFriction": False}
    run = load_scenario(write_doc(tmp_path, document))[0]
    assert dict(run.plant.parameters) == {"J2": 0.004, "link.r[1]": 2, "useFriction": False}


@pytest.mark.parametrize("fmu", ["", "a\x00b.fmu"])
def test_bad_fmu_path(tmp_path: Path, fmu: str) -> None:
    one_line_error(write_doc(tmp_path, mutated(fmu=fmu)), "key fmu:")


# ------------------------------------------------------- odd YAML that must still give one clean line


def test_key_with_a_line_break_is_shown_escaped(tmp_path: Path) -> None:
    document = mutated()
    document["sp\need"] = 1
    one_line_error(write_doc(tmp_path, document), "unknown key 'sp\\need'", "allowed here:")


def test_keys_of_mixed_types(tmp_path: Path) -> None:
    document = mutated()
    document[1] = 2
    document["speed"] = 3
    document[None] = 4
    one_line_error(write_doc(tmp_path, document), "key (top level): the key 1 is not a name: YAML reads an unquoted")


@pytest.mark.parametrize(
    "text",
    [
        "t_end: 0x" + "f" * 4000,  # a valid YAML integer with ~4800 decimal digits
        "stroke: {x_start: 0x" + "f" * 4000 + ", x_target: 0.3}",
        "plant: {parameters: {J2: 0b" + "1" * 20000 + "}}",
        "? 0x" + "f" * 4000 + "\n: 1",  # as a key
    ],
)
def test_integer_too_large_for_a_float(tmp_path: Path, text: str) -> None:
    base = "name: fig\nt_end: 1.5\nT_s: 0.0005\nstroke: {x_start: 0.2329, x_target: 0.3199}\n"
    key = text.split(":")[0]
    if key in ("t_end", "stroke"):
        base = "\n".join(line for line in base.splitlines() if not line.startswith(f"{key}:")) + "\n"
    one_line_error(write_text(tmp_path, base + text + "\n"), "bits is too large", "finite")


@pytest.mark.parametrize(
    "text",
    [
        "junk: &a [*a]\n",
        "junk: &a {self: *a}\n",
        "plant: &p {parameters: {J2: 1}, x: [*p]}\n",
    ],
)
def test_recursive_alias(tmp_path: Path, text: str) -> None:
    base = (SCENARIOS / "fig4_nominal.yaml").read_text(encoding="utf-8").replace("plant:\n", "old_plant:\n")
    one_line_error(write_text(tmp_path, base + text), "recursive")


@pytest.mark.parametrize("where", ["junk", "t_end"])
def test_alias_bomb_is_refused_quickly(tmp_path: Path, where: str) -> None:
    """Nine levels of ten aliases: a 1 KB file that expands to 10**9 values."""
    lines = [
        "name: fig",
        "T_s: 0.0005",
        "stroke: {x_start: 0.2329, x_target: 0.3199}",
        "a0: &a0 [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]",
    ]
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 9)]
    lines.append(f"{where}: *a8")
    started = time.perf_counter()
    one_line_error(write_text(tmp_path, "\n".join(lines) + "\n"), "more than")
    assert time.perf_counter() - started < 5.0


@pytest.mark.parametrize("depth", [200, 5000])
def test_deep_nesting(tmp_path: Path, depth: int) -> None:
    one_line_error(write_text(tmp_path, "junk: " + "[" * depth + "]" * depth + "\n"), "")


def test_long_value_gives_one_line(tmp_path: Path) -> None:
    path = write_doc(tmp_path, mutated(t_end="x" * 100_000))
    one_line_error(path, "key t_end:", "not of type number")


def test_path_with_spaces_and_unicode(tmp_path: Path) -> None:
    path = write_doc(tmp_path, mutated(plant__muu=1), name="my scénario (copy).yaml")
    one_line_error(path, "plant.muu")


def test_finite_numbers_from_yaml_spellings(tmp_path: Path) -> None:
    text = (SCENARIOS / "fig4_nominal.yaml").read_text(encoding="utf-8")
    text = text.replace("t_end: 1.5", "t_end: 0b10").replace("T_s: 0.0005", "T_s: 5.0e-4")
    run = load_scenario(write_text(tmp_path, text))[0]
    assert run.t_end == 2.0 and run.T_s == 0.0005 and math.isfinite(run.t_end)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("components: {true: {fmu: x.fmu}}", "key components: the key True is not a name: YAML reads"),
        ("components: {yes: {fmu: x.fmu}}", "key components: the key True is not a name"),
        ("plant: {inputs: {1: 2.0}}", "key plant.inputs: the key 1 is not a name"),
        ("variants: {null: {t_end: 1.0}}", "key variants: the key None is not a name"),
        (
            "plant: {F_E: {kind: points, points: [" + ", ".join(f"[{i}, 0]" for i in range(10_001)) + "]}}",
            "key plant.F_E.points: [[0, 0], [1, 0], [2, 0], [3, 0], [4, 0], [5, 0], [6, 0], [7, 0], ...] "
            "(a list of 10001) is too long",
        ),
    ],
)
def test_a_key_that_is_no_name_or_a_huge_value_is_one_short_line_before_any_run(
    tmp_path: Path, text: str, needle: str
) -> None:
    """A YAML boolean, null or number as a name (a component `true:`) is refused naming the key,
    not a traceback; a value too long for the schema is shown by its first elements and size."""
    from click.testing import CliRunner

    from toggle_cosim.cli import main

    base = yaml.safe_dump({k: v for k, v in BASE.items() if k not in ("plant", "variants")}, sort_keys=False)
    path = write_text(tmp_path, f"{base}{text}\n")
    result = CliRunner().invoke(main, ["run", str(path), "--out", str(tmp_path / "out"), "-q"])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1, result.output[:2000]
    assert lines[0].startswith(f"error: {path}: {needle}"), lines[0][:2000]
    assert len(lines[0]) < 500 and "Traceback" not in result.output and not (tmp_path / "out").exists()

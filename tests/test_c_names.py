"""Models the generated C cannot spell, and C compiler failures: one line naming the variable,
or the compiler's first error; an expression nested too deeply is one line too."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from toggle_cosim.cli import main
from toggle_cosim.fmu_export.c_names import c_name_problem

MODELS = {
    "keyword": (
        "model K\n  Real int(start = 1, fixed = true);\n  parameter Real default = 2;\n"
        "equation\n  der(int) = -default * int;\nend K;\n",
        "variable 'int': its name is the C keyword or macro int",
    ),
    "double": (
        "model K\n  Real x(start = 1, fixed = true);\n  Real double;\nequation\n  der(x) = -x;\n  double = 2 * x;\nend K;\n",
        "variable 'double'",
    ),
    "quoted": (
        "model K\n  Real 'Café'(start = 1, fixed = true);\nequation\n  der('Café') = -'Café';\nend K;\n",
        "variable \"'Café'\": its C name _Café_ has characters outside ASCII",
    ),
    "nested": (
        "model K\n  Real x(start = 0, fixed = true);\nequation\n  der(x) = "
        + "sin(" * 200
        + "x"
        + ")" * 200
        + ";\nend K;\n",
        "an expression is nested too deeply for the compiler",
    ),
}


def _build(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, text: str) -> list[str]:
    (tmp_path / "pyproject.toml").write_text("[project]\nname = 'x'\n")
    (tmp_path / "K.mo").write_text(text, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(main, ["build", "--source", "K.mo", "--model", "K", "--out", "fmus/K.fmu"])
    assert result.exit_code == 2, result.output
    assert not (tmp_path / "fmus" / "K.fmu").exists()
    return result.output.strip().splitlines()


@pytest.mark.parametrize("case", sorted(MODELS))
def test_a_model_the_c_cannot_spell_is_refused_in_one_line(
    case: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    text, needle = MODELS[case]
    lines = _build(tmp_path, monkeypatch, text)
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0], lines
    assert "RecursionError" not in lines[0] and "Traceback" not in lines[0]


def test_names_the_c_can_use_pass() -> None:
    called = {"sqrt", "sin"}
    assert [c_name_problem(s, called) for s in ("x", "body_v", "_a_b_", "int_", "sqrt_")] == [None] * 5
    assert all(c_name_problem(s, called) for s in ("int", "default", "sqrt", "_Café_", "bool", "NAN"))


@pytest.mark.parametrize("says", ["model.c:3:1: error: boom here", ""])
def test_a_failing_c_compiler_shows_its_first_error(says: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """$CC that fails: the one line carries its first error line (or says it printed nothing),
    never ends at 'failed for K:'."""
    fake = tmp_path / "fakecc"
    printed = f"echo 'In function rhs:' >&2\necho {says!r} >&2\n" if says else ""
    fake.write_text(f"#!/bin/sh\n{printed}exit 1\n")
    fake.chmod(0o755)
    monkeypatch.setenv("CC", str(fake))
    lines = _build(
        tmp_path, monkeypatch, "model K\n  Real x(start = 1, fixed = true);\nequation\n  der(x) = -x;\nend K;\n"
    )
    assert len(lines) == 1, lines
    expected = "C compiler failed for K: " + (says if says else "it exited with status 1 and printed nothing")
    assert lines[0] == f"error: {expected}", lines
    assert not lines[0].endswith(":")

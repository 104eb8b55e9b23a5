"""`toggle-cosim compare` on random and mutated input: exit 2 with one `error:` line and
nothing written, or a normal verdict (0/1) -- never a traceback, never a stray file."""

from __future__ import annotations

from pathlib import Path

from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from toggle_cosim.cli import main

GOOD = '"time","x","y"\n0,0,1\n0.5,0.25,1\n1,1,1\n'
FUZZ = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _invoke(folder: Path, result: bytes, reference: bytes, tolerances: bytes | None) -> None:
    (folder / "result.csv").write_bytes(result)
    (folder / "reference.csv").write_bytes(reference)
    args = ["compare", str(folder / "result.csv"), str(folder / "reference.csv"), "--out", str(folder / "report")]
    if tolerances is not None:
        (folder / "tol.yaml").write_bytes(tolerances)
        args += ["--tolerances", str(folder / "tol.yaml")]
    outcome = CliRunner().invoke(main, args)
    assert outcome.exception is None or isinstance(outcome.exception, SystemExit), outcome.exception
    assert "Traceback" not in outcome.output + outcome.stderr
    if outcome.exit_code == 2:
        lines = outcome.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: "), outcome.stderr
        assert not (folder / "report").exists()
    else:
        assert outcome.exit_code in (0, 1), (outcome.exit_code, outcome.stderr)


def _mutate(text: str, position: int, junk: str) -> bytes:
    position %= len(text) + 1
    return (text[:position] + junk + text[position:]).encode("utf-8", "surrogatepass")


@FUZZ
@given(data=st.binary(max_size=300))
def test_random_bytes_as_result(tmp_path_factory, data: bytes) -> None:
    _invoke(tmp_path_factory.mktemp("c"), data, GOOD.encode(), None)


@FUZZ
@given(data=st.binary(max_size=300))
def test_random_bytes_as_reference(tmp_path_factory, data: bytes) -> None:
    _invoke(tmp_path_factory.mktemp("c"), GOOD.encode(), data, None)


@FUZZ
@given(position=st.integers(0, 200), junk=st.text(max_size=12))
def test_mutated_csv(tmp_path_factory, position: int, junk: str) -> None:
    _invoke(tmp_path_factory.mktemp("c"), _mutate(GOOD, position, junk), GOOD.encode(), None)


@FUZZ
@given(data=st.one_of(st.binary(max_size=200), st.text(max_size=200).map(str.encode)))
def test_random_tolerance_files(tmp_path_factory, data: bytes) -> None:
    _invoke(tmp_path_factory.mktemp("c"), GOOD.encode(), GOOD.encode(), data)

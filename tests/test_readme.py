"""Every command the README shows works when pasted: each `toggle-cosim ...` line of its sh/bash
code blocks names a command and options that exist (parsed by the click command itself, without
running it), and no block calls a bare `python` that would be the system's interpreter."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import click
import pytest

from toggle_cosim.cli import main

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PROGRAMS = ("toggle-cosim", ".venv/bin/toggle-cosim")
# what a line of a README shell block may start with (after the set-up line activates .venv)
ALLOWED_FIRST_WORDS = (*PROGRAMS, ".venv/bin/python", "scripts/run-paper", "scripts/test", ".")


def shell_commands(text: str) -> list[tuple[int, str]]:
    """(line number, command) for every command in the ```sh / ```bash blocks: continuation lines
    joined, comments dropped."""
    commands: list[tuple[int, str]] = []
    inside, pending, start = False, "", 0
    for number, line in enumerate(text.splitlines(), start=1):
        if line.startswith("```"):
            inside = not inside and line[3:].strip() in ("sh", "bash")
            continue
        if not inside:
            continue
        if not pending:
            start = number
        pending += line.rstrip().removesuffix("\\") + ("\n" if not line.rstrip().endswith("\\") else " ")
        if line.rstrip().endswith("\\"):
            continue
        try:
            words = shlex.split(pending, comments=True)
        except ValueError:  # an open quotation: the command goes on over the next line
            continue
        pending = ""
        if words:
            commands.append((start, shlex.join(words)))
    return commands


def dry_parse(arguments: list[str]) -> None:
    """Parse `toggle-cosim ARGUMENTS` as click would, without running the command: raises
    click.UsageError (no such command, no such option, a bad value) for a line that would fail."""
    # a usage synopsis writes optional parts in brackets: [--out DIR] parses as --out DIR
    arguments = [word.strip("[]") for word in arguments if word.strip("[]")]
    with main.make_context("toggle-cosim", arguments) as context:
        name, command, rest = main.resolve_command(context, [*context._protected_args, *context.args])
        with command.make_context(name, rest, parent=context):
            pass


COMMANDS = shell_commands(README.read_text(encoding="utf-8"))
CLI_LINES = [(n, c) for n, c in COMMANDS if shlex.split(c)[0] in PROGRAMS]


def test_the_readme_has_examples_to_check() -> None:
    assert len(CLI_LINES) >= 15  # build, run, plot, compare, references, sweep, ... (a broken extraction finds none)
    assert {shlex.split(c)[1] for _, c in CLI_LINES} >= {"build", "run", "plot", "compare", "references", "sweep"}


@pytest.mark.parametrize(("line", "command"), COMMANDS, ids=[f"line{n}" for n, _ in COMMANDS])
def test_every_shell_line_uses_the_projects_programs(line: int, command: str) -> None:
    """A bare `python` (or any program the set-up does not provide) would not be the project's."""
    first = shlex.split(command)[0]
    assert first in ALLOWED_FIRST_WORDS, f"README.md:{line}: {command!r} starts with {first!r}"


@pytest.mark.parametrize(("line", "command"), CLI_LINES, ids=[f"line{n}" for n, _ in CLI_LINES])
def test_every_toggle_cosim_example_parses(line: int, command: str) -> None:
    try:
        dry_parse(shlex.split(command)[1:])
    except click.UsageError as error:
        pytest.fail(f"README.md:{line}: {command!r}: {error.format_message()}")


def test_the_set_up_block_activates_the_environment() -> None:
    """After the set-up command the reader activates .venv, so bare `toggle-cosim` is found."""
    first_block = [c for n, c in COMMANDS][:3]
    assert first_block[0].startswith("scripts/run-paper")
    assert ". .venv/bin/activate" in first_block


def test_inline_python_commands_name_the_projects_interpreter() -> None:
    """`python benchmarks/...` in the prose would run the system's Python (3.11 here)."""
    text = README.read_text(encoding="utf-8")
    bare = [
        m.group(0) for m in re.finditer(r"`(?:[^`]*\s)?python3? [^`]*`", text) if ".venv/bin/python" not in m.group(0)
    ]
    assert not bare, bare


@pytest.mark.parametrize(
    "arguments",
    [
        ["sweep", "s.yaml", "--output", "x"],  # the old argparse-only spelling
        ["build", "--output", "x.fmu"],
        ["runn", "s.yaml"],
        ["run", "s.yaml", "--no-such-option"],
    ],
)
def test_the_check_fails_for_a_wrong_example(arguments: list[str]) -> None:
    with pytest.raises(click.UsageError):
        dry_parse(arguments)


def test_the_same_option_name_for_the_output_everywhere() -> None:
    """--out names where every command writes (a folder, or the one file it writes)."""
    for name in ("build", "run", "plot", "paper", "compare", "references", "sweep"):
        options = {opt for p in main.commands[name].params for opt in getattr(p, "opts", [])}
        assert "--out" in options, name
        assert "--output" not in options, name

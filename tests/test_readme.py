"""Every example in the README and the documentation works when a reader runs it.

The shell examples (```sh / ```bash blocks) of README.md and of the documentation pages, in the
order a reader meets them (the README, then the pages in the order of mkdocs.yml's nav), are
run one block after the other, each block as one bash script, in a working copy of the
repository's top folder with `.venv/bin` first on PATH: so no example breaks the next. Only
`scripts/test` is left out (it is the command that runs this test). Examples that cannot run
here are written as ```text; their `toggle-cosim` lines are still parsed by the command itself.
The documentation site builds with `mkdocs build --strict`."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import click
import pytest
import yaml

import toggle_cosim
from toggle_cosim.cli import main

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PROGRAMS = ("toggle-cosim", ".venv/bin/toggle-cosim")
NOT_RUN = ("scripts/test",)  # the test command itself
# what a line of a shell block may start with (the set-up line activates .venv)
ALLOWED_FIRST_WORDS = (
    *PROGRAMS,
    ".venv/bin/python",
    "scripts/run-paper",
    "scripts/test",
    ".",
    "cd",
    "dask",
    "pythonfmu",  # the PythonFMU template plant (the test extra installs it)
    "kill",
    "mkdir",
    "cat",
)


def _nav_pages(nav: list) -> list[str]:  # noqa: ANN001 - mkdocs.yml's nav, nested lists of {title: page}
    pages: list[str] = []
    for entry in nav:
        for value in entry.values() if isinstance(entry, dict) else [entry]:
            pages += _nav_pages(value) if isinstance(value, list) else [value]
    return pages


def documents() -> list[Path]:
    """README.md, then every documentation page in the order of the site's navigation."""
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))
    return [README, *(ROOT / "docs" / page for page in _nav_pages(config["nav"]))]


def code_blocks(path: Path, languages: tuple[str, ...]) -> list[tuple[int, str]]:
    """(first line number, text) of each fenced block in one of `languages`."""
    blocks: list[tuple[int, str]] = []
    inside, start, lines = False, 0, []
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        if line.startswith("```"):
            if inside:
                blocks.append((start, "\n".join(lines)))
                inside = False
            elif line[3:].strip() in languages:
                inside, start, lines = True, number + 1, []
            continue
        if inside:
            lines.append(line)
    return blocks


def shell_commands(text: str) -> list[str]:
    """The commands of a shell block: continuation lines joined, comments dropped, a heredoc's
    body skipped."""
    commands: list[str] = []
    pending, heredoc = "", None
    for line in text.splitlines():
        if heredoc is not None:
            heredoc = None if line.strip() == heredoc else heredoc
            continue
        pending += line.rstrip().removesuffix("\\") + (" " if line.rstrip().endswith("\\") else "\n")
        if line.rstrip().endswith("\\"):
            continue
        marker = re.search(r"<<-?'?(\w+)'?", pending)
        try:
            words = shlex.split(pending, comments=True)
        except ValueError:  # an open quotation: the command goes on over the next line
            continue
        pending = ""
        heredoc = marker.group(1) if marker else None
        if words:
            commands.append(shlex.join(words))
    return commands


def cli_lines(text: str) -> list[str]:
    """`toggle-cosim ...` lines of any block (shell or text), comments dropped."""
    found = []
    for line in re.sub(r"\\\n\s*", " ", text).splitlines():  # continuation lines joined
        words = shlex.split(line, comments=True) if line.startswith(PROGRAMS) else []
        if words and words[0] in PROGRAMS and "&&" not in words and "|" not in words:
            found.append(shlex.join(words))
    return found


def dry_parse(arguments: list[str]) -> None:
    """Parse `toggle-cosim ARGUMENTS` as click would, without running the command: raises
    click.UsageError (no such command, no such option, a bad value) for a line that would fail."""
    # a usage synopsis writes optional parts in brackets: [--out DIR] parses as --out DIR
    arguments = [word.strip("[]") for word in arguments if word.strip("[]")]
    with main.make_context("toggle-cosim", arguments) as context:
        name, command, rest = main.resolve_command(context, [*context._protected_args, *context.args])
        with command.make_context(name, rest, parent=context):
            pass


SHELL_BLOCKS = [(path, line, text) for path in documents() for line, text in code_blocks(path, ("sh", "bash"))]
CLI_LINES = [
    (f"{path.relative_to(ROOT)}:{line}", command)
    for path in documents()
    for line, text in code_blocks(path, ("sh", "bash", "text"))
    for command in cli_lines(text)
]


def test_the_documents_have_examples_to_run() -> None:
    """A broken extraction finds none: the README's two commands and the everyday tasks, the
    pages' examples of every command."""
    assert len(SHELL_BLOCKS) >= 12
    commands = [shlex.split(c) for _, _, text in SHELL_BLOCKS for c in shell_commands(text)]
    assert commands[0][0] == "scripts/run-paper"
    used = {words[1] for words in commands if words[0] in PROGRAMS}
    assert used >= {"run", "plot", "compare", "references", "sweep", "init", "build"}
    assert {shlex.split(c)[1] for _, c in CLI_LINES} >= {"build", "run", "plot", "compare", "references", "sweep"}


@pytest.mark.parametrize(("path", "line", "text"), SHELL_BLOCKS, ids=[f"{p.name}:{n}" for p, n, _ in SHELL_BLOCKS])
def test_every_shell_line_uses_the_projects_programs(path: Path, line: int, text: str) -> None:
    """A bare `python` (or any program the set-up does not provide) would not be the project's."""
    for command in shell_commands(text):
        first = shlex.split(command)[0]
        assert first in ALLOWED_FIRST_WORDS, f"{path.name}:{line}: {command!r} starts with {first!r}"


@pytest.mark.parametrize(("where", "command"), CLI_LINES, ids=[w for w, _ in CLI_LINES])
def test_every_toggle_cosim_example_parses(where: str, command: str) -> None:
    try:
        dry_parse(shlex.split(command)[1:])
    except click.UsageError as error:
        pytest.fail(f"{where}: {command!r}: {error.format_message()}")


def test_the_set_up_block_activates_the_environment() -> None:
    """After the set-up command the reader activates .venv, so bare `toggle-cosim` is found."""
    first_block = shell_commands(code_blocks(README, ("sh",))[0][1])
    assert first_block[0].startswith("scripts/run-paper")
    assert ". .venv/bin/activate" in first_block


def test_inline_python_commands_name_the_projects_interpreter() -> None:
    """`python benchmarks/...` in the prose would run the system's Python (3.11 here); only the
    installed package's `python -m toggle_cosim` is meant for any interpreter."""
    for path in documents():
        text = path.read_text(encoding="utf-8")
        bare = [
            m.group(0)
            for m in re.finditer(r"`(?:[^`]*\s)?python3? [^`]*`", text)
            if ".venv/bin/python" not in m.group(0) and m.group(0) != "`python -m toggle_cosim`"
        ]
        assert not bare, (path.name, bare)


HISTORY = re.compile(
    r"\b(now|previously|formerly|used to|as before|has since|since replaced|no longer (?:needed|used|required)"
    r"|before the [\w -]+ existed|about a minute|half a minute|a few minutes)\b",
    re.IGNORECASE,
)


def test_the_documents_describe_the_code_today() -> None:
    """README and the pages say what the code does, not how it came to be (that is the
    changelog's), and give no vague time that nobody re-measures: a timing names what it
    measured (docs/performance.md)."""
    for path in documents():
        if path.name == "changelog.md":
            continue
        found = [match.group(0) for match in HISTORY.finditer(path.read_text(encoding="utf-8"))]
        assert not found, (path.name, found)


def test_the_readme_stays_short() -> None:
    assert len(README.read_text(encoding="utf-8").splitlines()) <= 150


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


def test_the_documentation_site_builds_strictly(tmp_path: Path) -> None:
    """Every page in the nav, every link and anchor resolves, the API reference renders from
    the docstrings and the changelog is included (mkdocs.yml sets strict)."""
    mkdocs = Path(sys.executable).parent / "mkdocs"
    if not mkdocs.is_file():
        pytest.skip("mkdocs is not installed (the extra [docs])")
    result = subprocess.run(
        [mkdocs, "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
        check=False,
    )
    assert result.returncode == 0, result.stderr
    api = (tmp_path / "site" / "api" / "index.html").read_text(encoding="utf-8")
    assert "doc-heading" in api
    for name, module in toggle_cosim._PUBLIC.items():  # every public name, its docstring rendered
        assert f'id="{module}.{name}"' in api, name
    assert api.count("Example") >= 6  # simulate, Result, Comparison, compare, sweep, load_scenario
    assert "Unreleased" in (tmp_path / "site" / "changelog" / "index.html").read_text(encoding="utf-8")
    # long code lines wrap instead of being cut off: the style sheet is in the site and every page links it
    css = (tmp_path / "site" / "assets" / "extra.css").read_text(encoding="utf-8")
    assert "white-space: pre-wrap" in css and "overflow-x: auto" in css
    assert 'href="../assets/extra.css"' in api


def test_the_api_reference_documents_the_public_api_only() -> None:
    """docs/api.md renders exactly `toggle_cosim.__all__` (each name from the module that defines
    it), not the internals (`cosim.master.simulate`, `RunOutcome`)."""
    rendered = re.findall(r"^::: (\S+)$", (ROOT / "docs" / "api.md").read_text(encoding="utf-8"), re.MULTILINE)
    assert sorted(rendered) == sorted(f"{module}.{name}" for name, module in toggle_cosim._PUBLIC.items())
    assert set(toggle_cosim.__all__) == {"__version__", *toggle_cosim._PUBLIC}


@pytest.mark.parametrize("name", ["simulate", "Result", "Comparison", "compare", "sweep", "load_scenario"])
def test_the_public_api_has_real_docstrings(name: str) -> None:
    """What the user pages teach is documented: parameters, what it returns, what it raises, and
    an example (functions); the attributes and an example (classes)."""
    import inspect

    value = getattr(toggle_cosim, name)
    doc = inspect.getdoc(value) or ""
    sections = ("Attributes:", "Example:") if inspect.isclass(value) else ("Args:", "Returns:", "Raises:", "Example:")
    assert all(section in doc for section in sections), (name, [s for s in sections if s not in doc])
    example = doc.split("Example:", 1)[1]
    assert "tc." in example or "result" in example


def tracked_entries(root: Path) -> list[str]:
    """The top-level names of the files git tracks in `root` (a reader's fresh clone has these
    and nothing else), and `.venv`, which scripts/setup makes: never what a reader left there
    (`toggle-cosim init study`, out/, fmus/, a site/ build)."""
    listed = subprocess.run(
        ["git", "-C", str(root), "ls-files", "-z"], capture_output=True, text=True, check=True
    ).stdout
    names = {name.split("/", 1)[0] for name in listed.split("\0") if name}
    return sorted(names | ({".venv"} if (root / ".venv").is_dir() else set()))


def test_the_working_copy_has_the_tracked_files_only(tmp_path: Path) -> None:
    """An untracked folder (what following getting-started inside the clone leaves: `study/`)
    is not in a reader's copy, so the examples that make it again do not fail."""
    repository = tmp_path / "clone"
    (repository / "docs").mkdir(parents=True)
    (repository / "docs" / "index.md").write_text("# x\n")
    (repository / "README.md").write_text("# x\n")
    subprocess.run(["git", "init", "-q", str(repository)], check=True)
    subprocess.run(["git", "-C", str(repository), "add", "."], check=True)
    (repository / "study").mkdir()
    (repository / "notes.txt").write_text("mine\n")
    assert tracked_entries(repository) == ["README.md", "docs"]
    names = tracked_entries(ROOT)
    assert {"README.md", "docs", "scenarios", "src", "mkdocs.yml", ".venv"} <= set(names)
    assert not {"out", "fmus", "site", ".git"} & set(names)


@pytest.fixture
def working_copy(tmp_path: Path) -> Path:
    """The repository's top folder as a reader's clone has it (`tracked_entries`): the scenarios
    and examples copied (examples write references), everything else linked; fmus/, out/ and
    reports/ start empty."""
    copy = tmp_path / "toggle-cosim"
    copy.mkdir()
    for name in tracked_entries(ROOT):
        entry = ROOT / name
        if name in ("scenarios", "examples"):
            shutil.copytree(entry, copy / name)
        elif name not in ("out", "fmus", "reports", "site", "build"):
            (copy / name).symlink_to(entry)
    return copy


def test_every_shell_example_runs_in_reading_order(working_copy: Path) -> None:
    env = {**os.environ, "PATH": f"{ROOT / '.venv' / 'bin'}{os.pathsep}{os.environ['PATH']}"}
    for path, line, text in SHELL_BLOCKS:
        script = "\n".join(
            row for row in text.splitlines() if not any(row.lstrip().startswith(skip) for skip in NOT_RUN)
        )
        process = subprocess.Popen(
            ["bash", "-e", "-o", "pipefail", "-c", script],
            cwd=working_copy,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            start_new_session=True,  # its own process group: whatever the block left running is ended below
        )
        try:
            output, _ = process.communicate(timeout=600)
        finally:
            try:
                os.killpg(process.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        assert process.returncode == 0, f"{path.relative_to(ROOT)}:{line}: exit {process.returncode}\n{output[-3000:]}"

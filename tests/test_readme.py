"""Every example in the README and the documentation works when a reader runs it.

The shell examples (```sh / ```bash blocks) and the Python examples (```python blocks) of
README.md and of the documentation pages, in the order a reader meets them (the README, then the
pages in the order of mkdocs.yml's nav), are run one block after the other in a working copy of
the repository's top folder with `.venv/bin` first on PATH: each shell block as one bash script,
the Python blocks of one page in one interpreter and one namespace (a page's later block uses
what its earlier blocks defined), so no example breaks the next. What they write stays under
`out/`, `fmus/` or a folder the reader names (`toggle-cosim init study`). Only `scripts/test`
is left out (it is the command that runs this test), and a block the page marks with
`<!-- docs-test: skip (why) -->` on the line before it (what needs a cluster or a server).
Examples that cannot run as written (a signature, an error message) are written as ```text;
their `toggle-cosim` lines are still parsed by the command itself. The documentation site
builds with `mkdocs build --strict`."""

from __future__ import annotations

import json
import os
import re
import select
import shlex
import shutil
import signal
import subprocess
import sys
from dataclasses import dataclass
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
    ".venv/bin/jupyter",  # nbconvert of the example notebooks (the notebook extra)
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


SKIP_MARK = re.compile(r"<!-- docs-test: skip \((.+)\) -->")


@dataclass(frozen=True)
class Block:
    """A fenced block of a page: where it starts, its language, its text, and why the reading-order
    test leaves it out (the page's `<!-- docs-test: skip (why) -->` on the line before; "" runs it)."""

    path: Path
    line: int
    language: str
    text: str
    skip: str = ""


def fenced_blocks(path: Path, languages: tuple[str, ...]) -> list[Block]:
    """Every fenced block of `path` in one of `languages`, in the page's order."""
    blocks: list[Block] = []
    inside, start, lines, language, skip, previous = False, 0, [], "", "", ""
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        if line.startswith("```"):
            if inside:
                blocks.append(Block(path, start, language, "\n".join(lines), skip))
                inside, previous = False, line  # a mark applies to the next block only
            elif line[3:].strip() in languages:
                mark = SKIP_MARK.fullmatch(previous.strip())
                inside, start, lines, language, skip = (
                    True,
                    number + 1,
                    [],
                    line[3:].strip(),
                    mark.group(1) if mark else "",
                )
            continue
        if inside:
            lines.append(line)
        elif line.strip():
            previous = line
    return blocks


def code_blocks(path: Path, languages: tuple[str, ...]) -> list[tuple[int, str]]:
    """(first line number, text) of each fenced block in one of `languages`."""
    return [(block.line, block.text) for block in fenced_blocks(path, languages)]


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
RUN_BLOCKS = [block for path in documents() for block in fenced_blocks(path, ("sh", "bash", "python"))]
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


def test_the_readme_counts_the_contracts_required_variables() -> None:
    """The README's count of the plant contract's required variables is the contract's."""
    from toggle_cosim.plant.contract import REQUIRED

    words = {"four": 4, "five": 5, "six": 6, "seven": 7, "eight": 8}
    text = " ".join(README.read_text(encoding="utf-8").split())
    (count,) = re.findall(r"\((\w+) required variables: ([^;]+);", text)
    assert words[count[0]] == len(REQUIRED) and count[1].split(", ") == list(REQUIRED)


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


@pytest.mark.slow
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


# the interpreter that runs a page's Python blocks: one namespace; a block's code arrives as one
# JSON line on stdin, its outcome leaves as one JSON line on the original stdout (what the block
# prints goes to stderr, into the log file)
PYTHON_SESSION = """
import json, os, sys, traceback
replies = os.fdopen(os.dup(1), "w")
os.dup2(2, 1)
sys.stdout = sys.stderr
namespace = {"__name__": "__main__"}
for line in sys.stdin:
    block = json.loads(line)
    try:
        exec(compile(block["code"], block["where"], "exec"), namespace)
        reply = {"ok": True}
    except BaseException:
        reply = {"ok": False, "error": traceback.format_exc()[-4000:]}
    replies.write(json.dumps(reply) + "\\n")
    replies.flush()
"""
BLOCK_TIMEOUT_S = 900.0  # a block that takes longer hangs: the test fails naming it


class PythonSession:
    """One interpreter for the Python blocks of one page (started in its own process group, ended
    with it)."""

    def __init__(self, cwd: Path, env: dict[str, str], log: Path) -> None:
        self.log = log.open("w")
        self.process = subprocess.Popen(
            [sys.executable, "-c", PYTHON_SESSION],
            cwd=cwd,
            env=env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self.log,
            text=True,
            start_new_session=True,
        )

    def run(self, where: str, code: str) -> str | None:
        """Run one block; None when it ran, else its traceback (or why it did not answer)."""
        assert self.process.stdin is not None and self.process.stdout is not None
        self.process.stdin.write(json.dumps({"where": where, "code": code}) + "\n")
        self.process.stdin.flush()
        ready, _, _ = select.select([self.process.stdout], [], [], BLOCK_TIMEOUT_S)
        line = self.process.stdout.readline() if ready else ""
        if not line:
            return f"no answer within {BLOCK_TIMEOUT_S:.0f} s, or the interpreter ended"
        reply = json.loads(line)
        return None if reply["ok"] else reply["error"]

    def close(self) -> None:
        try:
            os.killpg(self.process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.process.wait()
        self.log.close()


def run_shell_block(block: Block, cwd: Path, env: dict[str, str]) -> tuple[int, str]:
    script = "\n".join(
        row for row in block.text.splitlines() if not any(row.lstrip().startswith(skip) for skip in NOT_RUN)
    )
    process = subprocess.Popen(
        ["bash", "-e", "-o", "pipefail", "-c", script],
        cwd=cwd,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,  # its own process group: whatever the block left running is ended below
    )
    try:
        output, _ = process.communicate(timeout=BLOCK_TIMEOUT_S)
    finally:
        try:
            os.killpg(process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    return process.returncode, output


def run_in_reading_order(blocks: list[Block], cwd: Path) -> list[str]:
    """Run `blocks` in order in `cwd` (shell blocks by bash, each page's Python blocks in one
    session); the failures, each naming the page and line. Stops at the first failure, since
    later examples build on earlier ones."""
    env = {
        **os.environ,
        "PATH": f"{ROOT / '.venv' / 'bin'}{os.pathsep}{os.environ['PATH']}",
        "MPLBACKEND": "Agg",
    }
    sessions: dict[Path, PythonSession] = {}
    try:
        for block in blocks:
            if block.skip:
                continue
            where = f"{os.path.relpath(block.path, ROOT)}:{block.line}"
            if block.language == "python":
                if block.path not in sessions:
                    for session in sessions.values():  # one page at a time
                        session.close()
                    sessions = {block.path: PythonSession(cwd, env, cwd.parent / f"{block.path.stem}.python.log")}
                error = sessions[block.path].run(where, block.text)
                if error is not None:
                    log = (cwd.parent / f"{block.path.stem}.python.log").read_text(errors="replace")[-2000:]
                    return [f"{where}: {error}\n{log}"]
                continue
            code, output = run_shell_block(block, cwd, env)
            if code != 0:
                return [f"{where}: exit {code}\n{output[-3000:]}"]
    finally:
        for session in sessions.values():
            session.close()
    return []


def test_a_skip_mark_leaves_out_the_block_after_it_only(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text(
        "# x\n\n<!-- docs-test: skip (needs a Dask cluster) -->\n\n```sh\ndask scheduler\n```\n\n"
        "```python\nx = 1\n```\n\n```text\nnot run\n```\n"
    )
    blocks = fenced_blocks(page, ("sh", "bash", "python"))
    assert [(b.language, b.text, b.skip) for b in blocks] == [
        ("sh", "dask scheduler", "needs a Dask cluster"),
        ("python", "x = 1", ""),
    ]
    assert run_in_reading_order(blocks[:1], tmp_path) == []  # skipped: not run, so no failure


def test_the_skip_marks_are_few_and_say_why() -> None:
    """A skipped block is the exception: each mark gives its reason."""
    skipped = [block for block in RUN_BLOCKS if block.skip]
    assert len(skipped) <= 3, [(block.path.name, block.line) for block in skipped]
    assert all(len(block.skip) > 10 for block in skipped)
    assert sum(block.language == "python" for block in RUN_BLOCKS) >= 20


@pytest.mark.slow
def test_every_shell_and_python_example_runs_in_reading_order(working_copy: Path) -> None:
    before = set(os.listdir(working_copy))
    failures = run_in_reading_order(RUN_BLOCKS, working_copy)
    assert not failures, failures[0]
    left = sorted(set(os.listdir(working_copy)) - before - {"out", "fmus", "study"})
    assert not left, f"the examples wrote {left} in the top folder: write under out/ (or a folder the reader names)"

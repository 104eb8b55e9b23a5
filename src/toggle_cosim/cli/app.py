"""The command group and what every command shares: the exit-status policy (0 success, 1 a
run or comparison failed, 2 bad input in one line, 130 interrupted), the errors that carry it,
the project's default paths, and the check that a path lies inside the project."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from toggle_cosim import __version__, interrupts
from toggle_cosim.experiments.shipped import (  # noqa: F401 - the commands' defaults, imported from here
    DEFAULT_BUILDS,
    DEFAULT_FMU,
    DEFAULT_MODEL,
    DEFAULT_REFERENCES,
    DEFAULT_SOURCE,
    PAPER_SCENARIOS,
    SHIPPED_SCENARIOS,
)
from toggle_cosim.files.outputs import OutputError, check_destination

DEFAULT_OUT = Path("out")


class InputError(click.ClickException):
    """Bad input: one line on stderr, exit status 2."""

    exit_code = 2

    def show(self, file=None) -> None:  # noqa: ANN001 - click's signature
        click.echo(f"error: {self.message}", err=True)


class RunFailed(click.ClickException):
    exit_code = 1

    def show(self, file=None) -> None:  # noqa: ANN001
        click.echo(f"failed: {self.message}", err=True)


class _Commands(click.Group):
    """The command group, with one exit-status policy: 0 success, 1 a run or comparison failed,
    2 bad input (one line), 130 interrupted (SIGINT or SIGTERM, at any moment; no traceback)."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):  # noqa: ANN001, ANN201
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        old_handlers = interrupts.install()
        try:
            try:
                result = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
            except SystemExit:
                interrupts.ignore()  # done: a signal during the interpreter's teardown changes nothing
                raise
            interrupts.ignore()
        except (KeyboardInterrupt, click.exceptions.Abort):
            interrupts.ignore()
            click.echo("interrupted (exit 130): finished runs are kept; run the command again for the rest", err=True)
            interrupts.exit_interrupted()
        except click.UsageError as error:  # one line, like every other bad input
            interrupts.ignore()  # the work is over: from here the process only ends
            command = error.ctx.command_path if error.ctx is not None else "toggle-cosim"
            click.echo(f"error: {' '.join(error.format_message().split())} (see '{command} --help')", err=True)
            sys.exit(2)
        except click.ClickException as error:
            interrupts.ignore()  # the work is over: from here the process only ends
            error.show()
            sys.exit(error.exit_code)
        except click.exceptions.Exit as error:
            interrupts.ignore()  # the work is over: from here the process only ends
            sys.exit(error.exit_code)
        except SystemExit:
            raise
        except OutputError as error:  # an output path that must not be written: one line naming it
            interrupts.ignore()  # the work is over: from here the process only ends
            click.echo(f"error: {error}", err=True)
            sys.exit(2)
        except OSError as error:  # a file system problem found late (e.g. a disk that filled up): one line
            interrupts.ignore()  # the work is over: from here the process only ends
            if interrupts.is_interrupt(error):
                interrupts.exit_interrupted()
            where = f"{error.filename}: " if error.filename else ""
            click.echo(
                f"error: {where}{error.strerror or error} (check the path, its permissions and free space)", err=True
            )
            sys.exit(2)
        except BaseException as error:
            interrupts.ignore()
            if not interrupts.is_interrupt(error):  # e.g. a SystemError from a C call the signal landed in
                raise
            click.echo("interrupted (exit 130): finished runs are kept; run the command again for the rest", err=True)
            interrupts.exit_interrupted()
        finally:
            if not interrupts.running_as_program():
                interrupts.restore(old_handlers)  # in-process (tests): give the caller its handlers back
        sys.exit(result if isinstance(result, int) else 0)


@click.group(cls=_Commands, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="toggle-cosim")
def main() -> None:
    """Co-simulation of the PMLSM-driven toggle mechanism (Fung, Wu and Chen 2001)."""


def project_root() -> Path:
    """The project this command runs in: the nearest folder up from here with a pyproject.toml."""
    here = Path.cwd().resolve()
    for folder in (here, *here.parents):
        if (folder / "pyproject.toml").is_file():
            return folder
    return here


def project_of(source: Path) -> Path:
    """The project a Modelica source belongs to: the nearest folder up from it with a
    pyproject.toml (whatever the current folder is); a one-line refusal if there is none."""
    resolved = source.resolve()
    for folder in (resolved, *resolved.parents):
        if (folder / "pyproject.toml").is_file():
            return folder
    raise InputError(
        f"{source}: the Modelica source lies in no project (no pyproject.toml above it); "
        "the build only reads and writes inside a project"
    )


def inside_project(path: Path, what: str, option: str, root: Path | None = None) -> Path:
    """`path`, resolved, if it lies inside the project; else a one-line refusal."""
    root = root or project_root()
    resolved = path.resolve()
    if not resolved.is_relative_to(root):
        raise InputError(
            f"{path}: the {what} lies outside the project {root}; the build only reads and writes "
            f"inside it (give a path under it with {option})"
        )
    return resolved


def check_output(path: Path | None, what: str) -> None:
    """A one-line refusal (InputError) when something that is not a regular file lies at the
    output `path` (`files.outputs.check_destination`; `what` names it); nothing when `path` is None."""
    if path is not None:
        try:
            check_destination(path, what)
        except OutputError as error:
            raise InputError(str(error)) from error


def out_file_option(help_text: str):  # noqa: ANN201 - a click decorator
    """`--out/-o FILE` of the commands that write one file (build, plot), as the parameter `output`."""
    return click.option("--out", "-o", "output", type=click.Path(path_type=Path), default=None, help=help_text)

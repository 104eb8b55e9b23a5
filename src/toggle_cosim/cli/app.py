"""The command group and what every command shares: the exit-status policy (0 success, 1 a
run or comparison failed, 2 bad input in one line, 130 interrupted), the errors that carry it,
the default paths, and the one-line message for a command whose optional extra is not installed."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from toggle_cosim import __version__, interrupts
from toggle_cosim.experiments.shipped import (  # noqa: F401 - the commands' defaults, imported from here
    CONTROLLER_MODEL,
    DEFAULT_BUILDS,
    DEFAULT_CONTROLLER,
    DEFAULT_FMU,
    DEFAULT_MODEL,
    DEFAULT_REFERENCES,
    DEFAULT_SOURCE,
    PAPER_SCENARIOS,
    SHIPPED_SCENARIO_FOLDER,
    SHIPPED_SCENARIOS,
)
from toggle_cosim.files.outputs import OutputError, OutputKind, check_destination
from toggle_cosim.messages import bounded_text

DEFAULT_OUT = Path("out")
# an error line, file names and the fix included; a value in it is shorter (messages.value_text)
INPUT_ERROR_CHARS = 1000
# The optional extras (pyproject.toml) and the top-level modules that each brings.
EXTRAS = {
    "modelica": "build",
    "distributed": "sweep",
    "dask": "sweep",
    "pyarrow": "sweep",
    "tqdm": "sweep",
    "junitparser": "ci",
    "buildingspy": "ci",
    "matplotlib": "plot",
    "control": "design",
    "scipy": "design",
    "plotly": "report",
    "optuna": "tune",
    "cmaes": "tune",
}


class InputError(click.ClickException):
    """Bad input: one line on stderr (at most INPUT_ERROR_CHARS, whatever value it echoes), exit status 2."""

    exit_code = 2

    def show(self, file=None) -> None:  # noqa: ANN001 - click's signature
        click.echo(f"error: {bounded_text(self.message, INPUT_ERROR_CHARS)}", err=True)


class RunFailed(click.ClickException):
    exit_code = 1

    def show(self, file=None) -> None:  # noqa: ANN001
        click.echo(f"failed: {self.message}", err=True)


def missing_extra(error: ModuleNotFoundError, command: str) -> str | None:
    """The one-line message for a module of an optional extra that is not installed, or None
    when the missing module belongs to no extra (a broken installation: the traceback stays)."""
    top = (error.name or "").split(".")[0]
    extra = EXTRAS.get(top)
    if extra is None:
        return None
    return (
        f"{command} needs the Python package '{top}' of the extra [{extra}]: "
        f"pip install 'toggle-cosim[{extra}]' (or 'toggle-cosim[all]')"
    )


def require(*modules: str) -> None:
    """Check before any work that the optional modules a command will import are installed: a
    missing one raises the ModuleNotFoundError that the command group turns into its one line."""
    from importlib.util import find_spec

    for module in modules:
        try:
            found = sys.modules[module] is not None if module in sys.modules else find_spec(module) is not None
        except (ImportError, ValueError):  # a module blocked in sys.modules, or a broken one
            found = False
        if not found:
            raise ModuleNotFoundError(f"No module named {module!r}", name=module)


class _Commands(click.Group):
    """The command group, with one exit-status policy: 0 success, 1 a run or comparison failed,
    2 bad input (one line), 130 interrupted (SIGINT or SIGTERM, at any moment; no traceback)."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):  # noqa: ANN001, ANN201
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        old_handlers: dict[int, object] = {}
        try:
            old_handlers = interrupts.install()  # inside: an interrupt right after it is handled below
            try:
                result = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
                interrupts.raise_if_noted()  # an interrupt some C code dropped: the command still ends as interrupted
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
        except ModuleNotFoundError as error:  # an optional extra is not installed: say which, exit 2
            interrupts.ignore()  # the work is over: from here the process only ends
            words = [word for word in (sys.argv[1:] if args is None else args) if not word.startswith("-")]
            message = missing_extra(error, " ".join(["toggle-cosim", *words[:1]]))
            if message is None:
                raise
            click.echo(f"error: {message}", err=True)
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


def check_output(path: Path | None, what: str, kind: OutputKind) -> None:
    """A one-line refusal (InputError), before any work, when something that is not a regular
    file, or a file that is not of the output's `kind`, lies at the output `path`
    (`files.outputs.check_destination`, the one rule every writer applies again; `what` names
    the output); nothing when `path` is None."""
    if path is not None:
        try:
            check_destination(path, what, kind)
        except OutputError as error:
            raise InputError(str(error)) from error


def out_file_option(help_text: str):  # noqa: ANN201 - a click decorator
    """`--out/-o FILE` of the commands that write one file (build, plot), as the parameter `output`."""
    return click.option("--out", "-o", "output", type=click.Path(path_type=Path), default=None, help=help_text)

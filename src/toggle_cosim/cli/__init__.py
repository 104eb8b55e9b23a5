"""Command line: `toggle-cosim build | init | run | repeat | plot | paper | compare | references | pack | verify |
sweep | tune | ssp | report`.

The only package that knows about files, exit codes and progress display. Exit status:
0 success, 1 a run or comparison failed, 2 bad input (nothing is written then), 130 interrupted.

    app.py             the command group, its exit-status policy, the shared errors and paths
    build_command.py   build
    init_command.py    init: the shipped scenarios copied into a working folder
    execution.py       what the run commands share: checks, supervised runs, files, options
    run_commands.py    run, plot, paper
    repeat_command.py  repeat: a run again from its provenance record, its trace compared
    check_commands.py  compare, references
    lsref_commands.py  pack, verify: files an FMU carries (FMI-LS-REF), the FMU checked against them
    sweep_command.py   sweep
    tune_command.py    tune
    ssp_command.py     ssp, and the SSPs that run reads
    report_command.py  report (the HTML page), and plot --vars/--reference

Each command imports what it needs when it runs: `toggle-cosim --help` imports click only.
"""

from __future__ import annotations

import sys
from pathlib import Path

from toggle_cosim import interrupts

# As a program (the `toggle-cosim` script; `python -m toggle_cosim.cli`, while Python still
# locates the module and argv[0] is "-m"; `python -m toggle_cosim`, whose __main__.py imports
# this): an interrupt at start-up exits 130 too.
_program = Path(sys.argv[0])
if _program.name == "toggle-cosim" or sys.argv[0] == "-m" or _program.parts[-2:] == ("toggle_cosim", "__main__.py"):
    interrupts.install_for_start_up()  # before the heavy imports

from toggle_cosim.cli import (  # noqa: E402, F401 - they add the commands
    build_command,
    check_commands,
    init_command,
    linearize_command,
    lsref_commands,
    repeat_command,
    report_command,
    run_commands,
    ssp_command,
    sweep_command,
    tune_command,
)
from toggle_cosim.cli.app import main  # noqa: E402

__all__ = ["main"]

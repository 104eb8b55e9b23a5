"""`toggle-cosim repeat RUN_FOLDER`: a run repeated from its provenance record.

The record (`RUN_FOLDER/provenance.srmd`, `cosim.run_provenance`) is read and every file it names
is checked against its SHA3-256 before anything runs: a missing or changed file is named in one
line (exit 2, nothing written). The run is then built again from the recorded scenario (or SSP)
with the recorded plant, variant and coupling; the files it uses must be exactly the files the
record names. It runs into OUT/<scenario>/<variant>/ as `run` writes it, and its new trace.csv is
compared byte for byte (by SHA3-256) with the recorded one: equal, or exit 1.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

import click

from toggle_cosim.cli.app import InputError, RunFailed, main
from toggle_cosim.cli.execution import TIME_LIMIT_OPTION, execute_runs, load_runs, raise_if_failed

DEFAULT_REPEAT_OUT = Path("repeated")


def _real(path: Path) -> str:
    return os.path.realpath(path)


def _rebuilt(record_path: Path, record, stack: contextlib.ExitStack) -> tuple:  # noqa: ANN001
    """The (run, plant, checked) triple the record describes, built again from its recorded files
    with its recorded coupling (`checked`: its check before the run); InputError if the record's
    settings or files do not make one."""
    from toggle_cosim.cli.ssp_command import ssp_runs
    from toggle_cosim.cosim import run_provenance as rp
    from toggle_cosim.provenance.srmd import located

    by_role = {item.role: located(record_path, item.uri) for item in record.resources}
    source, variant = record.setting(rp.SOURCE), record.setting(rp.VARIANT) or None
    wanted = "ssp" if source == "ssp" else "scenario"
    if source not in ("ssp", "scenario") or wanted not in by_role or (wanted == "scenario" and "plant" not in by_role):
        raise InputError(
            f"{record_path}: the record names no {wanted} file and plant to repeat the run from; "
            "give the folder of a run that toggle-cosim run wrote"
        )
    coupling = record.setting(rp.COUPLING) or None
    if wanted == "ssp":
        pairs = load_runs([], None, ssp_runs([by_role["ssp"]], [variant], stack), coupling=coupling)
    else:
        pairs = load_runs([by_role["scenario"]], by_role["plant"], coupling=coupling)
    chosen = [
        (run, plant, checked)
        for run, plant, checked in pairs
        if run.variant == variant and run.scenario == record.setting(rp.SCENARIO)
    ]
    if len(chosen) != 1:
        raise InputError(
            f"{record_path}: the recorded {wanted} has no run {record.name!r} (scenario and variant) to repeat"
        )
    run, plant, checked = chosen[0]
    _check_same_files(record_path, record, run, plant.path)
    return run, plant, checked


def _check_same_files(record_path: Path, record, run, plant: Path) -> None:  # noqa: ANN001
    """InputError unless the run built again uses exactly the files the record names (a record
    naming other files, e.g. edited to point elsewhere, is refused)."""
    from toggle_cosim.cosim.run_provenance import files_used
    from toggle_cosim.provenance.srmd import located

    named = {_real(located(record_path, item.uri)): item.role for item in record.resources}
    used = {_real(item.path): item.role for item in files_used(run, plant)}
    for path, role in named.items():
        if path not in used:
            raise InputError(
                f"{record_path}: names {path} (as the {role}), which the recorded run does not use; "
                "the record was not written by this run (refused)"
            )
    for path, role in used.items():
        if path not in named:
            raise InputError(
                f"{record_path}: the recorded run uses {path} (the {role}), which the record does not name; "
                "it cannot be repeated as recorded"
            )


@main.command()
@click.argument("run_folder", type=click.Path(path_type=Path))
@click.option(
    "--out",
    type=click.Path(path_type=Path),
    default=DEFAULT_REPEAT_OUT,
    show_default=True,
    help="Output folder: the repeated run's files go to OUT/<scenario>/<variant>/ (never the recorded run's folder).",
)
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
@TIME_LIMIT_OPTION
def repeat(run_folder: Path, out: Path, quiet: bool, time_limit: float | None) -> None:
    """Repeat the run in RUN_FOLDER from its provenance record (provenance.srmd): every file it
    names is checked first (a missing or changed one: exit 2, nothing run), the run is built
    again from them, and its new trace.csv must be bit-identical to the recorded one (else exit 1)."""
    from toggle_cosim.cosim.run_provenance import RECORD_NAME
    from toggle_cosim.files.checksums import file_sha3_256
    from toggle_cosim.provenance.srmd import RecordError, changed_files, read_record

    record_path = run_folder / RECORD_NAME
    try:
        record = read_record(record_path)
    except RecordError as error:
        raise InputError(f"{error} (RUN_FOLDER is a run's folder with its {RECORD_NAME})") from error
    changed = changed_files(record_path, record)
    if changed:
        more = f" (and {len(changed) - 1} more)" if len(changed) > 1 else ""
        raise InputError(f"{changed[0]}{more}; the run cannot be repeated as recorded")
    if record.data is None:
        raise InputError(f"{record_path}: the record names no trace to compare with; write the record again")
    with contextlib.ExitStack() as stack:  # an SSP's FMUs live in a folder removed after the run
        run, plant, checked = _rebuilt(record_path, record, stack)
        target = out / run.folder
        if _real(target) == _real(run_folder):
            raise InputError(
                f"--out {out}: the repeated run would write {target}, the recorded run's folder; give another --out"
            )
        outcomes = execute_runs([(run, plant, checked)], out, quiet, time_limit, jobs=1)
    trace = target / "trace.csv"
    raise_if_failed(outcomes)
    digest = file_sha3_256(trace)
    if digest != record.data.checksum:
        raise RunFailed(
            f"{trace}: differs from the recorded trace {run_folder / 'trace.csv'} (SHA3-256 {digest} "
            f"against the record's {record.data.checksum})"
        )
    click.echo(f"{trace}: bit-identical to the recorded trace (SHA3-256 {record.data.checksum})")

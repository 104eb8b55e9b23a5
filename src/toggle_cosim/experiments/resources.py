"""Resources checked before any work: the size of what a run will record, and the output folder.

A run records (steps + 1) samples x columns. While it runs, the samples sit in a disk-backed
buffer of 8 bytes each (`supervision`); trace.csv then holds every `record_every`-th sample at
about CSV_BYTES_PER_VALUE bytes per value. A run whose buffer or CSV would pass the output limit
(default 2 GB, `TOGGLE_COSIM_MAX_OUTPUT` in bytes overrides it) is refused in one line naming the
estimate and the fix, as is an output folder that is a file, a symbolic link that leads nowhere
(dangling, or in a loop; also any folder on its path), cannot be created or written, has a
name longer than the file system allows, or lacks free space for the estimate.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import click

from toggle_cosim import limits
from toggle_cosim.files.bounded import link_problem

CSV_BYTES_PER_VALUE = 24  # "%.17g" and a comma: 20 to 25 characters


class ResourceError(click.ClickException):
    """Bad input found before any work: one line on stderr, exit status 2."""

    exit_code = 2

    def show(self, file=None) -> None:  # noqa: ANN001
        click.echo(f"error: {self.message}", err=True)


def max_output() -> int:
    """TOGGLE_COSIM_MAX_OUTPUT (`limits`), or a ResourceError (one line, exit 2)."""
    try:
        return limits.max_output()
    except limits.LimitError as error:
        raise ResourceError(str(error)) from None


@dataclass(frozen=True)
class TraceEstimate:
    samples: int
    columns: int
    every: int

    @property
    def buffer_bytes(self) -> int:
        return self.samples * self.columns * 8

    @property
    def csv_bytes(self) -> int:
        kept = (self.samples + self.every - 1) // self.every + 1
        return kept * self.columns * CSV_BYTES_PER_VALUE


def estimate(run, plant) -> TraceEstimate:  # noqa: ANN001
    from toggle_cosim.cosim.master import other_inputs, trace_names

    columns = len(trace_names(plant, inputs=other_inputs(run)))
    return TraceEstimate(run.steps + 1, columns, int(run.resolved.get("record_every", 1)))


def _gb(value: int) -> str:
    return f"{value / 1e9:.2f} GB" if value >= 1e7 else f"{value / 1e6:.2f} MB"


def check_size(run, plant, limit: int | None = None) -> TraceEstimate:  # noqa: ANN001
    """Refuse a run whose trace buffer or CSV would pass the output limit."""
    limit = max_output() if limit is None else limit
    found = estimate(run, plant)
    biggest = max(found.buffer_bytes, found.csv_bytes)
    if biggest > limit:
        where = f"{run.source}: " if run.source else ""
        raise ResourceError(
            f"{where}{run.label}: t_end / T_s = {found.samples - 1} steps x {found.columns} columns would record about "
            f"{_gb(found.csv_bytes)} of CSV ({_gb(found.buffer_bytes)} while running), over the {_gb(limit)} output limit; "
            f"raise T_s or shorten t_end (record_every thins only the CSV), or raise TOGGLE_COSIM_MAX_OUTPUT"
        )
    return found


def _name_max(folder: Path) -> int:
    try:
        return os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError):
        return 255


def check_output_folder(out: Path, needed: int = 0) -> None:
    """`out` is a folder, or can be made one; it is writable and has `needed` bytes free. Nothing
    is created (a probe file in the nearest existing folder is removed at once)."""
    out = Path(out)
    for part in out.parts:
        if len(os.fsencode(part)) > _name_max(Path(".")):
            raise ResourceError(
                f"{out}: the name {part[:20]}... is longer than the file system allows "
                f"({_name_max(Path('.'))} bytes); use a shorter --out"
            )
    existing = out
    try:
        while not existing.exists() and existing != existing.parent:
            broken = link_problem(existing)
            if broken:
                where = "the output folder" if existing == out else f"{existing}, a part of the output folder's path,"
                raise ResourceError(f"{out}: {where} is {broken} (remove it or choose another --out)")
            existing = existing.parent
    except OSError as error:
        raise ResourceError(
            f"{out}: unusable output folder ({error.strerror or error}); choose another --out"
        ) from None
    if existing.exists() and not existing.is_dir():
        what = "the output folder" if existing == out else f"{existing}, a part of the output folder's path,"
        raise ResourceError(f"{out}: {what} is an existing file, not a folder (choose another --out)")
    try:
        handle, probe = tempfile.mkstemp(prefix=".toggle-cosim-probe-", dir=existing)
        os.close(handle)
        os.unlink(probe)
    except OSError as error:
        raise ResourceError(
            f"{out}: cannot write in {existing} ({error.strerror or error}); choose another --out"
        ) from None
    free = shutil.disk_usage(existing).free
    if needed > free:
        raise ResourceError(
            f"{out}: the runs need about {_gb(needed)} but {existing} has {_gb(free)} free (free space or choose another --out)"
        )


def check_runs(pairs: Sequence[tuple], out: Path | None, jobs: int = 1) -> None:
    """Before the first run: each run's size, then the output folder and the scratch space for
    the `jobs` biggest trace buffers (that many runs may be under way at once). The environment's
    numbers come first (`limits.check_environment`): a bad one must not surface in a run's child."""
    try:
        limits.check_environment()
    except limits.LimitError as error:
        raise ResourceError(str(error)) from None
    sizes = [check_size(run, plant) for run, plant, *_ in pairs]
    if out is not None:
        check_output_folder(out, sum(s.csv_bytes for s in sizes))
    at_once = sorted((s.buffer_bytes for s in sizes), reverse=True)[: max(1, jobs)]
    needed = sum(at_once)
    scratch = Path(tempfile.gettempdir())
    if needed > shutil.disk_usage(scratch).free:
        what = "a run needs" if len(at_once) == 1 else f"{len(at_once)} runs at once need"
        raise ResourceError(
            f"{scratch}: {what} about {_gb(needed)} of scratch space there (free space, set TMPDIR or lower --jobs)"
        )


__all__ = ["ResourceError", "check_runs", "check_size", "check_output_folder", "estimate"]

"""`verify_fmu`: run the experiments an FMU carries (FMI-LS-REF) and compare each with the
reference it carries, as `toggle-cosim verify` does.

    check = tc.verify_fmu("fmus/ToggleLSM.fmu")
    assert check.passed, check.failures     # every carried experiment inside its funnel
    for experiment in check.checks:         # per experiment: label, trace, reference, comparison
        print(experiment.label, experiment.comparison.passed)

An FMU whose manifest names a file it lacks, or whose file does not match its SHA3-256
checksum, raises `LsRefError` with one line naming the file.
"""

from __future__ import annotations

from pathlib import Path

from toggle_cosim.fmi_ls_ref.manifest import LsRefError
from toggle_cosim.fmi_ls_ref.verify import ExperimentCheck, Verification
from toggle_cosim.fmi_ls_ref.verify import verify_fmu as _verify

__all__ = ["ExperimentCheck", "LsRefError", "Verification", "verify_fmu"]


def verify_fmu(fmu: str | Path) -> Verification:
    """Run the experiments an FMU carries (FMI-LS-REF) and compare each with its carried reference.

    Args:
        fmu: the FMU file: a plant of ours (its carried scenarios run through the master) or any
            FMU (its carried experiments, or its default experiment for a carried result, run
            with FMPy).

    Returns:
        The `Verification`: `passed`, `failures` (one line per variable outside its funnel) and
        `checks` (per experiment: label, trace, reference, comparison, runner).

    Raises:
        LsRefError: the FMU carries no manifest, or its manifest names a file the FMU lacks, or
            a file does not match its SHA3-256 checksum (one line naming the file).

    Example:
        >>> check = tc.verify_fmu("fmus/ToggleLSM.fmu")  # doctest: +SKIP
        >>> check.passed, check.failures  # doctest: +SKIP
        (True, [])
    """
    return _verify(Path(fmu))

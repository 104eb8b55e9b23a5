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
    """The FMU `fmu`'s carried experiments, run and compared with their carried references."""
    return _verify(Path(fmu))

"""The FMU carries what it takes to rebuild its binary (issue 12, "one source for metadata"):
FMI 2.0 lists its C files in <SourceFiles>, so FMPy's build_platform_binary (CMake) compiles
them from the FMU's sources/ alone, and the rebuilt binary gives the same trace."""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu

pytestmark = pytest.mark.slow  # rebuilds the FMU binaries from their sources

RUN = dict(stop_time=0.3, output=["x_B", "v_B"], start_values={"iq_ref": 1.0, "mu": 0.2})


@pytest.mark.skipif(shutil.which("cmake") is None, reason="FMPy's build_platform_binary needs CMake")
def test_fmi2_source_files_rebuild_to_the_same_trace(plant_fmu: Path) -> None:
    from fmpy.build import build_platform_binary

    md = read_model_description(str(plant_fmu))
    assert md.buildConfigurations[0].sourceFileSets[0].sourceFiles == ["solver.c", "instance.c", "fmi2.c", "model.c"]
    with zipfile.ZipFile(plant_fmu) as archive:  # both interface elements list them
        assert archive.read("modelDescription.xml").decode().count("<SourceFiles>") == 2
    unzipped = Path(extract(str(plant_fmu)))
    try:
        shipped = {
            kind: simulate_fmu(str(unzipped), fmi_type=kind, **RUN) for kind in ("CoSimulation", "ModelExchange")
        }
        shutil.rmtree(unzipped / "binaries")
        build_platform_binary(str(unzipped))
        assert (
            any((unzipped / "binaries").rglob("*.so"))
            or any((unzipped / "binaries").rglob("*.dll"))
            or any((unzipped / "binaries").rglob("*.dylib"))
        )
        for kind, before in shipped.items():
            after = simulate_fmu(str(unzipped), fmi_type=kind, **RUN)
            np.testing.assert_array_equal(after["x_B"], before["x_B"])  # bit for bit
            np.testing.assert_array_equal(after["v_B"], before["v_B"])
        assert abs(shipped["CoSimulation"]["x_B"][-1] - 0.2329) > 0.02  # the stroke happened
    finally:
        shutil.rmtree(unzipped, ignore_errors=True)

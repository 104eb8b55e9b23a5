"""FMUs written in Python for the tests, built with PythonFMU's command line."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path


def build_python_fmu(source: str, folder: Path, model: str) -> Path:
    """`source` (a PythonFMU slave class `model`) built into folder/<model>.fmu."""
    script = folder / f"{model.lower()}.py"
    script.write_text(source, encoding="utf-8")
    command = [str(Path(sys.executable).parent / "pythonfmu"), "build", "-f", str(script), "-d", str(folder)]
    built = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert built.returncode == 0, built.stderr
    return folder / f"{model}.fmu"

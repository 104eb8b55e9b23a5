"""The start-up parts the README's "Start-up and the paper suite" quotes, each against what it
replaced, measured in fresh interpreters (imports) or as the best of repetitions (work):

    .venv/bin/python benchmarks/startup_parts.py [--fmu fmus/ToggleLSM.fmu]

* importing jsonschema, against checking a paper scenario with files/schema_check;
* run.json's package versions and platform (cosim.outcome.installed_versions), against
  importlib.metadata and platform.platform();
* the plant's modelDescription from plant/description_cache, against fmpy's parse (lxml's
  import included, in a fresh interpreter);
* formatting a paper trace's values (csv_rows.c), against the Python route's '%.17g' (the one
  used without a C compiler) and np.savetxt (what wrote the traces before).
"""

from __future__ import annotations

import argparse
import io
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def fresh(setup: str, work: str, repeat: int = 7) -> float:
    """Best time of `work` in a fresh interpreter after `setup` (timed inside that process, so
    the interpreter's start and the setup's imports do not count)."""
    code = f"import time\n{setup}\nstarted = time.perf_counter()\n{work}\nprint(time.perf_counter() - started)"
    times = []
    for _ in range(repeat):
        done = subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT, capture_output=True, text=True)
        times.append(float(done.stdout.strip().splitlines()[-1]))
    return min(times)


def best(work, repeat: int = 7) -> float:  # noqa: ANN001
    times = []
    for _ in range(repeat):
        started = time.perf_counter()
        work()
        times.append(time.perf_counter() - started)
    return min(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fmu", type=Path, default=ROOT / "fmus" / "ToggleLSM.fmu")
    args = parser.parse_args()
    if not args.fmu.is_file():
        raise SystemExit(f"error: {args.fmu}: no such FMU; build it first with 'toggle-cosim build'")
    fmu = args.fmu.resolve()
    rows = []

    scenario = "from pathlib import Path; from toggle_cosim.experiments.scenario import load_scenario"
    check = "load_scenario(Path('scenarios/fig4_nominal.yaml'))"
    rows.append(("check a paper scenario, schema_check (first call in a process)", fresh(scenario, check)))
    rows.append(("  the same with jsonschema: its import", fresh(scenario, "import jsonschema")))

    base = "from toggle_cosim.cosim import outcome"
    versions = "outcome.installed_versions()"
    old_versions = (
        "import platform; from importlib import metadata; platform.platform(); "
        "[metadata.version(n) for n in ('toggle-cosim', 'fmpy', 'numpy', 'scipy', 'pandas', 'modelica')]"
    )
    rows.append(("run.json's versions and platform, installed_versions", fresh(base, versions)))
    rows.append(("  importlib.metadata and platform.platform()", fresh(base, old_versions)))

    from toggle_cosim.plant.description_cache import read_description

    read_description(fmu)  # the entry is there
    imported = "import fmpy; from toggle_cosim.plant.description_cache import read_description"
    rows.append(
        ("modelDescription from the cache (first in a process)", fresh(imported, f"read_description({str(fmu)!r})"))
    )
    parsed = f"fmpy.read_model_description({str(fmu)!r}, validate=False)"
    rows.append(("  fmpy's parse, lxml's import included", fresh(imported, parsed)))

    import numpy as np

    from toggle_cosim.cosim.master import simulate
    from toggle_cosim.experiments.scenario import load_scenario
    from toggle_cosim.files import csv_rows
    from toggle_cosim.plant.contract import check_plant

    run = load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0]
    data = simulate(run, check_plant(fmu)).trace.data  # a paper trace: 3001 samples x 35 columns
    values = data.size
    rows.append(
        (f"format {values} trace values, csv_rows.c (per value)", best(lambda: csv_rows.format_rows(data)) / values)
    )
    rows.append(
        (
            "  Python's '%.17g' (the fallback route; per value)",
            best(lambda: csv_rows.format_rows_python(data), 3) / values,
        )
    )

    def savetxt() -> None:
        np.savetxt(io.StringIO(), data, fmt="%.17g", delimiter=",")

    rows.append(("  np.savetxt (per value)", best(savetxt, 3) / values))
    for label, seconds in rows:
        shown = f"{seconds * 1e9:8.0f} ns" if seconds < 1e-4 else f"{seconds * 1e3:8.1f} ms"
        print(f"{label:<62} {shown}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

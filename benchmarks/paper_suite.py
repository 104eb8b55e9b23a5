"""The paper suite end to end: `toggle-cosim paper --skip-build` in a fresh process, from process
start to the last file written, against the sum of its runs' simulate() calls.

    .venv/bin/python benchmarks/paper_suite.py [--repeat 3] [--fmu fmus/ToggleLSM.fmu]

Each repetition runs the suite twice, interleaved: supervised (every run in a forked child, the
default) and with TOGGLE_COSIM_SUPERVISE=0 (in-process simulate()). The runs' own wall times come
from their run.json (`wall_time_s`: the supervised call, fork included; or simulate() itself).
Printed: per repetition the time to the last file, the sums of the runs' wall times, and the
ratios. This is the whole main job, three nine-panel figures included (matplotlib's import and
about a second of drawing each: most of the time); issue 12's target, "process start to last
file <= 4 x the simulate() calls", is for the six paper runs and is checked by bench.py.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import sys
import tempfile
from pathlib import Path

from timing import run_to_last_file  # benchmarks/timing.py, beside this script

ROOT = Path(__file__).resolve().parents[1]


def suite(fmu: Path, out: Path, supervised: bool) -> dict[str, float]:
    shutil.rmtree(out, ignore_errors=True)
    env = {**os.environ, "TOGGLE_COSIM_SUPERVISE": "1" if supervised else "0"}
    timed = run_to_last_file(["paper", "--skip-build", "--fmu", str(fmu), "--out", str(out)], out, env, cwd=ROOT)
    records = [json.loads(p.read_text()) for p in out.rglob("run.json")]
    return {
        "to_last_file": timed["to_last_file"],
        "process": timed["process"],
        "runs": len(records),
        "runs_wall": sum(r["wall_time_s"] for r in records),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--fmu", type=Path, default=ROOT / "fmus" / "ToggleLSM.fmu")
    args = parser.parse_args()
    if not args.fmu.is_file():
        raise SystemExit(f"error: {args.fmu}: no such FMU; build it first with 'toggle-cosim build'")
    ratios, supervision = [], []
    with tempfile.TemporaryDirectory() as folder:
        for number in range(1, args.repeat + 1):
            on = suite(args.fmu.resolve(), Path(folder) / "on", True)
            off = suite(args.fmu.resolve(), Path(folder) / "off", False)
            ratio = on["to_last_file"] / off["runs_wall"]
            ratios.append(ratio)
            supervision.append(on["runs_wall"] - off["runs_wall"])
            print(
                f"[{number}] {on['runs']} runs: start -> last file {on['to_last_file']:.2f} s (exit {on['process']:.2f} s); "
                f"simulate() in-process {off['runs_wall']:.2f} s, supervised calls {on['runs_wall']:.2f} s; "
                f"ratio {ratio:.1f} x simulate() ({on['to_last_file'] / on['runs_wall']:.1f} x the supervised calls); "
                f"unsupervised suite: start -> last file {off['to_last_file']:.2f} s"
            )
    print(
        f"median ratio {statistics.median(ratios):.1f} x (figures included; the six runs' target is bench.py's); "
        f"supervision adds "
        f"{statistics.median(supervision):.2f} s over the runs (median)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

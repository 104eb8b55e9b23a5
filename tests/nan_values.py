"""Runs whose recorded values turn NaN part-way, for the tests that every sample is written
whatever its values (issue 37, item 1): a Python controller whose diagnostic turns NaN, and a
system part whose output does, each from t = 0.01 s of a 0.05 s run at T_s = 0.5 ms (101
samples, the first 20 finite)."""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from toggle_cosim.files.traces import Trace

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = 101  # t_end 0.05 s at T_s 0.5 ms: samples 0 .. 100
FINITE = 20  # samples before t = 0.01 s

CONTROLLER = '''
import math
import os
from toggle_cosim.control.protocol import ControlStep


class NanDiagnostic:
    """A PD law whose diagnostic number `which` (of `names`: e, then flags of 1.0) is NaN from
    t = 0.01 s on; the command stays finite. With `exit_at`, it ends its process there."""

    def __init__(self, which, names, exit_at):
        self.which, self.diagnostics, self.exit_at = which, tuple(names), exit_at

    def start(self, t0, measurement):
        return None

    def step(self, state, t, measurement):
        if self.exit_at is not None and t >= self.exit_at - 1e-12:
            os._exit(3)
        e = 0.3199 - measurement["x_B"]
        values = [e] + [1.0] * (len(self.diagnostics) - 1)
        if t >= 0.01 - 1e-12:
            values[self.which] = math.nan
        return ControlStep(12.0 * e - 2.5 * measurement["v_B"], tuple(values), state)


def make(context, which, names=("e", "flag"), exit_at=None):
    return NanDiagnostic(which, names, exit_at)
'''

PART = '''
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class NanAfter(Fmi2Slave):
    """y = x until t = 0.01 s, then NaN: a part whose output turns NaN (our own FMU build
    refuses a non-finite value, so this part is a Python FMU)."""

    author = "toggle-cosim tests"
    description = "an output that turns NaN at t = 0.01 s"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.x, self.time = 0.0, 0.0
        self.register_variable(Real("x", causality=Fmi2Causality.input))
        self.register_variable(Real("y", causality=Fmi2Causality.output, getter=self.output))

    def output(self) -> float:
        return self.x if self.time < 0.01 - 1e-9 else float("nan")

    def do_step(self, current_time: float, step_size: float) -> bool:
        self.time = current_time + step_size
        return True
'''


def base_document() -> dict:
    """The Fig. 4 stroke of examples/controllers/user_controllers.yaml, 0.05 s long, no fmu key."""
    document = yaml.safe_load((ROOT / "examples" / "controllers" / "user_controllers.yaml").read_text("utf-8"))
    for key in ("variants", "fmu"):
        document.pop(key)
    document["t_end"] = 0.05
    return document


def nan_controller_scenario(
    folder: Path, which: int, names: tuple[str, ...] = ("e", "flag"), exit_at: float | None = None
) -> Path:
    """A scenario whose Python controller records the diagnostics `names` (e, then flags), of
    which number `which` (1 of e, flag: the trace's last column) turns NaN at t = 0.01 s; with
    `exit_at`, the controller ends the run's process at that sample (os._exit)."""
    (folder / "nan_laws.py").write_text(CONTROLLER, encoding="utf-8")
    document = base_document()
    parameters = {"which": which, "names": list(names), "exit_at": exit_at}
    document["controller"] = {**document["controller"], "python": "nan_laws:make", "parameters": parameters}
    path = folder / "nan_diagnostic.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    return path


def nan_part_scenario(folder: Path, part: Path, record: list[str]) -> Path:
    """A system: the plant and its built-in law, and the part NanAfter fed by plant.x_B;
    `record` the trace's ports."""
    document = base_document()
    document["controller"] = {key: value for key, value in document["controller"].items() if key != "python"}
    document["components"] = {"probe": {"fmu": str(part)}}
    document["connections"] = [
        "plant.x_B -> controller.x_B",
        "plant.v_B -> controller.v_B",
        "controller.iq_ref -> plant.iq_ref",
        "plant.x_B -> probe.x",
    ]
    document["record"] = record
    path = folder / "nan_part.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    return path


def run_scenario(scenario: Path, plant_fmu: Path, out: Path) -> tuple[dict, Trace]:
    """`toggle-cosim run SCENARIO --fmu PLANT --out OUT -q`, which must exit 0: the one run's
    run.json and trace.csv, read back."""
    from click.testing import CliRunner

    from toggle_cosim.cli import main
    from toggle_cosim.files.traces import read_csv

    result = CliRunner().invoke(main, ["run", str(scenario), "--fmu", str(plant_fmu), "--out", str(out), "-q"])
    assert result.exit_code == 0, result.output
    folder = out / "user_controllers" / "run"
    return json.loads((folder / "run.json").read_text(encoding="utf-8")), read_csv(folder / "trace.csv")

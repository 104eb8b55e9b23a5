"""Systems in the compiled system loop (`cosim.execution.system_loop`) against a plain C master.

    .venv/bin/python benchmarks/system_bench.py [--quick] [--fmu PLANT.fmu]   # this section alone

bench.py prints the same rows in its table (`section`); both take the table, the paper runs and
the built-in pair's loop cost from bench_parts.py. Two systems, each assembled and
initialised by the master (`cosim.systems.assemble`, `cosim.execution.algorithm.Execution.initialize`: the
FMUs loaded, their values set, one initialisation pass) and stepped over fig4_nominal/friction
(3000 samples of 0.5 ms):

* the pair: the plant FMU and the controller FMU ToggleVSC (FMI 2.0);
* three FMUs: the pair and a second ToggleVSC instance ("monitor") reading the plant's outputs
  (its outputs recorded, not connected);
* the press: examples/press_system/press.yaml's four FMUs (the plant, its sensor and die-load
  models built here, the controller as ToggleVSC), 5000 samples.

Each is timed per sample in the compiled system loop (`SystemLoop.run`, the trace recorded; each
FMU logging only its non-OK statuses, as the master sets it) and in the master's Python execution of
the same plan (`Execution.advance`; its trace must equal the loop's bit for bit). Against what the
FMUs cost from C: for the first two `system_master.c`, a plain C master of the same FMUs compiled
here (dlopen, instantiate, initialise, per sample get/set/doStep, a row recorded; no Python, no
tables; its last x_B, last command and sum of x_B compared with the loop's trace); for the press
`system_replay.c`, each FMU alone on a fresh instance making the loop's calls with the inputs
the run recorded, summed over the FMUs (its outputs compared with the recorded ones).

A user's Python controller (examples/controllers/my_controllers.py's PD law) in the pair (on
the press example's plant and stroke) and in the four-part press system (`python_controller`),
each by `master.check_and_simulate`, interleaved: the compiled loop calls the controller back into Python
at its turns (`cosim.execution.system_python`), beside the master's Python execution of the press system
(TOGGLE_COSIM_KERNEL=0); the system's trace must have the Python execution's bits, and both stay
within 1.2 x the 5.7 us per sample the same controller cost in the pair's own loop before the
pair ran in the execution (`PAIR_PYTHON_SAMPLE_S`).

And the built-in law through the execution (bench.py's `full_loop`, fig4_nominal/friction)
against the plain C master of the plant and the controller FMU of that law (ToggleVSC).
"""

from __future__ import annotations

import argparse
import ctypes
import dataclasses
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np
from bench_parts import ROOT, Table, full_loop, paper_runs, us  # benchmarks/bench_parts.py, beside this script

from toggle_cosim.cosim.controllers import controller_for
from toggle_cosim.cosim.execution.algorithm import Execution, TraceObserver
from toggle_cosim.cosim.execution.system_loop import (
    DONE,
    SystemLoop,
    compiled_system,
    system_library,
    system_library_reason,
)
from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.cosim.systems import assemble, pair_connections
from toggle_cosim.experiments.scenario import load_scenario, runs_from_document
from toggle_cosim.system.model import Connection, Part, Port, Wiring

SOURCE = Path(__file__).resolve().parent / "system_master.c"


def fig4_with(controller: Path, plant, monitor: bool):  # noqa: ANN001, ANN201 - a Run
    """fig4_nominal/friction with the controller FMU, wired as the pair (each controller input
    that is a plant output from it, the command to the plant); with `monitor`, a second instance
    of the controller FMU reading the same plant outputs."""
    run = next(r for r in load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml") if r.label.endswith("/friction"))
    run = dataclasses.replace(run, controller=dataclasses.replace(run.controller, fmu=controller, python=None))
    chosen = controller_for(run, plant.recorded_outputs)  # a ControllerFmuPart: nothing loaded
    inputs = [v for v in chosen.fmu.inputs if v in plant.recorded_outputs]
    values = tuple(chosen.settings)  # the controller's values, for the monitor too
    wiring = Wiring(parts=(Part("monitor", controller, values),) if monitor else ())
    connections = pair_connections(wiring, inputs)
    if monitor:
        connections += tuple(Connection(Port("plant", v), Port("monitor", v)) for v in inputs)
    return dataclasses.replace(run, system=dataclasses.replace(wiring, connections=connections))


def _assembled(run, plant):  # noqa: ANN001, ANN202 - (Assembly, Execution, trace)
    """The run's system assembled and initialised by the master (each FMU logging only its
    non-OK statuses, as `cosim.execution.slaves.FmuSlave` sets it)."""
    assembly = assemble(run, plant)
    n = run.steps
    trace = np.full((n + 1, len(assembly.plan.names)), np.nan)
    execution = Execution(
        assembly.plan, assembly.slaves, assembly.signals, n, run.T_s, run.t_end, [TraceObserver(assembly.plan, trace)]
    )
    execution.initialize()
    return assembly, execution, trace


def compiled_run(run, plant) -> tuple[float, np.ndarray, tuple[str, ...]]:  # noqa: ANN001
    """Seconds per sample of the system in the compiled system loop, its trace and column names."""
    assembly, _, trace = _assembled(run, plant)
    try:
        n = run.steps
        loop = compiled_system(assembly.plan, assembly.slaves, assembly.signals, trace, n, run.T_s)
        if not isinstance(loop, SystemLoop):
            raise RuntimeError(f"no compiled system loop: {loop}")
        t0 = time.perf_counter()
        code, k = loop.run(0, n + 1)
        seconds = time.perf_counter() - t0
        if code != DONE:
            raise RuntimeError(f"the system loop stopped at sample {k}: {loop.failure()}")
        return seconds / n, trace, assembly.plan.names
    finally:
        assembly.close()


def python_run(run, plant) -> tuple[float, np.ndarray]:  # noqa: ANN001
    """Seconds per sample of the same system in the master's Python execution, and its trace."""
    assembly, execution, trace = _assembled(run, plant)
    try:
        t0 = time.perf_counter()
        execution.advance(0, run.steps + 1)
        return (time.perf_counter() - t0) / run.steps, trace
    finally:
        assembly.close()


PRESS = ROOT / "examples" / "press_system"
PAIR_PYTHON_SAMPLE_S = 5.7e-6  # the PD law per sample in the pair's own loop, before the pair ran in the execution


def _pd_controller(run):  # noqa: ANN001, ANN202 - the examples' PDController
    """examples/controllers/my_controllers.py's PD law (Kp 12 A/m, Kd 2.5 A s/m) for the run's target."""
    import importlib.util

    path = ROOT / "examples" / "controllers" / "my_controllers.py"
    spec = importlib.util.spec_from_file_location("my_controllers_bench", path)
    module = sys.modules.setdefault(spec.name, importlib.util.module_from_spec(spec))
    if not hasattr(module, "PDController"):
        spec.loader.exec_module(module)
    return module.PDController(run.x_target, 12.0, 2.5)


def python_controller(plant, parts: dict[str, Path], controller: Path, repetitions: int) -> dict:  # noqa: ANN001
    """The examples' PD law in the pair (the press example's plant and stroke, a two-part system
    in the execution) and in the press system (the compiled system loop calling it back; the Python execution
    with TOGGLE_COSIM_KERNEL=0), by `master.check_and_simulate`, interleaved: the best loop seconds per
    sample of each, and whether the compiled loop's trace has the Python execution's bits."""
    import os

    run = press_with(controller, parts)
    run = dataclasses.replace(run, controller=dataclasses.replace(run.controller, fmu=None))
    pair_run = dataclasses.replace(run, system=Wiring())
    times: dict[str, list[float]] = {"pair": [], "system": [], "python": []}
    same = True
    for _ in range(repetitions):
        pair = check_and_simulate(pair_run, plant, controller=_pd_controller(run))
        system = check_and_simulate(run, plant, controller=_pd_controller(run))
        previous = os.environ.get("TOGGLE_COSIM_KERNEL")
        os.environ["TOGGLE_COSIM_KERNEL"] = "0"
        try:
            python = check_and_simulate(run, plant, controller=_pd_controller(run))
        finally:
            if previous is None:
                os.environ.pop("TOGGLE_COSIM_KERNEL")
            else:
                os.environ["TOGGLE_COSIM_KERNEL"] = previous
        for outcome, kind in ((pair, "python"), (system, "system, compiled"), (python, "system, python")):
            if not outcome.complete or outcome.record["loop"]["kind"] != kind:
                raise RuntimeError(f"a Python controller, {kind}: {outcome.reason or outcome.record['loop']}")
        for key, outcome in (("pair", pair), ("system", system), ("python", python)):
            times[key].append(outcome.loop_seconds / run.steps)
        same = same and np.array_equal(system.trace.data, python.trace.data, equal_nan=True)
    return {**{key: min(value) for key, value in times.items()}, "bit_for_bit": same, "samples": run.steps}


def build_press_parts(folder: Path) -> dict[str, Path]:
    """The press example's sensor and die-load FMUs (FMI 2.0, Co-Simulation), built here."""
    from toggle_cosim.fmu_export import build_fmu

    built = {}
    for name, model in (("sensor", "PositionSensor"), ("die", "DieLoad")):
        built[name] = build_fmu(PRESS / f"{model}.mo", model, folder / f"{model}.fmu", "2.0", "cs").fmu.path
    return built


def press_with(controller: Path, parts: dict[str, Path]):  # noqa: ANN201 - a Run
    """examples/press_system/press.yaml's first variant (four components: the plant, the sensor,
    the die load, the controller), with the controller as the controller FMU and the parts built here."""
    import yaml

    document = yaml.safe_load((PRESS / "press.yaml").read_text(encoding="utf-8"))
    for name, component in document["components"].items():
        component["fmu"] = str(parts[name])
    document["controller"]["fmu"] = str(controller)
    return runs_from_document(document, PRESS / "press.yaml")[0]


def compile_replay(folder: Path) -> ctypes.CDLL | None:
    """system_replay.c as a shared library in `folder` (None without a C compiler)."""
    from toggle_cosim.native import c_compiler

    try:
        compiler = c_compiler()
    except RuntimeError:
        return None
    library = folder / "system_replay.so"
    source = Path(__file__).resolve().parent / "system_replay.c"
    subprocess.run([compiler, "-O2", "-fPIC", "-shared", "-o", str(library), str(source)], check=True)
    replay = ctypes.CDLL(str(library))
    replay.replay.restype = ctypes.c_long
    replay.replay.argtypes = [
        *(ctypes.c_void_p,) * 5,
        ctypes.c_long,
        ctypes.c_void_p,
        ctypes.c_void_p,
        ctypes.c_long,
        ctypes.c_void_p,
        ctypes.c_void_p,
        ctypes.c_long,
        ctypes.c_void_p,
        ctypes.c_long,
        ctypes.c_double,
    ]
    return replay


def replayed(run, plant, library: ctypes.CDLL, trace: np.ndarray, names: tuple[str, ...]) -> tuple[float, bool]:  # noqa: ANN001
    """Seconds per sample of the system's FMUs' own calls from C, each FMU replayed alone on a fresh
    instance with the inputs the system run recorded (`trace`, `names`), summed; and whether every
    output it read has the system run's bits."""
    assembly, _, _ = _assembled(run, plant)
    plan, n, total, same = assembly.plan, run.steps, 0.0, True
    try:
        for c, slave in enumerate(assembly.slaves):
            calls = slave.c_functions()
            if calls.fmi3:
                raise ValueError("the replay driver calls FMI 2.0 FMUs only")
            component, inputs = plan.order[c], plan.input_names[c]
            in_vr = (ctypes.c_uint32 * max(len(inputs), 1)).from_address(calls.in_vr)
            late = plan.late[c]
            tables, vrs = [], []
            for positions in (plan.early[c], late):
                columns = [names.index(f"{component}.{inputs[i]}") for i in positions]
                tables.append(np.ascontiguousarray(trace[:, columns]))
                vrs.append((ctypes.c_uint32 * max(len(positions), 1))(*(in_vr[i] for i in positions)))
            outputs = plan.output_names[c]
            read = np.full((n + 1, len(outputs)), np.nan)
            t0 = time.perf_counter()
            done = library.replay(
                calls.get,
                calls.set,
                calls.step,
                calls.component,
                calls.out_vr,
                len(outputs),
                read.ctypes.data,
                ctypes.addressof(vrs[0]),
                len(plan.early[c]),
                tables[0].ctypes.data,
                ctypes.addressof(vrs[1]),
                len(late),
                tables[1].ctypes.data,
                n,
                run.T_s,
            )
            total += time.perf_counter() - t0
            if done != n + 1:
                raise RuntimeError(f"the replay of {component} stopped at sample {done}")
            recorded = trace[:, [names.index(f"{component}.{v}") for v in outputs]]
            same = same and np.array_equal(read, recorded)
        return total / n, same
    finally:
        assembly.close()


def compile_master(folder: Path) -> Path | None:
    """system_master.c compiled into `folder` (None without a C compiler)."""
    from toggle_cosim.fmu_export.packaging import fmi_headers
    from toggle_cosim.native import c_compiler

    try:
        compiler = c_compiler()
    except RuntimeError:
        return None
    binary = folder / "system_master"
    subprocess.run([compiler, "-O2", f"-I{fmi_headers()}", str(SOURCE), "-o", str(binary), "-ldl"], check=True)
    return binary


def _binary(fmu: Path, identifier: str, folder: Path) -> Path:
    from toggle_cosim.fmu_export.packaging import platform_folder, shared_library_suffix

    target = folder / fmu.stem
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(target)
    return target / "binaries" / platform_folder() / f"{identifier}{shared_library_suffix()}"


def _values(settings, references, types, kinds) -> list[str]:  # noqa: ANN001
    """The spec's three lists (Real, Integer, Boolean) of (value reference, value)."""
    groups: dict[str, list[str]] = {"real": [], "int": [], "bool": []}
    for name, value in settings:
        kind = types[name]
        group = "bool" if kind == "Boolean" else "int" if kind in ("Integer", "Enumeration", "Int32") else "real"
        if group == "real" and kind not in ("Real", "Float64"):
            raise ValueError(f"{name}: a {kind} parameter; the C master sets Real, Integer and Boolean only")
        groups[group].append(f"{references[name]} {float(value)!r}")
    return [f"{len(groups[g])} {' '.join(groups[g])}" for g in kinds]


def c_master(binary: Path, run, plant, copies: int, repetitions: int, folder: Path) -> dict:  # noqa: ANN001
    """The plain C master over the plant and `copies` instances of the run's controller FMU."""
    from toggle_cosim.cosim.master import plant_settings

    controller = controller_for(run, plant.recorded_outputs)  # a ControllerFmuPart: nothing loaded
    fmu = controller.fmu
    if not isinstance(run.plant.F_E, (int, float)):
        raise ValueError("the C master takes a constant F_E")
    outputs = list(plant.recorded_outputs)
    spec = [
        *_values(plant_settings(run, plant), plant.references, plant.types, ("real", "int", "bool")),
        f"{len(outputs)} {' '.join(str(plant.references[v]) for v in outputs)}",
        f"{plant.references['iq_ref']} {plant.references['F_E']} {float(run.plant.F_E)!r}",
        *_values(controller.settings, fmu.references, fmu.types, ("real", "int", "bool")),
        f"{len(fmu.inputs)} {' '.join(f'{fmu.references[v]} {outputs.index(v)}' for v in fmu.inputs)}",
        f"{1 + len(fmu.diagnostics)} {' '.join(str(fmu.references[v]) for v in ('iq_ref', *fmu.diagnostics))}",
    ]
    if outputs[0] != "x_B":
        raise ValueError("the C master reports the plant's first output as x_B")
    plant_binary = _binary(plant.path, plant.model_identifier, folder / "plant")
    ctrl_binary = _binary(fmu.path, fmu.model_identifier, folder / "controller")
    command = [str(binary), str(plant_binary), plant.model_description.guid, str(ctrl_binary), fmu.token]
    command += [str(copies), str(run.steps), repr(run.T_s), repr(run.t_end), str(repetitions)]
    done = subprocess.run(command, input="\n".join(spec), capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"system_master failed: {done.stderr.strip()[-500:]}")
    ns, x_B, command_n, total = (float(v) for v in done.stdout.split())
    return {"per_step_s": ns * 1e-9, "x_B_n": x_B, "iq_ref_n": command_n, "x_B_sum": total}


def same_bits(master: dict, trace: np.ndarray, names: tuple[str, ...]) -> bool:
    """Whether the C master's x_B at N, command at N and sum of x_B (in order) are the trace's."""
    x_B, command = trace[:, names.index("plant.x_B")], trace[:, names.index("plant.iq_ref")]
    total = 0.0
    for value in x_B.tolist():
        total += value
    return (x_B[-1], command[-1], total) == (master["x_B_n"], master["iq_ref_n"], master["x_B_sum"])


def both_loops(run, plant, times: dict[str, list[float]], label: str) -> tuple[np.ndarray, tuple[str, ...]]:  # noqa: ANN001
    """One repetition of the system in the compiled loop and in the Python execution, their
    seconds per sample appended to `times`; the trace (the two must be equal bit for bit) and names."""
    per_step, trace, names = compiled_run(run, plant)
    times["compiled"].append(per_step)
    seconds, python_trace = python_run(run, plant)
    times["python"].append(seconds)
    if not np.array_equal(python_trace, trace, equal_nan=True):
        raise RuntimeError(f"{label}: the compiled system loop's trace is not the Python execution's")
    return trace, names


def measure(plant, controller: Path, folder: Path, repetitions: int, parts: dict[str, Path] | None = None) -> dict:  # noqa: ANN001
    """Best per-sample times of the pair and the three-FMU system (compiled, Python,
    the C master; for the pair, the built-in law's fig4_nominal/friction by `full_loop` too,
    each repetition right after the C master's run), and with `parts`, of the press system
    (compiled, Python, its FMUs replayed)."""
    folder.mkdir(parents=True, exist_ok=True)
    binary = compile_master(folder)
    figures: dict = {}
    builtin = next(r for r in paper_runs() if r.label == "fig4_nominal/friction")
    for key, monitor in (("pair", False), ("three", True)):
        run = fig4_with(controller, plant, monitor)
        times: dict[str, list[float]] = {"compiled": [], "python": [], "c_master": [], "builtin": []}
        for _ in range(repetitions):
            trace, names = both_loops(run, plant, times, key)
            if binary is not None:
                master = c_master(binary, run, plant, 2 if monitor else 1, 1, folder / key)  # one run, as the loop
                times["c_master"].append(master["per_step_s"])
                if not monitor:  # the built-in law in the execution beside it, for their ratio
                    times["builtin"].append(full_loop(plant, builtin)["per_step"])
        result = {k: min(v) for k, v in times.items() if v}
        result["columns"] = len(names) - 1
        if binary is not None:
            result["bit_for_bit"] = same_bits(master, trace, names)
        figures[key] = result
    if parts is not None:
        run = press_with(controller, parts)
        replay = compile_replay(folder)
        times = {"compiled": [], "python": [], "replay": []}
        for _ in range(repetitions):
            trace, names = both_loops(run, plant, times, "press")
            if replay is not None:
                seconds, same = replayed(run, plant, replay, trace, names)
                times["replay"].append(seconds)
        figures["press"] = {k: min(v) for k, v in times.items() if v}
        figures["press"].update(samples=run.steps, components=2 + len(run.system.parts))
        if replay is not None:
            figures["press"]["bit_for_bit"] = same
    return figures


def section(table, figures: dict, plant, controller: Path | None, folder: Path, repetitions: int, builtin_s: float):  # noqa: ANN001, ANN201
    """bench.py's section: rows and targets of the systems in the compiled system loop."""
    table.section(
        "Systems in the compiled system loop, per sample (fig4_nominal/friction, 3000 samples; press: its own)"
    )
    if system_library() is None:
        table.text(f"no compiled system loop: {system_library_reason()}")
        return
    if controller is None:
        table.text("no controller FMU (toggle_cosim.controller_fmu absent): not measured")
        return
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    parts = build_press_parts(folder)
    build_s = time.perf_counter() - t0
    got = measure(plant, controller, folder, repetitions, parts)
    figures["systems"] = {**got, "builtin_loop_s": builtin_s}
    table.add("built-in law through the execution (full_loop)", us(builtin_s), "as above; natively in C")
    if "c_master" in got["pair"]:
        beside = got["pair"]["builtin"]  # measured in turn with the C master, so a burst of load hits both
        ratio = beside / got["pair"]["c_master"]
        figures["systems"]["builtin_over_c_master"] = ratio
        table.check(
            "built-in law through the execution <= 1.05 x a plain C master of the plant and controller FMUs",
            ratio <= 1.05,
            f"{us(beside)} / {us(got['pair']['c_master'])} = {ratio:.3f}, the two measured in turn",
        )
    for key, what in (("pair", "plant + controller FMU"), ("three", "pair + monitor FMU")):
        r = got[key]
        table.add(
            f"{what}: compiled system loop",
            us(r["compiled"]),
            f"{r['columns']} columns recorded; FMUs log non-OK statuses only",
        )
        table.add(
            f"{what}: Python execution of the same plan", us(r["python"]), "cosim.execution.algorithm; same bits as C"
        )
        if "c_master" in r:
            bits = "same bits" if r["bit_for_bit"] else "NOT the same bits"
            table.add(f"{what}: plain C master (system_master.c)", us(r["c_master"]), f"the FMUs' own calls; {bits}")
            table.add(f"{what}: ratio compiled loop / plain C master", f"{r['compiled'] / r['c_master']:.2f}")
    press = got["press"]
    what = f"press, {press['components']} FMUs"
    table.text(
        f"press: examples/press_system/press.yaml (plant, sensor, die load, the controller as ToggleVSC), "
        f"{press['samples']} samples; its parts built in {build_s:.2f} s"
    )
    table.add(f"{what}: compiled system loop", us(press["compiled"]), "FMUs log non-OK statuses only")
    table.add(
        f"{what}: Python execution of the same plan", us(press["python"]), "cosim.execution.algorithm; same bits as C"
    )
    if "replay" in press:
        bits = "same bits" if press["bit_for_bit"] else "NOT the same bits"
        table.add(
            f"{what}: its FMUs' own calls from C, summed",
            us(press["replay"]),
            f"system_replay.c: each FMU alone, its recorded inputs; {bits}",
        )
        table.add(f"{what}: ratio compiled loop / its FMUs' own calls", f"{press['compiled'] / press['replay']:.2f}")
        ratio = press["compiled"] / press["replay"]
        table.check(
            f"{press['components']}-FMU press system in the compiled loop <= 1.2 x the sum of its FMUs' own calls from C",
            ratio <= 1.2 and press["bit_for_bit"],
            f"{us(press['compiled'])} / {us(press['replay'])} = {ratio:.2f}"
            + ("" if press["bit_for_bit"] else "; NOT bit for bit"),
        )
    python = python_controller(plant, parts, controller, repetitions)
    figures["systems"]["python_controller"] = python
    table.text(
        f"a Python controller (examples/controllers' PD law) in the pair and in the press system, {python['samples']} samples:"
    )
    table.add("Python controller in the pair, compiled loop", us(python["pair"]), "called back from C at its turn")
    bits = "same bits" if python["bit_for_bit"] else "NOT the same bits"
    table.add(
        "Python controller in the press system, compiled loop",
        us(python["system"]),
        f"called back from C at its turns; {bits} as the Python execution",
    )
    table.add(
        "Python controller in the press system, Python execution",
        us(python["python"]),
        "TOGGLE_COSIM_KERNEL=0: every FMU called from Python",
    )
    for key, where in (("pair", "the pair"), ("system", "the press system")):
        ratio = python[key] / PAIR_PYTHON_SAMPLE_S
        table.check(
            f"a Python controller in {where} <= 1.2 x the pair's own loop before (5.7 us per sample)",
            ratio <= 1.2 and python["bit_for_bit"],
            f"{us(python[key])} / {us(PAIR_PYTHON_SAMPLE_S)} = {ratio:.2f}"
            + ("" if python["bit_for_bit"] else "; NOT bit for bit"),
        )
    ssp = _press_ssp(controller, parts, plant, folder)
    run = press_with(controller, parts)
    masters = ssp_masters(ssp, run.T_s, run.t_end, max(repetitions // 3, 1), folder)
    figures["ssp_masters"] = masters
    table.text(f"the press example's SSP (paper variant, {run.steps} steps, Jacobi in every master), per step:")
    for key, what in (
        ("ours", f"ours, toggle-cosim run --coupling jacobi ({masters['ours_loop']})"),
        ("libcosim", "libcosim (libcosimpy 0.0.6), simulate_until"),
        ("ecos", "Ecos (ecospy), step(n)"),
    ):
        value = masters[key]
        if isinstance(value, float):
            ratio = "" if key == "ours" else f"{value / masters['ours']:.2f} x ours"
            table.add(f"press SSP: {what}", us(value), ratio)
        else:
            table.add(f"press SSP: {what}", value)
    for key, label in (
        ("pair", "plant + controller-FMU system in the compiled loop <= 1.2 x a plain C master"),
        ("three", "3-FMU system in the compiled loop <= 1.2 x its FMUs' own calls from C"),
    ):
        r = got[key]
        if "c_master" in r:
            ratio = r["compiled"] / r["c_master"]
            detail = f"{us(r['compiled'])} / {us(r['c_master'])} = {ratio:.2f}"
            table.check(
                label, ratio <= 1.2 and r["bit_for_bit"], detail + ("" if r["bit_for_bit"] else "; NOT bit for bit")
            )


def _press_ssp(controller: Path, parts: dict[str, Path], plant, folder: Path) -> Path:  # noqa: ANN001
    """The press example's first variant as an SSP (`toggle-cosim ssp`), its FMUs the ones built here."""
    import yaml

    document = yaml.safe_load((PRESS / "press.yaml").read_text(encoding="utf-8"))
    document["fmu"] = str(plant.path)
    for name, component in document["components"].items():
        component["fmu"] = str(parts[name])
    document["variants"] = {"paper": document["variants"]["paper"]}
    scenario = folder / "press_bench.yaml"
    scenario.write_text(yaml.safe_dump(document), encoding="utf-8")
    archive = folder / "press_bench.ssp"
    command = [sys.executable, "-m", "toggle_cosim", "ssp", str(scenario), "--out", str(archive)]
    subprocess.run([*command, "--controller", str(controller)], check=True, capture_output=True, timeout=300)
    return archive


def ssp_masters(ssp: Path, T_s: float, t_end: float, repetitions: int, folder: Path) -> dict[str, float | str]:
    """Seconds per step of the same SSP in our master (`run --coupling jacobi`, the loop's time from
    run.json), libcosim (`simulate_until`) and Ecos (`step`), each the best of `repetitions`
    (loading and initialisation left out), or why a master was not measured."""
    import json

    n = round(t_end / T_s)
    found: dict[str, float | str] = {}
    best = float("inf")
    for _ in range(repetitions):
        out = folder / "ssp_runs"
        command = [
            sys.executable,
            "-m",
            "toggle_cosim",
            "run",
            str(ssp),
            "--coupling",
            "jacobi",
            "-q",
            "--out",
            str(out),
        ]
        subprocess.run(command, check=True, capture_output=True, timeout=600)
        record = json.loads(next(out.glob("*/*/run.json")).read_text(encoding="utf-8"))
        best = min(best, record["loop_time_s"] / n)
        found["ours_loop"] = record["loop"]["kind"]
    found["ours"] = best
    try:
        from libcosimpy.CosimExecution import CosimExecution
        from libcosimpy.CosimLogging import CosimLogLevel, log_output_level

        log_output_level(CosimLogLevel.WARNING)
        unpacked = folder / "press_unpacked"
        shutil.rmtree(unpacked, ignore_errors=True)
        with zipfile.ZipFile(ssp) as archive:
            archive.extractall(unpacked)
        best = float("inf")
        for _ in range(repetitions):
            execution = CosimExecution.from_ssp_file(str(unpacked), step_size=round(T_s * 1e9))
            started = time.perf_counter()
            if not execution.simulate_until(n * round(T_s * 1e9)):
                raise RuntimeError("libcosim stopped early")
            best = min(best, (time.perf_counter() - started) / n)
            del execution
        found["libcosim"] = best
    except Exception as error:  # noqa: BLE001 - not installed, or it failed: said in the table
        found["libcosim"] = f"not measured ({type(error).__name__}: {str(error)[:80]})"
    try:
        from ecospy import EcosLib, EcosSimulation

        EcosLib.set_log_level("warn")
        best = float("inf")
        for _ in range(repetitions):
            with EcosSimulation(ssp_path=str(ssp), step_size=T_s) as sim:
                if not sim.init(0.0, "paper"):
                    raise RuntimeError(EcosLib.get_last_error())
                started = time.perf_counter()
                sim.step(n)
                best = min(best, (time.perf_counter() - started) / n)
                sim.terminate()
        found["ecos"] = best
    except Exception as error:  # noqa: BLE001 - not installed (it needs Debian's libtbb12), or it failed
        found["ecos"] = f"not measured ({type(error).__name__}: {str(error)[:80]})"
    return found


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 repetitions instead of 9")
    parser.add_argument("--fmu", type=Path, default=None, help="the plant FMU (default: built here)")
    args = parser.parse_args()
    from toggle_cosim.controller_fmu import build_controller_fmu
    from toggle_cosim.fmu_export import build_fmu
    from toggle_cosim.plant.contract import check_plant

    folder = Path(tempfile.mkdtemp(prefix="toggle-system-bench-"))
    try:
        fmu = (
            args.fmu or build_fmu(ROOT / "modelica" / "ToggleLSM", "ToggleLSM.Plant", folder / "ToggleLSM.fmu").fmu.path
        )
        plant = check_plant(Path(fmu).resolve())
        controller = Path(build_controller_fmu(folder / "ToggleVSC.fmu", "2.0").path)
        repetitions = 3 if args.quick else 9
        run = next(r for r in paper_runs() if r.label == "fig4_nominal/friction")
        builtin = min(full_loop(plant, run)["per_step"] for _ in range(repetitions))
        table, figures = Table(), {}
        section(table, figures, plant, controller, folder, repetitions, builtin)
        table.print()
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

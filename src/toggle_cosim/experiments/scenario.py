"""Scenario files (YAML) -> validated, typed runs.

A scenario holds one experiment and its variants (typically with and without joint friction).
Every key is checked against a JSON Schema; the first problem becomes one `ScenarioError`
line that names the file, the key and what is allowed. Physical limits that a schema cannot
say (a target beyond the toggle position) are checked after it.

    name: fig4_nominal
    description: Nominal case of Fig. 4
    fmu: ../fmus/ToggleLSM.fmu          # relative to this file; --fmu overrides it
    t_end: 1.5                          # s
    T_s: 0.0005                         # s, controller sample time
    stroke: {x_start: 0.2329, x_target: 0.3199}
    # the built-in law may track a profile instead of the constant x_target (control/trajectory.py):
    # stroke: {x_start: .., x_target: .., trajectory: {kind: trapezoid, v_max: 0.2, a_max: 2.0}}
    plant: {F_E: 0.0, m_B: 4.43, mu: 0.2, current_loop: first_order, parameters: {},
            friction_model: paper, mu_s: 0.2}     # friction_model: paper | dissipative | stick_slip
    # F_E may be a signal in time: {kind: step, start_time: 0.25, height: 100.0}, ... (`signals.schema`)
    controller: {objective: x_B, gains: {C: 5, Q: 4, P: 50, delta: 0.25, beta: 65}}
    # or a user's controller: {python: "module:factory", parameters: {...}} (docs/controllers.md)
    # or a controller FMU: {fmu: controllers/MyLaw.fmu, parameters: {...}}
    coupling: gauss-seidel              # or jacobi: the plant gets the previous sample's command
    variants:
      friction: {plant: {mu: 0.2}}
      no_friction: {plant: {mu: 0.0}}
"""

from __future__ import annotations

import copy
import functools
import math
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from toggle_cosim.control.lti import DISCRETISE_METHODS
from toggle_cosim.control.trajectory import KINDS as TRAJECTORY_KINDS
from toggle_cosim.control.trajectory import ProfileSpec, build
from toggle_cosim.limits import MAX_SECONDS
from toggle_cosim.messages import schema_text, value_text
from toggle_cosim.physics.mechanism import SINGULARITY_MARGIN, folded_limit, toggle_limit, working_range
from toggle_cosim.physics.parameters import ControllerGains, MechanismParameters
from toggle_cosim.runs.definition import COUPLINGS, ControllerSettings, ErrorSignal, PlantSettings, Run
from toggle_cosim.signals.definitions import Signal, SignalError, Table
from toggle_cosim.signals.schema import signal_from_document, signal_schema
from toggle_cosim.system.model import Connection, Part, Port, Wiring

if TYPE_CHECKING:
    import jsonschema

_NUMBER = {"type": "number"}
_POSITIVE = {"type": "number", "exclusiveMinimum": 0}

_PLANT = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "F_E": signal_schema(-10000, 10000, "external force on slider B in N, >= 0 resists the stroke"),
        "m_B": {"type": "number", "exclusiveMinimum": 0, "maximum": 1000},
        "mu": {"type": "number", "minimum": 0, "maximum": 1},
        "current_loop": {"enum": ["first_order", "ideal"]},
        "friction_model": {"enum": ["paper", "dissipative", "stick_slip"]},
        "mu_s": {"type": "number", "minimum": 0, "maximum": 1},
        "K": {"type": "number", "exclusiveMinimum": 0, "maximum": 1e6},
        "rated_current": {
            "type": "number",
            "exclusiveMinimum": 0,
            "maximum": 1e6,
            "description": "motor rating in A: a run whose |i_q*| exceeds it is flagged (default 10 A, assumed)",
        },
        "working_range": {
            "type": "array",
            "items": {"type": "number", "exclusiveMinimum": 0, "maximum": 100},
            "minItems": 2,
            "maxItems": 2,
            "description": "[x_min, x_max] of slider B in m: a run whose x_B leaves it is flagged",
        },
        "parameters": {
            "type": "object",
            "propertyNames": {"type": "string", "pattern": r"^[A-Za-z_][A-Za-z0-9_.\[\]]*\Z"},
            "additionalProperties": {"type": ["number", "boolean"]},
        },
        "inputs": {
            "type": "object",
            "propertyNames": {"type": "string", "pattern": r"^[A-Za-z_][A-Za-z0-9_]*\Z"},
            "additionalProperties": signal_schema(-1e6, 1e6, "an input of the plant FMU, in its unit"),
            "description": "the plant FMU's other inputs by name: a number or a signal each",
        },
    },
}
_GAINS = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "C": {"type": "number", "exclusiveMinimum": 0, "maximum": 1e4},
        "Q": {"type": "number", "exclusiveMinimum": 0, "maximum": 1e6},
        "P": {"type": "number", "exclusiveMinimum": 0, "maximum": 1e6},
        "delta": {"type": "number", "exclusiveMinimum": 0, "maximum": 1e3},
        "beta": {"type": "number", "exclusiveMinimum": 0, "maximum": 1e6},
    },
}
_CONTROLLER = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "objective": {"enum": ["x_B", "theta1"]},
        "gains": _GAINS,
        "nominal_m_B": {"type": "number", "exclusiveMinimum": 0, "maximum": 1000},
        "law": {"enum": ["paper", "integral"]},  # the integral law: control/laws.py, docs/controllers.md
        "C_I": {"type": "number", "exclusiveMinimum": 0, "maximum": 1e4},  # 1/s, integral law only
        "K_I": {"type": "number", "minimum": 0, "maximum": 1e6},  # 1/s², integral law only
        "i_max": {"type": "number", "exclusiveMinimum": 0, "maximum": 1e4},  # A, integral law only
        # the user's controller (cosim/controllers.py): a factory, its parameters, and for a
        # python-control system the error it acts on and the command it gives
        "python": {
            "type": "string",
            "pattern": r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*:[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*\Z",
            "description": "package.module:callable, imported from the scenario's folder or sys.path",
        },
        "fmu": {
            "type": "string",
            "minLength": 1,
            "pattern": r"^[^\x00]*\Z",
            "description": "a controller FMU (Co-Simulation, FMI 2.0 or 3.0), relative to this file",
        },
        "parameters": {
            "type": "object",
            "propertyNames": {"type": "string", "pattern": r"^[A-Za-z_][A-Za-z0-9_]*\Z"},
            "additionalProperties": {"description": "any value the factory takes (a sweep axis may set one)"},
            "description": "keyword arguments of the controller.python factory, or the controller FMU's parameters",
        },
        "error": {
            "type": "object",
            "additionalProperties": False,
            "required": ["output"],
            "properties": {
                "output": {"type": "string", "pattern": r"^[A-Za-z_][A-Za-z0-9_.\[\]]*\Z"},
                "target": {"type": "number"},
            },
        },
        "command": {"enum": ["iq_ref"]},
        "discretise": {"enum": list(DISCRETISE_METHODS)},  # a continuous-time system, sampled at T_s
    },
}
_TRAJECTORY = {
    "type": "object",
    "additionalProperties": False,
    "required": ["kind", "v_max", "a_max"],
    "description": "the reference the built-in law tracks from x_start to x_target (control/trajectory.py)",
    "properties": {
        "kind": {"enum": list(TRAJECTORY_KINDS)},
        "v_max": {"type": "number", "exclusiveMinimum": 0, "maximum": 100, "description": "velocity limit in m/s"},
        "a_max": {"type": "number", "exclusiveMinimum": 0, "maximum": 1e5, "description": "acceleration limit, m/s2"},
        "j_max": {"type": "number", "exclusiveMinimum": 0, "maximum": 1e8, "description": "jerk limit in m/s3"},
        "dwell": {"type": "number", "minimum": 0, "maximum": 100, "description": "a cycle's dwell at each end, s"},
        "repeat": {"type": "integer", "minimum": 1, "maximum": 10000, "description": "a cycle's number of cycles"},
        "t_start": {"type": "number", "minimum": 0, "maximum": 100, "description": "when the first move starts, s"},
    },
}
_STROKE = {
    "type": "object",
    "additionalProperties": False,
    "required": ["x_start", "x_target"],
    "properties": {"x_start": _POSITIVE, "x_target": _POSITIVE, "trajectory": _TRAJECTORY},
}
_NAME = r"^[A-Za-z_][A-Za-z0-9_]*\Z"
_PORT = r"^[A-Za-z_][A-Za-z0-9_]*\.[^\s]+\Z"
_CONNECTION = r"^\s*[A-Za-z_][A-Za-z0-9_]*\.[^\s]+\s*->\s*[A-Za-z_][A-Za-z0-9_]*\.[^\s]+\s*\Z"
_PATTERN_HINTS = {
    _CONNECTION: "a connection (write 'component.variable -> component.variable', e.g. 'plant.x_B -> sensor.x')",
    _PORT: "a port (write 'component.variable', e.g. 'plant.x_B')",
}
_PART = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "fmu": {"type": "string", "minLength": 1, "pattern": r"^[^\x00]*\Z", "description": "relative to this file"},
        "parameters": {
            "type": "object",
            "additionalProperties": {"type": ["number", "boolean"]},
            "description": "values set before initialisation, by the FMU's variable names",
        },
    },
}
_COMPONENTS = {
    "type": "object",
    "propertyNames": {"pattern": _NAME, "not": {"enum": ["plant", "controller"]}},
    "additionalProperties": _PART,
    "description": "FMU components besides the plant and the controller (a sensor, a drive, a load)",
}
_OVERRIDE = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "description": {"type": "string"},
        "t_end": {"type": "number", "exclusiveMinimum": 0, "maximum": 100},
        "T_s": {"type": "number", "minimum": 1e-6, "maximum": 0.1},
        "stroke": {**_STROKE, "required": []},
        "plant": _PLANT,
        "controller": _CONTROLLER,
        "time_limit": {
            "type": "number",
            "exclusiveMinimum": 0,
            "maximum": MAX_SECONDS,
            "description": "wall-clock limit of the run in s (default max(30 s, 20 x t_end))",
        },
        "budget": {
            "type": "object",
            "additionalProperties": False,
            "minProperties": 1,
            "properties": {
                "events": {"type": "integer", "minimum": 1, "description": "the plant's solver events over the run"},
                "events_per_sample": {
                    "type": "number",
                    "exclusiveMinimum": 0,
                    "description": "the plant's solver events over the run, per sample",
                },
                "steps": {"type": "integer", "minimum": 1, "description": "the plant's accepted solver steps"},
            },
            "description": "the simulated work the run may do, counted by the plant FMU (docs/sweeps.md)",
        },
        "record_every": {
            "type": "integer",
            "minimum": 1,
            "maximum": 1_000_000,
            "description": "write every n-th sample (and the last) to trace.csv",
        },
        "coupling": {
            "enum": list(COUPLINGS),
            "description": "gauss-seidel (default): sample k's command drives the plant over [t_k, t_k+1]; "
            "jacobi: sample k-1's does (docs/controllers.md); --coupling overrides it",
        },
        "components": _COMPONENTS,
    },
}
SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "type": "object",
    "additionalProperties": False,
    "required": ["name", "t_end", "T_s", "stroke"],
    "properties": {
        "name": {"type": "string", "pattern": r"^[A-Za-z0-9_][A-Za-z0-9_.-]*\Z"},
        "description": {"type": "string"},
        "fmu": {"type": "string", "minLength": 1, "pattern": r"^[^\x00]*\Z"},  # no NUL: not a path
        "t_end": _OVERRIDE["properties"]["t_end"],
        "T_s": _OVERRIDE["properties"]["T_s"],
        "stroke": _STROKE,
        "plant": _PLANT,
        "controller": _CONTROLLER,
        "time_limit": _OVERRIDE["properties"]["time_limit"],
        "budget": _OVERRIDE["properties"]["budget"],
        "record_every": _OVERRIDE["properties"]["record_every"],
        "coupling": _OVERRIDE["properties"]["coupling"],
        "components": {**_COMPONENTS, "additionalProperties": {**_PART, "required": ["fmu"]}},
        "connections": {
            "type": "array",
            "minItems": 1,
            "items": {"type": "string", "pattern": _CONNECTION},
            "description": "start -> end, e.g. 'plant.x_B -> sensor.x' (docs/systems.md)",
        },
        "record": {
            "type": "array",
            "minItems": 1,
            "items": {"type": "string", "pattern": _PORT},
            "description": "component.variable to record (default: every connector)",
        },
        "variants": {
            "type": "object",
            "minProperties": 1,
            "propertyNames": {"type": "string", "pattern": r"^[A-Za-z0-9_][A-Za-z0-9_.-]*\Z"},
            "additionalProperties": _OVERRIDE,
        },
    },
}


class ScenarioError(Exception):
    """A scenario file that cannot be used; str() is the one-line message for the user."""


def _part(part: Any) -> str:
    """A key as the message shows it: plain if it is a printable string, else its repr (one line)."""
    return part if isinstance(part, str) and part.isprintable() and part else repr(part)


def _key(path: Any) -> str:
    return ".".join(_part(part) for part in path) or "(top level)"


def _schema_message(error: jsonschema.ValidationError) -> str:
    key = _key(error.absolute_path)
    if error.validator == "additionalProperties":
        extra = sorted(map(_part, set(error.instance) - set(error.schema.get("properties", {}))))
        allowed = ", ".join(sorted(error.schema.get("properties", {}))) or "none"
        where = f"{key}." if error.absolute_path else ""
        return f"unknown key {where}{extra[0]} (allowed here: {allowed})"
    if error.validator == "required":
        return f"missing key: {schema_text(error.message, error.instance)}"
    if error.validator in ("minimum", "exclusiveMinimum", "maximum", "exclusiveMaximum"):
        relation = {"minimum": ">=", "exclusiveMinimum": ">", "maximum": "<=", "exclusiveMaximum": "<"}
        bound = f"{relation[error.validator]} {error.validator_value}"
        return f"key {key}: {value_text(error.instance)} is out of range (must be {bound})"
    if error.validator == "type" and isinstance(error.validator_value, list):
        kinds = " or ".join("mapping" if kind == "object" else kind for kind in error.validator_value)
        return f"key {key}: {value_text(error.instance)} is not of type {kinds} (write a {kinds})"
    if error.validator == "type":
        kind = error.validator_value
        return f"key {key}: {value_text(error.instance)} is not of type {kind} (write a {kind})"
    if error.validator == "enum":
        choices = ", ".join(map(str, error.validator_value))
        return f"key {key}: {value_text(error.instance)} is not allowed (choose one of {choices})"
    if error.validator == "pattern" and error.validator_value in _PATTERN_HINTS:
        return f"key {key}: {value_text(error.instance)} is not {_PATTERN_HINTS[error.validator_value]}"
    if error.validator == "not" and error.absolute_path and error.absolute_path[0] == "components":
        name = _part(error.instance)
        return f"key {key}: {name!r} is taken by the scenario's own {name} (give the part another name)"
    if error.validator == "pattern" and error.absolute_path and error.absolute_path[0] == "components":
        return (
            f"key {key}: {_part(error.instance)!r} is not a component name (letters, digits and _, not first a digit)"
        )
    return f"key {key}: {schema_text(error.message, error.instance)}"


_MAX_VALUES = 100_000  # a scenario holds a few dozen; YAML aliases can expand a 1 KB file to billions


def _reject_non_finite(document: Any) -> None:
    """Reject NaN, infinities and integers beyond float range (as values or keys), keys that are not
    text (a component `true:`), self-containing YAML aliases and alias bombs, before the schema
    (whose messages repr the values) sees them."""
    seen = 0
    open_containers: set[int] = set()

    def check_number(value: Any, path: tuple[Any, ...], what: str) -> None:
        if isinstance(value, float) and not math.isfinite(value):
            raise ScenarioError(f"key {_key(path)}: {what}{value!r} is not a finite number")
        if isinstance(value, int) and not isinstance(value, bool) and abs(value) > sys.float_info.max:
            raise ScenarioError(
                f"key {_key(path)}: {what}an integer of {value.bit_length()} bits is too large"
                f" (numbers must be finite, at most {sys.float_info.max:.1e} in size)"
            )

    def visit(node: Any, path: tuple[Any, ...]) -> None:
        nonlocal seen
        seen += 1
        if seen > _MAX_VALUES:
            raise ScenarioError(
                f"key {_key(path)}: the file holds more than {_MAX_VALUES} values (YAML aliases expanded)"
            )
        check_number(node, path, "")
        if not isinstance(node, (dict, list)):
            return
        if id(node) in open_containers:
            raise ScenarioError(
                f"key {_key(path)}: a YAML alias inside the value it names (recursive data is not allowed)"
            )
        open_containers.add(id(node))
        if isinstance(node, dict):
            for k, v in node.items():
                check_number(k, path, "the key ")
                if not isinstance(k, str):
                    raise ScenarioError(
                        f"key {_key(path)}: the key {k!r} is not a name: YAML reads an unquoted true, false, yes, no, "
                        "on, off, null or number as that value (quote the name, or choose another)"
                    )
                visit(v, (*path, k))
        else:
            for i, v in enumerate(node):
                visit(v, (*path, i))
        open_containers.discard(id(node))

    visit(document, ())


@functools.cache
def _validator() -> jsonschema.Draft202012Validator:
    """The validator of SCHEMA (jsonschema; made once per process)."""
    import jsonschema

    return jsonschema.Draft202012Validator(SCHEMA)


def validate_document(document: Any) -> None:
    """Check a parsed scenario against the schema and the physical limits (raises ScenarioError)."""
    if not isinstance(document, dict):
        raise ScenarioError("the file must hold a YAML mapping of scenario keys (name, t_end, T_s, stroke, ...)")
    _reject_non_finite(document)
    errors = sorted(_validator().iter_errors(document), key=lambda e: (len(e.absolute_path), _key(e.absolute_path)))
    if errors:
        raise ScenarioError(_schema_message(errors[0]))


def merge_documents(base: dict[str, Any], override: Mapping[str, Any]) -> dict[str, Any]:
    """`base` with `override` applied key by key, nested mappings merged (a variant, a sweep case);
    a signal of another kind (plant.F_E: {kind: ...}) replaces the base's, never merges with it."""
    merged = copy.deepcopy(base)
    for key, value in override.items():
        old = merged.get(key)
        if (
            isinstance(value, Mapping)
            and isinstance(old, dict)
            and value.get("kind", old.get("kind")) == old.get("kind")
        ):
            merged[key] = merge_documents(merged[key], value)
        else:
            merged[key] = copy.deepcopy(value)
    return merged


MIN_STROKE = 1e-4  # m: a shorter stroke is refused (the summary's figures divide by it)
# keys of their own: plant.parameters may not set these FMU parameters behind the record's back
OWN_KEYS = {
    "m_B": "plant.m_B",
    "mu": "plant.mu",
    "K": "plant.K",
    "idealCurrentLoop": "plant.current_loop",
    "x_B0": "stroke.x_start",
    "frictionModel": "plant.friction_model",
    "mu_s": "plant.mu_s",
}


def _working_range(given: Any, geometry: MechanismParameters, suffix: str) -> tuple[float, float]:
    """plant.working_range if given (x_min < x_max), else the linkage's (`physics.mechanism`)."""
    if given is None:
        return working_range(geometry)
    low, high = (float(value) for value in given)
    if not low < high:
        raise ScenarioError(
            f"key plant.working_range{suffix}: [{low}, {high}] is empty (write [x_min, x_max], x_min < x_max)"
        )
    return low, high


def _user_controller(controller_doc: Mapping[str, Any], suffix: str, source: Path | None) -> dict[str, Any]:
    """The ControllerSettings fields of a user's controller (controller.python or controller.fmu
    and the keys that go with them); the factory itself is imported and called, the FMU checked,
    by `cosim.controllers`."""
    if "python" in controller_doc and "fmu" in controller_doc:
        raise ScenarioError(
            f"key controller.fmu{suffix}: controller.python and controller.fmu name two controllers (keep one)"
        )
    if "fmu" in controller_doc:
        extra = [key for key in ("error", "command", "discretise") if key in controller_doc]
        if extra:
            raise ScenarioError(
                f"key controller.{extra[0]}{suffix}: only with controller.python (a controller FMU reads the plant"
                " outputs named by its inputs and gives iq_ref; remove the key)"
            )
        fmu = Path(controller_doc["fmu"])
        if source is not None and not fmu.is_absolute():
            fmu = source.parent / fmu
        return {"fmu": fmu, "parameters": copy.deepcopy(dict(controller_doc.get("parameters", {})))}
    if "python" not in controller_doc:
        extra = [key for key in ("parameters", "error", "command", "discretise") if key in controller_doc]
        if extra:
            raise ScenarioError(
                f"key controller.{extra[0]}{suffix}: only with controller.python or controller.fmu (name the"
                " controller's factory as python: module:callable, or its FMU as fmu: PATH)"
            )
        return {}
    error = controller_doc.get("error")
    return {
        "python": controller_doc["python"],
        "parameters": copy.deepcopy(dict(controller_doc.get("parameters", {}))),
        "error": None if error is None else ErrorSignal(error["output"], error.get("target")),
        "command": controller_doc.get("command", "iq_ref"),
        "discretise": controller_doc.get("discretise"),
    }


def _input_signal(
    value: Any, name: str, t_end: float, suffix: str, source: Path | None, key: str | None = None
) -> float | Signal:
    """The plant input `name` from its scenario value at `key` (default plant.NAME; `signals.schema`):
    a number stays a float; a table must cover [0, t_end]. Raises ScenarioError naming the key."""
    try:
        signal = signal_from_document(value, name, None if source is None else source.parent)
        if isinstance(signal, Table):
            signal.check_covers(t_end)
    except SignalError as error:
        raise ScenarioError(f"key {key or f'plant.{name}'}{suffix}: {error}") from None
    return signal


OWN_INPUTS = {"F_E": "it has its own key; set plant.F_E instead", "iq_ref": "it is the controller's command"}


def _other_inputs(given: Mapping[str, Any], t_end: float, suffix: str, source: Path | None) -> dict[str, Any]:
    """plant.inputs: the plant's other inputs by name, each a float or a Signal."""
    inputs = {}
    for name, value in given.items():
        if name in OWN_INPUTS:
            raise ScenarioError(f"key plant.inputs.{name}{suffix}: {name} cannot be set here: {OWN_INPUTS[name]}")
        inputs[name] = _input_signal(value, name, t_end, suffix, source, key=f"plant.inputs.{name}")
    return inputs


_ONLY_FOR = {"j_max": ("scurve", "cycle"), "dwell": ("cycle",), "repeat": ("cycle",)}


def _trajectory(
    stroke: Mapping[str, Any], controller: ControllerSettings, t_end: float, suffix: str
) -> ProfileSpec | None:
    """stroke.trajectory as a `ProfileSpec`, checked: its keys fit its kind, the built-in law
    on the x_B objective tracks it, and it ends by t_end. Raises ScenarioError naming the key."""
    doc = stroke.get("trajectory")
    if doc is None:
        return None
    key = f"key stroke.trajectory{suffix}"
    kind = doc["kind"]
    for name, kinds in _ONLY_FOR.items():
        if name in doc and kind not in kinds:
            raise ScenarioError(
                f"key stroke.trajectory.{name}{suffix}: only for kind {' or '.join(kinds)} (remove it, or change the kind)"
            )
    if kind == "scurve" and "j_max" not in doc:
        raise ScenarioError(f"{key}: an S-curve needs a jerk limit (add j_max in m/s3, or use kind: trapezoid)")
    if controller.python is not None and controller.error is None:
        raise ScenarioError(
            f"{key}: only the built-in law, its controller FMU or a python-control system (controller.error) tracks a"
            " trajectory (remove stroke.trajectory, or controller.python)"
        )
    if controller.error is not None and controller.error.output != "x_B":
        raise ScenarioError(
            f"key controller.error.output{suffix}: stroke.trajectory is a profile of x_B, not of"
            f" {controller.error.output!r} (read x_B, or remove stroke.trajectory)"
        )
    if controller.error is not None and controller.error.target is not None:
        raise ScenarioError(
            f"key controller.error.target{suffix}: the reference is stroke.trajectory (remove error.target, or the"
            " trajectory)"
        )
    if controller.objective != "x_B":
        raise ScenarioError(
            f"{key}: the theta1 objective tracks a constant target only (use controller.objective: x_B, or remove"
            " stroke.trajectory)"
        )
    spec = ProfileSpec(
        kind=kind,
        x_start=float(stroke["x_start"]),
        x_target=float(stroke["x_target"]),
        v_max=float(doc["v_max"]),
        a_max=float(doc["a_max"]),
        j_max=float(doc["j_max"]) if "j_max" in doc else None,
        dwell=float(doc.get("dwell", 0.0)),
        repeat=int(doc.get("repeat", 1)),
        t_start=float(doc.get("t_start", 0.0)),
    )
    end = build(spec).end
    if end > t_end:
        raise ScenarioError(
            f"{key}: the profile ends at t = {end:.6g} s, after t_end = {t_end:g} s (raise v_max or a_max"
            + (", j_max" if spec.j_max is not None else "")
            + (", shorten dwell or repeat" if kind == "cycle" else "")
            + ", or lengthen t_end)"
        )
    return spec


def _relative(path: str, source: Path | None) -> Path:
    return Path(path) if source is None or Path(path).is_absolute() else source.parent / path


def _wiring(document: Mapping[str, Any], source: Path | None, suffix: str) -> Wiring:
    """The scenario's system keys (components, connections, record) as a `Wiring`: the plain
    pair without them. Every port names a component the scenario has; a part's FMU exists; a
    plant input given a value (plant.F_E) is not also connected."""
    parts = []
    for name, given in (document.get("components") or {}).items():
        if "fmu" not in given:
            raise ScenarioError(
                f"key components.{name}.fmu{suffix}: missing (a variant may change a part's parameters; a part "
                "it adds needs its fmu: too)"
            )
        fmu = _relative(given["fmu"], source)
        if not fmu.is_file():
            raise ScenarioError(
                f"key components.{name}.fmu{suffix}: no such file {fmu} (build the FMU, or fix the path: it is "
                "relative to the scenario file)"
            )
        parts.append(Part(name, fmu, tuple((given.get("parameters") or {}).items()), given["fmu"]))
    names = ("plant", "controller", *(part.name for part in parts))
    connections = None
    if "connections" in document:
        connections = []
        for index, text in enumerate(document["connections"]):
            sides = text.split("->")
            if len(sides) != 2:
                raise ScenarioError(
                    f"key connections[{index}]{suffix}: {text.strip()!r} is not one connection (write one "
                    "'component.variable -> component.variable' per item)"
                )
            start, end = (Port.parse(side.strip()) for side in sides)
            for port in (start, end):
                if port.component not in names:
                    raise ScenarioError(
                        f"key connections[{index}]{suffix}: {text.strip()!r} names the component {port.component!r}, "
                        f"which the scenario does not have (its components: {', '.join(names)})"
                    )
            connections.append(Connection(start, end))
        plant_doc = document.get("plant") or {}
        for given in ("F_E", *(plant_doc.get("inputs") or {})):
            fed = [c for c in connections if c.end == Port("plant", given)]
            if fed and (given in plant_doc or given in (plant_doc.get("inputs") or {})):
                key = "F_E" if given == "F_E" else f"inputs.{given}"
                raise ScenarioError(
                    f"key plant.{key}{suffix}: the connection {fed[0]} feeds plant.{given} too (remove the key or the "
                    "connection)"
                )
    record = None
    if "record" in document:
        record = tuple(Port.parse(text) for text in document["record"])
        for index, port in enumerate(record):
            if port.component not in names:
                raise ScenarioError(
                    f"key record[{index}]{suffix}: {str(port)!r} names the component {port.component!r}, which the "
                    f"scenario does not have (its components: {', '.join(names)})"
                )
    return Wiring(tuple(parts), None if connections is None else tuple(connections), record)


def _build_run(document: Mapping[str, Any], variant: str | None, source: Path | None) -> Run:
    stroke = document["stroke"]
    geometry = MechanismParameters()
    upper, lower = toggle_limit(geometry), folded_limit(geometry)
    suffix = f" (variant {variant})" if variant else ""
    for key in ("x_start", "x_target"):
        value = stroke[key]
        if not lower + SINGULARITY_MARGIN - 1e-12 <= value <= upper - SINGULARITY_MARGIN + 1e-12:
            raise ScenarioError(
                f"key stroke.{key}{suffix}: {value} m is outside the working range of the linkage (must lie between"
                f" {lower + SINGULARITY_MARGIN:.4f} m and {upper - SINGULARITY_MARGIN:.4f} m: {SINGULARITY_MARGIN * 1e3:.0f} mm"
                f" from the folded position {lower:.4f} m and the toggle position {upper:.4f} m, where the"
                f" linkage is singular)"
            )
    if abs(stroke["x_target"] - stroke["x_start"]) < MIN_STROKE:
        raise ScenarioError(
            f"key stroke.x_target{suffix}: {stroke['x_target']} m is within {MIN_STROKE * 1e3:g} mm of x_start"
            f" ({stroke['x_start']} m): a stroke needs a length (move x_target)"
        )
    for name in (document.get("plant") or {}).get("parameters") or {}:
        if name in OWN_KEYS:
            raise ScenarioError(
                f"key plant.parameters.{name}{suffix}: {name} has its own key; set {OWN_KEYS[name]} instead"
            )
    t_end, T_s = float(document["t_end"]), float(document["T_s"])
    if T_s > t_end:
        raise ScenarioError(f"key T_s: {T_s} s is longer than t_end = {t_end} s (make T_s < t_end)")
    if abs(round(t_end / T_s) * T_s - t_end) > 1e-9 * t_end:
        raise ScenarioError(f"key t_end: {t_end} s is not a whole number of samples T_s = {T_s} s")
    plant_doc = document.get("plant", {})
    controller_doc = document.get("controller", {})
    plant = PlantSettings(
        F_E=_input_signal(plant_doc.get("F_E", 0.0), "F_E", t_end, suffix, source),
        m_B=float(plant_doc.get("m_B", 4.43)),
        mu=float(plant_doc.get("mu", 0.2)),
        current_loop=plant_doc.get("current_loop", "first_order"),
        friction_model=plant_doc.get("friction_model", "paper"),
        mu_s=float(plant_doc["mu_s"]) if "mu_s" in plant_doc else None,
        K=float(plant_doc["K"]) if "K" in plant_doc else None,
        rated_current=float(plant_doc.get("rated_current", PlantSettings.rated_current)),
        working_range=_working_range(plant_doc.get("working_range"), geometry, suffix),
        parameters=dict(plant_doc.get("parameters", {})),
        inputs=_other_inputs(plant_doc.get("inputs") or {}, t_end, suffix, source),
    )
    controller = ControllerSettings(
        objective=controller_doc.get("objective", "x_B"),
        gains=ControllerGains(**{k: float(v) for k, v in controller_doc.get("gains", {}).items()}),
        nominal_m_B=float(controller_doc.get("nominal_m_B", 4.43)),
        law=controller_doc.get("law", "paper"),
        C_I=float(controller_doc.get("C_I", ControllerSettings.C_I)),
        K_I=float(controller_doc.get("K_I", ControllerSettings.K_I)),
        i_max=float(controller_doc.get("i_max", ControllerSettings.i_max)),
        **_user_controller(controller_doc, suffix, source),
    )
    trajectory = _trajectory(stroke, controller, t_end, suffix)
    system = _wiring(document, source, suffix)
    fmu = document.get("fmu")
    fmu_path = None
    if fmu is not None:
        fmu_path = Path(fmu) if source is None or Path(fmu).is_absolute() else (source.parent / fmu)
    return Run(
        scenario=document["name"],
        variant=variant,
        source=source,
        description=document.get("description", ""),
        fmu=fmu_path,
        t_end=t_end,
        T_s=T_s,
        x_start=float(stroke["x_start"]),
        x_target=float(stroke["x_target"]),
        trajectory=trajectory,
        plant=plant,
        controller=controller,
        resolved={k: v for k, v in document.items() if k != "variants"},
        coupling=document.get("coupling", "gauss-seidel"),
        system=system,
    )


def runs_from_document(document: Any, source: Path | None = None) -> list[Run]:
    """Every run a scenario document defines: one per variant, or one if it has none."""
    validate_document(document)
    variants = document.get("variants")
    if not variants:
        return [_build_run(document, None, source)]
    base = {k: v for k, v in document.items() if k != "variants"}
    return [_build_run(merge_documents(base, override), name, source) for name, override in variants.items()]


def read_scenario(path: Path) -> tuple[Any, list[Run]]:
    """A scenario file's parsed document and its runs (`yaml_loader`, then `runs_from_document`).
    Raises ScenarioError with 'FILE: problem'."""
    from toggle_cosim.files.yaml_loader import YamlError, load_yaml

    path = Path(path)
    try:
        document = load_yaml(path, "scenario file")
    except YamlError as error:
        raise ScenarioError(str(error)) from error
    if document is None:
        raise ScenarioError(f"{path}: the file is empty (a scenario needs name, t_end, T_s and stroke)")
    try:
        return document, runs_from_document(document, path)
    except ScenarioError as error:
        raise ScenarioError(f"{path}: {error}") from error


def load_scenario(path: Path) -> list[Run]:
    """Read and validate a scenario file: its runs. Raises ScenarioError with 'FILE: problem'."""
    return read_scenario(path)[1]

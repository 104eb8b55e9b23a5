"""Linearise the plant FMU about an operating point (`trim`): A, B, C, D with named states,
inputs and outputs, their units, and an error estimate.

The plant FMU offers no directional derivatives (docs/fmu-export.md says why), so the
derivatives are central differences of its Model Exchange interface (state derivatives and
outputs), Richardson-extrapolated (`design.differences`), with a step per state from its value
and the FMU's nominal value; the error estimate is reported per matrix.

Two sets of states:

* ``"manifold"`` (the default): the one degree of freedom of the mechanism, (θ1, ω1), and the
  current loop's state i_lag (dropped under an ideal current loop, where i_q = i_q*). The FMU
  keeps the index-reduced DAE's dependent angles and rates as states, held on the constraint
  manifold by Baumgarte terms; the manifold (Φ = 0, Φ_q q̇ = 0) is invariant, so the model on it
  is exact: each column is the derivative along the manifold's tangent, δq = t δθ1 with
  Φ_q t = 0 (Φ_q from central differences of the FMU's outputs Φ1, Φ2), δq̇ = t δω1.
* ``"fmu"``: every continuous state of the FMU, as the FMU defines them (ten for the shipped
  plant: the dependent angles and rates, whose constraint modes sit at −baumgarte, and the
  energy integrals, at 0).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from toggle_cosim.design.differences import Derivatives, FloatArray, directional_derivatives, step_for
from toggle_cosim.design.model_exchange import ModelExchangePlant, state_info, variable_unit
from toggle_cosim.design.roles import SHIPPED, PlantStates
from toggle_cosim.design.trim import INPUTS, OperatingPoint, TrimError, open_at
from toggle_cosim.plant.contract import PlantInterface
from toggle_cosim.runs.definition import Run

__all__ = ["DEFAULT_OUTPUTS", "LinearModel", "linearize", "short_name"]

DEFAULT_OUTPUTS = ("x_B", "v_B", "theta1")
COORDINATES = ("manifold", "fmu")


def short_name(state: str) -> str:
    """A state's name without its component's prefix (mechanism.theta1 -> theta1)."""
    return state.rsplit(".", 1)[-1]


@dataclass(frozen=True)
class LinearModel:
    """ẋ = A x + B u, y = C x + D u in deviations from `point`; `system` is the python-control
    StateSpace with the same names. Units by signal name in `units`."""

    A: FloatArray
    B: FloatArray
    C: FloatArray
    D: FloatArray
    states: tuple[str, ...]  # short names (theta1, omega1, i_lag)
    inputs: tuple[str, ...]  # iq_ref, F_E
    outputs: tuple[str, ...]  # x_B, v_B, theta1, and any asked for
    units: Mapping[str, str]  # unit of every state, input and output, by name
    fmu_states: tuple[str, ...]  # the FMU's names of the states (mechanism.theta1, ...)
    point: OperatingPoint
    coordinates: Literal["manifold", "fmu"]
    error: Mapping[str, float]  # the largest estimated absolute error of each matrix, A B C D
    steps: Mapping[str, float] = field(default_factory=dict)  # the central differences' step per state and input
    method: str = ""  # how the derivatives were taken, and why

    @property
    def system(self) -> Any:
        """The model as a continuous-time `control.StateSpace` (python-control, the extra [design])."""
        try:
            import control
        except ModuleNotFoundError:
            raise ModuleNotFoundError(
                "LinearModel.system needs python-control: pip install 'toggle-cosim[design]' (or 'toggle-cosim[all]')",
                name="control",
            ) from None

        return control.ss(
            self.A,
            self.B,
            self.C,
            self.D,
            states=list(self.states),
            inputs=list(self.inputs),
            outputs=list(self.outputs),
            name="plant",
        )

    @property
    def relative_error(self) -> float:
        """The largest error estimate relative to the largest entry of its matrix."""
        scales = {name: float(np.max(np.abs(getattr(self, name)), initial=0.0)) for name in "ABCD"}
        return max((self.error[name] / scales[name] for name in "ABCD" if scales[name] > 0), default=0.0)

    def eigenvalues(self) -> np.ndarray:
        return np.linalg.eigvals(self.A)

    def as_arrays(self) -> dict[str, Any]:
        """Everything as arrays and strings, for an .npz or .mat file."""
        point = self.point
        return {
            "A": self.A,
            "B": self.B,
            "C": self.C,
            "D": self.D,
            "states": np.array(self.states),
            "inputs": np.array(self.inputs),
            "outputs": np.array(self.outputs),
            "state_units": np.array([self.units[n] for n in self.states]),
            "input_units": np.array([self.units[n] for n in self.inputs]),
            "output_units": np.array([self.units[n] for n in self.outputs]),
            "fmu_states": np.array(self.fmu_states),
            "x0": np.array([point.states[n] for n in self.fmu_states]),
            "u0": np.array([point.iq_ref, point.F_E]),
            "y0": np.array([point.outputs[n] for n in self.outputs]),
            "x_B": point.x_B,
            "m_B": point.m_B,
            "coordinates": self.coordinates,
            "error_A": self.error["A"],
            "error_B": self.error["B"],
            "error_C": self.error["C"],
            "error_D": self.error["D"],
            "friction_free": point.friction_free,
            "warnings": np.array(point.warnings if point.warnings else ("",)),
            "method": self.method,
        }


def _tangent(
    me: ModelExchangePlant,
    x0: FloatArray,
    u0: FloatArray,
    index: Mapping[str, int],
    roles: PlantStates,
    steps: FloatArray,
) -> FloatArray:
    """δq per δθ1 along the constraint manifold: Φ_q t = 0 with t[θ1] = 1 (Φ from the FMU's outputs)."""
    residuals = [me.reference(name) for name in roles.residuals]
    positions = [index[name] for name in roles.positions]
    directions = np.zeros((len(x0), len(positions)))
    for j, k in enumerate(positions):
        directions[k, j] = 1.0
    jac = directional_derivatives(lambda x: me.evaluate(x, u0, residuals)[1], x0, directions, steps[positions]).value
    dependent = np.linalg.solve(jac[:, 1:], -jac[:, 0])
    t = np.zeros(len(x0))
    t[positions] = (1.0, *dependent)
    return t


def _checked_outputs(
    plant: PlantInterface, extra: Sequence[str], coordinates: str, roles: PlantStates
) -> tuple[str, ...]:
    """x_B, v_B, theta1 and the outputs asked for: recorded outputs of the plant, and on the
    manifold only those that depend on no state the manifold leaves out (the energy integrals)."""
    outputs = tuple(dict.fromkeys((*DEFAULT_OUTPUTS, *extra)))
    recorded = plant.recorded_outputs
    unknown = [name for name in outputs if name not in recorded]
    if unknown:
        raise TrimError(
            f"output {', '.join(map(repr, unknown))}: not a recorded output of {plant.path} "
            f"(choose from {', '.join(recorded)})"
        )
    if coordinates == "manifold":
        states = set(state_info(plant).names)
        kept = {*roles.required}
        for unknown_ in plant.model_description.outputs:
            name = unknown_.variable.name
            left_out = [d.name for d in unknown_.dependencies or () if d.name in states and d.name not in kept]
            if name in outputs and left_out:
                raise TrimError(
                    f"output {name!r} depends on {', '.join(left_out)}, a state the manifold coordinates leave out "
                    "(an energy integral); linearise with coordinates='fmu' (--coordinates fmu) to have it"
                )
    return outputs


def linearize(
    run: Run,
    point: OperatingPoint,
    plant: PlantInterface,
    outputs: Sequence[str] = (),
    coordinates: Literal["manifold", "fmu"] = "manifold",
    roles: PlantStates = SHIPPED,
) -> LinearModel:
    """The plant linearised about `point` (from `trim` of the same run and plant): see the module's docstring."""
    if coordinates not in COORDINATES:
        raise TrimError(f"coordinates {coordinates!r}: choose manifold or fmu")
    names_out = _checked_outputs(plant, outputs, coordinates, roles)
    with open_at(run, plant, point.x_B) as me:
        names = me.states.names
        index = {name: k for k, name in enumerate(names)}
        x0 = np.array([point.states[name] for name in names])
        u0 = np.array([point.iq_ref, point.F_E])
        nominals = _nominals(me, names)
        steps = np.array([step_for(x0[k], nominals[k]) for k in range(len(names))])
        if coordinates == "manifold":
            kept = [roles.coordinate, roles.rate]
            if run.plant.current_loop != "ideal":
                kept.append(roles.current)
            t = _tangent(me, x0, u0, index, roles, steps)
            state_directions = []
            for name in kept:
                d = np.zeros(len(names))
                if name == roles.coordinate:
                    d[[index[n] for n in roles.positions]] = t[[index[n] for n in roles.positions]]
                elif name == roles.rate:
                    d[[index[n] for n in (roles.rate, *roles.dependent_rates)]] = t[[index[n] for n in roles.positions]]
                else:
                    d[index[name]] = 1.0
                state_directions.append(d)
            X = np.column_stack(state_directions)
        else:
            kept = list(names)
            X = np.eye(len(names))
        rows = [index[name] for name in kept]
        out_refs = [me.reference(name) for name in names_out]
        n, m = len(names), len(INPUTS)

        def f(z: FloatArray) -> FloatArray:
            derivatives, values = me.evaluate(z[:n], z[n:], out_refs)
            return np.concatenate([derivatives[rows], values])

        directions = np.zeros((n + m, len(kept) + m))
        directions[:n, : len(kept)] = X
        directions[n:, len(kept) :] = np.eye(m)
        state_steps = [steps[index[name]] for name in kept]
        input_steps = [step_for(u0[0], 1.0), step_for(u0[1], 1.0)]
        J = directional_derivatives(f, np.concatenate([x0, u0]), directions, np.array(state_steps + input_steps))
        units = {short_name(name): me.states.units[index[name]] for name in kept}
    return _model(J, kept, names_out, units, point, coordinates, plant, state_steps + input_steps)


def _nominals(me: ModelExchangePlant, names: Sequence[str]) -> FloatArray:
    return me.nominals if me.nominals is not None else np.ones(len(names))


def _model(
    J: Derivatives,
    kept: list[str],
    names_out: tuple[str, ...],
    units: dict[str, str],
    point: OperatingPoint,
    coordinates: Literal["manifold", "fmu"],
    plant: PlantInterface,
    steps: list[float],
) -> LinearModel:
    ns, m = len(kept), len(INPUTS)
    value, error = J.value, J.error
    blocks = {
        "A": (slice(0, ns), slice(0, ns)),
        "B": (slice(0, ns), slice(ns, ns + m)),
        "C": (slice(ns, None), slice(0, ns)),
        "D": (slice(ns, None), slice(ns, ns + m)),
    }
    matrices = {name: value[rows, cols].copy() for name, (rows, cols) in blocks.items()}
    errors = {name: float(np.max(error[rows, cols], initial=0.0)) for name, (rows, cols) in blocks.items()}
    variables = {v.name: v for v in plant.model_description.modelVariables}
    units.update({name: variable_unit(variables[name]) for name in (*INPUTS, *names_out)})
    states = tuple(short_name(name) for name in kept)
    return LinearModel(
        A=matrices["A"],
        B=matrices["B"],
        C=matrices["C"],
        D=matrices["D"],
        states=states,
        inputs=INPUTS,
        outputs=names_out,
        units=units,
        fmu_states=tuple(kept),
        point=point,
        coordinates=coordinates,
        error=errors,
        steps=dict(zip((*states, *INPUTS), steps, strict=True)),
        method=_method(plant),
    )


def _method(plant: PlantInterface) -> str:
    """How the derivatives are taken: central differences, saying whether the FMU offers directional derivatives."""
    offered = bool(getattr(plant.model_description.modelExchange, "providesDirectionalDerivative", False))
    why = (
        "the FMU declares directional derivatives, which linearize does not use yet"
        if offered
        else "the FMU provides no directional derivatives (providesDirectionalDerivative is false)"
    )
    return f"central differences, Richardson-extrapolated over steps h, h/2, h/4: {why}"

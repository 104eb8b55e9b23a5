"""A system's stepping plan: every value of a sample in one flat buffer, and the tables that say
which slot feeds which (`build_plan`). The Python execution (`cosim.execution.algorithm`) and the C loop
(`cosim.execution.system_loop`) both run a plan, so they make the same calls with the same values.

The buffer holds, per component in stepping order, its outputs and then its inputs. Each fed
input slot has one feed: another slot (an output, times `factor` plus `offset`, or copied when
the connection is the identity) or a column of the run's signal table (a number or a signal in
time sampled at every t_k, `signals`).

One sample k under Gauss-Seidel (`coupling: gauss-seidel`):

    for each component c in order:  compute and set c's early inputs;  get c's outputs
    compute the late inputs;  record row k;  if k < n: set the late inputs;  doStep every c

An input is early when its feed is an output of a component before c in the order, late
otherwise: fed by a later component (its component reads its outputs before that value exists;
it has no direct feedthrough, `system.graph`) or by a signal. A reference signal (`references`:
a tracking controller FMU's x_ref, v_ref, a_ref) goes with the component's measurements: early
when every input a connection feeds it is early, so the outputs read at t_k are computed from
the measurements and the reference at t_k, as the built-in law computes them; late otherwise
(and under Jacobi), beside the measurements it steps with. Any other signal's sample at t_k is sent
after the component's outputs at t_k are read, with the values it steps with, as FMPy and
libcosim send theirs: the outputs at t_k are those of the inputs
the component stepped with, so a step in a load shows in the outputs one sample later. Under
Jacobi every input is late: each component's outputs at t_k are read with the inputs it stepped
with, and all inputs are then set from them, as libcosim's fixed-step algorithm does.

The initialisation pass (`init_early`) sets signals early too: every input is set before the
outputs at t = 0 are read, as the pair initialises its plant with sample 0's inputs.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from toggle_cosim.system.model import Connection, Interface, Port

__all__ = ["Plan", "build_plan", "SIGNAL"]

SIGNAL = -1  # feed_source[i] = SIGNAL - j: column j of the signal table


@dataclass(frozen=True)
class Plan:
    """The tables of one system's run (module docstring). Per component, in stepping order:
    `outputs[c]` and `inputs[c]` the buffer slots of its outputs and of its fed inputs (their
    names in `output_names[c]`, `input_names[c]`), `early[c]` the positions in inputs[c] set
    before its outputs are read (a signal's only for a reference, module docstring). `feed_source[s]`,
    `feed_factor[s]`, `feed_offset[s]` feed the input slot s (an output slot, or SIGNAL - j for
    signal column j; factor 1 and offset 0: a copy). `late[c]` the positions in inputs[c] set
    after every output of the sample is known (`init_early[c]`, `init_late[c]`: of the
    initialisation pass); `fed_by[c]` what feeds each of inputs[c], in words ("component
    'plant': its output x_B", "the signal fed to plant.F_E"). `record` are the slots recorded in
    trace columns 1 .., named `names[1:]`."""

    order: tuple[str, ...]
    output_names: tuple[tuple[str, ...], ...]
    input_names: tuple[tuple[str, ...], ...]
    outputs: tuple[tuple[int, ...], ...]
    inputs: tuple[tuple[int, ...], ...]
    early: tuple[tuple[int, ...], ...]
    feed_source: np.ndarray  # int64, one per buffer slot (unused for output slots: 0)
    feed_factor: np.ndarray  # float64
    feed_offset: np.ndarray  # float64
    signals: tuple[Port, ...]  # the input each signal column feeds
    record: tuple[int, ...]
    names: tuple[str, ...]
    size: int
    jacobi: bool
    # the early inputs of the Gauss-Seidel order and every signal, whatever the coupling:
    # initialisation runs one Gauss-Seidel pass, so every connected input starts from its
    # source's initial output (the fixed point libcosim's initialisation iterates to)
    init_early: tuple[tuple[int, ...], ...] = ()
    late: tuple[tuple[int, ...], ...] = ()
    init_late: tuple[tuple[int, ...], ...] = ()
    fed_by: tuple[tuple[str, ...], ...] = ()

    def slot(self, port: Port) -> int:
        """The buffer slot of a component's output or fed input."""
        c = self.order.index(port.component)
        if port.variable in self.output_names[c]:
            return self.outputs[c][self.output_names[c].index(port.variable)]
        return self.inputs[c][self.input_names[c].index(port.variable)]


def build_plan(
    order: Sequence[str],
    interfaces: Mapping[str, Interface],
    connections: Sequence[Connection],
    signals: Sequence[Port],
    record: Sequence[Port] | None,
    jacobi: bool,
    references: Collection[Port] = (),
) -> Plan:
    """The plan of a system stepped in `order` (`system.graph.gauss_seidel_order`, for Jacobi too:
    its initialisation pass follows it). `signals` are the inputs fed by the signal table's columns, in its column order;
    `record` the ports recorded (None: every output and fed input of every component, in
    stepping order). `references`: signals a component reads with what it measures (a tracking
    controller's x_ref, v_ref, a_ref), set with its measurements: early when every input a
    connection feeds it is early (module docstring). Raises ValueError for an input fed twice
    (the caller has checked names)."""
    fed: dict[Port, object] = {}
    for connection in connections:
        if connection.end in fed:
            raise ValueError(f"{connection.end} is fed twice ({fed[connection.end]} and {connection})")
        fed[connection.end] = connection
    for j, port in enumerate(signals):
        if port in fed:
            raise ValueError(f"{port} is fed twice (a connection and a signal)")
        fed[port] = j
    output_names, input_names, outputs, inputs = [], [], [], []
    slots: dict[Port, int] = {}
    size = 0
    for name in order:
        interface = interfaces[name]
        output_names.append(tuple(interface.outputs))
        outputs.append(tuple(range(size, size + len(interface.outputs))))
        for variable in interface.outputs:
            slots[Port(name, variable)] = size
            size += 1
        own = tuple(v for v in interface.inputs if Port(name, v) in fed)
        input_names.append(own)
        inputs.append(tuple(range(size, size + len(own))))
        for variable in own:
            slots[Port(name, variable)] = size
            size += 1
    position = {name: c for c, name in enumerate(order)}
    source = np.zeros(size, dtype=np.int64)
    factor = np.ones(size, dtype=np.float64)
    offset = np.zeros(size, dtype=np.float64)
    early, init_early, fed_by = [], [], []
    for c, name in enumerate(order):
        own_early, own_init, measured, paced, words = [], [], [], [], []
        for i, variable in enumerate(input_names[c]):
            port = Port(name, variable)
            feed, slot = fed[port], slots[port]
            if isinstance(feed, Connection):
                source[slot] = slots[feed.start]
                factor[slot], offset[slot] = feed.factor, feed.offset
                measured.append(position[feed.start.component] < c)
                if measured[-1]:
                    own_early.append(i)
                    own_init.append(i)
                words.append(f"component {feed.start.component!r}: its output {feed.start.variable}")
            else:
                source[slot] = SIGNAL - feed
                own_init.append(i)  # a signal: set early only in the initialisation pass
                if port in references:
                    paced.append(i)
                words.append(f"the signal fed to {port}")
        if paced and measured and all(measured):  # a reference goes with the measurements
            own_early = sorted(own_early + paced)
        init_early.append(tuple(own_init))
        early.append(() if jacobi else tuple(own_early))
        fed_by.append(tuple(words))
    if record is None:
        chosen = [Port(name, v) for c, name in enumerate(order) for v in (*output_names[c], *input_names[c])]
    else:
        chosen = list(record)
    return Plan(
        order=tuple(order),
        output_names=tuple(output_names),
        input_names=tuple(input_names),
        outputs=tuple(outputs),
        inputs=tuple(inputs),
        early=tuple(early),
        feed_source=source,
        feed_factor=factor,
        feed_offset=offset,
        signals=tuple(signals),
        record=tuple(slots[port] for port in chosen),
        names=("time", *(str(port) for port in chosen)),
        size=size,
        jacobi=jacobi,
        init_early=tuple(init_early),
        late=tuple(_others(len(input_names[c]), early[c]) for c in range(len(order))),
        init_late=tuple(_others(len(input_names[c]), init_early[c]) for c in range(len(order))),
        fed_by=tuple(fed_by),
    )


def _others(count: int, chosen: Sequence[int]) -> tuple[int, ...]:
    """The positions 0 .. count - 1 not in `chosen`, in order."""
    taken = set(chosen)
    return tuple(i for i in range(count) if i not in taken)

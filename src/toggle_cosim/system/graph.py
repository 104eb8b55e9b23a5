"""The order a system is stepped in, from its connections and each component's direct
dependencies (after libcosim's and the SSP standard's reading of connections).

Ports are the nodes: a connection is an edge start -> end, and an output that depends directly
on an input (`Interface.depends`) an edge input -> output. A cycle is an algebraic loop: no
order of calls gives every value before it is needed (`AlgebraicLoop` names it).

Gauss-Seidel steps components in an order where every component comes after those whose
outputs feed one of its direct-feedthrough inputs; among components free to go, the system's
own order (the plant first) decides. An input with no direct feedthrough may be fed by a
component later in the order: it is set after every output of the sample is known. Where no
such order exists only because of outputs nothing is connected to (the plant's electrical
power depends directly on its current command, which the controller computes from the plant's
position), only the connected outputs count: the others are recorded as read, before the
inputs that come later in the sample are set (as the plant + controller loop always has).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

from toggle_cosim.system.model import Connection, Interface

__all__ = ["AlgebraicLoop", "algebraic_loop", "gauss_seidel_order"]


class AlgebraicLoop(ValueError):
    """A cycle through connections and direct dependencies; `cycle` lists its ports."""

    def __init__(self, cycle: Sequence[str], message: str) -> None:
        super().__init__(message)
        self.cycle = tuple(cycle)


def _port_edges(connections: Sequence[Connection], interfaces: Mapping[str, Interface]) -> dict[str, list[str]]:
    edges: dict[str, list[str]] = {}
    for connection in connections:
        edges.setdefault(str(connection.start), []).append(str(connection.end))
    for component, interface in interfaces.items():
        for output in interface.outputs:
            for variable in interface.depends.get(output, ()):
                edges.setdefault(f"{component}.{variable}", []).append(f"{component}.{output}")
    return edges


def algebraic_loop(connections: Sequence[Connection], interfaces: Mapping[str, Interface]) -> list[str] | None:
    """A cycle of ports (first = last) through the connections and direct dependencies, or None."""
    edges = _port_edges(connections, interfaces)
    state: dict[str, int] = {}  # 1: on the path, 2: done
    for root in list(edges):
        if root in state:
            continue
        path: list[str] = []
        stack: list[tuple[str, int]] = [(root, 0)]
        state[root] = 1
        path.append(root)
        while stack:
            node, index = stack[-1]
            following = edges.get(node, ())
            if index < len(following):
                stack[-1] = (node, index + 1)
                nxt = following[index]
                if state.get(nxt) == 1:
                    return [*path[path.index(nxt) :], nxt]
                if nxt not in state:
                    state[nxt] = 1
                    path.append(nxt)
                    stack.append((nxt, 0))
            else:
                stack.pop()
                path.pop()
                state[node] = 2
    return None


def gauss_seidel_order(
    components: Sequence[str], connections: Sequence[Connection], interfaces: Mapping[str, Interface]
) -> tuple[str, ...]:
    """The components in the order Gauss-Seidel steps them (module docstring). Raises
    AlgebraicLoop for a cycle of ports, and for a cycle of components that no single pass can
    serve (each needs the other's output first through different ports)."""
    cycle = algebraic_loop(connections, interfaces)
    if cycle is not None:
        raise AlgebraicLoop(
            cycle,
            f"an algebraic loop {' -> '.join(cycle)} (through the connections and the components' direct "
            "dependencies): break it, e.g. with a component without direct feedthrough in the loop",
        )
    connected = {(c.start.component, c.start.variable) for c in connections}
    strict = _order(components, connections, interfaces, lambda _component, _output: True)
    if strict is not None:
        return strict
    loose = _order(components, connections, interfaces, lambda component, output: (component, output) in connected)
    if loose is not None:
        return loose
    waiting = [name for name in components]
    raise AlgebraicLoop(
        waiting,
        f"the components {', '.join(waiting)} each need another's output first through direct feedthrough "
        "(no Gauss-Seidel order serves them; use coupling: jacobi or break the chain)",
    )


def _order(
    components: Sequence[str],
    connections: Sequence[Connection],
    interfaces: Mapping[str, Interface],
    counts: Callable[[str, str], bool],
) -> tuple[str, ...] | None:
    """Components in an order where each comes after every component feeding an input on which an
    output of it that `counts` depends directly; None if there is none."""
    before: dict[str, set[str]] = {name: set() for name in components}
    for connection in connections:
        start, end = connection.start.component, connection.end.component
        interface = interfaces[end]
        if start != end and any(
            connection.end.variable in interface.depends.get(output, ()) and counts(end, output)
            for output in interface.outputs
        ):
            before[end].add(start)
    order: list[str] = []
    done: set[str] = set()
    while len(order) < len(components):
        ready = [name for name in components if name not in done and before[name] <= done]
        if not ready:
            return None
        order.append(ready[0])
        done.add(ready[0])
    return tuple(order)

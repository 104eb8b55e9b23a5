"""The package's import graph, read from its `import` statements (AST): no module imports
itself back through others, and the co-simulation parts reach no private attribute of another
object. A graph with a cycle must be reported, so the finder is checked on a known cycle."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src"


def _modules(root: Path) -> dict[str, Path]:
    found = {}
    for path in root.rglob("*.py"):
        parts = list(path.relative_to(root.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


def _imported(name: str, path: Path, modules: dict[str, Path], lazy: bool) -> set[str]:
    """The package's modules `name` imports: at import time (module level, also under `if`
    and `try`, e.g. TYPE_CHECKING), and with `lazy` also those imported inside functions."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    nodes: list[ast.AST] = []
    pending: list[ast.AST] = list(tree.body)
    while pending:
        node = pending.pop()
        nodes.append(node)
        if lazy or not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            pending.extend(ast.iter_child_nodes(node))
    named: set[str] = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            named.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                prefix = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(prefix + ([base] if base else []))
            named.update(f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base for alias in node.names)
    found = set()
    for module in named:
        while module and module not in modules:
            module = module.rpartition(".")[0]
        if module and module != name:
            found.add(module)
    return found


def import_graph(root: Path, lazy: bool = False) -> dict[str, set[str]]:
    modules = _modules(root)
    return {name: _imported(name, path, modules, lazy) for name, path in modules.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_cycle_finder_finds_a_cycle(tmp_path: Path) -> None:
    package = tmp_path / "pkg"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "sub" / "__init__.py").write_text("")
    (package / "a.py").write_text("from pkg.sub import b\n")
    (package / "sub" / "b.py").write_text("from ..c import thing\n")
    (package / "c.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import pkg.a\n")
    (package / "d.py").write_text("def later():\n    from pkg import a\n")
    graph = import_graph(package)
    assert graph["pkg.c"] == {"pkg.a"} and graph["pkg.d"] == set()
    assert cycles(graph) == [["pkg.a", "pkg.c", "pkg.sub.b"]]
    (package / "a.py").write_text("import pkg.d\n")
    assert cycles(import_graph(package)) == []
    assert cycles(import_graph(package, lazy=True)) == [["pkg.a", "pkg.d"]]


def test_no_import_cycles_in_the_package() -> None:
    """No module imports itself back through others: at import time, nor through the imports
    inside functions (a lazy import that closes a loop is a cycle all the same)."""
    graph = import_graph(SRC / "toggle_cosim")
    assert len(graph) > 50 and "toggle_cosim.cosim.master" in graph
    assert cycles(graph) == []
    assert cycles(import_graph(SRC / "toggle_cosim", lazy=True)) == []


def script_graph(folder: Path) -> dict[str, set[str]]:
    """The scripts of a folder that import each other by their file names (each run with its
    folder first on sys.path, as benchmarks/ is): per script the others it imports, anywhere in it."""
    scripts = {path.stem: path for path in folder.glob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in scripts.items():
        named: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                named.update(alias.name.partition(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                named.add(node.module.partition(".")[0])
        graph[name] = {other for other in named if other in scripts and other != name}
    return graph


def test_the_benchmark_scripts_import_each_other_one_way_only() -> None:
    """bench.py prints system_bench.py's rows; what both need (the table, the paper runs, the
    pair's loop cost) is in bench_parts.py, so system_bench.py runs alone without bench.py."""
    graph = script_graph(SRC.parent / "benchmarks")
    assert "system_bench" in graph["bench"]  # the graph sees the scripts' imports
    assert cycles(graph) == []


def test_the_cosim_parts_import_each_other_one_way_only() -> None:
    """Within cosim/ not even a function-level import closes a loop (fmi_pointers, the C calls
    of any FMU, imports no other part of it), and the parts import no CLI or sweep."""
    graph = {
        name: {m for m in imports if m.startswith("toggle_cosim.cosim")}
        for name, imports in import_graph(SRC / "toggle_cosim", lazy=True).items()
        if name.startswith("toggle_cosim.cosim")
    }
    assert cycles(graph) == []
    assert graph["toggle_cosim.cosim.execution.fmi_pointers"] == set()
    full = import_graph(SRC / "toggle_cosim", lazy=True)
    for name in graph:
        assert not full[name] & {"toggle_cosim.cli", "toggle_cosim.experiments.sweep"}, name


def test_no_module_touches_a_private_attribute_of_another_object() -> None:
    """`x._name` only on self or cls (os._exit is public API), in the whole package: no module
    reads another's (or fmpy's) private attributes."""
    found = []
    for path in (SRC / "toggle_cosim").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__"):
                owner = ast.unparse(node.value)
                if owner not in ("self", "cls", "os"):
                    found.append(f"{path.name}:{node.lineno} {ast.unparse(node)}")
    assert found == []


# The package's layers, lowest first: a subpackage (or top-level module) imports only from
# layers below its own, counting imports inside functions too. `toggle_cosim` is the package
# root (its __version__). Runs (what one co-simulation is) sit below the plant, the plant below
# the co-simulation, which carries a run's outcome and summary; analysis reads outcomes and
# experiments (scenarios, sweeps, references) drive all of them; the CLI and the Python API
# are on top, side by side (neither imports the other).
LAYERS: tuple[tuple[str, ...], ...] = (
    ("toggle_cosim",),
    ("native", "interrupts", "limits", "process_tree"),
    ("messages", "relay"),
    ("files",),
    ("provenance",),  # SRMD records: below every builder and runner that writes one
    ("physics", "fmu_export", "signals"),
    ("system",),
    ("control",),
    ("controller_fmu",),
    ("runs",),
    ("plant",),
    ("cosim",),
    ("design",),
    ("analysis",),
    ("experiments",),
    ("ssp",),
    ("fmi_ls_ref",),
    ("cli", "api"),
    ("__main__",),  # `python -m toggle_cosim`: the command line as a program
)


def _part_of(module: str) -> str:
    """The subpackage (or top-level module) of toggle_cosim that `module` belongs to."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def subpackage_graph(graph: dict[str, set[str]]) -> dict[str, dict[str, set[str]]]:
    """Edges between subpackages, each with the module imports that make it (`a.x -> b.y`)."""
    grouped: dict[str, dict[str, set[str]]] = {}
    for module, imports in graph.items():
        for imported in imports:
            a, b = _part_of(module), _part_of(imported)
            if a != b:
                grouped.setdefault(a, {}).setdefault(b, set()).add(f"{module} -> {imported}")
    return grouped


def test_the_subpackages_import_downward_only() -> None:
    """Grouped by subpackage, the lazy import graph (imports in functions too) has no cycle and
    every edge goes to a lower entry of LAYERS; every subpackage has its place there."""
    graph = import_graph(SRC / "toggle_cosim", lazy=True)
    grouped = subpackage_graph(graph)
    tier = {name: rank for rank, names in enumerate(LAYERS) for name in names}
    assert {_part_of(module) for module in graph} <= set(tier), "a subpackage missing from LAYERS"
    assert cycles({a: set(targets) for a, targets in grouped.items()}) == []
    upward = sorted(
        why for a, targets in grouped.items() for b, whys in targets.items() if tier[b] >= tier[a] for why in whys
    )
    assert upward == []


def test_the_layer_check_sees_an_upward_import(tmp_path: Path) -> None:
    """A function-level import from a low layer into a higher one is an upward edge and a cycle."""
    package = tmp_path / "toggle_cosim"
    for sub in ("files", "cosim"):
        (package / sub).mkdir(parents=True)
        (package / sub / "__init__.py").write_text("")
    (package / "__init__.py").write_text("")
    (package / "cosim" / "run.py").write_text("from toggle_cosim.files.csv import write\n")
    (package / "files" / "csv.py").write_text("def write():\n    from toggle_cosim.cosim import run\n")
    grouped = subpackage_graph(import_graph(package, lazy=True))
    assert grouped == {
        "cosim": {"files": {"toggle_cosim.cosim.run -> toggle_cosim.files.csv"}},
        "files": {"cosim": {"toggle_cosim.files.csv -> toggle_cosim.cosim.run"}},
    }
    assert cycles({a: set(targets) for a, targets in grouped.items()}) == [["cosim", "files"]]
    assert subpackage_graph(import_graph(package)) == {
        "cosim": {"files": {"toggle_cosim.cosim.run -> toggle_cosim.files.csv"}}
    }


def test_no_module_imports_a_private_name_of_another() -> None:
    """`from toggle_cosim.x import _name` anywhere in the package (a function-level import too)
    would reach into another module's private part: what is shared is public."""
    found = []
    for path in (SRC / "toggle_cosim").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("toggle_cosim"):
                private = [a.name for a in node.names if a.name.startswith("_") and not a.name.startswith("__")]
                if private:
                    found.append(f"{path.relative_to(SRC)}:{node.lineno} {node.module}: {', '.join(private)}")
    assert found == []


# Inside cosim/, lowest first: the execution and its kinds (`cosim/execution/`: slaves, the plan
# stepped in Python and in C, checkpoints, the instance pool) know no run, scenario or process;
# the master's modules (`cosim/*.py`: a run as a system, its controller, outcome and figures) use
# the execution; the process isolation of runs (`cosim/isolation/`: supervision, the plant host,
# batches, exit reasons) runs the master in children and is used by nothing below it.
COSIM_TIERS: tuple[str, ...] = ("execution", "", "isolation")


def _cosim_tier(module: str) -> str | None:
    """The tier of a module of toggle_cosim.cosim (its subpackage, "" for the master's modules),
    None outside cosim/."""
    parts = module.split(".")
    if parts[:2] != ["toggle_cosim", "cosim"]:
        return None
    return parts[2] if len(parts) > 3 else ""


def cosim_upward(graph: dict[str, set[str]]) -> list[str]:
    """The imports inside cosim/ that go to a tier above the importer's (`COSIM_TIERS`)."""
    rank = {tier: i for i, tier in enumerate(COSIM_TIERS)}
    found = []
    for module, imports in graph.items():
        own = _cosim_tier(module)
        if own is None:
            continue
        for imported in imports:
            theirs = _cosim_tier(imported)
            if theirs is not None and rank[theirs] > rank[own]:
                found.append(f"{module} -> {imported}")
    return sorted(found)


def test_the_cosim_tiers_import_downward_only() -> None:
    """Every module of cosim/ is in a tier, and no import (in functions too) climbs a tier: the
    execution imports neither the master's modules nor the isolation, and the master's modules
    do not import the isolation. The execution also knows no run, scenario or experiment."""
    graph = import_graph(SRC / "toggle_cosim", lazy=True)
    tiers = {_cosim_tier(module) for module in graph} - {None}
    assert tiers == set(COSIM_TIERS), tiers
    assert cosim_upward(graph) == []
    execution = {m: imports for m, imports in graph.items() if _cosim_tier(m) == "execution"}
    assert len(execution) > 5
    above = {"toggle_cosim.runs", "toggle_cosim.experiments", "toggle_cosim.cli", "toggle_cosim.api"}
    reaching = sorted(
        f"{m} -> {i}"
        for m, imports in execution.items()
        for i in imports
        if any(i == a or i.startswith(f"{a}.") for a in above)
    )
    assert reaching == []


def test_the_tier_check_sees_an_import_that_climbs(tmp_path: Path) -> None:
    """An execution module importing the supervision is an upward import."""
    package = tmp_path / "toggle_cosim"
    for sub in ("cosim", "cosim/execution", "cosim/isolation"):
        (package / sub).mkdir(parents=True)
        (package / sub / "__init__.py").write_text("")
    (package / "__init__.py").write_text("")
    (package / "cosim" / "execution" / "slaves.py").write_text(
        "def f():\n    from toggle_cosim.cosim.isolation import supervision\n"
    )
    (package / "cosim" / "isolation" / "supervision.py").write_text("from toggle_cosim.cosim import master\n")
    (package / "cosim" / "master.py").write_text("from toggle_cosim.cosim.execution import slaves\n")
    assert cosim_upward(import_graph(package, lazy=True)) == [
        "toggle_cosim.cosim.execution.slaves -> toggle_cosim.cosim.isolation.supervision"
    ]

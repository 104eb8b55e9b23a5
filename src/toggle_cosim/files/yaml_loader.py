"""The one YAML loader of every input file (scenario, sweep, tolerances).

- safe: PyYAML's SafeLoader, plain data only;
- a regular file of at most `bounded_files.YAML_LIMIT` bytes, UTF-8;
- at most MAX_ALIASES aliases, MAX_DEPTH levels of nesting and MAX_NODES values after the
  aliases are expanded (an alias bomb is refused before it is built);
- duplicate keys in a mapping are refused (PyYAML keeps the last one silently);
- numbers as YAML 1.2 writes them: `5e-4`, `1E3`, `+2.5e+3` are floats (YAML 1.1, and so
  PyYAML, reads them as strings);
- every failure is one `YamlError` line naming the file and, where known, the line and column.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from toggle_cosim.files.bounded import YAML_LIMIT, InputFileError, read_bounded

MAX_ALIASES = 100
MAX_DEPTH = 32
MAX_NODES = 100_000


class YamlError(Exception):
    """A YAML input file that cannot be used; str() is the one-line message (file first)."""


class _Loader(yaml.SafeLoader):
    """SafeLoader with YAML 1.2 floats and duplicate keys refused."""

    def construct_mapping(self, node: Node, deep: bool = False) -> dict[Any, Any]:
        if isinstance(node, MappingNode):
            self.flatten_mapping(node)
            seen: dict[Any, Any] = {}
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=True)
                try:
                    duplicate = key in seen
                except TypeError:  # an unhashable key: let PyYAML say so
                    break
                if duplicate:
                    mark = key_node.start_mark
                    raise yaml.constructor.ConstructorError(
                        None, None, f"duplicate key {key!r} (first at line {seen[key].line + 1}); keep one", mark
                    )
                seen[key] = key_node.start_mark
        return super().construct_mapping(node, deep=deep)


_FLOAT_12 = re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$")
_Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_12, list("-+0123456789."))


class Dumper(yaml.SafeDumper):
    """SafeDumper that quotes strings this loader would read as numbers (`"1e5"`), so that what
    it writes reads back the same."""


Dumper.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_12, list("-+0123456789."))


def _where(mark: Any) -> str:
    return f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""


def _check_events(text: str) -> None:
    """Depth and alias count, from the event stream (not recursive, cheap)."""
    depth = aliases = 0
    for event in yaml.parse(text, Loader=_Loader):
        if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            depth += 1
            if depth > MAX_DEPTH:
                raise YamlError(f"nested more than {MAX_DEPTH} levels deep{_where(event.start_mark)} (flatten it)")
        elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            depth -= 1
        elif isinstance(event, yaml.AliasEvent):
            aliases += 1
            if aliases > MAX_ALIASES:
                raise YamlError(
                    f"more than {MAX_ALIASES} aliases (*name){_where(event.start_mark)}; write the values out"
                )


def _check_expansion(root: Node) -> None:
    """Values after alias expansion (memoised per node, so a bomb is counted, not built), and no
    alias inside the value it names."""
    sizes: dict[int, int] = {}
    open_nodes: set[int] = set()

    def size(node: Node) -> int:
        key = id(node)
        if key in sizes:
            return sizes[key]
        if key in open_nodes:
            raise YamlError(
                f"an alias inside the value it names{_where(node.start_mark)} (recursive data is not allowed)"
            )
        if isinstance(node, ScalarNode):
            return 1
        open_nodes.add(key)
        total = 1
        if isinstance(node, SequenceNode):
            for child in node.value:
                total += size(child)
        elif isinstance(node, MappingNode):
            for k, v in node.value:
                total += size(k) + size(v)
        open_nodes.discard(key)
        if total > MAX_NODES:
            raise YamlError(f"more than {MAX_NODES} values once its aliases are expanded{_where(node.start_mark)}")
        sizes[key] = total
        return total

    size(root)


def parse_yaml(text: str) -> Any:
    """Parse YAML text with the limits above; raises YamlError (message without a file name)."""
    try:
        _check_events(text)
        loader = _Loader(text)
        try:
            node = loader.get_single_node()
            if node is None:
                return None
            _check_expansion(node)
            return loader.construct_document(node)
        finally:
            loader.dispose()
    except YamlError:
        raise
    except yaml.reader.ReaderError as error:  # a control character: it has a position, not a mark
        lines = re.split("\r\n|[\n\r\x85\u2028\u2029]", text[: error.position])
        raise YamlError(
            f"YAML syntax error at line {len(lines)}, column {len(lines[-1]) + 1}: unacceptable character"
            f" #x{error.character:04x} ({error.reason})"
        ) from None
    except yaml.MarkedYAMLError as error:
        problem = " ".join(str(error.problem or error.context or "malformed YAML").split())
        raise YamlError(f"YAML syntax error{_where(error.problem_mark)}: {problem}") from None
    except yaml.YAMLError as error:
        raise YamlError(f"YAML error: {' '.join(str(error).split())}") from None
    except RecursionError:
        raise YamlError(f"nested too deeply (more than {MAX_DEPTH} levels)") from None
    except Exception as error:  # noqa: BLE001 - PyYAML's constructors raise plain errors ("!!int abc")
        raise YamlError(
            f"YAML value that cannot be converted ({' '.join(f'{type(error).__name__}: {error}'.split())})"
        ) from None


def load_yaml(path: Path | str, what: str = "YAML file") -> Any:
    """Read and parse the YAML file `path` (see the module doc); YamlError names the file."""
    path = Path(path)
    try:
        raw = read_bounded(path, YAML_LIMIT, what)
    except InputFileError as error:
        raise YamlError(str(error)) from None
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise YamlError(f"{path}: not UTF-8 text (byte {error.start}); save the {what} as UTF-8") from None
    try:
        return parse_yaml(text)
    except YamlError as error:
        raise YamlError(f"{path}: {error}") from None

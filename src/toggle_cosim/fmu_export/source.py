"""Read a Modelica package stored as a directory into one `modelica` IR program.

The `modelica` compiler (v0.0.205) parses one file at a time and does not assemble a package
split over files (`package.mo`, `package.order`, one class per file, each `within Pkg;`).
This module does that assembly, following the Modelica Language Specification 3.6, section
13.4 ("Mapping package/class structures to a hierarchical file system"): a directory with a
`package.mo` is a package, its `package.order` fixes the order of its members, and every other
`.mo` file or sub-directory with a `package.mo` is a member.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from modelica.ir import nodes as ir
from modelica.lang import ModelicaSyntaxError, parse


class ModelSourceError(Exception):
    """The Modelica source cannot be read: the message names the file and the problem."""


def _parse_file(path: Path) -> tuple[ir.Class, ...]:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise ModelSourceError(f"{path}: cannot read Modelica source ({error})") from error
    try:
        return parse(text, str(path)).classes
    except ModelicaSyntaxError as error:
        raise ModelSourceError(f"{path}: {error}") from error


def _member_names(directory: Path) -> list[str]:
    """Members in `package.order` order, then any not listed, alphabetically."""
    found = sorted(
        {p.stem for p in directory.glob("*.mo") if p.name != "package.mo"}
        | {p.name for p in directory.iterdir() if p.is_dir() and (p / "package.mo").is_file()}
    )
    order_file = directory / "package.order"
    listed = order_file.read_text(encoding="utf-8").split() if order_file.is_file() else []
    unknown = [name for name in listed if name not in found]
    if unknown:
        raise ModelSourceError(f"{order_file}: lists {', '.join(unknown)} but no such file or package exists")
    return listed + [name for name in found if name not in listed]


def load_package(directory: Path) -> ir.Class:
    """The package stored in `directory` as a single IR class with its members nested."""
    directory = Path(directory)
    package_file = directory / "package.mo"
    if not package_file.is_file():
        raise ModelSourceError(f"{directory}: not a Modelica package directory (no package.mo)")
    classes = _parse_file(package_file)
    if len(classes) != 1 or classes[0].restriction != "package" or classes[0].name != directory.name:
        raise ModelSourceError(f"{package_file}: must define exactly one package named {directory.name}")
    package = classes[0]
    members: list[ir.Class] = list(package.classes)
    for name in _member_names(directory):
        sub = directory / name
        if sub.is_dir():
            members.append(load_package(sub))
            continue
        parsed = _parse_file(directory / f"{name}.mo")
        if [c.name for c in parsed] != [name]:
            raise ModelSourceError(f"{directory / f'{name}.mo'}: must define exactly one class named {name}")
        members.extend(parsed)
    return dataclasses.replace(package, classes=tuple(members))


def load_program(path: Path) -> ir.Program:
    """A program from a package directory or a single `.mo` file."""
    path = Path(path)
    if path.is_dir():
        return ir.Program((load_package(path),))
    if path.suffix == ".mo" and path.is_file():
        return ir.Program(_parse_file(path))
    raise ModelSourceError(f"{path}: expected a Modelica package directory or a .mo file")

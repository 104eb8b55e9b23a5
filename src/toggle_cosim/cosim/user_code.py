"""What a scenario may run, and how: the user code a scenario names (`controller.python`'s
module, `controller.fmu`'s binary) found without running it, checked, and imported in its own
namespace.

A scenario may run

* a module beside the scenario file (``module.py``, or a package folder with ``__init__.py``),
  named by ``controller.python: "module:factory"`` (``"package.module:factory"``); or
* a module on the user's ``sys.path``: ``PYTHONPATH`` and the installed packages (only when no
  such module lies beside the scenario file); or
* a controller FMU, ``controller.fmu``.

A module beside the scenario file and a controller FMU are refused (`ControllerError`, one
line naming the file and the fix) when the file, or the folder that holds it, is writable by
group or others, or is owned by someone other than the user running the command (or root):
anyone who could have put it there could otherwise run code as that user. A module from
``sys.path`` is the user's own environment and is not checked.

A module beside the scenario file is imported from its file under a name of its own
(``toggle_cosim_scenario_N``, a fresh N at every import), never through ``sys.path`` and the
module cache: two scenario folders with a module of the same name each run their own, and each
import runs the module's top level again (no module-level state carries over from an earlier
import). `locate` and `check_owned` never import anything: the command calls them before any
run; `import_module` runs the user's code and belongs in the run's supervised child.
"""

from __future__ import annotations

import importlib
import importlib.machinery
import importlib.util
import itertools
import os
import re
import stat
import sys
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

from toggle_cosim.control.protocol import ControllerError

__all__ = ["Located", "check_owned", "import_module", "locate", "shown"]

PREFIX = "toggle_cosim_scenario_"  # the module names a scenario's own modules are imported under
_serial = itertools.count(1)
_origins: dict[str, str] = {}  # the name a scenario's module was imported under -> the name it was given


def shown(text: str) -> str:
    """`text` (a module's or class's name, a message) with each name a scenario's module was
    imported under put back as the scenario gave it (`toggle_cosim_scenario_3.PID` -> `mylaws.PID`)."""
    if PREFIX not in text:
        return text
    return re.sub(rf"\b{PREFIX}\d+\b", lambda found: _origins.get(found.group(0), found.group(0)), text)


@dataclass(frozen=True)
class Located:
    """Where a controller module is: `beside` the scenario file (`path` its .py file, `package`
    the top-level package folder or None for a plain module), or on sys.path (`path` None for a
    built-in or already imported module)."""

    name: str
    path: Path | None
    beside: bool
    package: Path | None = None


def _beside(name: str, folder: Path) -> Located | None:
    parts = name.split(".")
    top = folder / parts[0]
    if len(parts) == 1 and (folder / f"{parts[0]}.py").is_file():
        return Located(name, folder / f"{parts[0]}.py", True)
    if not (top / "__init__.py").is_file():
        return None
    stem = folder.joinpath(*parts)
    for candidate in (stem / "__init__.py", stem.with_suffix(".py")):
        if candidate.is_file():
            return Located(name, candidate, True, top)
    return None


def _on_sys_path(name: str) -> Located | None:
    """The module's spec found through sys.path without importing it (nor its parents)."""
    parts = name.split(".")
    if parts[0] in sys.modules or parts[0] in sys.builtin_module_names:
        return Located(name, None, False)
    search: list[str] | None = None
    spec = None
    for depth in range(1, len(parts) + 1):
        spec = importlib.machinery.PathFinder.find_spec(".".join(parts[:depth]), search)
        if spec is None:
            return None
        search = list(spec.submodule_search_locations or [])
        if depth < len(parts) and not search:
            return None
    origin = spec.origin if spec is not None else None
    return Located(name, Path(origin) if origin and origin not in ("built-in", "frozen") else None, False)


def locate(name: str, folder: Path | None) -> Located:
    """The module `name` (dotted), beside the scenario file in `folder` first, then on sys.path;
    nothing is imported. ControllerError (key controller.python) when neither has it."""
    folder = Path(os.path.abspath(folder)) if folder is not None else None  # a chdir later moves nothing
    found = _beside(name, folder) if folder is not None else None
    found = found or _on_sys_path(name)
    if found is None:
        where = f"beside the scenario file ({folder}) or on sys.path (PYTHONPATH)" if folder else "on sys.path"
        raise ControllerError(
            f"key controller.python: cannot import {name!r}: no such module; put it {where} (a package"
            " needs an __init__.py)"
        )
    if found.beside:
        for path in _checked_paths(found, folder):
            check_owned(path, "key controller.python")
    return found


def _checked_paths(found: Located, folder: Path | None) -> list[Path]:
    """The module's file, every folder from it up to the scenario's folder, and the bytecode
    caches (`__pycache__`) in them that Python would read a package's modules from."""
    assert found.path is not None
    paths = [found.path]
    parent = found.path.parent
    while True:
        paths.append(parent)
        if (parent / "__pycache__").exists():
            paths.append(parent / "__pycache__")
        if folder is None or parent == folder or parent == parent.parent:
            break
        parent = parent.parent
    return paths


def check_owned(path: Path, key: str) -> None:
    """Refuse (ControllerError naming `key` and the file) a file, or the folder holding it, that
    is writable by group or others or owned by another user than the one running (root's own
    files excepted): the file is code this command would run."""
    try:
        real = path.resolve()  # a link is judged by what it leads to, and by the folder the link is in
    except (OSError, RuntimeError) as error:  # a loop of links
        raise ControllerError(f"{key}: {path}: {getattr(error, 'strerror', None) or error}") from None
    targets = (path, real) if path.is_dir() else (path, path.parent, real, real.parent)
    for target in dict.fromkeys(targets):
        try:
            status = target.stat()
        except OSError as error:
            raise ControllerError(f"{key}: {target}: {error.strerror or error}") from None
        if status.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
            kind = "folder" if stat.S_ISDIR(status.st_mode) else "file"
            raise ControllerError(
                f"{key}: the {kind} {target} is writable by group or others, so anyone of them could change the code"
                f" this scenario runs; refused (make it writable by you only: chmod go-w {target},"
                " or move the code to a folder of your own)"
            )
        if status.st_uid not in (os.geteuid(), 0):
            raise ControllerError(
                f"{key}: {target} is owned by user id {status.st_uid}, not by you (user id {os.geteuid()}), so it is"
                " not yours to run; refused (copy the code into a folder of your own, or run as its owner)"
            )


def import_module(found: Located) -> ModuleType:
    """Import the located module: one beside the scenario from its file, under a fresh name of
    its own (its package's relative imports work); one on sys.path by the ordinary import."""
    if not found.beside:
        importlib.invalidate_caches()
        return importlib.import_module(found.name)
    assert found.path is not None
    unique = f"{PREFIX}{next(_serial)}"
    _origins[unique] = found.name.split(".")[0]
    if found.package is None:
        return _exec(unique, found.path, None)
    package = _exec(unique, found.package / "__init__.py", [str(found.package)])
    rest = found.name.split(".")[1:]
    return importlib.import_module(".".join([unique, *rest])) if rest else package


class _SourceOnly(importlib.machinery.SourceFileLoader):
    """A loader that compiles the checked source file itself: no bytecode cache is read (one
    that others could have written) or written beside the scenario."""

    def get_code(self, fullname: str) -> object:
        return compile(self.get_data(self.path), self.path, "exec", dont_inherit=True)


def _exec(name: str, path: Path, search: list[str] | None) -> ModuleType:
    loader = _SourceOnly(name, str(path))
    spec = importlib.util.spec_from_file_location(name, path, loader=loader, submodule_search_locations=search)
    if spec is None or spec.loader is None:
        raise ImportError(f"{path} cannot be imported")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # while it runs (dataclasses, relative imports) and after
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return module

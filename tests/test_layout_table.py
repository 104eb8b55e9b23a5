"""The layout table ("What is where", docs/architecture.md) matches the tree: every module of the package
is named there, and every `src/toggle_cosim/...` path it names exists."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "src" / "toggle_cosim"


def _table() -> str:
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    start = text.index("## What is where")
    return text[start : text.index("\n## ", start + 5)]


def test_every_module_is_in_the_table() -> None:
    table = _table()
    modules = [
        path
        for path in PACKAGE.rglob("*")
        if path.suffix in (".py", ".c")
        and "__pycache__" not in path.parts
        and not {"shell", "fmi_headers"} & set(path.parts)  # the C shell is one row: `shell/`
        and path.name not in ("__init__.py", "__main__.py")
    ]
    assert len(modules) > 60

    def named(path: Path) -> bool:  # by its name in its package's row, or by its path
        return f"`{path.name}`" in table or f"`src/toggle_cosim/{path.relative_to(PACKAGE)}`" in table

    assert [str(p.relative_to(PACKAGE)) for p in modules if not named(p)] == []


def test_every_path_the_table_names_exists() -> None:
    named = re.findall(r"`((?:src/toggle_cosim|modelica|scenarios|templates|docs|benchmarks|tests)/[^`]*)`", _table())
    assert named
    assert [path for path in named if not any(ROOT.glob(path))] == []

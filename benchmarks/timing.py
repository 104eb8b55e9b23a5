"""Timing a toggle-cosim command in a fresh process, from process start to the last file it
wrote (shared by bench.py and paper_suite.py)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path


def cli_command() -> list[str]:
    """The project's `toggle-cosim` beside this interpreter, else the CLI through it."""
    script = Path(sys.executable).parent / "toggle-cosim"
    if script.is_file():
        return [str(script)]
    return [sys.executable, "-c", "import sys; from toggle_cosim.cli import main; sys.exit(main())"]


def run_to_last_file(arguments: list[str], out: Path, env: dict[str, str], cwd: Path | None = None) -> dict:
    """Run `toggle-cosim ARGUMENTS` writing under `out`: seconds from start to the last file
    written and to the process's exit, and the files written. SystemExit naming the command
    when it fails."""
    started = time.time()
    result = subprocess.run([*cli_command(), *arguments], cwd=cwd, capture_output=True, text=True, check=False, env=env)
    ended = time.time()
    if result.returncode != 0:
        raise SystemExit(f"toggle-cosim {arguments[0]} failed ({result.returncode}): {result.stderr.strip()[-500:]}")
    files = [p for p in out.rglob("*") if p.is_file()]
    return {
        "to_last_file": max(p.stat().st_mtime for p in files) - started,
        "process": ended - started,
        "files": files,
    }

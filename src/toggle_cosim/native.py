"""Small C libraries compiled on the user's machine and cached by a hash of what builds them:
the co-simulation loop generated from the control law (`cosim.compiled_loop`) and the trace-row
formatter (`files.csv_rows`).

The compiler is $CC, else cc, gcc or clang: `c_compiler` is the one lookup, for these helpers and
for the FMU export's build alike (it lives here, below the FMU export, because importing that
pulls in the Modelica compiler, about 1 s). The cache is
$TOGGLE_COSIM_CACHE, else $XDG_CACHE_HOME/toggle-cosim (~/.cache/toggle-cosim), else a
per-user folder in the temporary directory when that one cannot be written.
"""

from __future__ import annotations

import hashlib
import os
import platform
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path


def c_compiler() -> str:
    """The C compiler as a full path; RuntimeError when there is none."""
    for name in (os.environ.get("CC", ""), "cc", "gcc", "clang"):
        found = shutil.which(name) if name else None
        if found:
            return found
    raise RuntimeError("no C compiler found (set CC or install gcc)")


def cache_folders() -> list[Path]:
    """Where compiled libraries are kept, in the order they are tried. Without a home folder
    (HOME unset and no passwd entry for the user) only the temporary directory's."""
    user = os.getuid() if hasattr(os, "getuid") else "user"
    fallback = Path(tempfile.gettempdir()) / f"toggle-cosim-{user}"
    if os.environ.get("TOGGLE_COSIM_CACHE"):
        return [Path(os.environ["TOGGLE_COSIM_CACHE"]), fallback]
    if os.environ.get("XDG_CACHE_HOME"):
        return [Path(os.environ["XDG_CACHE_HOME"]) / "toggle-cosim", fallback]
    try:
        home = Path.home()
    except (RuntimeError, KeyError, OSError):  # no HOME and no passwd entry: no home cache
        return [fallback]
    return [home / ".cache" / "toggle-cosim", fallback]


def cached_library(source: str, stem: str, flags: Sequence[str], libraries: Sequence[str] = ()) -> Path:
    """The shared library built from the C `source` with `flags`: taken from the cache when a
    build of the same source, flags, compiler and platform is there, else compiled into it
    (atomically, so concurrent builds only race to the same file). RuntimeError when the
    compiler fails or no cache folder can be written."""
    compiler = c_compiler()
    suffix = {"Windows": ".dll", "Darwin": ".dylib"}.get(platform.system(), ".so")
    key = hashlib.sha256("\0".join((source, *flags, compiler, platform.machine(), sys.platform)).encode())
    name = f"{stem}-{key.hexdigest()[:16]}{suffix}"
    for folder in cache_folders():
        library = folder / name
        if library.is_file():
            return library
        try:
            folder.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryDirectory(dir=folder) as work:
                source_path = Path(work) / f"{stem}.c"
                source_path.write_text(source, encoding="utf-8")
                built = Path(work) / f"{stem}{suffix}"
                result = subprocess.run(
                    [compiler, *flags, "-o", str(built), str(source_path), *libraries],
                    capture_output=True,
                    text=True,
                    check=False,
                )
                if result.returncode != 0:
                    raise RuntimeError(f"the C compiler failed: {result.stderr.strip()[:500]}")
                os.replace(built, library)
            return library
        except OSError:
            continue
    raise RuntimeError(f"no writable cache folder for {stem} (tried {', '.join(map(str, cache_folders()))})")


def cached_library_from(
    inputs: Sequence[Path],
    make_source: Callable[[], str],
    stem: str,
    flags: Sequence[str],
    libraries: Sequence[str] = (),
) -> Path:
    """`cached_library(make_source(), ...)`, without making the source when it was made before
    from the same `inputs` (the files it is generated from: making it may cost more than the
    run it serves). A marker named by the hash of those files' bytes, the flags, the compiler,
    the platform and the Python version names the library; any change to one of them makes the
    source again, and so the library by its own hash."""
    digest = hashlib.sha256()
    for path in inputs:
        digest.update(str(path).encode() + b"\0" + Path(path).read_bytes() + b"\0")
    digest.update("\0".join((*flags, *libraries, c_compiler(), platform.machine(), sys.platform, sys.version)).encode())
    marker = f"{stem}-inputs-{digest.hexdigest()[:16]}.txt"
    for folder in cache_folders():
        try:
            named = folder / (folder / marker).read_text(encoding="utf-8").strip()
        except (OSError, ValueError):
            continue
        if named.parent == folder and named.name.startswith(f"{stem}-") and named.is_file():
            return named
    library = cached_library(make_source(), stem, flags, libraries)
    try:
        handle, temporary = tempfile.mkstemp(dir=library.parent, prefix=f".{marker}.")
        with os.fdopen(handle, "w", encoding="utf-8") as stream:
            stream.write(library.name + "\n")
        os.replace(temporary, library.parent / marker)
    except OSError:
        pass  # no marker: the source is made again next time, nothing worse
    return library

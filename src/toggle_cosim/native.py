"""Small C libraries compiled on the user's machine, kept in a private cache and loaded only
after their content is checked: the loop that steps a system (`cosim.execution.system_loop`), generated
behind the control law, compiled with `KERNEL_FLAGS` (strict IEEE arithmetic: no contraction into
fused multiply-adds, no fast math, no built-in substitutions, so C and Python agree bit for bit).

The compiler is $CC, else cc, gcc or clang: `c_compiler` is the one lookup, for these helpers and
for the FMU export's build alike (it lives here, below the FMU export, because importing that
pulls in the Modelica compiler, about 1 s).

The cache is one folder of this user's: $TOGGLE_COSIM_CACHE, else
$XDG_CACHE_HOME/toggle-cosim (~/.cache/toggle-cosim); only when that one cannot be used, a
per-user folder in the temporary directory ($TMPDIR/toggle-cosim-<uid>). Either is used only
when it is private (`private_folder`): created 0700, owned by this user, writable by no one
else, in a folder where no one else can swap it (writable by others only with the sticky bit).
A folder that fails a check is not used, and one `warning:` line on stderr says why and how to
fix it. Every file taken from the cache is owned by this user and writable by no one else; a
library is loaded only when the SHA-256 of its bytes, read from the descriptor that is then
loaded, equals the one recorded when it was built here (else it is built again). Nothing in
the cache is unpickled or executed on trust of its name.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import shutil
import stat
import subprocess
import sys
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

KERNEL_FLAGS = ("-std=c99", "-O2", "-fPIC", "-shared", "-ffp-contract=off", "-fno-fast-math", "-fno-builtin")


class CacheError(RuntimeError):
    """A cache folder or file that must not be used, or no usable cache folder: one line."""


def c_compiler() -> str:
    """The C compiler as a full path; RuntimeError when there is none."""
    for name in (os.environ.get("CC", ""), "cc", "gcc", "clang"):
        found = shutil.which(name) if name else None
        if found:
            return found
    raise RuntimeError("no C compiler found (set CC or install gcc)")


def _user() -> int:
    return os.geteuid()


def configured_cache() -> Path:
    """The cache folder asked for: $TOGGLE_COSIM_CACHE, else $XDG_CACHE_HOME/toggle-cosim, else
    ~/.cache/toggle-cosim."""
    if os.environ.get("TOGGLE_COSIM_CACHE"):
        return Path(os.environ["TOGGLE_COSIM_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME")
    if not base:
        try:
            base = str(Path.home() / ".cache")
        except RuntimeError:  # no HOME and no passwd entry: only the fallback is left
            base = ""
    return Path(base) / "toggle-cosim" if base else Path()


def fallback_cache() -> Path:
    """The per-user folder in the temporary directory, used only when `configured_cache()` cannot be."""
    return Path(tempfile.gettempdir()) / f"toggle-cosim-{_user()}"


def check_private(info: os.stat_result, path: Path, what: str) -> None:
    """Raise CacheError unless `info` (of `path`) belongs to this user and no one else may write it."""
    if info.st_uid != _user():
        raise CacheError(
            f"{path}: the {what} belongs to another user (uid {info.st_uid}, not {_user()}): not used; "
            "remove it, or set TOGGLE_COSIM_CACHE to a folder of your own"
        )
    if info.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        raise CacheError(
            f"{path}: the {what} is writable by other users (mode {stat.S_IMODE(info.st_mode):04o}): not used; "
            f"remove it (or chmod go-w it if you trust what is in it)"
        )


def private_folder(path: Path) -> Path:
    """`path` as a private folder of this user, created 0700 (its missing parents with the usual
    mode) when it does not exist. Raises CacheError (one line) when it is not a folder, belongs to
    another user, is writable by group or others, or lies in a folder that others can write
    without the sticky bit (they could swap it); OSError when it cannot be made."""
    path = Path(path)
    if path == Path():
        raise CacheError("no cache folder: HOME is not set (set TOGGLE_COSIM_CACHE)")
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.mkdir(path, 0o700)
        os.chmod(path, 0o700)  # whatever the umask
    except FileExistsError:
        pass
    link = os.lstat(path)
    if stat.S_ISLNK(link.st_mode) and link.st_uid != _user():  # a link of one's own (to a bigger disk) is fine
        raise CacheError(
            f"{path}: the cache folder is a symbolic link of another user (uid {link.st_uid}): not used; "
            "remove it, or set TOGGLE_COSIM_CACHE to a folder of your own"
        )
    info = os.stat(path)
    if not stat.S_ISDIR(info.st_mode):
        raise CacheError(f"{path}: the cache folder is not a folder: not used; remove it or set TOGGLE_COSIM_CACHE")
    check_private(info, path, "cache folder")
    parent = os.stat(path.parent)
    if parent.st_mode & stat.S_IWOTH and not parent.st_mode & stat.S_ISVTX:
        raise CacheError(
            f"{path}: the cache folder lies in {path.parent}, which anyone may write without the sticky bit: "
            "not used; set TOGGLE_COSIM_CACHE to a folder of your own"
        )
    if not os.access(path, os.W_OK | os.X_OK):
        raise CacheError(f"{path}: the cache folder cannot be written")
    return path


_warned: set[str] = set()


def _warn_once(message: str) -> None:
    if message not in _warned:
        _warned.add(message)
        sys.stderr.write(f"warning: {message}\n")
        sys.stderr.flush()


def cache_folder() -> Path:
    """The private cache folder of this user: `configured_cache()`, or when that one cannot be
    used (one warning line says why), `fallback_cache()`, checked the same way. CacheError (one
    line) when neither can be used."""
    problems = []
    for folder in (configured_cache(), fallback_cache()):
        try:
            return private_folder(folder)
        except (CacheError, OSError) as error:
            problem = str(error) if isinstance(error, CacheError) else f"{folder}: {error.strerror or error}"
            problems.append(problem)
            _warn_once(problem)
    raise CacheError(f"no usable cache folder ({'; '.join(problems)})")


@dataclass(frozen=True)
class CachedLibrary:
    """A library in the cache and the SHA-256 of the bytes it had when it was built here."""

    path: Path
    sha256: str


def _open_private(path: Path, what: str) -> int:
    """A read descriptor on `path`, a regular file of this user's that no one else may write
    (not followed if it is a symbolic link). OSError if it is missing, CacheError if it is not private."""
    fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_NONBLOCK", 0))
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise CacheError(f"{path}: the cached {what} is not a regular file")
        check_private(info, path, f"cached {what}")
    except BaseException:
        os.close(fd)
        raise
    return fd


def _read_private_text(path: Path, what: str, limit: int = 4096) -> str:
    fd = _open_private(path, what)
    try:
        return os.read(fd, limit).decode("ascii").strip()
    finally:
        os.close(fd)


def _write_private_text(folder: Path, name: str, text: str) -> None:
    handle, temporary = tempfile.mkstemp(dir=folder, prefix=f".{name}.", suffix=".partial")
    try:
        with os.fdopen(handle, "w", encoding="ascii") as stream:
            stream.write(text + "\n")
        os.replace(temporary, folder / name)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def _fd_sha256(fd: int) -> str:
    digest = hashlib.sha256()
    os.lseek(fd, 0, os.SEEK_SET)
    while chunk := os.read(fd, 1 << 20):
        digest.update(chunk)
    return digest.hexdigest()


def _record_name(library: str) -> str:
    return f"{library}.sha256"


def _verified(folder: Path, name: str) -> CachedLibrary | None:
    """The library `name` in `folder` if it is there, private and has the bytes its record names."""
    found = _checked_bytes(folder, name, "library")
    return None if found is None else CachedLibrary(folder / name, found[1])


def cached_bytes(folder: Path, name: str, what: str) -> bytes | None:
    """The bytes of the file `name` in the cache `folder` when it is there, private and has the
    SHA-256 recorded when it was stored (`store`), else None. The bytes returned are the bytes
    hashed (read once, from one descriptor), so a caller writes exactly what was checked."""
    found = _checked_bytes(folder, name, what)
    return None if found is None else found[0]


def _checked_bytes(folder: Path, name: str, what: str) -> tuple[bytes, str] | None:
    """The bytes of `name` in `folder` and their SHA-256, when the file is private and has the
    SHA-256 its record (`store`) names; None otherwise (missing, not private, another hash)."""
    try:
        expected = _read_private_text(folder / _record_name(name), f"{what} record")
        data = read_private(folder / name, what)
    except (OSError, CacheError, UnicodeDecodeError):
        return None
    actual = hashlib.sha256(data).hexdigest()
    return (data, actual) if actual == expected else None


def read_private(path: Path, what: str) -> bytes:
    """The bytes of `path`, a regular file of this user's that no one else may write (not
    followed if it is a symbolic link); OSError if it is missing, CacheError if it is not private."""
    fd = _open_private(path, what)
    try:
        chunks = []
        while chunk := os.read(fd, 1 << 20):
            chunks.append(chunk)
        return b"".join(chunks)
    finally:
        os.close(fd)


def _suffix() -> str:
    return {"Windows": ".dll", "Darwin": ".dylib"}.get(platform.system(), ".so")


def cached_library(source: str, stem: str, flags: Sequence[str], libraries: Sequence[str] = ()) -> CachedLibrary:
    """The shared library built from the C `source` with `flags`: taken from the cache when a
    build of the same source, flags, compiler and platform is there with the bytes recorded when
    it was built, else compiled into it (atomically, so concurrent builds only race to the same
    file) and its SHA-256 recorded. RuntimeError (CacheError) when the compiler fails or no
    cache folder can be used."""
    compiler = c_compiler()
    key = hashlib.sha256("\0".join((source, *flags, *libraries, compiler, platform.machine(), sys.platform)).encode())
    name = f"{stem}-{key.hexdigest()[:16]}{_suffix()}"
    folder = cache_folder()
    found = _verified(folder, name)
    if found is not None:
        return found

    def compile_into(built: Path) -> None:
        source_path = built.parent / f"{stem}.c"
        source_path.write_text(source, encoding="utf-8")
        result = subprocess.run(
            [compiler, *flags, "-o", str(built), str(source_path), *libraries],
            capture_output=True,
            text=True,
            check=False,
        )
        if result.returncode != 0:
            raise RuntimeError(f"the C compiler failed: {result.stderr.strip()[:500]}")

    return store(folder, name, compile_into, 0o700)


def store(folder: Path, name: str, build: Callable[[Path], None], mode: int) -> CachedLibrary:
    """`build(path)` writes the file `name` in a private temporary folder inside the cache
    `folder`; it is given `mode`, moved into place (atomically: concurrent builds only race to the
    same file) and its SHA-256 recorded beside it."""
    with tempfile.TemporaryDirectory(dir=folder) as work:
        built = Path(work) / name
        build(built)
        os.chmod(built, mode)
        sha256 = hashlib.sha256(built.read_bytes()).hexdigest()
        os.replace(built, folder / name)
        _write_private_text(folder, _record_name(name), sha256)
    return CachedLibrary(folder / name, sha256)


def cached_library_from(
    inputs: Sequence[Path],
    make_source: Callable[[], str],
    stem: str,
    flags: Sequence[str],
    libraries: Sequence[str] = (),
) -> CachedLibrary:
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
    folder = cache_folder()
    try:
        named = _read_private_text(folder / marker, "marker")
    except (OSError, CacheError, UnicodeDecodeError):
        named = ""
    if named and Path(named).name == named and named.startswith(f"{stem}-") and named.endswith(_suffix()):
        found = _verified(folder, named)
        if found is not None:
            return found
    library = cached_library(make_source(), stem, flags, libraries)
    try:
        _write_private_text(library.path.parent, marker, library.path.name)
    except OSError:
        pass  # no marker: the source is made again next time, nothing worse
    return library


def load_library(library: CachedLibrary) -> ctypes.CDLL:
    """ctypes.CDLL of `library`, loaded only if the file is private and its bytes have the
    recorded SHA-256: hashed from an open descriptor, and on Linux that same descriptor is
    loaded (/proc/self/fd/N), so the bytes checked are the bytes loaded. That descriptor stays
    open while the process lives, as the library stays loaded: the loader knows a library by
    the name it was loaded under, so the name must not come back for another file. CacheError
    when the bytes differ."""
    fd = _open_private(library.path, "library")
    keep = False
    try:
        if _fd_sha256(fd) != library.sha256:
            raise CacheError(
                f"{library.path}: the cached library's SHA-256 is not the one recorded when it was built: not loaded"
            )
        through = f"/proc/self/fd/{fd}"
        if not os.path.exists(through):  # no /proc (macOS): the path, in the private folder
            return ctypes.CDLL(str(library.path))
        loaded = ctypes.CDLL(through)
        keep = True
        return loaded
    finally:
        if not keep:
            os.close(fd)


def load_library_from(
    inputs: Sequence[Path],
    make_source: Callable[[], str],
    stem: str,
    flags: Sequence[str],
    libraries: Sequence[str] = (),
) -> ctypes.CDLL:
    """`load_library(cached_library_from(...))`; a library whose bytes changed between the two
    is removed and built again, once."""
    library = cached_library_from(inputs, make_source, stem, flags, libraries)
    try:
        return load_library(library)
    except CacheError:
        library.path.unlink(missing_ok=True)
    return load_library(cached_library_from(inputs, make_source, stem, flags, libraries))

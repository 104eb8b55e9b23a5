"""The cache of compiled helpers is private to its user, and nothing planted in it runs
(`native`): its folder is created 0700 and refused (one warning line) when another user owns
it, others may write it, or it lies where others can swap it; the temporary-directory fallback
is used only when the configured cache cannot be, and is checked the same way; a library is
loaded only when its bytes have the SHA-256 recorded when it was built here, else rebuilt.

The cases with another user are played with two uids: as root, the "attacker" runs under
`setpriv --reuid=65534` and plants folders and libraries in a shared place; the victim's
command must neither load them nor fail for them."""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from toggle_cosim import native

ATTACKER = 65534
SOURCE = "int answer(void) { return 42; }\n"
FLAGS = ("-O0", "-shared", "-fPIC")
ROOT = Path(__file__).resolve().parent.parent

needs_compiler = pytest.mark.skipif(shutil.which("cc") is None and not os.environ.get("CC"), reason="no C compiler")
needs_two_users = pytest.mark.skipif(
    not hasattr(os, "geteuid") or os.geteuid() != 0 or shutil.which("setpriv") is None,
    reason="needs root and setpriv to play a second user",
)


def payload_source(flag: Path) -> str:
    """C whose constructor leaves `flag` behind: proof that a planted library ran."""
    return (
        "#include <stdio.h>\n"
        f'__attribute__((constructor)) static void planted(void) {{ FILE *f = fopen("{flag}", "w");'
        ' if (f) { fputs("ran", f); fclose(f); } }\n'
        "int answer(void) { return 666; }\n"
        "int kernel_run(void) { return 0; }\nint kernel_control(void) { return 0; }\n"
    )


def compile_payload(folder: Path, flag: Path, name: str = "payload.so") -> Path:
    source = folder / "payload.c"
    source.write_text(payload_source(flag))
    library = folder / name
    subprocess.run([native.c_compiler(), "-shared", "-fPIC", "-o", str(library), str(source)], check=True)
    return library


@pytest.fixture
def shared() -> Iterator[Path]:
    """A folder anyone may write, with the sticky bit, like /tmp (outside pytest's private tmp)."""
    folder = Path(tempfile.mkdtemp(prefix="toggle-cosim-shared-"))
    os.chmod(folder, 0o1777)
    try:
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def as_attacker(script: str, cwd: Path) -> None:
    """Run the shell `script` as uid/gid 65534 with no groups (another user)."""
    subprocess.run(
        ["setpriv", f"--reuid={ATTACKER}", f"--regid={ATTACKER}", "--clear-groups", "sh", "-ec", script],
        cwd=cwd,
        check=True,
        capture_output=True,
    )


@pytest.fixture
def caches(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> tuple[Path, Path]:
    """(configured cache, the temporary directory of the fallback), both under tmp_path."""
    configured = tmp_path / "home-cache" / "toggle-cosim"
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    monkeypatch.setenv("TOGGLE_COSIM_CACHE", str(configured))
    monkeypatch.setattr(tempfile, "tempdir", str(temporary))
    native._warned.clear()
    return configured, temporary


# ------------------------------------------------------------------------------- the folder checks


def test_a_new_cache_folder_is_created_private_whatever_the_umask(tmp_path: Path) -> None:
    old = os.umask(0)
    try:
        folder = native.private_folder(tmp_path / "toggle-cosim")
    finally:
        os.umask(old)
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700 and folder.stat().st_uid == os.geteuid()


@pytest.mark.parametrize("mode", [0o770, 0o707, 0o777])
def test_a_cache_folder_others_may_write_is_refused(tmp_path: Path, mode: int) -> None:
    folder = tmp_path / "cache"
    folder.mkdir()
    os.chmod(folder, mode)
    with pytest.raises(native.CacheError, match=rf"writable by other users \(mode {mode:04o}\): not used"):
        native.private_folder(folder)


def test_a_cache_folder_of_another_owner_is_refused(tmp_path: Path) -> None:
    if os.geteuid() != 0:
        pytest.skip("only root can give a folder to another user")
    folder = tmp_path / "cache"
    folder.mkdir(mode=0o700)
    os.chown(folder, ATTACKER, ATTACKER)
    with pytest.raises(native.CacheError, match=rf"belongs to another user \(uid {ATTACKER}, not 0\)"):
        native.private_folder(folder)


def test_a_cache_folder_where_anyone_may_swap_it_is_refused(tmp_path: Path) -> None:
    parent = tmp_path / "open"
    parent.mkdir()
    os.chmod(parent, 0o777)  # no sticky bit: anyone may rename our folder away and put theirs
    with pytest.raises(native.CacheError, match="anyone may write without the sticky bit"):
        native.private_folder(parent / "toggle-cosim")
    os.chmod(parent, 0o1777)  # like /tmp
    assert native.private_folder(parent / "toggle-cosim").is_dir()


def test_a_cache_path_that_is_a_file_is_refused(tmp_path: Path) -> None:
    (tmp_path / "cache").write_text("")
    with pytest.raises(native.CacheError, match="is not a folder"):
        native.private_folder(tmp_path / "cache")


def test_the_fallback_is_used_only_when_the_configured_cache_cannot_be(caches: tuple[Path, Path]) -> None:
    configured, temporary = caches
    assert native.cache_folder() == configured
    assert not (temporary / f"toggle-cosim-{os.geteuid()}").exists()
    os.chmod(configured, 0o777)
    assert native.cache_folder() == temporary / f"toggle-cosim-{os.geteuid()}"
    assert stat.S_IMODE((temporary / f"toggle-cosim-{os.geteuid()}").stat().st_mode) == 0o700


def test_a_refused_folder_is_reported_in_one_warning_line(caches: tuple[Path, Path], capsys) -> None:  # noqa: ANN001
    configured, temporary = caches
    configured.mkdir(parents=True)
    os.chmod(configured, 0o777)
    fallback = temporary / f"toggle-cosim-{os.geteuid()}"
    fallback.mkdir()
    os.chmod(fallback, 0o775)
    with pytest.raises(native.CacheError, match="no usable cache folder"):
        native.cache_folder()
    with pytest.raises(native.CacheError):
        native.cache_folder()  # said once per process
    lines = capsys.readouterr().err.splitlines()
    assert lines == [
        f"warning: {configured}: the cache folder is writable by other users (mode 0777): not used; "
        "remove it (or chmod go-w it if you trust what is in it)",
        f"warning: {fallback}: the cache folder is writable by other users (mode 0775): not used; "
        "remove it (or chmod go-w it if you trust what is in it)",
    ]


# ------------------------------------------------------------------------------- the files in it


@needs_compiler
def test_a_library_is_built_once_recorded_and_loaded_after_its_hash(caches: tuple[Path, Path]) -> None:
    configured, _ = caches
    built = native.cached_library(SOURCE, "probe", FLAGS)
    assert built.path.parent == configured and stat.S_IMODE(built.path.stat().st_mode) == 0o700
    assert (configured / f"{built.path.name}.sha256").read_text().strip() == built.sha256
    assert native.cached_library(SOURCE, "probe", FLAGS) == built  # from the cache
    assert native.load_library(built).answer() == 42


def built_from_inputs(tmp_path: Path) -> tuple[Path, list[Path], native.CachedLibrary]:
    """(where a payload would leave its flag, the input files, the library built from them)."""
    inputs = [tmp_path / "input.txt"]
    inputs[0].write_text("v1")
    return tmp_path / "payload-ran", inputs, native.cached_library_from(inputs, lambda: SOURCE, "probe", FLAGS)


@needs_compiler
def test_a_library_whose_bytes_changed_is_not_loaded_but_rebuilt(caches: tuple[Path, Path], tmp_path: Path) -> None:
    configured, _ = caches
    flag, inputs, first = built_from_inputs(tmp_path)
    payload = compile_payload(tmp_path, flag)
    shutil.copy(payload, first.path)  # same owner, same name, other bytes
    with pytest.raises(native.CacheError, match="SHA-256 is not the one recorded"):
        native.load_library(first)
    library = native.load_library_from(inputs, lambda: SOURCE, "probe", FLAGS)
    assert library.answer() == 42
    assert not flag.exists()


@needs_compiler
def test_a_file_in_the_cache_owned_by_another_user_is_not_used(caches: tuple[Path, Path], tmp_path: Path) -> None:
    if os.geteuid() != 0:
        pytest.skip("only root can give a file to another user")
    configured, _ = caches
    flag = tmp_path / "payload-ran"
    built = native.cached_library(SOURCE, "probe", FLAGS)
    shutil.copy(compile_payload(tmp_path, flag), built.path)
    record = configured / f"{built.path.name}.sha256"
    record.write_text(native.hashlib.sha256(built.path.read_bytes()).hexdigest() + "\n")  # a matching record
    os.chown(built.path, ATTACKER, ATTACKER)
    os.chown(record, ATTACKER, ATTACKER)
    again = native.cached_library(SOURCE, "probe", FLAGS)
    assert native.load_library(again).answer() == 42 and not flag.exists()
    assert built.path.stat().st_uid == os.geteuid()


@needs_compiler
def test_a_marker_naming_a_library_outside_the_cache_is_ignored(caches: tuple[Path, Path], tmp_path: Path) -> None:
    configured, _ = caches
    flag, inputs, first = built_from_inputs(tmp_path)
    marker = next(configured.glob("probe-inputs-*.txt"))
    outside = compile_payload(tmp_path, flag, "probe-x.so")
    marker.write_text(f"../../{outside.name}\n")
    again = native.cached_library_from(inputs, lambda: SOURCE, "probe", FLAGS)
    assert again == first and native.load_library(again).answer() == 42 and not flag.exists()


# ------------------------------------------------------------------------------- two users


KERNEL_PROBE = (
    "from toggle_cosim.cosim.execution import system_loop\n"
    "print(system_loop.system_library() is not None); print(system_loop.system_library_reason())\n"
)


def plant_kernel_payload(folder: Path, flag: Path, shared: Path) -> None:
    """As the attacker, make `folder` with a payload named by every system-loop marker the
    victim could look for (the marker's name is public: it hashes public inputs), with a
    matching SHA-256 record: only the folder's owner tells it is not the victim's."""
    from toggle_cosim.cosim.execution import system_loop

    payload = compile_payload(shared, flag, "system-loop-0000000000000000.so")
    digest = native.hashlib.sha256()
    for path in system_loop.system_inputs():
        digest.update(str(path).encode() + b"\0" + Path(path).read_bytes() + b"\0")
    extra = (*native.KERNEL_FLAGS, "-lm", native.c_compiler(), native.platform.machine(), sys.platform)
    digest.update("\0".join((*extra, sys.version)).encode())
    marker = f"system-loop-inputs-{digest.hexdigest()[:16]}.txt"
    sha = native.hashlib.sha256(payload.read_bytes()).hexdigest()
    os.chmod(shared / "payload.c", 0o644)
    os.chmod(payload, 0o755)
    as_attacker(
        f"mkdir -p '{folder}' && chmod 777 '{folder}' && cp '{payload}' '{folder}/' && "
        f"echo {payload.name} > '{folder}/{marker}' && echo {sha} > '{folder}/{payload.name}.sha256'",
        shared,
    )
    assert folder.stat().st_uid == ATTACKER


@needs_two_users
@needs_compiler
def test_a_fallback_folder_planted_by_another_user_is_refused_and_nothing_of_it_runs(shared: Path) -> None:
    flag = shared / "payload-ran"
    planted = shared / f"toggle-cosim-{os.geteuid()}"
    plant_kernel_payload(planted, flag, shared)
    blocked = shared / "not-a-folder"
    blocked.write_text("")  # the configured cache cannot be made: the fallback is tried
    env = {**os.environ, "TMPDIR": str(shared), "TOGGLE_COSIM_CACHE": str(blocked / "cache")}
    done = subprocess.run([sys.executable, "-c", KERNEL_PROBE], env=env, capture_output=True, text=True, check=True)
    assert not flag.exists(), "the planted library ran"
    available, reason = done.stdout.splitlines()
    assert available == "False" and "no usable cache folder" in reason
    warnings = [line for line in done.stderr.splitlines() if line.startswith("warning:")]
    assert any(f"{planted}: the cache folder belongs to another user (uid {ATTACKER}" in w for w in warnings)


@needs_two_users
@needs_compiler
def test_a_run_ignores_a_cache_planted_by_another_user_and_completes(shared: Path, plant_fmu: Path) -> None:
    """The issue's case end to end: another user made the cache folder first with a payload that
    would run in the victim's `run`; the run completes with the loop built in a private folder."""
    flag = shared / "payload-ran"
    planted = shared / "cache"
    plant_kernel_payload(planted, flag, shared)
    private_tmp = Path(tempfile.mkdtemp())
    try:
        env = {**os.environ, "TMPDIR": str(private_tmp), "TOGGLE_COSIM_CACHE": str(planted)}
        out = private_tmp / "out"
        done = subprocess.run(
            [sys.executable, "-m", "toggle_cosim.cli", "run", str(ROOT / "scenarios" / "fig4_nominal.yaml")]
            + ["--fmu", str(plant_fmu), "--out", str(out), "-q"],
            env=env,
            capture_output=True,
            text=True,
            check=False,
        )
        assert done.returncode == 0, done.stderr
        assert not flag.exists(), "the planted library ran"
        assert done.stderr.count(f"warning: {planted}: the cache folder belongs to another user") == 1
        assert '"kind": "compiled"' in (out / "fig4_nominal" / "friction" / "run.json").read_text()
        assert list((private_tmp / f"toggle-cosim-{os.geteuid()}").glob("system-loop-*.so"))
    finally:
        shutil.rmtree(private_tmp, ignore_errors=True)


def test_without_a_home_folder_the_cache_is_the_temporary_one_and_the_plant_is_read(
    plant_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """HOME unset and no passwd entry (Path.home() raises): the cache is the per-user folder in
    the temporary directory, and the FMU is read, not reported as an unreadable modelDescription.xml."""
    import tempfile

    from toggle_cosim.native import cache_folder
    from toggle_cosim.plant.contract import check_plant

    def no_home() -> Path:
        raise RuntimeError("Could not determine home directory.")

    for name in ("HOME", "XDG_CACHE_HOME", "TOGGLE_COSIM_CACHE"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(Path, "home", staticmethod(no_home))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    assert cache_folder() == tmp_path / f"toggle-cosim-{os.geteuid()}"
    plant = check_plant(plant_fmu)
    assert "x_B" in plant.references

"""The interrupt machinery itself (`toggle_cosim.interrupts`), each case in a fresh interpreter
running as the program does: an interrupt is never lost, and a child process being started
cannot be hit by one.

The commands' own behaviour under interrupts at any moment is in test_supervision.py.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

SIGINT_AND_SIGTERM = (1 << (signal.SIGINT - 1)) | (1 << (signal.SIGTERM - 1))


def _program(source: str, setup: str = "", timeout: float = 30) -> subprocess.CompletedProcess[str]:
    """Run `source` after the program's own set-up of the signals (install_for_start_up, install)
    and the line `setup`."""
    prelude = "from toggle_cosim import interrupts\ninterrupts.install_for_start_up()\ninterrupts.install()\n"
    return subprocess.run(
        [sys.executable, "-c", prelude + setup + "\n" + textwrap.dedent(source)],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
        start_new_session=True,  # its own process group: a Ctrl-C it sends to the group stays there
    )


BUSY = """
import threading, time
started_thread = threading.Thread.start
def slow_start(thread):  # the caller is held up 50 ms after starting a thread, as on a busy machine
    started_thread(thread)
    time.sleep(0.05)
threading.Thread.start = slow_start
"""


@pytest.mark.parametrize("busy", [False, True])
def test_an_interrupt_that_lands_in_a_finalizer_is_not_lost(busy: bool) -> None:
    """A signal whose handler runs inside __del__ raises a KeyboardInterrupt that cannot leave
    the finalizer (Python reports it as unraisable and goes on). It must come back, and land in
    the ordinary code that follows, with nothing printed. On a busy machine the hook itself can
    be held up for longer than the delay before the signal is sent again: it must not be sent
    into the hook then, where it would be dropped again (a lost interrupt never lands: the 20 s
    the program waits for it are a hang guard, not a speed it must reach)."""
    done = _program(
        """
        import signal, time

        class Finalized:
            def __del__(self):
                signal.raise_signal(signal.SIGTERM)  # the handler runs here, inside __del__

        started = time.monotonic()
        try:
            Finalized()  # collected at once
            while time.monotonic() - started < 20:
                time.sleep(0.001)
            print("lost")
        except KeyboardInterrupt as error:
            print("landed", error)
        """,
        setup=BUSY if busy else "",
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["landed", "SIGTERM"], (done.stdout, done.stderr)
    assert done.stderr == ""


def test_a_child_being_started_cannot_be_interrupted() -> None:
    """A child started inside starting_children() begins with SIGINT and SIGTERM blocked (its
    /proc status says so), so a Ctrl-C sent to the whole process group while it starts does not
    reach its imports. as_child() then ignores SIGINT (the pending one is discarded) and unblocks;
    the parent gets its interrupt when the block ends, with the child's pid already known."""
    done = _program(
        """
        import os, signal, subprocess, sys, time
        child_source = (
            "import sys, time\\n"
            "sys.stdin.readline()\\n"  # the parent has sent SIGINT to the group meanwhile
            "from toggle_cosim import interrupts\\n"
            "interrupts.as_child()\\n"
            "time.sleep(0.05)\\n"
            "print('child alive', flush=True)\\n"
        )
        pid = None
        try:
            with interrupts.starting_children():
                child = subprocess.Popen([sys.executable, "-c", child_source], stdin=subprocess.PIPE, text=True)
                pid = child.pid  # Popen returns once the child has exec'd: its mask is set
                status = open(f"/proc/{pid}/status").read()
                blocked = int(status.split("SigBlk:")[1].split()[0], 16)
                print(f"blocked {blocked}", flush=True)
                os.killpg(0, signal.SIGINT)  # Ctrl-C: this process and the child
                time.sleep(0.1)
                print("parent still in the block", flush=True)
        except KeyboardInterrupt as error:
            print(f"parent interrupted {error}, child known {pid is not None}", flush=True)
        child.communicate("go\\n")
        print(f"child status {child.returncode}", flush=True)
        """
    )
    lines = done.stdout.splitlines()
    assert done.returncode == 0, done.stderr
    blocked = int(lines[0].split()[1])
    assert blocked & SIGINT_AND_SIGTERM == SIGINT_AND_SIGTERM
    assert lines[1:] == [
        "parent still in the block",
        "parent interrupted SIGINT, child known True",
        "child alive",
        "child status 0",
    ]
    assert "Traceback" not in done.stderr


def test_without_the_block_the_same_child_dies_in_its_start_up() -> None:
    """The control for the test above: the same Ctrl-C to a child started outside the block
    ends it with a KeyboardInterrupt traceback (so the test above can fail)."""
    done = _program(
        """
        import os, signal, subprocess, sys, time
        child_source = "import sys\\nprint('ready', flush=True)\\nsys.stdin.readline()\\nprint('child alive')\\n"
        child = subprocess.Popen(
            [sys.executable, "-c", child_source],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        child.stdout.readline()  # its interpreter is up, its own code runs (as a starting worker's imports)
        try:
            os.killpg(0, signal.SIGINT)
            time.sleep(0.1)
        except KeyboardInterrupt:
            pass
        _, errors = child.communicate("go\\n")
        print("child alive" if child.returncode == 0 else "child died", "Traceback" in errors, flush=True)
        """
    )
    assert done.stdout.split() == ["child", "died", "True"], done.stderr


WAITS = ["toggle_cosim.cosim.isolation.plant_host:wait_for_hosts", "toggle_cosim.cosim.isolation.supervision:wait_for"]

WAIT_FOR_A_SILENT_CHILD = """
import importlib, os, signal, threading, time

module, name = WAIT.split(":")
wait = getattr(importlib.import_module(module), name)
read, write = os.pipe()

class SilentHost:  # a busy host (or run) that never answers, with a far deadline
    busy, polls, done = True, False, False
    deadline = time.monotonic() + 600
    def watched(self):
        return [read]
    def service(self, ready):
        return None

main = threading.get_native_id()

def selecting():  # the main thread asleep in select (select, pselect6: x86-64; pselect6: arm64)
    with open(f"/proc/self/task/{main}/syscall") as stream:
        return stream.read().split()[0] in ("23", "270", "72")

def guard():  # a main thread still asleep 20 s after the interrupt is woken through the pipe
    limit = time.monotonic() + 20
    while selecting() and time.monotonic() < limit:
        time.sleep(0.01)
    if selecting():
        print("still asleep", flush=True)
        os.write(write, b"x")

def wait_and_say():
    try:
        wait([SilentHost()])
        print("returned", flush=True)
    except KeyboardInterrupt as error:
        print("interrupted", error, flush=True)
"""


def _waited(wait: str, source: str) -> list[str]:
    """What the program `source` printed, run after WAIT_FOR_A_SILENT_CHILD with `wait`."""
    done = _program(source, setup=f"WAIT = {wait!r}\n{WAIT_FOR_A_SILENT_CHILD}", timeout=60)
    assert done.returncode == 0, done.stderr
    return done.stdout.splitlines()


@pytest.mark.parametrize("wait", WAITS)
def test_an_interrupt_another_thread_receives_ends_the_wait_for_children(wait: str) -> None:
    """The kernel gives a process's signal to any thread that does not block it: to another
    thread (tqdm's monitor in a sweep) while the main thread blocks it, as it does while it
    starts a child. That thread only notes the signal for the main thread. A main thread already
    asleep in the wait for its plant hosts or supervised runs, whose deadline is a time limit,
    must wake and be interrupted now, not when the deadline comes. Here the signal goes to the
    other thread once the main thread sleeps in select; if it is still asleep 20 s later, the
    other thread wakes it through the host's pipe (a hang guard) and says so."""
    said = _waited(
        wait,
        """
        def other():
            while not selecting():
                time.sleep(0.001)
            signal.pthread_kill(threading.get_ident(), signal.SIGINT)  # to this thread, not the main one
            guard()

        threading.Thread(target=other, daemon=True).start()
        wait_and_say()
        """,
    )
    assert said == ["interrupted SIGINT"]


@pytest.mark.parametrize("wait", WAITS)
def test_an_interrupt_some_code_dropped_is_raised_by_the_next_wait(wait: str) -> None:
    """C code that calls Python and clears what it raised drops a KeyboardInterrupt (lxml's
    import did, inside `abc.register`, and the sweep ran on to its held case and hung there):
    here the interrupt lands in code that drops it. The command's next wait for its children
    must raise it at once instead of sleeping to the deadline (the guard as above)."""
    said = _waited(
        wait,
        """
        try:
            signal.raise_signal(signal.SIGTERM)  # lands here, and is dropped
        except KeyboardInterrupt:
            pass
        threading.Thread(target=guard, daemon=True).start()
        wait_and_say()
        """,
    )
    assert said == ["interrupted SIGTERM"]


def test_a_command_that_dropped_an_interrupt_ends_as_interrupted(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A command whose interrupt some C code dropped, and which then had nothing to wait for,
    still ends with exit status 130 and the interrupt's line, not as if no one had pressed
    Ctrl-C: `toggle-cosim init`, with an interrupt raised and dropped while it copies."""
    import shutil

    from click.testing import CliRunner

    from toggle_cosim.cli import init_command, main

    copytree = shutil.copytree

    def copy_with_a_dropped_interrupt(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        try:
            signal.raise_signal(signal.SIGINT)
        except KeyboardInterrupt:
            pass  # as C code that clears what the Python it called raised
        return copytree(*args, **kwargs)

    monkeypatch.setattr(init_command.shutil, "copytree", copy_with_a_dropped_interrupt)
    result = CliRunner().invoke(main, ["init", str(tmp_path / "work")])
    assert result.exit_code == 130, result.output
    assert "interrupted (exit 130)" in result.output

"""A forked child and every process it starts, ended together.

A plant's native code may start helper processes (a `fork` in fmi2Instantiate, `system("sleep
40 &")` in its library's constructor). Such a helper inherits the child's descriptors (the
answer pipe, the command's stdout) and would hold the command, or a `| cat` after it, for its
own life. So a child made with `fork_child`

* leads its own process group (set by the child and by the parent, so that neither can act
  before it exists), which the helpers join unless they leave it on purpose, and
* is a child subreaper (Linux PR_SET_CHILD_SUBREAPER): a helper whose parent ends (a daemon's
  double fork, `setsid` included) becomes the child's own, so it stays in the child's tree;

and `end_tree(pid)` ends the child's whole tree: it stops what it finds (a stopped process
cannot fork) and looks again until the tree is frozen, then kills the process group and every
process found with SIGKILL. Frozen means a walk found nothing new while every process found was
stopped or a zombie: a process still running may be forking, or exiting, and an exiting
process hands its children to the subreaper while the walk reads the lists, so one walk that
finds nothing new proves nothing (a daemon would slip through to init). The child calls
`end_descendants()` before it exits; the parent calls `end_tree` when the child has ended or
must end (its time limit, an interrupt). A process that crashes cannot end what it started,
and its orphans would go to init: so the child does its work in a grandchild (`run_kept`)
and stays as the keeper, which adopts those orphans, ends them when the grandchild has ended,
and then ends as the grandchild did (the same exit status, or the same signal).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import time
from collections.abc import Callable
from pathlib import Path
from typing import NoReturn

_PR_SET_PDEATHSIG = 1
_PR_SET_CHILD_SUBREAPER = 36
FREEZE_S = 5.0  # the longest a tree may take to freeze (a process in uninterruptible sleep, a core dump)
_PAUSE_S = 0.001  # between walks while a process found has not stopped yet
_FROZEN = frozenset("TtZX")  # /proc states: stopped, traced, zombie, dead


def become_leader() -> None:
    """In a freshly forked child: lead a new process group and adopt orphaned descendants."""
    with contextlib.suppress(OSError):
        os.setpgid(0, 0)
    with contextlib.suppress(Exception):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)


def adopt(pid: int) -> None:
    """In the parent right after the fork: the child leads its group (the child does the same)."""
    with contextlib.suppress(OSError):
        os.setpgid(pid, pid)


def _children_of(pid: int) -> set[int]:
    found: set[int] = set()
    try:
        tasks = list(Path(f"/proc/{pid}/task").iterdir())
    except OSError:
        return found
    for task in tasks:
        with contextlib.suppress(OSError, ValueError):
            found.update(int(word) for word in (task / "children").read_text().split())
    return found


def descendants(pid: int) -> set[int]:
    """The processes below `pid` (its children, theirs, ...), as /proc shows them now."""
    found: set[int] = set()
    todo = [pid]
    while todo:
        for child in _children_of(todo.pop()):
            if child not in found:
                found.add(child)
                todo.append(child)
    return found


def _signal(pids: set[int], number: int) -> None:
    for pid in pids:
        with contextlib.suppress(OSError):
            os.kill(pid, number)


def _state(pid: int) -> str:
    """The process's state letter in /proc (R, S, D, T, Z, ...); "X" once it is gone."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return "X"


def _stop_tree(pid: int) -> set[int]:
    """Stop every descendant of `pid` and walk again until the tree is frozen (module doc), or
    FREEZE_S has passed; the processes found."""
    seen: set[int] = set()
    deadline = time.monotonic() + FREEZE_S
    while True:
        now = descendants(pid)
        new = now - seen
        _signal(new, signal.SIGSTOP)
        seen |= new
        if not new and all(_state(each) in _FROZEN for each in now):
            return seen
        if time.monotonic() > deadline:
            return seen
        if not new:
            time.sleep(_PAUSE_S)


def end_tree(pid: int) -> None:
    """SIGKILL `pid`, the process group it leads and every descendant of it. Call it while
    `pid` is not yet reaped (its pid and group cannot be another's then)."""
    found = _stop_tree(pid)
    with contextlib.suppress(OSError):
        os.killpg(pid, signal.SIGKILL)
    _signal(found | {pid}, signal.SIGKILL)


def end_descendants() -> None:
    """In a child about to exit: SIGKILL everything it started. As a subreaper it has adopted
    every orphan among them, so its tree holds them all."""
    _signal(_stop_tree(os.getpid()), signal.SIGKILL)


def die_with(parent: int) -> None:
    """In a child: SIGKILL when `parent` ends (PR_SET_PDEATHSIG); exit now if it already has."""
    with contextlib.suppress(Exception):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent:  # the parent died before prctl took effect
        os._exit(1)


def run_kept(work: Callable[[], None]) -> NoReturn:
    """In a child that called `become_leader`: run `work` (which should end in os._exit) in a
    grandchild, wait for it, end everything else in the tree, and end as it ended."""
    keeper = os.getpid()
    pid = os.fork()
    if pid == 0:
        die_with(keeper)
        try:
            work()
        finally:
            os._exit(0)
    status = 0
    while True:
        try:
            status = os.waitpid(pid, 0)[1]
            break
        except InterruptedError:
            continue
        except ChildProcessError:
            break
    with contextlib.suppress(BaseException):
        end_descendants()
    if os.WIFSIGNALED(status):
        number = os.WTERMSIG(status)
        with contextlib.suppress(Exception):
            import resource

            resource.setrlimit(resource.RLIMIT_CORE, (0, resource.getrlimit(resource.RLIMIT_CORE)[1]))
        with contextlib.suppress(Exception):  # the keeper's own core would repeat the plant's
            signal.signal(number, signal.SIG_DFL)
            signal.pthread_sigmask(signal.SIG_UNBLOCK, [number])
            os.kill(keeper, number)
    os._exit(os.waitstatus_to_exitcode(status) if os.WIFEXITED(status) else 1)


def has_ended(pid: int) -> bool:
    """True once the child `pid` has exited (it is left unreaped: `finish` reaps it)."""
    try:
        return os.waitid(os.P_PID, pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is not None
    except ChildProcessError:
        return True


def finish(pid: int) -> int | None:
    """End the child's tree (`end_tree`) and reap it: its wait status (None if already reaped)."""
    end_tree(pid)
    try:
        return os.waitpid(pid, 0)[1]
    except ChildProcessError:
        return None


__all__ = [
    "adopt",
    "become_leader",
    "descendants",
    "die_with",
    "end_descendants",
    "end_tree",
    "finish",
    "has_ended",
    "run_kept",
]

"""FMU instances kept loaded from run to run in one process (`InstancePool`): what lets a sweep's
or a tuning's worker run case after case of a system without loading its components again.

A system's run takes each FMU component's instance from the pool (`FmuSlave.instantiate`) and
gives it back when the run ends (`FmuSlave.close(reuse=)`), keyed by the FMU's SHA-256 and the
component's name in the system (its role: two sensors of one FMU are two instances):

* after a complete run the instance is terminated and reset (fmi2Reset / fmi3Reset) to the state
  instantiation leaves: the next run sets up its experiment and its values on it;
* after a failed or interrupted run, or when the FMU refuses terminate or reset, the instance is
  freed and its binary stays loaded: the next run instantiates anew from it;
* an FMU that answered Fatal is never called again (FMI 2.0, 2.1.3): the pool drops it and says
  so (`fatal`), and its owner (a plant host) retires so the next run loads a fresh binary.

So a run never sees what another left: it starts from a reset or a new instance, as a run alone
does, and gives the same trace bit for bit. The pool belongs to one process: a forked child
does not use (or free) the instances of its parent's pool. `close()` frees every instance,
unloads the binaries and gives back the unzipped copies (`unzipped.release`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from toggle_cosim.cosim.execution.unzipped import release

__all__ = ["InstancePool", "Kept", "PoolCounts"]


@dataclass
class Kept:
    """A component's FMU kept between runs: fmpy's slave object (its binary loaded), the unzipped
    folder it was loaded from (held, `unzipped`), and whether it holds an instance reset to the
    state instantiation leaves (`instantiated`) or only the loaded binary (freed after a failed
    run or a refused reset: the next run instantiates anew)."""

    slave: Any
    folder: Path
    instantiated: bool


@dataclass
class PoolCounts:
    """What the pool did, for a worker's record and the tests: binaries loaded, instances reset
    and used again, instances made anew from a binary already loaded."""

    loaded: int = 0
    reset: int = 0
    renewed: int = 0


@dataclass
class InstancePool:
    """The FMU instances of this process's runs, by (FMU SHA-256, component name) (module docstring)."""

    kept: dict[tuple[str, str], Kept] = field(default_factory=dict)
    counts: PoolCounts = field(default_factory=PoolCounts)
    fatal: bool = False  # a component answered Fatal: its binary may not be called again
    pid: int = field(default_factory=os.getpid)

    def _own(self) -> None:
        """In a forked child, forget the parent's instances (never called or freed here)."""
        if self.pid != os.getpid():
            self.kept, self.counts, self.fatal, self.pid = {}, PoolCounts(), False, os.getpid()

    def take(self, sha256: str, role: str) -> Kept | None:
        """The kept FMU of that SHA-256 for the component `role`, now the caller's; None: load it."""
        self._own()
        return self.kept.pop((sha256, role), None)

    def give_back(self, sha256: str, role: str, kept: Kept) -> None:
        """Keep `kept` for the next run's component `role` (one per key: an older one is unloaded)."""
        self._own()
        previous = self.kept.pop((sha256, role), None)
        if previous is not None:
            _unload(previous)
        self.kept[(sha256, role)] = kept

    def close(self) -> None:
        """Free every kept instance, unload the binaries, give back their unzipped folders."""
        self._own()
        kept, self.kept = self.kept, {}
        for one in kept.values():
            _unload(one)


def _unload(kept: Kept) -> None:
    """Free the instance (if any) and the binary; freeing never raises."""
    try:
        if kept.instantiated:
            kept.slave.freeInstance()  # fmpy: the instance freed, then the library unloaded
        else:
            kept.slave.freeLibrary()
    except Exception:  # noqa: BLE001, S110 - unloading never changes a run's outcome
        pass
    finally:
        release(kept.folder)

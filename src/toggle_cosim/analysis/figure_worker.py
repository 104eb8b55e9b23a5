"""Figures drawn beside the runs: a child Python process that imports matplotlib while the
parent simulates, and draws a scenario's nine-panel figure as soon as its traces are written.

Drawing a figure costs several times a paper run (matplotlib's import alone ~0.9 s, each figure
~1 s and more), and the parent spends a run mostly waiting for its supervised plant process;
so `toggle-cosim paper` hands each results folder to this worker and collects the file names at
the end. The protocol: one folder a line on the child's stdin; on its stdout "wrote PATH" or
"error: MESSAGE" (one line each, in order). End of input ends the child.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

from toggle_cosim import interrupts


class FigureWorker:
    """The child process, from the parent's side."""

    def __init__(self) -> None:
        with interrupts.starting_children():  # a Ctrl-C cannot hit the child in its imports
            self._process = subprocess.Popen(
                # -P: the current folder is not put first on sys.path (a toggle_cosim.py or copyreg.py
                # there never runs); the environment (PYTHONPATH, the user's site-packages) is kept
                [sys.executable, "-P", "-m", "toggle_cosim.analysis.figure_worker"],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                text=True,
                bufsize=1,
            )
        self._submitted = 0

    def submit(self, folder: Path) -> None:
        """Draw `folder`'s figure (its runs' trace.csv and run.json are written)."""
        assert self._process.stdin is not None
        self._process.stdin.write(f"{folder}\n")  # the child works in this folder too
        self._process.stdin.flush()
        self._submitted += 1

    def results(self) -> list[str]:
        """Wait for every figure: the child's lines ("wrote PATH" or "error: MESSAGE"), in order."""
        output, _ = self._process.communicate()
        lines = output.splitlines()
        if self._process.returncode != 0 or len(lines) != self._submitted:
            lines.append(
                f"error: the figure process ended with status {self._process.returncode} "
                f"after {len(lines)} of {self._submitted} figures"
            )
        return lines

    def stop(self) -> None:
        """End the child now (the command is failing or interrupted: its figures are not wanted);
        a figure being written is removed, not left half-written."""
        if self._process.poll() is None:
            self._process.terminate()
        try:
            self._process.communicate(timeout=2)
        except subprocess.TimeoutExpired:
            self._process.kill()
            self._process.communicate()


class FigureWorkers:
    """Several FigureWorker children, figures handed out in turn: on a machine with several
    cores the three paper figures are drawn side by side. Same interface as one worker; the
    lines come back in the order the folders were submitted."""

    def __init__(self, count: int) -> None:
        self._workers = [FigureWorker() for _ in range(max(1, count))]
        self._order: list[int] = []

    def submit(self, folder: Path) -> None:
        worker = len(self._order) % len(self._workers)
        self._workers[worker].submit(folder)
        self._order.append(worker)

    def results(self) -> list[str]:
        answers = [iter(worker.results()) for worker in self._workers]
        lines = [next(answers[worker], "error: the figure process gave no answer") for worker in self._order]
        return lines + [line for answer in answers for line in answer]  # a worker's own error line

    def stop(self) -> None:
        for worker in self._workers:
            worker.stop()


def _serve() -> int:
    # an interrupt is the parent's; end of input ends us. SIGTERM comes from stop(): while the
    # imports run there is nothing of ours to remove, and an exception raised inside an extension
    # module's initialisation (matplotlib's ft2font) ends in a traceback, so it ends the process
    # at once; after them, exiting by SystemExit removes a partial PNG on the way out
    interrupts.as_child(lambda *_: os._exit(130))
    from toggle_cosim.analysis import plots  # noqa: F401 - matplotlib's import, while the parent runs
    from toggle_cosim.analysis.results_figure import ResultsError, plot_results

    signal.signal(signal.SIGTERM, lambda *_: sys.exit(130))

    for line in sys.stdin:
        folder = Path(line.rstrip("\n"))
        try:
            print(f"wrote {plot_results(folder, None)}", flush=True)
        except (ResultsError, OSError) as error:  # OSError: e.g. an output path that is not a file
            print(f"error: {' '.join(str(error).split())}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(_serve())

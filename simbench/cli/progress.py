"""The terminal's one progress bar of a run or a sweep, whatever process runs the jobs.

A job reports to a :class:`JobStatus`: how many of its estimators are done and what it is doing
now (building the scenario, running ``l2``). In a single run the status lives in memory; in a
sweep each job writes it to ``<sweep dir>/.progress/job<N>.json`` (atomically), since Hydra's
joblib or submitit launchers run jobs in other processes, or on other machines that share the
folder. One :class:`LiveBar` in the process that started the run draws it: a thread redraws
the bar every :data:`REFRESH_S` from the status (files), so the elapsed time, a spinner and the
step's own time move while a scenario loads or one slow estimator runs. A sweep counts jobs
(done / total and an ETA), a single run estimators.
"""

from __future__ import annotations

import io
import json
import logging
import shutil
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO, cast

from tqdm import tqdm

from simbench.cli.text import one_line_warnings
from simbench.contract import write_bytes

#: Seconds between two redraws of the bar.
REFRESH_S = 0.25
#: The spinner's frames, one per redraw while something runs.
SPINNER = "|/-\\"
#: Folder of the sweep directory the jobs' status files are written to (removed when the sweep ends).
STATUS_DIR = ".progress"


class Planned:
    """What the command line said before Hydra started: jobs the sweep will run (None: not known)."""

    jobs: int | None = None


@dataclass
class Snapshot:
    """A run's or sweep's progress at one moment."""

    done: int  #: jobs finished (a sweep) or estimators done (a single run)
    estimators_done: int
    estimators: int  #: estimators of the jobs started so far
    steps: list[str]  #: what each running job is doing, with its time, e.g. ``job1 urban seed 1: l2 12s``
    messages: list[str]  #: every job's lines for the terminal so far, in order per job

    def state(self) -> tuple[object, ...]:
        """What changed when the bar must be redrawn without a terminal (no clock, no spinner)."""
        return self.done, self.estimators_done, [s.rpartition(" ")[0] for s in self.steps], len(self.messages)


class JobStatus:
    """One job's progress: a sink with tqdm's ``update`` and ``set_postfix_str``, which :func:`run_job` calls.

    Parameters
    ----------
    estimators : int
        Estimators of the job.
    path : Path, optional
        The JSON file the status is written to at each change (a sweep); None keeps it in memory.
    name : str
        The job's name in the bar, e.g. ``job1``.
    """

    def __init__(self, estimators: int, path: Path | None = None, name: str = "") -> None:
        self.estimators, self.path, self.name = estimators, path, name
        self.n, self.step, self.since, self.finished = 0, "preparing", time.time(), False
        self.messages: list[str] = []
        self._write()

    def message(self, line: str) -> None:
        """A line for the terminal (a warning), printed above the bar by the process that draws it."""
        self.messages.append(line)
        self._write()

    def update(self, n: int = 1) -> None:
        self.n += n
        self._write()

    def set_postfix_str(self, step: str) -> None:
        self.step, self.since = step, time.time()
        self._write()

    def close(self) -> None:
        self.finished = True
        self._write()

    def record(self) -> dict[str, object]:
        return {
            "name": self.name,
            "n": self.n,
            "estimators": self.estimators,
            "step": self.step,
            "since": self.since,
            "finished": self.finished,
            "messages": self.messages,
        }

    def _write(self) -> None:
        if self.path is not None:
            write_bytes(self.path, json.dumps(self.record()).encode())


def step_text(record: dict[str, object], now: float) -> str:
    """``job1 urban seed 1: l2 12s``: a running job's name, step and time in the step."""
    name = f"{record['name']} " if record.get("name") else ""
    return f"{name}{record['step']} {now - float(record['since']):.0f}s"  # type: ignore[arg-type]


def single_run(status: JobStatus) -> Callable[[], Snapshot]:
    """The reader of a single run's in-memory status: the bar counts estimators."""

    def read() -> Snapshot:
        record = status.record()
        steps = [] if status.finished else [step_text(record, time.time())]
        return Snapshot(status.n, status.n, status.estimators, steps, list(status.messages))

    return read


def sweep_files(directory: Path) -> Callable[[], Snapshot]:
    """The reader of a sweep's status files: the bar counts finished jobs."""

    def read() -> Snapshot:
        records = []
        for path in sorted(directory.glob("*.json")):
            try:
                records.append(json.loads(path.read_text()))
            except (OSError, ValueError):  # replaced between the listing and the read: the next redraw has it
                continue
        now = time.time()
        return Snapshot(
            done=sum(bool(r["finished"]) for r in records),
            estimators_done=sum(int(r["n"]) for r in records),
            estimators=sum(int(r["estimators"]) for r in records),
            steps=[step_text(r, now) for r in records if not r["finished"]],
            messages=[str(m) for r in records for m in r.get("messages", [])],
        )

    return read


def status_dir(sweep_dir: str | Path) -> Path:
    """Where a sweep's jobs write their :class:`JobStatus` files."""
    return Path(sweep_dir) / STATUS_DIR


class LiveBar:
    """One tqdm bar on stderr, redrawn by a thread from ``read`` until :meth:`close`.

    Parameters
    ----------
    read : callable
        Returns the current :class:`Snapshot` (:func:`single_run`, :func:`sweep_files`).
    total : int, optional
        Jobs (a sweep) or estimators (a single run); None: unknown, no ETA.
    unit : str
        ``job`` or ``est``.
    """

    def __init__(self, read: Callable[[], Snapshot], total: int | None, unit: str) -> None:
        self.read, self.unit = read, unit
        desc = "sweep" if unit == "job" else "estimators"
        self.bar = tqdm(total=total, desc=desc, unit=unit, dynamic_ncols=True, file=sys.stderr, mininterval=0)
        self._stop = threading.Event()
        self._frame = 0
        self._printed: set[str] = set()
        self._state: tuple[object, ...] | None = None
        # a log file gets a line when something happens, not four redraws a second of the clock
        self._clock = sys.stderr.isatty()
        self._thread = threading.Thread(target=self._run, name="simbench-progress", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(REFRESH_S):
            self.draw()

    def draw(self, final: bool = False) -> None:
        """Bring the bar to the current snapshot (the last time without a spinner)."""
        snap = self.read()
        for line in snap.messages:  # above the bar, once each
            if line not in self._printed:
                self._printed.add(line)
                self.bar.write(line, file=sys.stderr)
        if not (self._clock or final) and snap.state() == self._state:
            return
        self._state = snap.state()
        parts = []
        if self.unit == "job":  # the workers start before the first job reports (seconds under joblib)
            parts.append(f"{snap.estimators_done}/{snap.estimators} est" if snap.estimators else "starting the jobs")
        if snap.steps and not final:
            self._frame += 1
            parts.append(f"{SPINNER[self._frame % len(SPINNER)]} {' | '.join(snap.steps)}")
        self.bar.set_postfix_str(", ".join(parts), refresh=False)
        if snap.done > self.bar.n:
            self.bar.update(snap.done - self.bar.n)
        else:
            self.bar.refresh()

    def close(self) -> None:
        """Stop the thread, draw the final state and end the bar's line."""
        self._stop.set()
        self._thread.join()
        self.draw(final=True)
        self.bar.close()


@contextmanager
def job_progress(on: bool, estimators: int, results_dir: str, job: str | None) -> Iterator[JobStatus | None]:
    """The :class:`JobStatus` a job reports to while it runs (None when ``on`` is false).

    A sweep's job (``job`` named, e.g. ``job3``) writes ``job3.json`` for the parent's bar
    (:func:`start_sweep_bar`); a single run (``job`` None) draws its own :class:`LiveBar` over its
    estimators. Meanwhile simbench's warnings go through the status, so they print above the bar,
    not into it.
    """
    if not on:
        yield None
        return
    if job is not None:
        status, live = JobStatus(estimators, status_dir(results_dir) / f"{job}.json", job), None
    else:
        status = JobStatus(estimators)
        live = LiveBar(single_run(status), estimators, "est")
    one_line_warnings(status.message)
    try:
        yield status
    finally:
        status.close()
        if live is not None:
            live.close()
        one_line_warnings()  # what comes after the job (the report) prints as usual


class AboveBar(io.TextIOBase):
    """A text stream whose every complete line is written above a tqdm bar: the bar is cleared, the
    line written to ``stream`` and the bar drawn again (tqdm.write does so only for sys.stdout itself)."""

    def __init__(self, stream: TextIO, bar: tqdm) -> None:
        self.stream, self.bar, self.pending = stream, bar, ""

    def write(self, text: str) -> int:
        lines, newline, self.pending = (self.pending + text).rpartition("\n")
        if newline:
            with self.bar.get_lock():
                self.bar.clear(nolock=True)
                self.stream.write(lines + newline)
                self.stream.flush()
                self.bar.refresh(nolock=True)
        return len(text)

    def flush(self) -> None:
        if self.pending:
            self.write("\n")
        self.stream.flush()

    def isatty(self) -> bool:
        return self.stream.isatty()

    def fileno(self) -> int:
        return self.stream.fileno()


class SweepBar:
    """The bar of the sweep this process runs; a module-level holder, not an attribute of the Hydra
    callback, since the joblib launcher pickles the callbacks for its workers and a thread does not pickle."""

    current: LiveBar | None = None
    #: This process's standard output while the bar runs; meanwhile a line printed or logged to it (Hydra's
    #: "Launching 2 jobs", "#1 : seed=1") goes through tqdm.write, above the bar instead of after it
    stdout: TextIO | None = None


def start_sweep_bar(sweep_dir: str | Path) -> None:
    """Start the parent's bar over a sweep's jobs (:data:`Planned` jobs), reading fresh status files."""
    directory = status_dir(sweep_dir)
    shutil.rmtree(directory, ignore_errors=True)  # a killed sweep's files
    directory.mkdir(parents=True, exist_ok=True)
    SweepBar.current = LiveBar(sweep_files(directory), Planned.jobs, "job")
    SweepBar.stdout, sys.stdout = sys.stdout, cast(TextIO, AboveBar(sys.stdout, SweepBar.current.bar))
    # Hydra's log handlers hold the stream they were made with; a job's, made later, find the new one
    _swap_console_streams(SweepBar.stdout, sys.stdout)


def end_sweep_bar(sweep_dir: str | Path) -> None:
    """Close the sweep's bar at its final count and remove the status files."""
    if SweepBar.current is not None:
        SweepBar.current.close()
        SweepBar.current = None
    if SweepBar.stdout is not None:
        sys.stdout.flush()
        _swap_console_streams(sys.stdout, SweepBar.stdout)
        sys.stdout, SweepBar.stdout = SweepBar.stdout, None
    shutil.rmtree(status_dir(sweep_dir), ignore_errors=True)


def _swap_console_streams(old: TextIO, new: TextIO) -> None:
    """Point the root logger's console handlers that write to ``old`` at ``new``."""
    for handler in logging.root.handlers:
        if isinstance(handler, logging.StreamHandler) and handler.stream is old:
            handler.setStream(new)

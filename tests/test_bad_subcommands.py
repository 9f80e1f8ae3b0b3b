"""Every subcommand as careful as the run (issue 45, items 3 and 4): bad arguments, damaged files, faults.

Table-driven: each case damages a copy of one tiny run folder (30 s urban, the L2 estimator), or
injects a fault of the machine into the functions every file is written by (``Path.write_bytes``,
``Path.write_text``, ``pyarrow.parquet.write_table``, ``DataFrame.to_csv`` to a file: a full disk
``ENOSPC``, a forbidden ``EACCES``, an immutable ``EPERM``, a read-only mount ``EROFS``, or a kill), then runs
``python -m simbench tables|score|report|export|validate|zero-baseline`` in this process. A refusal
must be exit code 2 with one ``error:`` line naming the file or argument, never a traceback; a fault
must leave nothing half-written (no temporary file, no partial export) and no old report page
that does not say it is stale. CI runs as root, where ``chmod`` forbids nothing: an unwritable
folder is a ``tempfile.TemporaryFile`` that raises ``PermissionError`` in it.

Where a case is about the order of the checks, the command's computation (building the scenario,
the zero-baseline table) is replaced by one that fails the test if it is reached; elsewhere by the
fixture's cached scenario, so a case takes a fraction of a second.
"""

from __future__ import annotations

import contextlib
import errno
import functools
import importlib
import io
import shutil
import tempfile
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from conftest import empty, garble, truncate
from omegaconf import OmegaConf

import simbench.cli.callbacks
import simbench.cli.export
import simbench.cli.report
import simbench.cli.score
import simbench.cli.validate
import simbench.cli.zero_baseline
import simbench.runs.zero_baseline
from simbench.cli.callbacks import FinalizeRun
from simbench.cli.main import SUBCOMMANDS
from simbench.contract import Scenario
from simbench.data.export import export_scenario
from simbench.errors import SimbenchError, SimbenchWarning
from simbench.report.build import finalize
from simbench.runs.compose import compose_config
from simbench.runs.jobs import run_job
from simbench.runs.zero_baseline import COLUMNS as ZERO_BASELINE_COLUMNS

ARGS = ["estimator=[l2]", "scenario.duration_s=30", "progress=false"]
SECONDS_PER_WEEK = 604800
#: The marker of a stale page (simbench.report.stale.STALE_ID), spelled out: the test must not follow it.
STALE = "simbench-stale"


def subcommand(name: str) -> Callable[[list[str]], int]:
    """The ``main`` of subcommand ``name`` (its module is imported when it runs)."""
    return importlib.import_module(f"simbench.cli.{SUBCOMMANDS[name]}").main


@dataclass(frozen=True)
class World:
    """The session's tiny run folder, its scenario, and an exported RINEX log of it."""

    run: Path
    scenario: Scenario
    log: Path


@pytest.fixture(scope="module")
def world(tmp_path_factory: pytest.TempPathFactory) -> World:
    root = tmp_path_factory.mktemp("subcommands")
    run = root / "run"
    run_job(compose_config([*ARGS, f"results_dir={run}"]))
    finalize(run, None, figures=False)
    scenario = Scenario.load(next(run.glob("cache/*")))
    export_scenario(scenario, "rinex", root / "log", "log")
    return World(run, scenario, root / "log")


# --- damage -------------------------------------------------------------------------------------


def binary(path: Path) -> None:
    path.write_bytes(bytes(range(256)) * 4)


def other_table(path: Path) -> None:
    """A valid file of another table (a Parquet file for .parquet, a CSV otherwise)."""
    frame = pd.DataFrame({"a": [1, 2], "b": ["x", "y"]})
    frame.to_parquet(path) if path.suffix == ".parquet" else frame.to_csv(path, index=False)


def column_text(column: str) -> Callable[[Path], None]:
    def damage(path: Path) -> None:
        table = pd.read_csv(path, keep_default_na=False)
        table[column] = "abc"
        table.to_csv(path, index=False)

    damage.__name__ = f"{column}_abc"
    return damage


def study_times(path: Path) -> None:
    """A study collection's study_times.csv naming no study folder of this run (the run is its own)."""
    pd.DataFrame({"study": ["s"], "world": [""], "wall_s": [1.0], "results_dir": ["x"]}).to_csv(path, index=False)


def zero_baseline_csv(path: Path) -> None:
    pd.DataFrame([["urban", 0, "high", 30, 0.4, 0.3, 1.2, np.nan]], columns=ZERO_BASELINE_COLUMNS).to_csv(
        path, index=False
    )


#: Files of a run folder the tiny run has none of, made valid before a case damages them.
MADE = {"study_times.csv": study_times, "zero_baseline.csv": zero_baseline_csv}


def job(suffix: str) -> Callable[[Path], Path]:
    return lambda run: next(run.glob(f"jobs/*/l2-*{suffix}"))


# --- faults of the machine ----------------------------------------------------------------------


@dataclass(frozen=True)
class Fault:
    """A fault raised by every file write whose path contains ``where``, from its ``after``-th on (0: the first)."""

    code: int  #: errno, or 0 for a kill (KeyboardInterrupt)
    where: str = ""
    after: int = 0

    @property
    def label(self) -> str:
        return errno.errorcode[self.code] if self.code else "killed"


FAULTS = [Fault(errno.ENOSPC), Fault(errno.EACCES), Fault(errno.EPERM), Fault(errno.EROFS)]


@contextlib.contextmanager
def injected(fault: Fault | None, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Every write of a file (Path.write_bytes/write_text, pyarrow's write_table) raises ``fault``'s error."""
    if fault is None:
        yield
        return
    count = [0]

    def wrap(write: Callable[..., Any], name_of: Callable[..., str]) -> Callable[..., Any]:
        @functools.wraps(write)
        def faulty(*args: Any, **kwargs: Any) -> Any:
            name = name_of(*args)
            if name and fault.where in name:  # a file, not a buffer
                count[0] += 1
                if count[0] > fault.after:
                    if not fault.code:
                        raise KeyboardInterrupt
                    exc = PermissionError if fault.code in (errno.EACCES, errno.EPERM) else OSError
                    raise exc(fault.code, errno.errorcode[fault.code], name)
            return write(*args, **kwargs)

        return faulty

    with monkeypatch.context() as m:
        m.setattr(Path, "write_bytes", wrap(Path.write_bytes, lambda self, *a: str(self)))
        m.setattr(Path, "write_text", wrap(Path.write_text, lambda self, *a: str(self)))
        m.setattr(pq, "write_table", wrap(pq.write_table, lambda table, where, *a: str(where)))
        m.setattr(pd.DataFrame, "to_csv", wrap(pd.DataFrame.to_csv, lambda frame, where=None, *a: path_name(where)))
        yield


def path_name(where: Any) -> str:
    """The file a writer writes to, or '' for a buffer (``to_csv()`` into a string)."""
    return str(where) if isinstance(where, (str, Path)) else ""


def unwritable(which: str) -> Callable[[pytest.MonkeyPatch, Path], None]:
    """No file can be made in the case's folder ``which`` (``tmp``, ``run`` or ``report``): a read-only or
    immutable folder as root sees it (``chmod`` forbids root nothing)."""

    def patch(monkeypatch: pytest.MonkeyPatch, tmp: Path) -> None:
        refused_in = {"tmp": tmp, "run": tmp / "run", "report": tmp / "run" / "report"}[which].resolve()
        real = tempfile.TemporaryFile

        def refused(*args: Any, **kwargs: Any) -> Any:
            folder = kwargs.get("dir")
            if folder is not None and Path(folder).resolve() == refused_in:
                raise PermissionError(errno.EACCES, "Permission denied", str(folder))
            return real(*args, **kwargs)

        monkeypatch.setattr(tempfile, "TemporaryFile", refused)

    return patch


# --- the cases -----------------------------------------------------------------------------------

#: argv from (run folder, case folder); ``{run}``, ``{tmp}`` and ``{log}`` are filled in.
Argv = list[str]


@dataclass(frozen=True)
class Case:
    """One bad input or fault of a subcommand and what it must give.

    ``named`` is a fragment of the one ``error:`` line (``{run}``, ``{tmp}``, ``{log}`` filled in); with
    ``code`` 0 or 1 there is no error line and ``named`` must be in a warning (or is empty).
    """

    id: str
    command: str
    argv: Argv
    named: str
    code: int = 2
    damage: tuple[Callable[[Path], Path], Callable[[Path], None]] | None = None
    fault: Fault | None = None
    patch: Callable[[pytest.MonkeyPatch, Path], None] | None = None
    compute: str = "stub"  #: stub (the cached scenario), forbidden (a check must refuse first) or real


SUMMARY = (lambda run: run / "summary.parquet", None)
CLAIMS = (lambda run: run / "claims.csv", None)
TIMES = (lambda run: run / "study_times.csv", None)


def damaged(target: tuple[Callable[[Path], Path], Any], how: Callable[[Path], None]) -> tuple[Any, Any]:
    return (target[0], how)


def _tables_cases() -> list[Case]:
    run = ["{run}"]
    cases = [
        Case(f"summary {d.__name__}", "tables", run, "{run}/summary.parquet", damage=damaged(SUMMARY, d))
        for d in (truncate, empty, garble, binary, other_table)
    ]
    cases += [
        Case(f"claims {d.__name__}", "tables", run, "{run}/claims.csv", damage=damaged(CLAIMS, d))
        for d in (empty, binary, other_table, column_text("measured"), column_text("ci_low"))
    ]
    cases += [
        Case(f"study_times {d.__name__}", "tables", run, "{run}/study_times.csv", damage=damaged(TIMES, d))
        for d in (empty, binary, other_table, column_text("wall_s"))
    ]
    cases += [
        Case("run_dir a file", "tables", ["{run}/claims.csv"], "run_dir"),
        Case("run_dir missing", "tables", ["{tmp}/none"], "run_dir"),
        Case("only unknown", "tables", ["{run}", "--only", "bogus"], "--only"),
        Case(
            "only claims, claims damaged",
            "tables",
            ["{run}", "--only", "claims"],
            "claims.csv",
            damage=damaged(CLAIMS, empty),
        ),
    ]
    return [replace_id(c, "tables") for c in cases]


def replace_id(case: Case, prefix: str) -> Case:
    return Case(**{**case.__dict__, "id": f"{prefix}: {case.id}"})


def _score_cases() -> list[Case]:
    sel = ["{run}", "scenario=urban", "--name", "theirs", "--solution", "{tmp}/solution.csv"]
    key = ["{run}", "--scenario-key", "KEY", "--name", "theirs", "--solution", "{tmp}/solution.csv"]
    cases = [
        Case(f"summary {d.__name__}", "score", sel, "{run}/summary.parquet", damage=damaged(SUMMARY, d))
        for d in (truncate, garble, other_table)
    ]
    cases += [
        Case(f"job {s} damaged", "score", key, f"{s}", code=0, damage=(job(s), truncate))
        for s in (".summary.parquet", ".epochs.parquet")
    ]
    cases += [
        Case("RUN_DIR a file", "score", ["{run}/claims.csv", *sel[1:]], "RUN_DIR"),
        Case("RUN_DIR missing", "score", ["{tmp}/none", *sel[1:]], "RUN_DIR"),
        Case("report/ a file", "score", sel, "{run}/report", damage=(lambda r: r / "report", replace_by_file)),
        Case("RUN_DIR unwritable", "score", sel, "RUN_DIR", patch=unwritable("run")),
        Case("report/ unwritable", "score", sel, "{run}/report", patch=unwritable("report")),
        Case("its only row failed", "score", [*sel[:-1], "{tmp}/late.csv"], "", code=1),
        Case("solution missing", "score", [*sel[:-1], "{tmp}/none.csv"], "--solution"),
        Case("selector unknown", "score", [*sel[:1], "colour=red", *sel[2:]], "selector"),
        Case("name a registered estimator", "score", [*sel[:2], "--name", "l2", *sel[4:]], "--name"),
        Case("no --name", "score", [*sel[:2], *sel[4:]], "--name"),
    ]
    cases += [Case(f"store {f.label}", "score", sel, "jobs/", fault=Fault(f.code, "jobs/")) for f in FAULTS]
    cases += [
        Case(f"page {f.label}", "score", sel, "report/index.html", fault=Fault(f.code, "index.html"))
        for f in FAULTS[:2]
    ]
    cases.append(Case("killed while writing the page", "score", sel, "", code=-1, fault=Fault(0, "index.html", 1)))
    return [replace_id(c, "score") for c in cases]


def replace_by_file(path: Path) -> None:
    shutil.rmtree(path)
    path.write_text("not a folder")


def _report_cases() -> list[Case]:
    run = ["{run}"]
    cases = [
        Case(f"study_times {d.__name__}", "report", run, "{run}/study_times.csv", damage=damaged(TIMES, d))
        for d in (empty, binary, other_table, column_text("wall_s"))
    ]
    cases += [
        Case(
            "zero_baseline.csv damaged",
            "report",
            run,
            "zero_baseline.csv",
            code=0,
            damage=(lambda r: r / "zero_baseline.csv", column_text("mean_3d_diff_m")),
        ),
        Case("summary damaged (rebuilt)", "report", run, "", code=0, damage=damaged(SUMMARY, truncate)),
        Case("report/ a file", "report", run, "{run}/report", damage=(lambda r: r / "report", replace_by_file)),
        Case("run_dir unwritable", "report", run, "{run}", patch=unwritable("run")),
        Case("report/ unwritable", "report", run, "{run}/report", patch=unwritable("report")),
        Case("run_dir missing", "report", ["{tmp}/none"], "run_dir"),
        Case("formats unknown", "report", ["{run}", "--formats", "png,gif"], "report.formats"),
    ]
    cases += [
        Case(f"page {f.label}", "report", run, "{run}/report/index.html", fault=Fault(f.code, "index.html"))
        for f in FAULTS
    ]
    cases += [
        Case(
            "summary.parquet ENOSPC",
            "report",
            run,
            "{run}/summary.parquet",
            fault=Fault(errno.ENOSPC, "summary.parquet"),
        ),
        Case("claims.csv ENOSPC", "report", run, "{run}/claims.csv", fault=Fault(errno.ENOSPC, "claims.csv")),
        Case("killed while writing the page", "report", run, "", code=-1, fault=Fault(0, "index.html", 1)),
    ]
    return [replace_id(c, "report") for c in cases]


def _export_cases() -> list[Case]:
    sim = ["scenario.duration_s=30"]
    log = [
        "scenario=rinex",
        "scenario.obs={log}/log.obs",
        "scenario.nav={log}/log.nav",
        "scenario.truth={log}/log_truth.csv",
    ]
    cases = [
        Case("out a file", "export", [*sim, "out={run}/claims.csv"], "out", compute="forbidden"),
        Case("out under a file", "export", [*sim, "out={run}/claims.csv/x"], "out", compute="forbidden"),
        Case(
            "out unwritable", "export", [*sim, "out={tmp}/new/x"], "out", compute="forbidden", patch=unwritable("tmp")
        ),
        Case("out the log's folder", "export", [*log, "out={log}"], "out", compute="forbidden"),
        Case("out the log's folder, with a slash", "export", [*log, "out={log}/"], "out", compute="forbidden"),
        Case("out the log's folder, by ..", "export", [*log, "out={log}/../log"], "out", compute="forbidden"),
        Case("out empty", "export", [*sim, "out="], "out", compute="forbidden"),
        Case("format unknown", "export", [*sim, "format=csv", "out={tmp}/x"], "format", compute="forbidden"),
        Case("seed negative", "export", [*sim, "seed=-1", "out={tmp}/x"], "seed", compute="forbidden"),
    ]
    cases += [
        Case(f"second file {f.label}", "export", [*sim, "out={tmp}/out"], "{tmp}/out/", fault=Fault(f.code, "", 1))
        for f in FAULTS
    ]
    cases += [
        Case(
            "second file ENOSPC into an existing folder",
            "export",
            [*sim, "out={run}/cache"],
            "{run}/cache/",
            fault=Fault(errno.ENOSPC, "", 1),
        ),
        Case("killed after the first file", "export", [*sim, "out={tmp}/out"], "", code=-1, fault=Fault(0, "", 1)),
    ]
    return [replace_id(c, "export") for c in cases]


def _validate_cases() -> list[Case]:
    world = ["scenario.duration_s=30"]
    cases = [
        Case("out a file", "validate", [*world, "--out", "{run}/claims.csv"], "--out", compute="forbidden"),
        Case("out under a file", "validate", [*world, "--out", "{run}/claims.csv/x"], "--out", compute="forbidden"),
        Case(
            "out unwritable",
            "validate",
            [*world, "--out", "{tmp}/v"],
            "--out",
            compute="forbidden",
            patch=unwritable("tmp"),
        ),
        Case("out without a value", "validate", [*world, "--out"], "--out", compute="forbidden"),
        Case("mask not a number", "validate", [*world, "--mask", "abc"], "--mask", compute="forbidden"),
        *(
            Case(f"mask {m}", "validate", [*world, "--mask", m], "--mask", compute="forbidden")
            for m in ("95", "-5", "nan")
        ),
        Case("unknown flag", "validate", [*world, "--colour"], "--colour", compute="forbidden"),
    ]
    cases += [Case(f"write {f.label}", "validate", [*world, "--out", "{tmp}/v"], "{tmp}/v/", fault=f) for f in FAULTS]
    cases += [
        Case(
            "figure ENOSPC",
            "validate",
            [*world, "--out", "{tmp}/v"],
            "{tmp}/v/validation.png",
            fault=Fault(errno.ENOSPC, ".png"),
        ),
        Case("killed while writing", "validate", [*world, "--out", "{tmp}/v"], "", code=-1, fault=Fault(0, "", 1)),
    ]
    return [replace_id(c, "validate") for c in cases]


def _zero_baseline_cases() -> list[Case]:
    out = ["--out", "{tmp}/z"]
    cases = [
        Case("seed -1", "zero-baseline", ["urban", "--seed", "-1", *out], "--seed", compute="forbidden"),
        Case(
            "seed 1e20",
            "zero-baseline",
            ["urban", "--seed", "99999999999999999999", *out],
            "--seed",
            compute="forbidden",
        ),
        Case("seed not a number", "zero-baseline", ["urban", "--seed", "abc", *out], "--seed", compute="forbidden"),
        Case("out a file", "zero-baseline", ["urban", "--out", "{run}/claims.csv"], "--out", compute="forbidden"),
        Case(
            "out under a file", "zero-baseline", ["urban", "--out", "{run}/claims.csv/z"], "--out", compute="forbidden"
        ),
        Case("out unwritable", "zero-baseline", ["urban", *out], "--out", compute="forbidden", patch=unwritable("tmp")),
        Case("no scenario", "zero-baseline", ["scenario.duration_s=30", *out], "scenarios", compute="forbidden"),
        Case("unknown scenario", "zero-baseline", ["urbn", "scenario.duration_s=30", *out], "scenario", compute="real"),
        Case(
            "duration negative",
            "zero-baseline",
            ["urban", "scenario.duration_s=-30", *out],
            "scenario.duration_s",
            compute="real",
        ),
    ]
    cases += [
        Case(f"write {f.label}", "zero-baseline", ["urban", *out], "{tmp}/z/zero_baseline.csv", fault=f) for f in FAULTS
    ]
    cases.append(Case("killed while writing", "zero-baseline", ["urban", *out], "", code=-1, fault=Fault(0)))
    return [replace_id(c, "zero-baseline") for c in cases]


def _run_cases() -> list[Case]:
    """The run's own report (FinalizeRun, after the last job): a fault is one line and exit 2, not Hydra's warning."""
    cases = [
        Case(f"page {f.label}", "finalize-run", [], "{run}/report/index.html", fault=Fault(f.code, "index.html"))
        for f in FAULTS[:3]
    ]
    cases.append(Case("report/ unwritable", "finalize-run", [], "{run}/report", patch=unwritable("report")))
    return [replace_id(c, "run") for c in cases]


CASES = [
    *_tables_cases(),
    *_score_cases(),
    *_report_cases(),
    *_export_cases(),
    *_validate_cases(),
    *_zero_baseline_cases(),
    *_run_cases(),
]


# --- running a case ------------------------------------------------------------------------------


@dataclass
class Outcome:
    """What a case gave: ``traceback`` (an exception escaped), ``silent`` (exit 0 and no word), ``one-line``
    (the exit code asked for, one ``error:`` line naming what it should), or ``other`` (what it printed)."""

    kind: str
    code: int | None
    err: str
    warnings: list[str]
    exception: BaseException | None = None


def finalize_run(run: Path) -> int:
    """The run's report as Hydra's callback builds it after the last job; the exit code."""
    FinalizeRun().on_run_end(OmegaConf.create({"results_dir": str(run)}))
    return 0


def solution_csv(scenario: Scenario, path: Path, shift_s: float = 0.0) -> None:
    """The truth as another program's solution, CSV ``t,x,y,z`` (continuous GPS seconds, ECEF)."""
    truth = scenario.truth
    t = scenario.nav.gps_week * SECONDS_PER_WEEK + scenario.nav.start_sow_s + truth["t"].to_numpy() + shift_s
    pd.DataFrame({"t": t, "x": truth["x"], "y": truth["y"], "z": truth["z"]}).to_csv(path, index=False)


def run_case(case: Case, world: World, tmp: Path, monkeypatch: pytest.MonkeyPatch) -> Outcome:
    """Run ``case`` on a copy of the world's run folder in ``tmp``; what it gave."""
    run = tmp / "run"
    shutil.copytree(world.run, run)
    solution_csv(world.scenario, tmp / "solution.csv")
    solution_csv(world.scenario, tmp / "late.csv", shift_s=86400.0)  # a day late: no epoch matches
    key = next(run.glob("cache/*")).name
    fill = {"{run}": str(run), "{tmp}": str(tmp), "{log}": str(world.log)}

    def filled(text: str) -> str:
        for k, v in fill.items():
            text = text.replace(k, v)
        return text.replace("KEY", key)

    if case.damage is not None:
        target, how = case.damage
        path = target(run)
        if path.name in MADE:  # a file the tiny run has none of: a valid one first
            MADE[path.name](path)
        how(path)
    _stub_computation(case, world, monkeypatch)
    if case.patch is not None:
        case.patch(monkeypatch, tmp)
    argv = [filled(a) for a in case.argv]
    out, err = io.StringIO(), io.StringIO()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), injected(case.fault, monkeypatch):
                code = finalize_run(run) if case.command == "finalize-run" else subcommand(case.command)(argv)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 2
        except (Exception, KeyboardInterrupt) as exc:
            said = [str(w.message) for w in caught if issubclass(w.category, SimbenchWarning)]
            killed = isinstance(exc, KeyboardInterrupt) and case.code == -1
            return Outcome("killed" if killed else "traceback", None, err.getvalue(), said, exc)
    said = [str(w.message) for w in caught if issubclass(w.category, SimbenchWarning)]
    lines = [line for line in err.getvalue().splitlines() if line.startswith("error:")]
    named = filled(case.named)
    if code == case.code and case.code in (0, 1):
        return Outcome(
            "one-line" if not lines and (not named or any(named in w for w in said)) else "other",
            code,
            err.getvalue(),
            said,
        )
    if code == 0:
        return Outcome("silent", code, err.getvalue(), said)
    # the field as the line spells it (run_dir or RUN_DIR)
    ok = (
        code == case.code
        and len(lines) == 1
        and named.lower() in lines[0].lower()
        and "Traceback" not in err.getvalue()
    )
    return Outcome("one-line" if ok else "other", code, err.getvalue(), said)


def _stub_computation(case: Case, world: World, monkeypatch: pytest.MonkeyPatch) -> None:
    """The commands' computation: the cached scenario, a canned table, or a failure when reached."""
    monkeypatch.setattr(simbench.cli.report, "finalize", functools.partial(finalize, figures=False))
    monkeypatch.setattr(simbench.cli.score, "finalize", functools.partial(finalize, figures=False))
    monkeypatch.setattr(simbench.cli.callbacks, "finalize", functools.partial(finalize, figures=False))
    if case.compute == "real":
        return

    def reached(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError(f"{case.id}: computed before the arguments were checked")

    forbidden = case.compute == "forbidden"
    canned = pd.DataFrame([["urban", 0, "high", 30, 0.4, 0.3, 1.2, np.nan]], columns=ZERO_BASELINE_COLUMNS)
    monkeypatch.setattr(simbench.cli.export, "build_scenario", reached if forbidden else lambda sim: world.scenario)
    monkeypatch.setattr(
        simbench.cli.validate, "scenario_from_overrides", reached if forbidden else lambda o: (None, world.scenario)
    )
    monkeypatch.setattr(simbench.runs.zero_baseline, "zero_baseline", reached if forbidden else lambda *a, **k: canned)
    if not forbidden:  # a fault while writing: the three receivers' configs were checked by the cases above
        monkeypatch.setattr(simbench.runs.zero_baseline, "check_zero_baseline", lambda *a, **k: None)


# --- the test ------------------------------------------------------------------------------------


def leftovers(folder: Path) -> list[Path]:
    """Temporary files or folders of an atomic write left behind (simbench.contract.temporary_name)."""
    return [p for p in folder.rglob(".*.tmp")]


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_a_bad_subcommand_input_or_fault_is_one_line(
    case: Case, world: World, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    outcome = run_case(case, world, tmp_path, monkeypatch)
    expected = "killed" if case.code == -1 else "one-line"
    assert outcome.kind == expected, (outcome.kind, outcome.code, outcome.err, outcome.warnings, outcome.exception)
    assert not leftovers(tmp_path), leftovers(tmp_path)  # nothing half-written under a temporary name
    if case.fault is not None or case.patch is not None:
        run = tmp_path / "run"
        page = run / "report" / "index.html"
        if case.fault is not None and case.fault.where == "index.html":
            # the rebuild did not finish: the old page says so, or is gone (a full disk leaves no room to say it)
            assert not page.exists() or STALE in page.read_text(), case.id
        if case.command == "export":  # no file of a partial export
            out = tmp_path / "out"
            assert not out.exists() or not any(out.iterdir())
            assert sorted(p.name for p in (run / "cache").iterdir()) == sorted(
                p.name for p in (world.run / "cache").iterdir()
            )
        if case.command == "validate":
            assert not (tmp_path / "v").exists() or not any((tmp_path / "v").iterdir())
        if case.command == "zero-baseline":
            assert not (tmp_path / "z" / "zero_baseline.csv").exists()


def test_a_rebuilt_page_is_not_stale(world: World, tmp_path: Path) -> None:
    """The stale mark a failed rebuild leaves is gone once a rebuild finishes; a finished one never has it."""
    run = tmp_path / "run"
    shutil.copytree(world.run, run)
    page = run / "report" / "index.html"
    assert STALE not in page.read_text()
    # the page's second write fails: the stale mark (atomic) succeeds, the new page does not
    with pytest.MonkeyPatch.context() as m, injected(Fault(errno.ENOSPC, "index.html", 1), m):
        full = r"index\.html: cannot be written \(No space left on device\).*marked stale"
        with pytest.raises(SimbenchError, match=full):
            finalize(run, None, figures=False)
    assert STALE in page.read_text() and (run / "report" / "README.md").read_text().startswith("> **Stale:**")
    finalize(run, None, figures=False)
    assert STALE not in page.read_text() and "Stale" not in (run / "report" / "README.md").read_text()


def test_the_case_table_covers_every_subcommand_and_fault(world: World) -> None:
    commands = {c.command for c in CASES}
    assert commands == {*SUBCOMMANDS, "finalize-run"}
    for command in ("score", "report", "export", "validate", "zero-baseline"):
        kinds = {c.fault.label for c in CASES if c.command == command and c.fault is not None}
        assert {"ENOSPC", "EACCES", "killed"} <= kinds, (command, kinds)
    assert len(CASES) >= 80

"""No silent drops, and the exit codes README promises (issue 45): each case gets one line.

Table-driven: the command line (``main()`` in-process, argv monkeypatched: 2 and one line before any
job), the default run folder and the ``.hydra`` of earlier runs, ``report`` on a run without jobs,
reference rows lacking values, and a solution file whose times are in another time system.
"""

from __future__ import annotations

import dataclasses
import sys
import threading
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import one_line_error
from omegaconf import OmegaConf
from test_bad_logs import NAV, NAV_BDS, needs_hk, piece, piece_files, truth_rows  # noqa: F401 (fixtures)

import simbench
import simbench.cli.main
from simbench.cli import report
from simbench.cli.callbacks import FinalizeRun
from simbench.cli.main import main
from simbench.contract import Scenario
from simbench.core.constants import SECONDS_PER_WEEK
from simbench.data.reference import read_reference
from simbench.data.rinex import load_rinex
from simbench.errors import SimbenchWarning
from simbench.runs.foreign import check_time_system, score_solution_file
from simbench.runs.run_dirs import keep_earlier_configs, unique_run_dir

TINY = ["scenario.duration_s=30", "estimator=[l2]"]


def _simbench_warnings(fn: Callable[[], object]) -> tuple[object, list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = fn()
    return out, [str(w.message) for w in caught if issubclass(w.category, SimbenchWarning)]


def _main(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], args: list[str]) -> tuple[int, str]:
    """Run ``python -m simbench ARGS`` in-process; the exit code and stderr (0 and '' when it returns)."""
    monkeypatch.setattr("sys.argv", ["simbench", *args])
    try:
        main()
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    return code, capsys.readouterr().err.strip()


# ------------------------------------------------------------------ the command line: 2 and one line

#: (argv, stderr's start after 'error: ', a fragment). Before: 0 jobs and exit 0 (empty sweeps), Hydra's
#: error page and exit 1 (the rest), the unknown subcommand as "Error parsing override 'reprot'".
REFUSED: list[tuple[list[str], str, str]] = [
    # empty sweeps
    (["-m", "seed=range(5,0)"], "seed:", "'seed=range(5,0)' sweeps no value: 0 jobs"),
    (["-m", "seed=range(0,10,-1)"], "seed:", "sweeps no value"),
    (["-m", "seed=range(3,3)"], "seed:", "sweeps no value"),
    (["-m", "estimator=[l2]", "estimator.l2.prior_scale=range(2,1)"], "estimator.l2.prior_scale:", "no value"),
    (["--multirun", "seed=0,1", "receiver=range(1,1)"], "receiver:", "sweeps no value"),
    (["-m", "estimator=glob(zz*)"], "estimator:", "matches no estimator option: 0 jobs"),
    (["-m", "scenario=glob(mars*)"], "scenario:", "matches no scenario option"),
    # sweeps without -m
    (["seed=0,1"], "seed:", "'seed=0,1' is a sweep, and sweeps need -m -- run python -m simbench -m seed=0,1"),
    (["seed=range(3)"], "seed:", "sweeps need -m"),
    (["scenario=urban,flight"], "scenario:", "sweeps need -m"),
    (["estimator=[l2]", "estimator.l2.prior_scale=1,2"], "estimator.l2.prior_scale:", "sweeps need -m"),
    (["receiver=choice(low,high)"], "receiver:", "sweeps need -m"),
    # not a subcommand
    (["reprot", "results/x"], "command:", "unknown subcommand 'reprot' (did you mean 'report'?)"),
    (["expot"], "command:", "(did you mean 'export'?) -- the subcommands are report, export, score"),
    (["zero_baseline"], "command:", "did you mean 'zero-baseline'?"),
    (["results/run-1"], "command:", "unknown subcommand 'results/run-1'"),
    (["run", "seed=3"], "command:", "a run takes key=value overrides"),
    # what Hydra itself refuses
    (["seed=[1,2"], "override 'seed=[1,2':", "no viable alternative"),
    (["hydra.verbose=["], "override 'hydra.verbose=[':", ""),
    (["scenario.duration_s=30", "seed=1)"], "override 'seed=1)':", ""),
    (["--config-name", "nosuch"], "command line:", "Cannot find primary config 'nosuch'"),
    (["hydra.job.chdir=maybe"], "command line:", "hydra.job.chdir"),
    (["--cfg", "job", "seed=[1"], "override 'seed=[1':", ""),
]


@pytest.mark.parametrize(("args", "start", "fragment"), REFUSED, ids=[" ".join(c[0]) for c in REFUSED])
def test_refused_command_line_is_one_line_and_exit_2(
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    args: list[str],
    start: str,
    fragment: str,
) -> None:
    monkeypatch.chdir(tmp_path)  # a default run folder would be made here
    code, err = _main(monkeypatch, capsys, args)
    assert code == 2 and "\n" not in err and " -- " in err, err
    assert err.startswith(f"error: {start}") and fragment in err, err
    assert not (tmp_path / "results").exists() or not any((tmp_path / "results").iterdir())


@pytest.mark.parametrize(
    "args",
    [["-m", "seed=range(0,2)", *TINY], ["-m", "estimator=glob(l*)", "scenario.duration_s=30"], [*TINY, "seed=3"]],
    ids=["range(0,2)", "glob(l*)", "single run"],
)
def test_good_command_lines_reach_hydra_with_a_folder_of_their_own(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path, args: list[str]
) -> None:
    """Two runs of one second without results_dir get a folder each (before: one, shared)."""
    monkeypatch.chdir(tmp_path)
    handed: list[list[str]] = []

    def app() -> None:  # Hydra writes the run's .hydra into the folder it is handed
        handed.append(list(sys.argv))
        (Path(sys.argv[-1].removeprefix("results_dir=")) / ".hydra").mkdir()

    monkeypatch.setattr(simbench.cli.main, "_app", app)
    # both runs in the same second: the folder of the default name exists when the second starts
    monkeypatch.setattr(simbench.cli.main, "unique_run_dir", lambda p: unique_run_dir(p.with_name("run-same")))
    for _ in range(2):
        assert _main(monkeypatch, capsys, args) == (0, "")
    folders = [Path(argv[-1].removeprefix("results_dir=")) for argv in handed]
    assert [f.name for f in folders] == ["run-same", "run-same-2"]
    assert [argv[:-1] for argv in handed] == [["simbench", *args]] * 2


def test_a_reserved_folder_hydra_refuses_is_removed(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    monkeypatch.chdir(tmp_path)

    def app() -> None:
        raise SystemExit(2)

    monkeypatch.setattr(simbench.cli.main, "_app", app)
    assert _main(monkeypatch, capsys, TINY)[0] == 2
    assert list((tmp_path / "results").iterdir()) == []


def test_an_explicit_results_dir_is_kept(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    handed: list[list[str]] = []
    monkeypatch.setattr(simbench.cli.main, "_app", lambda: handed.append(list(sys.argv)))
    out = tmp_path / "mine"
    assert _main(monkeypatch, capsys, [*TINY, f"results_dir={out}"]) == (0, "")
    assert handed == [["simbench", *TINY, f"results_dir={out}"]] and not out.exists()


# ------------------------------------------------------------------ run folders and .hydra


def test_unique_run_dir_claims_the_first_free_name(tmp_path: Path) -> None:
    base = tmp_path / "results" / "run-20261129-061502"
    got = [unique_run_dir(base) for _ in range(3)]
    assert [p.name for p in got] == [base.name, f"{base.name}-2", f"{base.name}-3"]
    (tmp_path / "results" / "run-x").write_text("a file")
    assert unique_run_dir(tmp_path / "results" / "run-x").name == "run-x-2"
    msg = one_line_error(unique_run_dir, tmp_path / "results" / "run-x" / "below")
    assert msg.startswith("results_dir: cannot create a run folder")


def test_runs_started_at_once_get_a_folder_each(tmp_path: Path) -> None:
    got: list[Path] = []
    threads = [threading.Thread(target=lambda: got.append(unique_run_dir(tmp_path / "run"))) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(set(got)) == 8


#: (files before, files after, the number N kept). Before: the second run overwrote .hydra without a copy.
HYDRA_CASES: list[tuple[list[str], list[str], int | None]] = [
    ([".hydra/config.yaml"], [".hydra.1/config.yaml"], 1),
    ([".hydra/config.yaml", ".hydra.1/config.yaml"], [".hydra.1/config.yaml", ".hydra.2/config.yaml"], 2),
    (
        ["multirun.yaml", "job0/.hydra/config.yaml", "job1/.hydra/config.yaml"],
        ["job0/.hydra.1/config.yaml", "job1/.hydra.1/config.yaml", "multirun.1.yaml"],
        1,
    ),
    (["multirun.yaml", "multirun.3.yaml"], ["multirun.3.yaml", "multirun.4.yaml"], 4),
    (["summary.parquet", "jobs/.hydra/x"], ["jobs/.hydra/x", "summary.parquet"], None),  # the store is no job
    ([], [], None),
]


@pytest.mark.parametrize(("before", "after", "n"), HYDRA_CASES, ids=[" ".join(c[0]) or "empty" for c in HYDRA_CASES])
def test_an_earlier_runs_hydra_config_is_kept(
    tmp_path: Path, before: list[str], after: list[str], n: int | None
) -> None:
    for name in before:
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(name)
    config = OmegaConf.create({"hydra": {"run": {"dir": str(tmp_path)}}})
    got, messages = _simbench_warnings(lambda: keep_earlier_configs(tmp_path))
    assert got == n
    assert sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file()) == after
    assert len(messages) == (n is not None) and all(f"kept as .hydra.{n}" in m for m in messages), messages
    FinalizeRun().on_run_start(config)  # the callback again: nothing left to move
    assert sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file()) == after


# ------------------------------------------------------------------ report on a run without jobs


@pytest.mark.parametrize(
    ("make", "fragment"),
    [
        (lambda d: (d / "jobs").mkdir(), "no finished job"),
        (lambda d: (d / "jobs" / "abc").mkdir(parents=True), "no finished job"),
        (
            lambda d: ((d / "jobs" / "abc").mkdir(parents=True), (d / "jobs/abc/l2-x.epochs.parquet").write_text("")),
            "no finished job",
        ),
        (lambda d: None, "holds no jobs/ folder"),
    ],
    ids=["empty jobs", "empty scenario folder", "no summary file", "no jobs"],
)
def test_report_on_a_run_without_jobs_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], make: Callable[[Path], object], fragment: str
) -> None:
    """Before: an empty page and exit 0."""
    make(tmp_path)
    assert report.main([str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: run_dir:") and fragment in err and "\n" not in err
    assert not (tmp_path / "report").exists()


# ------------------------------------------------------------------ reference rows lacking a value


def _truth_lines(n: int = 100) -> list[str]:
    """A synthetic week,TOW,lat,lon,h reference: 1 Hz, moving north 1e-5 degrees (about 1.1 m) a second."""
    return [f"2051,{46701 + i},{22.3 + 1e-5 * i:.8f},114.17900000,6.5000" for i in range(n)]


def _field(lines: list[str], rows: range | list[int], col: int, value: str) -> list[str]:
    out = lines[:]
    for r in rows:
        f = out[r].split(",")
        f[col] = value
        out[r] = ",".join(f)
    return out


#: (name, file lines, rows kept, warning fragment or "", refusal fragment or ""). Before: every case read
#: without a word, the bad rows dropped.
TRUTH_CASES: list[tuple[str, list[str], int, str, str]] = [
    ("intact", _truth_lines(), 100, "", ""),
    ("header", ["week,TOW,lat,lon,h", *_truth_lines()], 100, "", ""),
    (
        "one nan lat",
        _field(_truth_lines(), [5], 2, "nan"),
        99,
        "1 of 100 rows lack a value (first at line 6: '2051,46706,nan,",
        "",
    ),
    (
        "a block of 30",
        _field(_truth_lines(), range(40, 70), 4, "NaN"),
        70,
        "30 of 100 rows lack a value (first at line 41",
        "",
    ),
    ("empty field", _field(_truth_lines(), [7], 3, ""), 99, "first at line 8", ""),
    ("text value", _field(_truth_lines(), [9], 3, "n/a"), 99, "'2051,46710,22.30009000,n/a,6.5000'", ""),
    ("nan time", _field(_truth_lines(), [3, 4], 1, "nan"), 98, "2 of 100 rows", ""),
    ("short line", [*_truth_lines()[:20], "2051,46721,22.3", *_truth_lines()[21:]], 99, "first at line 21", ""),
    ("header repeated inside", [*_truth_lines()[:50], "week,TOW,lat,lon,h", *_truth_lines()[50:]], 100, "line 51", ""),
    ("after a comment", ["# truth", "week,TOW,lat,lon,h", *_field(_truth_lines(), [0], 2, "nan")], 99, "line 3", ""),
    ("half", _field(_truth_lines(), range(0, 100, 2), 2, "nan"), 50, "50 of 100 rows", ""),
    ("most", _field(_truth_lines(), range(51), 2, "nan"), 0, "", "51 of 100 rows lack a value (first at line 1"),
    ("all nan", _field(_truth_lines(), range(100), 2, "nan"), 0, "", "contains no numeric rows"),
]


@pytest.mark.parametrize(("name", "lines", "kept", "warning", "refusal"), TRUTH_CASES, ids=[c[0] for c in TRUTH_CASES])
def test_reference_rows_lacking_a_value_are_said(
    tmp_path: Path, name: str, lines: list[str], kept: int, warning: str, refusal: str
) -> None:
    p = tmp_path / "truth.csv"
    p.write_text("\n".join(lines) + "\n")
    if refusal:
        msg = one_line_error(read_reference, p)
        assert msg.startswith(f"scenario.truth '{p}'") and refusal in msg, msg
        return
    ref, messages = _simbench_warnings(lambda: read_reference(p))
    assert isinstance(ref, simbench.data.Reference) and ref.t_gps.size == kept
    assert np.isfinite(ref.xyz).all() and np.isfinite(ref.t_gps).all()
    assert (messages == []) if not warning else (len(messages) == 1 and warning in messages[0]), messages
    if warning:
        assert messages[0].startswith(f"scenario.truth '{p}'") and "dropped them" in messages[0]


@pytest.mark.parametrize("sep", [" ", ","], ids=["SOW X Y Z", "t,x,y,z"])
def test_ecef_reference_rows_lacking_a_value_are_said(tmp_path: Path, sep: str) -> None:
    rows = [sep.join(["%.1f" % (46701 + i), "-2418000.0", "5385000.0", "2405000.0"]) for i in range(20)]
    rows[4] = rows[4].replace("5385000.0", "nan")
    p = tmp_path / "truth.txt"
    p.write_text("\n".join(rows) + "\n")
    ref, messages = _simbench_warnings(lambda: read_reference(p, week_hint=2051))
    assert isinstance(ref, simbench.data.Reference) and ref.t_gps.size == 19
    assert len(messages) == 1 and "1 of 20 rows lack a value (first at line 5" in messages[0]


@needs_hk
def test_log_truth_keeps_every_epoch_a_whole_row_covers(
    truth_rows: list[str],  # noqa: F811 (fixture)
    piece_files: Path,  # noqa: F811 (fixture)
    tmp_path: Path,
) -> None:
    """The Hong Kong piece (60 epochs from TOW 46710): a lone NaN row is bridged (a 2 s gap, truth_max_gap_s), a
    block of 10 leaves the epochs in it unscored, every other epoch keeps its truth; one warning says how many
    rows and where."""
    tow = [int(r.split(",")[1]) for r in truth_rows]
    block = [tow.index(t) for t in range(46730, 46740)]
    p = tmp_path / "truth.csv"
    p.write_text("\n".join(_field(truth_rows, [*block, tow.index(46750)], 2, "nan")) + "\n")
    sc, messages = _simbench_warnings(
        lambda: load_rinex(piece_files / "piece.obs", NAV, p, systems="GC", nav_bds_path=NAV_BDS)
    )
    # the epochs are tagged 3 ms after the whole second: the one at 46729.003 s falls into the gap too
    assert isinstance(sc, Scenario) and sorted(set(range(60)) - set(sc.truth["epoch"])) == list(range(19, 30))
    assert [m for m in messages if "truth" in m] == [
        f"scenario.truth '{p}': 11 of {len(truth_rows)} rows lack a value (first at line {block[0] + 1}: "
        f"'{truth_rows[block[0]].split(',', 2)[0]},46730,nan,{truth_rows[block[0]].split(',', 3)[3]}') -- "
        "dropped them: epochs only they would cover have no truth and are not scored"
    ]


# ------------------------------------------------------------------ a solution in another time system


@pytest.fixture(scope="module")
def urban() -> Scenario:
    return simbench.simulate("urban", "low", seed=0, **{"scenario.duration_s": 60})


def _solution(sc: Scenario, shift_s: float, east_m: float = 3.0, noise_m: float = 0.0) -> pd.DataFrame:
    """The truth moved ``east_m`` along x (plus noise), time-tagged ``shift_s`` off GPS time."""
    tr = sc.truth
    t = sc.nav.gps_week * SECONDS_PER_WEEK + sc.nav.start_sow_s + tr["t"].to_numpy()
    noise = np.random.default_rng(1000).normal(0.0, noise_m, (len(tr), 3))
    xyz = tr[["x", "y", "z"]].to_numpy() + noise + [east_m, 0.0, 0.0]
    return pd.DataFrame({"t_gps": t + shift_s, "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]})


#: (tag shift of the file [s], noise [m], the shift reported or 0 for no warning). Before: no case warned.
SHIFTS: list[tuple[float, float, float]] = [
    (0.0, 0.0, 0.0),
    (0.0, 5.0, 0.0),
    (-18.0, 0.0, 18.0),  # UTC under a GPST header
    (18.0, 0.0, -18.0),
    (-18.0, 5.0, 18.0),
    (-17.0, 0.0, 17.0),
    (-3.0, 0.0, 3.0),
    (0.002, 0.0, 0.0),  # a receiver clock's milliseconds are no time system
]


@pytest.mark.parametrize(("shift", "noise", "reported"), SHIFTS, ids=[f"{s:+g} s, {n:g} m" for s, n, _ in SHIFTS])
def test_solution_times_in_another_time_system_are_said(
    urban: Scenario, shift: float, noise: float, reported: float
) -> None:
    got, messages = _simbench_warnings(
        lambda: check_time_system(_solution(urban, shift, noise_m=noise), urban, 0.5, "sol.pos")
    )
    assert got == reported
    assert len(messages) == (reported != 0), messages
    if reported:
        assert messages[0].startswith("--solution 'sol.pos': its times fit the reference best shifted by")
        assert f"{reported:+g} s" in messages[0] and ("GPS-UTC" in messages[0]) == (abs(reported) == 18)


def test_static_solution_fits_every_shift_alike(urban: Scenario) -> None:
    still = urban.truth.assign(x=urban.truth["x"].iloc[0], y=urban.truth["y"].iloc[0], z=urban.truth["z"].iloc[0])
    sc = dataclasses.replace(urban, truth=still)
    got, messages = _simbench_warnings(lambda: check_time_system(_solution(sc, -18.0), sc, 0.5, "sol.pos"))
    assert got == 0.0 and messages == []


def test_a_truth_with_gaps_is_paired_by_epoch_index(urban: Scenario) -> None:
    """Epochs without truth (a reference outage; a real log's grid has gaps too): n_epochs counts truth rows, not
    epoch indices (before: IndexError)."""
    sc = dataclasses.replace(urban, truth=urban.truth[~urban.truth["epoch"].between(10, 19)].reset_index(drop=True))
    got, messages = _simbench_warnings(lambda: check_time_system(_solution(sc, -18.0), sc, 0.5, "sol.pos"))
    assert got == 18.0 and len(messages) == 1


def test_score_warns_about_a_utc_pos_file(tmp_path: Path, urban: Scenario) -> None:
    """End to end: an RTKLIB .pos whose header says GPST but whose times are UTC (18 s early)."""
    out = tmp_path / "run"
    simbench.run(estimators=["l2"], seeds=0, overrides={"scenario.duration_s": 60}, results_dir=out, progress=False)
    key = str(pd.read_parquet(out / "summary.parquet")["scenario_key"].iloc[0])
    sol = _solution(Scenario.load(out / "cache" / key), -18.0)
    week, tow = np.divmod(sol["t_gps"].to_numpy(), SECONDS_PER_WEEK)
    pos = ["%  GPST          x-ecef(m)      y-ecef(m)      z-ecef(m)   Q  ns   sdx(m)   sdy(m)   sdz(m)"]
    pos += [
        f"{w:.0f} {t:10.3f} {x:.4f} {y:.4f} {z:.4f} 5 8 1 1 1" for w, t, x, y, z in zip(week, tow, sol.x, sol.y, sol.z)
    ]
    (tmp_path / "utc.pos").write_text("\n".join(pos) + "\n")
    row, messages = _simbench_warnings(lambda: score_solution_file(out, key, "utc", tmp_path / "utc.pos"))
    assert len(messages) == 1 and f"--solution '{tmp_path / 'utc.pos'}'" in messages[0] and "+18 s" in messages[0]
    assert isinstance(row, pd.DataFrame) and row["horizontal_median"].iloc[0] > 10.0  # scored as written


def test_a_notebook_run_refused_leaves_no_folder(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """simbench.run claims its default folder as the command line does, and gives it back when a config is refused."""
    monkeypatch.chdir(tmp_path)
    msg = one_line_error(simbench.run, estimators=["l2"], overrides={"scenario.duration_s": -5}, progress=False)
    assert msg.startswith("scenario.duration_s:") and list((tmp_path / "results").iterdir()) == []

"""``python -m simbench`` end to end, and its one-line errors."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import run_simbench, simbench_summary

from estimators.baselines.rtklib_spp import RtklibSpp
from simbench.cli.main import SUBCOMMANDS, planned_jobs, suggest_names
from simbench.cli.score import scenario_key_of
from simbench.cli.terminal import SUMMARY_WIDTH, compact_summary
from simbench.contract import read_parquet_metadata
from simbench.errors import SimbenchError
from simbench.runs.checks import check_run
from simbench.runs.compose import available, compose_config, config_groups
from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.slow
def test_cli_writes_store_and_report(tmp_path: Path) -> None:
    out = tmp_path / "run"
    # 90 s as the smoke sweep: long enough for every estimator to run
    proc = run_simbench("scenario.duration_s=90", f"results_dir={out}", "progress=false", "seed=2")
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = pd.read_parquet(out / "summary.parquet")
    epochs = pd.read_parquet(out / "epochs.parquet")
    assert list(summary.columns) == list(SUMMARY_COLUMNS)
    assert list(epochs.columns) == list(EPOCH_COLUMNS)
    # every estimator runs on a simulated scenario (the RTKLIB baseline on the exported RINEX files), but
    # rtklib_spp where rnx2rtkp is not installed
    ran = summary["status"] == "ok"
    assert set(summary.loc[~ran, "estimator"]) <= {"rtklib_spp"}
    assert (summary.loc[~ran, "message"] == RtklibSpp.unavailable_reason()).all()
    assert set(summary.loc[ran, "estimator"]) == set(epochs["estimator"])
    assert (summary["seed"] == 2).all() and (summary["scenario"] == "urban").all()
    meta = read_parquet_metadata(out / "summary.parquet")
    assert meta["simbench.config"]["scenario"]["duration_s"] == 90
    assert len(meta["simbench.git_sha"]) >= 7 and "numpy" in meta["simbench.versions"]
    assert (out / "report" / "ecdf_urban_low.png").stat().st_size > 10_000
    assert "horizontal median" in (out / "report" / "README.md").read_text()
    # the compact summary: every estimator that ran, sorted by median, at most 100 columns
    lines = proc.stdout.splitlines()
    assert "h med [m]" in lines[0] and max(map(len, lines)) <= SUMMARY_WIDTH
    shown = [ln.split()[0] for ln in lines[2:] if ln.strip()]
    # the oracle, which reads the labels, is marked and listed last
    table = [name for name in shown if not name.endswith(":")]  # the notes of rows not ok follow the table
    assert set(summary["estimator"]) - {"oracle"} <= set(table) and "ekf_ppp" in table and table[-1] == "oracle†"


def test_cli_overrides_scenario_and_receiver(tmp_path: Path) -> None:
    out = tmp_path / "flight"
    # two estimators suffice: the rows must carry the scenario and receiver the command line chose
    summary = simbench_summary(
        out, "scenario=flight", "receiver=high", "seed=3", "scenario.duration_s=30", "estimator=[l2,ekf_ppp]"
    )
    assert len(summary) == 2 and (summary["status"] == "ok").all()
    assert (summary["scenario"] == "flight").all() and (summary["receiver"] == "high").all()
    assert (summary["seed"] == 3).all() and (summary["n_epochs"] == 30).all()


def test_cli_unknown_scenario_is_one_line() -> None:
    proc = run_simbench("scenario=mars")
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0
    assert "unknown scenario 'mars'" in proc.stderr and "urban" in proc.stderr


def test_a_misspelt_report_format_is_refused_before_any_job(tmp_path: Path) -> None:
    out = tmp_path / "run"
    line = _one_error_line(
        run_simbench("report.formats=[png,pfd]", "estimator=[l2]", f"results_dir={out}", "progress=false")
    )
    assert line == "error: report.formats: unknown pfd -- choose from png, pdf, svg"
    assert not out.exists()  # refused at the door: no job ran, no folder was made
    with pytest.raises(SimbenchError, match=r"^report.formats: is 'pdf', not a list -- .*report.formats=\[png,pdf\]"):
        check_run(compose_config(["report.formats=pdf"]))
    check_run(compose_config(["report.formats=[png,pdf,svg]", f"results_dir={out}"]))
    # a thesis run too: before its first study, not after its last
    thesis = run_simbench("+sweep=thesis", "report.formats=[pfd]", f"results_dir={out}")
    assert _one_error_line(thesis) == "error: report.formats: unknown pfd -- choose from png, pdf, svg"
    assert not out.exists()


def test_cli_negative_duration_is_one_line(tmp_path: Path) -> None:
    proc = run_simbench("scenario.duration_s=-3", f"results_dir={tmp_path}")
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines()[-1].startswith("error: scenario.duration_s")
    assert "Traceback" not in proc.stderr


def _one_error_line(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 2, proc.stderr[-2000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr[-2000:]
    return lines[0]


@pytest.mark.parametrize("source", ["missing_rinex", "malformed_librsf"])
def test_cli_scenario_that_cannot_be_built_ends_the_run_in_one_line(tmp_path: Path, source: str) -> None:
    if source == "missing_rinex":
        args, problem = ("scenario=hk_tst_2019", f"scenario.obs={tmp_path / 'none.obs'}"), "file does not exist"
    else:
        bad = tmp_path / "bad.txt"
        bad.write_text("garbage line\n1 2 3\n")
        args, problem = ("scenario=librsf", f"scenario.obs={bad}"), "unknown line types"
    out = tmp_path / "run"
    proc = run_simbench(*args, "estimator=[ekf_ppp,l2]", f"results_dir={out}", "progress=false")
    line = _one_error_line(proc)
    assert line.startswith("error: scenario.obs") and problem in line
    assert "failed" not in proc.stdout and "ekf_ppp" not in proc.stdout
    assert not (out / "jobs").exists() and not (out / "summary.parquet").exists()


def test_cli_sweep_records_a_scenario_failure_and_goes_on(tmp_path: Path) -> None:
    bad = tmp_path / "bad.txt"
    bad.write_text("garbage line\n")
    out = tmp_path / "sweep"
    proc = run_simbench(
        "-m",
        "scenario=librsf",
        f"scenario.obs={bad}",
        "seed=0,1",
        "estimator=[ekf_ppp,l2]",
        f"results_dir={out}",
        "progress=false",
    )
    assert proc.returncode == 1, proc.stderr[-2000:]  # every job ran, then the count of failed rows
    assert f"4 of 4 rows failed: see {out.resolve() / 'summary.parquet'}" in proc.stderr
    summary = pd.read_parquet(out / "summary.parquet")
    assert len(summary) == 4 and (summary["status"] == "failed").all()
    assert sorted(summary["seed"].unique()) == [0, 1]
    assert summary["message"].str.contains("unknown line types").all()


@pytest.mark.parametrize(
    "args",
    [
        ("estimator=[nosuch]",),
        ("estimator=nosuch",),
        ("estimator=[ekf_ppp,nosuch]",),
        ("-m", "estimator=[ekf_ppp],[nosuch]"),
    ],
)
def test_cli_unknown_estimator_names_the_known_ones(args: tuple[str, ...]) -> None:
    line = _one_error_line(run_simbench(*args))
    assert line.startswith("error: estimator: unknown estimator 'nosuch'")
    assert all(name in line for name in available("estimator"))
    assert "Could not load" not in line


def test_cli_unknown_scenario_in_a_sweep_is_one_line() -> None:
    line = _one_error_line(run_simbench("-m", "scenario=urban,mars"))
    assert "unknown scenario 'mars'" in line and "flight" in line


def test_cli_help_says_what_simbench_is_and_lists_the_groups() -> None:
    proc = run_simbench("--help")
    assert proc.returncode == 0, proc.stderr[-2000:]
    text = proc.stdout
    assert text.startswith("simbench -- a simulation-and-benchmark harness")
    for command in ("pip install -e . && python -m simbench", "+sweep=smoke", "python -m simbench report"):
        assert command in text
    for name in SUBCOMMANDS:  # every subcommand, not only report
        assert f"  python -m simbench {name} " in text, name
    assert "schema" not in text and "powered by Hydra" not in text
    lines = text.splitlines()
    for group in config_groups():
        key = "+sweep" if group == "sweep" else group
        line = next(ln for ln in lines if ln.startswith(f"  {key}: "))
        assert line.split(": ", 1)[1].split("  (")[0] == ", ".join(available(group))
    assert {"estimator", "scenario", "receiver", "imu", "sweep"} <= set(config_groups())


def test_a_misspelt_name_gets_a_suggestion() -> None:
    with pytest.raises(SimbenchError, match=r"unknown estimator 'dsc' \(did you mean 'dcs'\?\)"):
        suggest_names(["estimator=[l2,dsc]"])
    with pytest.raises(SimbenchError, match=r"unknown scenario 'urbn' \(did you mean 'urban'\?\)"):
        suggest_names(["scenario=urbn"])
    with pytest.raises(SimbenchError, match=r"^estimator.ekf_pp: unknown estimator 'ekf_pp' \(did you mean 'ekf_ppp'"):
        suggest_names(["estimator.ekf_pp.measurements=code"])
    with pytest.raises(SimbenchError, match=r"unknown estimator 'zzz' --"):  # nothing close: no guess
        suggest_names(["estimator=[zzz]"])
    suggest_names(["estimator=[l2,dcs]", "scenario=urban", "estimator.dcs.prior_scale=2"])


def test_compact_summary_sorts_by_median_and_fits_100_columns() -> None:
    rows = pd.DataFrame(
        [
            {"estimator": "dcs", "overrides": '{"prior_scale":10.0,"some_long_setting_name":"a-long-value"}'},
            {"estimator": "dcs", "overrides": "{}"},
            {"estimator": "l2", "overrides": "{}"},
            {"estimator": "ekf_ins", "overrides": "{}", "status": "failed", "message": "x" * 200},
            {"estimator": "oracle", "overrides": "{}"},
        ]
    ).assign(
        status=lambda f: f.get("status", pd.Series("ok", index=f.index)).fillna("ok"),
        gnss_model="urban",
        availability=[1.0, 1.0, 0.4, 0.0, 1.0],
        horizontal_median_ref=[3.0, 2.0, np.inf, np.nan, 0.5],
        horizontal_p95_ref=[4.0, 3.0, np.inf, np.nan, 1.0],
        error_3d_median_ref=[5.0, 4.0, np.inf, np.nan, 1.0],
        total_s=[1.0, 2.0, 0.5, np.nan, 1.0],
        n_epochs=100,
        uses_labels=[False, False, False, False, True],
    )
    lines = compact_summary(rows).splitlines()
    names = [ln.split()[0] for ln in lines[2:7]]
    assert names[0] == "dcs" and names[1].startswith("dcs[prior_scale=10.0,") and names[1].endswith("…")
    # undefined medians, then no ok row at all; the oracle, best of all, ranked apart as a floor
    assert names[2:] == ["l2", "ekf_ins", "oracle†"] and "—" in lines[4]
    assert lines[7].startswith("ekf_ins: failed: xxx") and len(lines) == 8
    assert max(map(len, lines)) <= SUMMARY_WIDTH and "20.0" in lines[2]  # 2 s over 100 epochs = 20 ms


def test_score_finds_the_scenario_by_name_and_seed(tmp_path: Path) -> None:
    pd.DataFrame(
        {
            "scenario_key": ["k0", "k0", "k1", "k2"],
            "scenario": ["urban", "urban", "urban", "flight"],
            "seed": [0, 0, 1, 0],
            "receiver": "low",
            "sweep": "",
            "source": "simulated",
        }
    ).to_parquet(tmp_path / "summary.parquet")
    assert scenario_key_of(tmp_path, ["scenario=urban", "seed=1"]) == "k1"
    assert scenario_key_of(tmp_path, ["scenario=flight"]) == "k2"
    with pytest.raises(SimbenchError, match="match 2 scenarios"):
        scenario_key_of(tmp_path, ["scenario=urban"])
    with pytest.raises(SimbenchError, match="is not key=value"):
        scenario_key_of(tmp_path, ["world=urban"])


def test_a_sweep_knows_its_job_count_for_the_progress_bar() -> None:
    args = ["-m", "seed=0,1,2", "receiver=low,high", "estimator=[l2]"]
    assert planned_jobs(args, compose_config(["estimator=[l2]"], with_hydra=True)) == 6
    # a sweep file's params count where the command line does not set the key: smoke is 2 scenarios x 2 seeds
    assert planned_jobs(["+sweep=smoke"], compose_config(["+sweep=smoke"], with_hydra=True)) == 4

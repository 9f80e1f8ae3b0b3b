"""Bad configs stop at the door: one line naming the field, exit 2, before any job (issue 25).

Table-driven: each case composes ``conf/config.yaml`` with its overrides
(:func:`simbench.runs.compose.compose_config`) and runs the up-front check
(:func:`simbench.runs.checks.check_run`), as ``python -m simbench`` does. A few
subprocess runs pin the exit codes: 0 with a diverged or skipped row, 1 with a
failed row (after every job ran), 2 for a refused config.
"""

from __future__ import annotations

import errno
import subprocess
import sys
import tempfile
from pathlib import Path

import pandas as pd
import pytest
from conftest import one_line_error

from simbench.cli.main import check_jobs, job_overrides, main
from simbench.runs.checks import check_run
from simbench.runs.compose import compose_config

ROOT = Path(__file__).resolve().parent.parent
TINY = ["scenario.duration_s=30"]
#: Any existing file, for a real-log scenario whose bad value is checked before the file is read.
TINY_FILE = ROOT / "README.md"

#: (overrides, the field the one-line error starts with, a fragment of the message or "")
CASES: list[tuple[list[str], str, str]] = [
    # scenario
    (["scenario.duration_s=0"], "scenario.duration_s", "positive"),
    (["scenario.duration_s=-5"], "scenario.duration_s", "positive"),
    (["scenario.duration_s=nan"], "scenario.duration_s", "positive"),
    (["scenario.duration_s=1e9"], "scenario.duration_s", "GB"),
    (["scenario.duration_s=inf"], "scenario.duration_s", "GB"),
    (["scenario.rate_hz=1e6"], "scenario.duration_s", "GB"),
    (["scenario.duration_s=abc"], "scenario.duration_s", ""),
    (["scenario.rate_hz=0"], "scenario.rate_hz", "positive"),
    # one epoch or none failed with an IndexError in the troposphere model after the bar started
    (["scenario.duration_s=1"], "scenario.duration_s", "gives 1 epoch(s), fewer than 2"),
    (["scenario.rate_hz=0.001"], "scenario.duration_s", "gives 0 epoch(s), fewer than 2"),
    (["scenario.constellation.elevation_mask_deg=-30"], "scenario.constellation.elevation_mask_deg", "[0, 90)"),
    (["scenario.constellation.elevation_mask_deg=90"], "scenario.constellation.elevation_mask_deg", "[0, 90)"),
    (["scenario.trajectory.kind=boat"], "scenario.trajectory.kind", ""),
    (["scenario.constellation.kind=broadcast"], "scenario.constellation.nav_path", "no navigation file"),
    # every number of the scenario by the unit in its name (simbench.bounds); these ran, or ran a broken world
    (["scenario.errors.multipath.code_sigma_m=-1"], "scenario.errors.multipath.code_sigma_m", "0 .. 1000"),
    (["scenario.errors.multipath.code_sigma_m=nan"], "scenario.errors.multipath.code_sigma_m", "got nan"),
    (["scenario.errors.multipath.code_sigma_m=1e9"], "scenario.errors.multipath.code_sigma_m", "not a ranging error"),
    (["scenario.errors.multipath.tau_s=-3"], "scenario.errors.multipath.tau_s", "positive"),
    (["scenario.errors.multipath.tau_s=0"], "scenario.errors.multipath.tau_s", "positive"),
    (["scenario.errors.multipath.el_c_deg=0"], "scenario.errors.multipath.el_c_deg", "positive"),
    (["scenario.errors.orbit_clock.orbit_sigma_m=inf"], "scenario.errors.orbit_clock.orbit_sigma_m", "got inf"),
    (["scenario.errors.ionosphere.scale_sigma=-1"], "scenario.errors.ionosphere.scale_sigma", "at least 0"),
    (["scenario.errors.ionosphere.residual_tau_s=nan"], "scenario.errors.ionosphere.residual_tau_s", "got nan"),
    (["scenario.errors.troposphere.wet_rw_mps=-1"], "scenario.errors.troposphere.wet_rw_mps", "at least 0"),
    (["scenario.errors.receiver_clock.h0=-1"], "scenario.errors.receiver_clock.h0", "at least 0"),
    (["scenario.errors.nlos.open_fraction=2"], "scenario.errors.nlos.open_fraction", "0 .. 1"),
    (["scenario.errors.nlos.reflection_probability=-0.1"], "scenario.errors.nlos.reflection_probability", "0 .. 1"),
    (["scenario.errors.nlos.building_height_m=[40,10]"], "scenario.errors.nlos.building_height_m", "above high"),
    (["scenario.errors.nlos.wall_distance_m=[-1,3]"], "scenario.errors.nlos.wall_distance_m", "[-1.0, 3.0]"),
    (["scenario.errors.cycle_slips.max_jump_cycles=-2"], "scenario.errors.cycle_slips.max_jump_cycles", "at least 1"),
    (["scenario.errors.cycle_slips.rate_per_s=-1"], "scenario.errors.cycle_slips.rate_per_s", "at least 0"),
    # a NaN fading sigma was blamed on the acquisition threshold
    (["scenario.errors.cn0.noise_db=nan"], "scenario.errors.cn0.noise_db", "got nan"),
    (["scenario.errors.cn0.received_power_dbw=-50"], "scenario.errors.cn0.received_power_dbw", "-200 .. -100"),
    (["scenario.errors.cn0.constant_db=nan"], "scenario.errors.cn0.constant_db", "finite"),
    (["scenario.gps_week=-1"], "scenario.gps_week", "0 .. 9999"),
    (["scenario.start_sow_s=nan"], "scenario.start_sow_s", "seconds of the week"),
    (["scenario.start_sow_s=700000"], "scenario.start_sow_s", "seconds of the week"),
    (["scenario.trajectory.origin_lat_deg=95"], "scenario.trajectory.origin_lat_deg", "latitude"),
    (["scenario.trajectory.origin_lon_deg=-200"], "scenario.trajectory.origin_lon_deg", "longitude"),
    (["scenario.trajectory.urban_drive.cruise_speed_mps=-1"], "scenario.trajectory.urban_drive.cruise_speed_mps", ""),
    (["scenario.trajectory.urban_drive.n_blocks_east=0"], "scenario.trajectory.urban_drive.n_blocks_east", "least 1"),
    (["scenario.trajectory.urban_drive.stop_duration_s=[30,5]"], "scenario.trajectory.urban_drive.stop_duration_s", ""),
    (["scenario=flight", "scenario.trajectory.flight.airspeed_mps=0"], "scenario.trajectory.flight.airspeed_mps", ""),
    (["scenario=flight", "scenario.trajectory.flight.climb_rate_mps=0"], "scenario.trajectory.flight", "positive"),
    (["scenario.odometry.rate_hz=0"], "scenario.odometry.rate_hz", "positive"),
    (["scenario.odometry.speed_sigma_mps=-0.1"], "scenario.odometry.speed_sigma_mps", "at least 0"),
    (["scenario=replay", "scenario.trajectory.replay.gps_week=-5"], "scenario.trajectory.replay.gps_week", "0 .. 9999"),
    (["scenario=replay", "scenario.trajectory.replay.max_gap_s=0"], "scenario.trajectory.replay.max_gap_s", "positive"),
    (["receiver.doppler_ref_cn0_dbhz=nan"], "receiver.doppler_ref_cn0_dbhz", "dB-Hz"),
    # physical consistency: L2 generated for an L1-only chip on 100 % of rows, without a word
    (["scenario.dual_frequency=true", "receiver=consumer"], "scenario.dual_frequency", "tracks L1 only"),
    (["scenario=flight", "receiver=consumer"], "scenario.dual_frequency", "tracks L1 only"),
    # real logs' settings (simbench.source_registry.Source.check): a false "does not overlap" after loading before
    (["scenario=hk_tst_2019", "scenario.truth_max_gap_s=-1"], "scenario.truth_max_gap_s", "positive"),
    (["scenario=hk_tst_2019", "scenario.truth_max_gap_s=nan"], "scenario.truth_max_gap_s", "got nan"),
    (["scenario=librsf", f"scenario.obs={TINY_FILE}", "scenario.start_sow_s=nan"], "scenario.start_sow_s", "week"),
    (["scenario=librsf", f"scenario.obs={TINY_FILE}", "scenario.gps_week=-3"], "scenario.gps_week", "0 .. 9999"),
    # receiver
    (
        ["receiver.acquisition_threshold_dbhz=80", "receiver.lock_threshold_dbhz=70"],
        "receiver.acquisition_threshold_dbhz",
        "no satellite is ever acquired",
    ),
    (["receiver.acquisition_threshold_dbhz=20"], "receiver.acquisition_threshold_dbhz", "lock threshold"),
    (["receiver.integration_s=10"], "receiver.integration_s", "0.001..0.02"),
    (["receiver.integration_s=0.0005"], "receiver.integration_s", "0.001..0.02"),
    (["receiver.integration_s=0"], "receiver.integration_s", "positive"),
    (["receiver.correlator_spacing_chips=3"], "receiver.correlator_spacing_chips", "2 chips"),
    (["receiver.dll_bw_hz=-1"], "receiver.dll_bw_hz", "positive"),
    (["receiver.sampling_mhz=0"], "receiver.sampling_mhz", "positive"),
    (["receiver.doppler_sigma_hz=-0.5"], "receiver.doppler_sigma_hz", "at least"),
    (["receiver.reacquisition_s=-1"], "receiver.reacquisition_s", "at least"),
    # IMU
    (["imu.accel_bias_sigma_mps2=1e6"], "imu.accel_bias_sigma_mps2", "beyond any IMU grade), got 1000000.0"),
    (["imu.accel_bias_sigma_mps2=-1"], "imu.accel_bias_sigma_mps2", ""),
    (["imu.gyro_bias_sigma_dph=inf"], "imu.gyro_bias_sigma_dph", ""),
    (["imu.accel_noise_mps2_rthz=nan"], "imu.accel_noise_mps2_rthz", ""),
    (["imu.gyro_noise_dph_rthz=1e9"], "imu.gyro_noise_dph_rthz", ""),
    (["imu.gyro_bias_instability_dph=1e7"], "imu.gyro_bias_instability_dph", ""),
    (["imu.rate_hz=10"], "imu.rate_hz", "100..1000"),
    (["imu.bias_tau_s=0"], "imu.bias_tau_s", "positive"),
    (["imu.bias_tau_s=inf"], "imu.bias_tau_s", "finite"),
    # estimators: each selected estimator's Config.validate, before any job
    (["estimator=[dcs]", "estimator.dcs.prior_scale=-1"], "estimator.dcs.prior_scale", "positive"),
    (["estimator=[isam2_dcs]", "estimator.isam2_dcs.lag_s=-10"], "estimator.isam2_dcs.lag_s", "at least 0"),
    (["estimator=[dcs]", "estimator.dcs.kernel_width=0"], "estimator.dcs.kernel_width", "positive"),
    (["estimator=[isam2_dcs]", "estimator.isam2_dcs.kernel_width=-1"], "estimator.isam2_dcs.kernel_width", ""),
    (["estimator=[l2]", "estimator.l2.elevation_mask_deg=95"], "estimator.l2.elevation_mask_deg", "[0, 90)"),
    (["estimator=[l2]", "estimator.l2.max_iterations=0"], "estimator.l2.max_iterations", "at least 1"),
    (["estimator=[ekf_ppp]", "estimator.ekf_ppp.code_sigma_m=0"], "estimator.ekf_ppp.code_sigma_m", "positive"),
    (["estimator=[mm]", "estimator.mm.outlier_weight=2"], "estimator.mm.outlier_weight", "(0, 1)"),
    (["estimator=[isam2_mm]", "estimator.isam2_mm.outlier_scale=0.5"], "estimator.isam2_mm.outlier_scale", ""),
    (["estimator=[isam2_ppp]", "estimator.isam2_ppp.relinearize_skip=0"], "estimator.isam2_ppp.relinearize_skip", ""),
    (["estimator=[bce]", "estimator.bce.truncation=0"], "estimator.bce.truncation", "at least 1"),
    (["estimator=[bce_ad]", "estimator.bce_ad.n_features=9"], "estimator.bce_ad.n_features", ""),
    (["estimator=[ice]", "estimator.ice.alpha=1.5"], "estimator.ice.alpha", "out of range"),
    (["estimator=[crt_lss]", "estimator.crt_lss.lambda_rho=0"], "estimator.crt_lss.lambda_rho", "positive"),
    (["estimator=[crt_lss]", "estimator.crt_lss.window=0"], "estimator.crt_lss.window", "at least 1"),
    (["estimator=[ekf_ins]", "estimator.ekf_ins.elevation_mask_deg=-1"], "estimator.ekf_ins.elevation_mask_deg", ""),
    (["estimator=[ekf_ins]", "estimator.ekf_ins.gate=0"], "estimator.ekf_ins.gate", "positive"),
    (["estimator=[ekf_ins]", "estimator.ekf_ins.accel_bias_sigma_mps2=1e6"], "estimator.ekf_ins", "IMU grade"),
    (["estimator=[rtklib_spp]", "estimator.rtklib_spp.elevation_mask_deg=90"], "estimator.rtklib_spp", "[0, 90)"),
    (["estimator.dcs.prior_scale=-1"], "estimator.dcs.prior_scale", "positive"),  # in the default estimator=all
    # NaN and infinity in any estimator's parameters (estimators.base.validate_config)
    (["estimator=[l2]", "estimator.l2.clock_sigma_m=nan"], "estimator.l2.clock_sigma_m", "finite"),
    (["estimator=[ekf_ppp]", "estimator.ekf_ppp.code_sigma_m=inf"], "estimator.ekf_ppp.code_sigma_m", "finite"),
    (["estimator=[ice]", "estimator.ice.alpha=nan"], "estimator.ice.alpha", "finite"),
    (["estimator=[dcs]", "estimator.dcs.kernel_width=inf"], "estimator.dcs.kernel_width", "finite"),
    (["estimator=[crt_lss]", "estimator.crt_lss.lambda_rho=inf"], "estimator.crt_lss.lambda_rho", "finite"),
    # typos, with and without '+'
    (["+scenario.duraton_s=10"], "scenario.duraton_s", "did you mean scenario.duration_s?"),
    (["scenario.duraton_s=10"], "scenario.duraton_s", ""),
    (["+scenario.errors.nlos.enabeld=false"], "scenario.errors.nlos.enabeld", "scenario.errors.nlos.enabled"),
    (["+receiver.integration=0.001"], "receiver.integration", "did you mean receiver.integration_s?"),
    (["+imu.rate=100"], "imu.rate", "did you mean imu.rate_hz?"),
    (["receiver.integraton_s=0.001"], "receiver.integraton_s", ""),
    (["estimator=[l2]", "+estimator.l2.prior_scal=2"], "estimator.l2.prior_scal", ""),
    (["estimator=[l2]", "estimator.l2.prior_scal=2"], "estimator.l2.prior_scal", ""),
    (["+seeed=3"], "seeed", "did you mean seed?"),
    # estimator selection
    (["estimator=[]"], "estimator", "no estimator selected"),
    (["estimator=[l2,nosuch]"], "estimator", "unknown estimator 'nosuch'"),
    (["estimator=nosuch"], "estimator", "unknown estimator 'nosuch'"),
    (["scenario=mars"], "scenario", "unknown scenario 'mars'"),
    # run options (before: numpy's message or an OverflowError after the estimators ran, after the bar started)
    (["seed=-1"], "seed", "0 .. 2**63-1"),
    (["seed=99999999999999999999"], "seed", "0 .. 2**63-1"),
    (["seed=1.5"], "seed", "0 .. 2**63-1"),
    (["progress=maybe"], "progress", "true or false"),
    # results_dir
    (["results_dir="], "results_dir", "is empty"),
    (["results_dir=/proc/simbench_run"], "results_dir", "cannot write"),
]


def _check(overrides: list[str]) -> None:
    logs = [o for o in overrides if o.startswith("scenario=") and o not in ("scenario=flight", "scenario=replay")]
    simulated = not logs
    check_run(compose_config([*(TINY if simulated else []), *overrides]))


@pytest.mark.parametrize(("overrides", "field", "fragment"), CASES, ids=[" ".join(c[0]) for c in CASES])
def test_bad_config_is_one_line_naming_the_field(overrides: list[str], field: str, fragment: str) -> None:
    message = one_line_error(_check, overrides)
    assert message.startswith((f"{field}:", f"{field}.")), message
    assert fragment in message, message


def test_results_dir_that_is_a_file_or_under_one(tmp_path: Path) -> None:
    afile = tmp_path / "notes.txt"
    afile.write_text("x")
    for path in (afile, afile / "run"):
        message = one_line_error(_check, [*TINY, f"results_dir={path}"])
        assert message.startswith("results_dir:") and "is a file" in message


def test_read_only_results_dir(tmp_path: Path, monkeypatch) -> None:
    """A folder no file can be made in (read-only, immutable, or not ours). CI runs as root, which
    writes through chmod, so the refusal of the temporary file is simulated: before, this test was
    skipped there."""
    folder = tmp_path / "locked"
    folder.mkdir()
    make = tempfile.TemporaryFile

    def refuse(*args, **kwargs):
        if Path(kwargs.get("dir") or ".") == folder:
            raise PermissionError(errno.EACCES, "Permission denied", str(folder))
        return make(*args, **kwargs)

    monkeypatch.setattr(tempfile, "TemporaryFile", refuse)
    message = one_line_error(_check, [*TINY, f"results_dir={folder / 'run'}"])
    assert message.startswith("results_dir:") and "cannot write" in message and "Permission denied" in message


def test_good_configs_pass(tmp_path: Path) -> None:
    _check([*TINY, f"results_dir={tmp_path / 'new' / 'run'}"])  # a missing folder is created by the run
    _check([*TINY, "receiver=consumer", "imu=tactical", "estimator=[l2,isam2_dcs]"])
    assert not (tmp_path / "new").exists()


def test_job_overrides_cover_every_swept_value() -> None:
    jobs = job_overrides(["-m", "estimator=[l2]", "seed=0,1", "estimator.l2.prior_scale=1,-1", "hydra.verbose=true"])
    assert jobs == [  # a seed sweep is checked at its first seed: no check depends on it
        ["estimator=[l2]", "seed=0", "estimator.l2.prior_scale=1"],
        ["estimator=[l2]", "seed=0", "estimator.l2.prior_scale=-1"],
    ]
    assert job_overrides(["--help"]) is None


def test_a_sweep_files_params_are_checked_too(monkeypatch) -> None:
    checked: list[float] = []
    # check_jobs imports it when it runs (simbench.cli.main imports no config check, for --help's start-up)
    monkeypatch.setattr("simbench.runs.checks.check_run", lambda cfg, schemas=None: checked.append(cfg.prior_scale))
    check_jobs(["+sweep=ch5_sensitivity", *TINY])
    assert sorted(checked) == [0.1, 0.3, 1, 3, 10, 100]


def test_sweep_with_one_bad_value_stops_before_any_job(tmp_path: Path, monkeypatch, capsys) -> None:
    out = tmp_path / "sweep"
    args = ["-m", *TINY, "estimator=[l2]", "estimator.l2.prior_scale=1,10,-1", f"results_dir={out}"]
    monkeypatch.setattr(sys, "argv", ["simbench", *args])
    with pytest.raises(SystemExit) as info:
        main()
    assert info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: estimator.l2.prior_scale: must be positive") and "\n" not in err
    assert not out.exists()


# a run of python -m simbench whose l2 estimator fails, diverges or is skipped
PATCHED_RUN = """
import sys
import estimators
from simbench.cli.main import main
cls = estimators.get("l2")
mode = sys.argv.pop(1)
original = cls._estimate
def broken(self, data):
    raise RuntimeError("boom")
def far(self, data):
    epochs, diagnostics = original(self, data)
    return epochs.assign(x=epochs["x"] + 1e6), diagnostics
if mode == "fail":
    cls._estimate = broken
elif mode == "diverge":
    cls._estimate = far
elif mode == "skip":
    cls.unavailable_reason = classmethod(lambda c: "not installed here")
main()
"""


def _run(mode: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", PATCHED_RUN, mode, *args, *TINY, "estimator=[l2]", "progress=false"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )


@pytest.mark.parametrize(("mode", "status"), [("diverge", "diverged"), ("skip", "skipped")])
def test_exit_0_with_a_diverged_or_skipped_row(tmp_path: Path, mode: str, status: str) -> None:
    proc = _run(mode, f"results_dir={tmp_path}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert list(pd.read_parquet(tmp_path / "summary.parquet")["status"]) == [status]


def test_exit_1_with_a_failed_row_after_every_job(tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    proc = _run("fail", "-m", "seed=0,1", f"results_dir={out}")
    assert proc.returncode == 1, proc.stderr[-2000:]
    summary = pd.read_parquet(out / "summary.parquet")
    assert sorted(summary["seed"]) == [0, 1] and (summary["status"] == "failed").all()
    assert f"2 of 2 rows failed: see {out.resolve() / 'summary.parquet'}" in proc.stderr


def test_exit_2_for_a_refused_config(tmp_path: Path) -> None:
    proc = _run("ok", "estimator.l2.prior_scale=-1", f"results_dir={tmp_path / 'run'}")
    assert proc.returncode == 2
    assert proc.stderr.strip() == (
        "error: estimator.l2.prior_scale: must be positive, got -1.0 "
        "-- give a covariance scale factor such as 1, 0.1 or 10"
    )
    assert not (tmp_path / "run").exists()

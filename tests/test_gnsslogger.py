"""Android GnssLogger Raw logs (simbench.data.gnsslogger): a simulated scenario exported with a phone's
clock (export format=gnsslogger) and read back, the clock handling, the rollovers of the other
constellations, hardware clock discontinuities, estimators on the read-back log, one-line errors."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import one_line_error
from test_rinex_wild import NG_NAV, NG_OBS, NG_POINT, cut

from simbench.cli.export import main as export_main
from simbench.contract import Scenario
from simbench.core.constants import C_LIGHT, F_L1, SECONDS_PER_DAY, SECONDS_PER_WEEK
from simbench.data.export import export_scenario
from simbench.data.export.gnsslogger import RAW_FIELDS, gps_nanoseconds
from simbench.data.gnsslogger import load_gnsslogger, read_gnsslogger
from simbench.data.rinex import LogInputs, load_rinex
from simbench.errors import SimbenchWarning
from simbench.runs.compose import compose_config
from simbench.runs.runner import run_estimators
from simbench.runs.scenarios import build_scenario, scenario_settings

_INT_FIELDS = ("TimeNanos", "FullBiasNanos", "ReceivedSvTimeNanos")
_NS = 1_000_000_000


def _scenario(*overrides: str) -> Scenario:
    return build_scenario(scenario_settings(compose_config(list(overrides))))


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Scenario, list[Path]]:
    # no orbit/clock product error: the satellite states recomputed from the navigation file equal the table's
    sc = _scenario(
        "scenario=open_sky",
        "seed=1000",
        "scenario.duration_s=60",
        "scenario.errors.orbit_clock.enabled=false",
        "scenario.errors.cycle_slips.rate_per_s=0.02",
    )
    return sc, export_scenario(sc, "gnsslogger", tmp_path_factory.mktemp("gnsslogger"), "os")


@pytest.fixture(scope="module")
def back(exported: tuple[Scenario, list[Path]]) -> Scenario:
    with warnings.catch_warnings():
        warnings.simplefilter("error", SimbenchWarning)  # a clean export refuses nothing
        return load_gnsslogger(exported[1][0], LogInputs(*exported[1][1:]))


def _raw(path: Path) -> tuple[list[str], pd.DataFrame]:
    """The '#' header lines and the Raw lines of a GnssLogger file, read independently of the reader."""
    header = [ln for ln in path.read_text().splitlines() if ln.startswith("#")]
    dtypes = {f: "Int64" for f in _INT_FIELDS} | {"CodeType": str}
    return header, pd.read_csv(path, comment="#", header=None, names=["record", *RAW_FIELDS], dtype=dtypes)


def _write(path: Path, header: list[str], table: pd.DataFrame) -> Path:
    path.write_text("\n".join(header) + "\n" + table.to_csv(header=False, index=False, na_rep="", lineterminator="\n"))
    return path


def _clock_term(sc: Scenario, raw: pd.DataFrame) -> np.ndarray:
    """Per epoch of ``sc``: c ((TimeNanos - FullBiasNanos_0 - BiasNanos_0) - T) [m], the offset of the clock
    Google's tools put into the pseudorange (the first epoch's bias estimate) from true GPS time T."""
    first = raw.groupby("TimeNanos", sort=False).first()
    time_nanos = first.index.to_numpy("int64")
    full_bias, bias = int(first["FullBiasNanos"].iloc[0]), float(first["BiasNanos"].iloc[0])
    t0 = sc.nav.gps_week * SECONDS_PER_WEEK + sc.nav.start_sow_s
    true_ns = gps_nanoseconds(t0, np.unique(sc.observations["t"].to_numpy()))
    return ((time_nanos - full_bias - true_ns).astype(float) - bias) * (C_LIGHT / _NS)


def test_round_trip_gives_the_simulated_observables_plus_the_phone_clock(
    exported: tuple[Scenario, list[Path]], back: Scenario
) -> None:
    """Same rows; code and phase (both frequencies) equal the simulated ones plus the known clock term to < 1 mm;
    times shifted by the hardware clock's wander, Doppler by its drift; C/N0 and loss of lock as simulated."""
    sc, files = exported
    _, raw = _raw(files[0])
    a = sc.observations.sort_values(["epoch", "sat"]).reset_index(drop=True)
    b = back.observations
    assert len(a) == len(b) > 400
    assert (a["epoch"].to_numpy() == b["epoch"].to_numpy()).all() and (a["sat"] == b["sat"]).all()
    # the phone's clock drifts: its own bias estimate moves by microseconds, the first epoch's clock by km
    assert np.ptp(raw["FullBiasNanos"].to_numpy("int64")) > 10_000
    k = _clock_term(sc, raw)[a["epoch"].to_numpy()]
    assert np.ptp(k) > 4_000.0
    for col in ("code_l1", "phase_l1", "code_l2", "phase_l2"):
        np.testing.assert_allclose(b[col] - a[col], k, rtol=0, atol=1e-3, err_msg=col)
    wander = raw.groupby("TimeNanos", sort=False).first().index.to_numpy("int64")
    wander = (wander - wander[0]) / _NS - np.unique(a["t"].to_numpy())
    np.testing.assert_allclose(b["t"] - a["t"], wander[a["epoch"].to_numpy()], rtol=0, atol=1e-9)
    drift = raw.loc[raw["CarrierFrequencyHz"] == F_L1, "DriftNanosPerSecond"].to_numpy()
    np.testing.assert_allclose(b["doppler_l1"] - a["doppler_l1"], -drift * 1e-9 * F_L1, rtol=0, atol=1e-6)
    np.testing.assert_allclose(b["cn0_l1"], a["cn0_l1"], rtol=0, atol=1e-9)
    for col in ("lli_l1", "lli_l2"):
        assert a[col].any() and (a[col].to_numpy() == b[col].to_numpy()).all(), col
    # the transmit time holds the simulated receiver clock dt_r, as in the RINEX export (satellite v dt_r off)
    sat_err = np.linalg.norm(
        b[["sat_x", "sat_y", "sat_z"]].to_numpy() - a[["sat_x", "sat_y", "sat_z"]].to_numpy(), axis=1
    )
    dt_r = np.abs(sc.truth.set_index("epoch").loc[a["epoch"], "rx_clock"].to_numpy()) / C_LIGHT
    assert (sat_err < 4.0e3 * dt_r + 1e-3).all()
    np.testing.assert_allclose(b["sat_clock"], a["sat_clock"], rtol=0, atol=1e-5)
    # the reference is looked up at the tags, microseconds off GPS time: sub-millimetre at car speed
    np.testing.assert_allclose(back.truth[["x", "y", "z"]], sc.truth[["x", "y", "z"]], rtol=0, atol=1e-3)
    assert back.meta["source"] == "gnsslogger" and back.rinex is None and back.nav.dual_frequency
    clock = back.meta["phone_clock"]
    assert clock["segments"] == 1 and clock["reference_epochs"] == [0]
    assert 5e-6 < clock["tag_minus_phone_time_max_s"] < 1e-4


def test_estimators_on_the_read_back_log_match_the_simulation(
    exported: tuple[Scenario, list[Path]], back: Scenario
) -> None:
    """wls_spp solves each epoch's clock: the same positions as on the simulated table (< 1 cm in the median);
    L2 carries the phone's 82 m/s clock drift in its clock states. Measured (open_sky seed 1000, 60 s),
    horizontal medians simulated / read back: wls_spp 10.216 / 10.216 m, l2 1.080 / 1.084 m."""
    sc = exported[0]
    runs = {
        name: run_estimators(s, {"wls_spp": None, "l2": None}, progress=False).summary.set_index("estimator")
        for name, s in (("sim", sc), ("back", back))
    }
    assert (runs["back"]["status"] == "ok").all() and (runs["back"]["availability"] == 1.0).all()
    h_sim, h_back = runs["sim"]["horizontal_median"], runs["back"]["horizontal_median"]
    assert abs(h_back["wls_spp"] - h_sim["wls_spp"]) < 0.01
    assert h_back["l2"] < 1.5 and abs(h_back["l2"] - h_sim["l2"]) < 0.2


def test_a_real_multi_system_log_round_trips(shared_data: Path, tmp_path: Path) -> None:
    """30 s of the Nagoya log (Septentrio, RINEX 3.04) read as GPS, Galileo, BeiDou and QZSS with their second
    signals, exported as a phone's GnssLogger log and read back: every row, both frequencies within 1 mm of the
    RINEX values plus the clock term (measured 1.1e-8 m), the same satellite states and group delays. BeiDou's
    transmit time counts in BDT, 14 s behind GPS time (a writer that forgets it has every BeiDou code refused)."""
    ng = load_rinex(cut(NG_OBS, tmp_path / "rover30.obs", 30), NG_NAV, NG_POINT, systems="GECJ")
    files = export_scenario(ng, "gnsslogger", tmp_path / "out", "ng")
    with warnings.catch_warnings():
        warnings.simplefilter("error", SimbenchWarning)
        back = load_gnsslogger(files[0], LogInputs(*files[1:], systems="GECJ"))
    a, b = ng.observations, back.observations
    assert len(a) == len(b) > 1000 and (a["sat"] == b["sat"]).all() and (a["epoch"] == b["epoch"]).all()
    assert set(a["sat"].str[0]) == set("GECJ") and back.meta["signals"] == {"G": "1C", "E": "1C", "C": "2I", "J": "1C"}
    k = _clock_term(ng, _raw(files[0])[1])[a["epoch"].to_numpy()]
    for col in ("code_l1", "phase_l1", "code_l2", "phase_l2"):
        has = a[col].notna().to_numpy()
        assert (b[col].notna().to_numpy() == has).all() and has.sum() > 1000, col
        np.testing.assert_allclose((b[col] - a[col])[has], k[has], rtol=0, atol=1e-3, err_msg=col)
    for col in ("sat_x", "sat_y", "sat_z", "sat_clock", "sat_dcb", "f1_f2_ratio"):
        np.testing.assert_allclose(b[col], a[col], rtol=0, atol=1e-6, err_msg=col)
    np.testing.assert_allclose(back.truth[["x", "y", "z"]], ng.truth[["x", "y", "z"]], rtol=0, atol=1e-6)


def test_other_record_types_are_ignored(exported: tuple[Scenario, list[Path]], tmp_path: Path) -> None:
    path = exported[1][0]
    lines = path.read_text().splitlines()
    noisy = []
    for i, ln in enumerate(lines):
        noisy.append(ln)
        if ln.startswith("Raw,") and i % 7 == 0:
            noisy += ["UncalAccel,1545393582000,1,0.1,9.8,0.2,0,0,0", "Fix,GPS,39.6,-79.9,300,1,5,0,1,,,1,3,0", ""]
    noisy_path = tmp_path / "noisy.txt"
    noisy_path.write_text("\n".join(noisy) + "\nStatus,1545393582000,12,0,1,5,1575420000,40,10,20,1,1,1,38\n")
    a, b = read_gnsslogger(path).obs, read_gnsslogger(noisy_path).obs
    assert a.sat.size > 400 and (a.sat == b.sat).all()
    np.testing.assert_array_equal(a.code, b.code)
    np.testing.assert_array_equal(a.epoch_t_frac, b.epoch_t_frac)


def test_a_hardware_clock_discontinuity_restarts_the_reference(
    exported: tuple[Scenario, list[Path]], tmp_path: Path
) -> None:
    """The phone restarts its hardware clock at an epoch (TimeNanos and FullBiasNanos jump together,
    HardwareClockDiscontinuityCount counts one up): from there the pseudoranges use that epoch's bias
    estimate (a constant step), and every phase arc is flagged as broken there."""
    header, raw = _raw(exported[1][0])
    before = read_gnsslogger(exported[1][0]).obs
    epochs = raw["TimeNanos"].to_numpy("int64")
    restart = np.unique(epochs)[30]
    after = epochs >= restart
    jump = -20_000 * _NS  # the counter restarts near boot
    for f in ("TimeNanos", "FullBiasNanos"):
        raw.loc[after, f] = raw.loc[after, f] + jump
    raw.loc[after, "HardwareClockDiscontinuityCount"] += 1
    read = read_gnsslogger(_write(tmp_path / "restart.txt", header, raw))
    obs = read.obs
    assert read.clock.segments == 2 and read.clock.reference_epochs == [0, 30]
    first = raw.groupby("TimeNanos", sort=False).first()
    step = (first["FullBiasNanos"].iloc[0] - (first["FullBiasNanos"].iloc[30] - jump)) + (
        first["BiasNanos"].iloc[0] - first["BiasNanos"].iloc[30]
    )
    expected = np.where(obs.row_epoch >= 30, float(step) * C_LIGHT / _NS, 0.0)
    assert abs(step) > 1000  # the first epoch's clock had drifted by microseconds
    np.testing.assert_allclose(obs.code - before.code, expected, rtol=0, atol=1e-6)
    assert not before.lli[before.row_epoch == 30].all()
    np.testing.assert_array_equal(obs.lli, before.lli | (obs.row_epoch == 30))


def _relabel(raw: pd.DataFrame, constellation: int, freq: float, code_type: str) -> pd.DataFrame:
    out = raw[raw["CarrierFrequencyHz"] == F_L1].copy()
    out["ConstellationType"], out["CarrierFrequencyHz"], out["CodeType"] = constellation, freq, code_type
    return out


def test_other_constellations_roll_over_in_their_own_time(
    exported: tuple[Scenario, list[Path]], tmp_path: Path
) -> None:
    """The GPS measurements relabelled as BeiDou (BDT week, GPS - 14 s), GLONASS (day of UTC(SU) = UTC + 3 h)
    and Galileo with only the secondary code locked (100 ms) give the same pseudoranges."""
    header, raw = _raw(exported[1][0])
    gps = read_gnsslogger(exported[1][0]).obs
    tow = raw["ReceivedSvTimeNanos"].astype("int64")
    leap = int(raw["LeapSecond"].iloc[0])
    variants = {
        "C": _relabel(raw, 5, 1561.098e6, "I").assign(ReceivedSvTimeNanos=(tow - 14 * _NS) % (604_800 * _NS)),
        "R": _relabel(raw, 3, 1602.5625e6, "C").assign(
            ReceivedSvTimeNanos=(tow - leap * _NS + 3 * 3600 * _NS) % int(SECONDS_PER_DAY * _NS),
            State=1 | 128 | 32768,  # time of day decoded and known
        ),
        "E": _relabel(raw, 6, F_L1, "C").assign(ReceivedSvTimeNanos=tow % (100_000_000), State=1 | 1024 | 2048),
    }
    for system, table in variants.items():
        if system == "R":  # GLONASS slots are 1-24
            table = table[table["Svid"] <= 24]
        obs = read_gnsslogger(_write(tmp_path / f"{system}.txt", header, table), system).obs
        prn = np.char.add("G", np.char.zfill(np.array([s[1:] for s in obs.sat.tolist()]), 2))
        ref = pd.Series(gps.code, index=pd.MultiIndex.from_arrays([gps.row_epoch, gps.sat]))
        expected = ref.reindex(pd.MultiIndex.from_arrays([obs.row_epoch, prn])).to_numpy()
        assert obs.sat.size > 200 and set(obs.sat.astype("<U1").tolist()) == {system}
        np.testing.assert_allclose(obs.code, expected, rtol=0, atol=1e-6, err_msg=system)


def test_a_log_across_the_gps_week_rollover(tmp_path: Path) -> None:
    sc = _scenario(
        "scenario=urban",
        "seed=1000",
        "scenario.duration_s=10",
        "scenario.start_sow_s=604795.0",
        "scenario.errors.orbit_clock.enabled=false",
    )
    files = export_scenario(sc, "gnsslogger", tmp_path, "week")
    back = load_gnsslogger(files[0], LogInputs(*files[1:]))
    a = sc.observations.sort_values(["epoch", "sat"])
    a = a[np.isfinite(a["code_l1"].to_numpy())].reset_index(drop=True)
    k = _clock_term(sc, _raw(files[0])[1])[a["epoch"].to_numpy()]
    assert len(a) == len(back.observations) > 30
    np.testing.assert_allclose(back.observations["code_l1"] - a["code_l1"], k, rtol=0, atol=1e-3)
    np.testing.assert_allclose(back.truth[["x", "y", "z"]], sc.truth[["x", "y", "z"]], rtol=0, atol=1e-3)


def test_measurements_without_a_decoded_time_are_refused_with_a_warning(
    exported: tuple[Scenario, list[Path]], tmp_path: Path
) -> None:
    header, raw = _raw(exported[1][0])
    raw.loc[raw.index[:25], "State"] = 1  # code lock only: the millisecond is all the phone knows
    raw.loc[raw.index[25:28], "ReceivedSvTimeUncertaintyNanos"] = 800.0
    with pytest.warns(SimbenchWarning, match=r"28 of \d+ measurements .*no time of week / day decoded \(State\): 25"):
        read = read_gnsslogger(_write(tmp_path / "weak.txt", header, raw))
    assert read.refused == {"no time of week / day decoded (State)": 25, "ReceivedSvTimeUncertaintyNanos > 500 ns": 3}


def test_bad_logs_are_refused_in_one_line(exported: tuple[Scenario, list[Path]], tmp_path: Path) -> None:
    header, raw = _raw(exported[1][0])
    path = exported[1][0]
    assert "does not exist" in one_line_error(read_gnsslogger, tmp_path / "none.txt")
    fixes = tmp_path / "fixes.txt"
    fixes.write_text("# Fix,Provider,LatitudeDegrees\nFix,GPS,39.6\nStatus,1,2,3\n")
    assert "has no Raw lines (record types in the file: Fix, Status)" in one_line_error(read_gnsslogger, fixes)
    no_header = _write(tmp_path / "no_header.txt", [], raw)
    assert "no '# Raw,...' header line" in one_line_error(read_gnsslogger, no_header)
    blind = [h.replace(",FullBiasNanos", "") for h in header]
    missing = _write(tmp_path / "missing.txt", blind, raw.drop(columns="FullBiasNanos"))
    assert "Raw header lacks the field(s) FullBiasNanos" in one_line_error(read_gnsslogger, missing)
    sbas = _write(tmp_path / "sbas.txt", header, raw.assign(ConstellationType=2))
    message = one_line_error(read_gnsslogger, sbas)
    assert f"has no measurement of systems 'G' ({len(raw)} Raw lines: SBAS {len(raw)})" in message
    undecoded = _write(tmp_path / "undecoded.txt", header, raw.assign(State=1))
    message = one_line_error(read_gnsslogger, undecoded)
    assert f"no usable pseudorange of systems 'G' ({len(raw)} measurements: no time of week" in message
    lines = path.read_text().splitlines()
    broken = next(i for i, ln in enumerate(lines) if ln.startswith("Raw,"))
    lines[broken] = lines[broken].replace(",16431,", ",sixteen,")
    (bad := tmp_path / "bad.txt").write_text("\n".join(lines))
    assert "has a non-numeric State" in one_line_error(read_gnsslogger, bad)
    lines[broken] = "Raw,1,abc"
    (bad := tmp_path / "bad_int.txt").write_text("\n".join(lines))
    assert "has a malformed Raw line" in one_line_error(read_gnsslogger, bad)
    assert "scenario.systems" in one_line_error(read_gnsslogger, path, "X")


def test_the_source_and_the_export_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``export format=gnsslogger`` writes the log, the navigation file and the reference and prints the
    ``scenario=gnsslogger`` line; that source reads them, and refuses a config without files in one line."""
    args = ["scenario=urban", "seed=1000", "scenario.duration_s=3", "format=gnsslogger", f"out={tmp_path}"]
    assert export_main(args) == 0
    names = ["urban_low_1000.nav", "urban_low_1000_gnss_log.txt", "urban_low_1000_truth.csv"]
    assert sorted(p.name for p in tmp_path.iterdir()) == names
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert line.startswith("read back: python -m simbench scenario=gnsslogger scenario.obs=")
    overrides = line.split("python -m simbench ")[1].split()
    sc = build_scenario(scenario_settings(compose_config(overrides)))
    assert sc.meta["source"] == "gnsslogger" and sc.meta["name"] == "urban_low_1000_gnss_log" and sc.n_epochs == 3
    message = one_line_error(build_scenario, scenario_settings(compose_config(["scenario=gnsslogger"])))
    assert message.startswith("scenario.obs: no file given for a gnsslogger scenario (missing: obs, nav, truth)")
    assert "scenario.obs=gnss_log.txt" in message

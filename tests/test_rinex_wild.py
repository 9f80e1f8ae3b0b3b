"""RINEX as it exists in the wild (issue 24): one test per quirk, on small files cut from the real logs.

Each test writes a few epochs of ``../shared/data/hk_tst_2019`` (u-blox M8T, RINEX 3.03, single
frequency) or ``../shared/data/nagoya_static`` (Septentrio mosaic-X5, RINEX 3.04, triple frequency,
mixed navigation file) into ``tmp_path``, edited where the quirk needs it (header version, labels,
navigation records split by time).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from conftest import one_line_error

import simbench
from simbench.contract import Scenario
from simbench.core.constants import F_B1I, F_L1, F_L2
from simbench.core.gpstime import datetime64_to_gps
from simbench.data.broadcast import read_navigation
from simbench.data.reference import read_reference
from simbench.data.rinex import load_rinex, read_rinex_obs
from simbench.errors import SimbenchError, SimbenchWarning
from simbench.gnss.navigation import read_gps_navigation
from simbench.runs.compose import compose_config
from simbench.runs.scenarios import check_scenario, scenario_settings

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
HK = DATA / "hk_tst_2019"
HK_OBS, HK_NAV, HK_BDS = HK / "COM3_190428_124409.obs", HK / "hksc1180.19n", HK / "hksc1180.19b"
NAGOYA = DATA / "nagoya_static"
NG_OBS, NG_NAV, NG_POINT = NAGOYA / "rover.obs", NAGOYA / "base.nav", NAGOYA / "rover_position.txt"
#: The surveyed Nagoya antenna (rover_position.txt): lat, lon [deg], ellipsoidal height [m].
NG_LLH = "35.13469901,136.97757549,104.8626"
#: Nagoya's BeiDou observation codes, and the same count of codes no reader knows (B1C/B2a/B2b).
NG_BDS_CODES = "C   13 X1  C2I L2I D2I S2I C7I L7I D7I S7I C6I L6I D6I S6I"
NG_BDS_UNKNOWN = "C   13 X1  C1X L1X D1X S1X C5X L5X D5X S5X C7D L7D D7D S7D"

# the conftest fixture fails these tests when ../shared is missing (skips with SIMBENCH_ALLOW_MISSING_SHARED)
pytestmark = pytest.mark.usefixtures("shared_data")


def cut(src: Path, dst: Path, n_epochs: int, edit: Callable[[list[str]], list[str]] = lambda h: h) -> Path:
    """Write the header of RINEX observation file ``src`` (through ``edit``) and its first ``n_epochs`` records."""
    lines = src.read_text().splitlines()
    end = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    starts = [i for i in range(end, len(lines)) if lines[i].startswith(">")]
    stop = starts[n_epochs] if n_epochs < len(starts) else len(lines)
    dst.write_text("\n".join(edit(lines[:end]) + lines[end:stop]) + "\n")
    return dst


def relabel(old: str, new: str) -> Callable[[list[str]], list[str]]:
    """A header edit replacing ``old`` by ``new`` (same width: RINEX columns are fixed)."""
    assert len(old) == len(new)
    return lambda header: [ln.replace(old, new) for ln in header]


def split_nav(src: Path, out: Path, keep: Callable[[int], bool]) -> Path:
    """The header of navigation file ``src`` and its records whose epoch hour passes ``keep``."""
    lines = src.read_text().splitlines()
    end = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    body, take = [], False
    for ln in lines[end:]:
        if ln[:1] != " ":
            take = keep(int(ln[15:17]))
        if take:
            body.append(ln)
    out.write_text("\n".join(lines[:end] + body) + "\n")
    return out


def rinex2(src: Path, dst: Path, n_epochs: int, columns: dict[str, list[str]]) -> Path:
    """A RINEX 2.11 file of the first epochs of RINEX 3 file ``src``: types ``C1 L1 D1 S1 P2 L2`` holding, per
    system, the RINEX 3 observables ``columns[system]`` ('' leaves a type blank)."""
    lines = src.read_text().splitlines()
    end = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln)
    have: dict[str, list[str]] = {}
    for ln in lines[:end]:
        if ln[60:].strip() == "SYS / # / OBS TYPES":
            have.setdefault(ln[0] if ln[0] != " " else list(have)[-1], []).extend(ln[7:60].split())
    out = [f"{'2.11':>9s}{'':11s}{'OBSERVATION DATA':20s}{'M (MIXED)':20s}RINEX VERSION / TYPE"]
    out += [f"{'     6    C1    L1    D1    S1    P2    L2':60s}# / TYPES OF OBSERV"]
    out += [ln for ln in lines[:end] if ln[60:].strip() in ("APPROX POSITION XYZ", "INTERVAL", "TIME OF FIRST OBS")]
    out.append(f"{'':60s}END OF HEADER")
    starts = [i for i in range(end, len(lines)) if lines[i].startswith(">")][: n_epochs + 1]
    for a, b in zip(starts[:-1], starts[1:]):
        sats = [ln for ln in lines[a + 1 : b] if ln[0] in columns]
        ids = "".join(ln[:3] for ln in sats)
        head = f" {int(lines[a][2:6]) % 100:02d}{lines[a][6:29]}  0{len(sats):3d}"
        out += [f"{head if k == 0 else '':32s}{ids[3 * k : 3 * k + 36]}" for k in range(0, len(sats), 12)]
        for ln in sats:
            cols = [have[ln[0]].index(c) if c else -1 for c in columns[ln[0]]]
            fields = [ln[3 + 16 * j : 19 + 16 * j].ljust(16) if j >= 0 else " " * 16 for j in cols]
            out += ["".join(fields[:5]).rstrip(), "".join(fields[5:]).rstrip()]
    dst.write_text("\n".join(out) + "\n")
    return dst


@pytest.fixture(scope="module")
def nagoya(tmp_path_factory: pytest.TempPathFactory) -> Scenario:
    """30 s of the Nagoya log as ``scenario=rinex`` with only the mixed navigation file, GREC, the surveyed point."""
    obs = cut(NG_OBS, tmp_path_factory.mktemp("nagoya") / "rover30.obs", 30)
    overrides = {"scenario.obs": obs, "scenario.nav": NG_NAV, "scenario.truth": NG_POINT, "scenario.systems": "GREC"}
    return simbench.scenario("rinex", **overrides)


def test_rinex_302_labels_beidou_b1i_c1i(tmp_path: Path) -> None:
    """B1I is C1I in RINEX 3.02 and C2I in 3.03: the same rows either way; C1I in a 3.04 file is not B1I."""
    v303 = read_rinex_obs(cut(HK_OBS, tmp_path / "v303.obs", 20), "GC")
    to_302 = relabel("C    4 C2I L2I D2I S2I", "C    4 C1I L1I D1I S1I")
    v302 = read_rinex_obs(
        cut(HK_OBS, tmp_path / "v302.obs", 20, lambda h: to_302([h[0].replace("3.03", "3.02")] + h[1:])), "GC"
    )
    n_bds = int(np.char.startswith(v303.sat.astype(str), "C").sum())
    assert n_bds > 40 and v302.signals == {"G": "1C", "C": "1I"} and v303.signals["C"] == "2I"
    np.testing.assert_array_equal(v302.sat, v303.sat)
    np.testing.assert_array_equal(v302.code, v303.code)
    np.testing.assert_array_equal(v302.phase_cycles, v303.phase_cycles)
    v304 = read_rinex_obs(
        cut(HK_OBS, tmp_path / "v304.obs", 20, lambda h: to_302([h[0].replace("3.03", "3.04")] + h[1:])), "GC"
    )
    assert not np.char.startswith(v304.sat.astype(str), "C").any()
    assert v304.system_notes == ["no BeiDou rows with a known code (codes in the file: C1I L1I D1I S1I)"]


def test_rinex_211_observation_files_read_as_their_rinex_3_codes(tmp_path: Path) -> None:
    """RINEX 2.11 (more than 12 satellites per epoch: continued satellite lists, two lines per satellite):
    C1 is L1 C/A, P2 and L2 the GPS L2 P(Y) pair; the same numbers as the RINEX 3 file they came from."""
    columns = {"G": ["C1C", "L1C", "D1C", "S1C", "C2W", "L2W"], "R": ["C1C", "L1C", "D1C", "S1C", "", ""]}
    old = read_rinex_obs(rinex2(NG_OBS, tmp_path / "rover.11o", 5, columns), "GR")
    new = read_rinex_obs(cut(NG_OBS, tmp_path / "rover.obs", 5), "GR")
    assert old.version == 2.11 and old.signals == {"G": "1C", "R": "1C"} and old.sat.size == new.sat.size > 5 * 12
    for name in ("sat", "code", "phase_cycles", "doppler_hz", "cn0_dbhz", "lli"):
        np.testing.assert_array_equal(getattr(old, name), getattr(new, name), err_msg=name)
    gps_l2 = new.signal_l2 == "2W"
    assert gps_l2.sum() > 40 and set(old.signal_l2[gps_l2]) == {"2W"} and set(old.signal_l2[~gps_l2]) <= {"", "2W"}
    np.testing.assert_array_equal(old.code_l2[gps_l2], new.code_l2[gps_l2])
    np.testing.assert_array_equal(old.phase_l2_cycles[gps_l2], new.phase_l2_cycles[gps_l2])


def test_qzss_rows_get_satellite_states_from_the_gps_orbit_code(tmp_path: Path) -> None:
    """QZSS (J) from the mixed file's GPS-like records: its code residuals against the surveyed point match GPS's."""
    sc = load_rinex(cut(NG_OBS, tmp_path / "r.obs", 10), NG_NAV, NG_LLH, systems="GJ")
    obs = sc.observations
    is_j = obs["sat"].str.startswith("J").to_numpy()
    assert sorted(set(obs["sat"][is_j])) == ["J02", "J03", "J07"] and sc.meta["systems_used"] == "GJ"
    sat = obs[["sat_x", "sat_y", "sat_z"]].to_numpy()
    radius = np.linalg.norm(sat[is_j], axis=1)
    assert ((radius > 38e6) & (radius < 46e6)).all()  # inclined geosynchronous and geostationary orbits
    truth = read_reference(NG_POINT).xyz[0]
    # code - range + satellite clock: receiver clock + atmosphere + Sagnac; QZSS runs on GPS time
    residual = obs["code_l1"].to_numpy() + obs["sat_clock"].to_numpy() - np.linalg.norm(sat - truth, axis=1)
    per_epoch = obs.assign(r=residual, j=is_j).groupby(["epoch", "j"])["r"].median().unstack()
    assert float((per_epoch[True] - per_epoch[False]).abs().max()) < 60.0
    assert float(per_epoch[False].std()) < 1e3  # not a wrong orbit: a receiver clock, steady over 10 s


def test_two_nav_files_per_system_give_the_states_of_the_one_file(tmp_path: Path) -> None:
    """A navigation file split by time (12:00 records in both) gives the same ephemerides, merged and deduplicated."""
    t = datetime64_to_gps(np.datetime64("2019-04-28T11:30:00")) + np.arange(0, 3600, 600.0)  # across the split
    for path, reader in ((HK_BDS, functools.partial(read_navigation, "C")), (HK_NAV, read_gps_navigation)):
        # hours 9-15 of the day's file (georinex takes seconds for a whole day), and its two halves
        whole = split_nav(path, tmp_path / f"whole_{path.name}", lambda hour: 9 <= hour <= 15)
        early = split_nav(path, tmp_path / f"early_{path.name}", lambda hour: 9 <= hour <= 12)
        late = split_nav(path, tmp_path / f"late_{path.name}", lambda hour: 12 <= hour <= 15)
        one, two = reader(whole), reader([early, late])
        np.testing.assert_array_equal(one.sats, two.sats)
        a, b = one.states(t), two.states(t)
        np.testing.assert_array_equal(a.pos, b.pos)
        np.testing.assert_array_equal(a.clock, b.clock)
    # the command line's list syntax reaches the typed config as a list
    cfg = compose_config(["scenario=hk_tst_2019", f"scenario.nav_bds=[{early},{late}]"])
    assert scenario_settings(cfg).scenario.nav_bds == [str(early), str(late)]


def test_mixed_nav_file_serves_every_system_with_second_frequencies(nagoya: Scenario) -> None:
    """scenario=rinex with only a mixed nav file: GREC rows, and each second frequency with its own ratio."""
    obs = nagoya.observations
    system = obs["sat"].str[0]
    assert nagoya.meta["name"] == "rover30" and nagoya.meta["systems_used"] == "GREC"
    assert set(system) == set("GREC") and (system.value_counts() > 100).all()
    ratio = obs.assign(s=system).groupby("s")["f1_f2_ratio"]
    expected = {"G": F_L1 / F_L2, "R": 9 / 7, "E": F_L1 / 1176.45e6, "C": F_B1I / 1268.52e6}
    for s, value in expected.items():
        r = ratio.get_group(s).dropna().to_numpy()
        assert r.size > 0.9 * (system == s).sum() and np.allclose(r, value, rtol=0, atol=1e-12), s
    has_l2 = np.isfinite(obs["code_l2"].to_numpy())
    assert nagoya.nav.dual_frequency and np.isfinite(obs["phase_l2"].to_numpy()[has_l2]).mean() > 0.95
    # every GPS L2, E5a and B3I row has its broadcast group delay; GLONASS broadcasts none
    dcb = obs["sat_dcb"].to_numpy()
    assert np.isfinite(dcb[has_l2 & (system != "R")]).all() and np.isnan(dcb[~has_l2 | (system == "R")]).all()
    # phase minus code on the second signal, per satellite: constant to metres (right wavelength, one signal)
    spread = (obs["phase_l2"] - obs["code_l2"]).groupby(obs["sat"]).agg(lambda x: x.max() - x.min())
    assert float(spread.max()) < 10.0


def test_static_one_point_truth_holds_the_surveyed_point_at_every_epoch(nagoya: Scenario) -> None:
    truth = nagoya.truth
    point = read_reference(NG_LLH).xyz[0]
    assert len(truth) == 30 and nagoya.meta["static_truth"]
    np.testing.assert_allclose(truth[["x", "y", "z"]].to_numpy(), np.tile(point, (30, 1)), atol=1e-6)
    assert (truth[["vx", "vy", "vz"]].to_numpy() == 0.0).all()
    # ECEF metres are told from degrees by magnitude
    np.testing.assert_allclose(read_reference(",".join(f"{v:.4f}" for v in point)).xyz[0], point, atol=1e-4)


def test_a_requested_system_without_rows_is_a_warning_and_a_meta_line(tmp_path: Path) -> None:
    obs = cut(NG_OBS, tmp_path / "b1c.obs", 5, relabel(NG_BDS_CODES, NG_BDS_UNKNOWN))
    with pytest.warns(SimbenchWarning) as caught:
        sc = load_rinex(obs, NG_NAV, NG_LLH, systems="GC")
    note = (
        "asked GC, used G: no BeiDou rows with a known code "
        "(codes in the file: X1 C1X L1X D1X S1X C5X L5X D5X S5X C7D L7D D7D S7D)"
    )
    assert [str(w.message) for w in caught] == [f"scenario.systems: {note} -- the run goes on without that system"]
    assert (sc.meta["systems_asked"], sc.meta["systems_used"], sc.meta["system_notes"]) == ("GC", "G", [note])
    assert set(sc.observations["sat"].str[0]) == {"G"}


def test_bad_wild_input_gives_one_line_errors(tmp_path: Path) -> None:
    hk = cut(HK_OBS, tmp_path / "hk.obs", 1000)  # 12:44:33 .. 13:01:13 GPS
    # navigation files with a missing hour: BeiDou records (hourly, valid +- 2 h) up to 11:00 and from 16:00 BDT
    early = split_nav(HK_BDS, tmp_path / "a.19b", lambda hour: hour <= 11)
    late = split_nav(HK_BDS, tmp_path / "b.19b", lambda hour: hour >= 16)
    msg = one_line_error(load_rinex, hk, HK_NAV, None, systems="GC", nav_bds_path=[early, late])
    assert msg.startswith(
        f"scenario.nav_bds ['{early}', '{late}']: has no BeiDou record (of any satellite) within 2 h of 59 epochs at "
        "which BeiDou satellites are observed, first 2019-04-28 13:00:15 .. 2019-04-28 13:01:13 GPS"
    )
    # a requested system whose codes are all unknown, alone: nothing to read
    b1c = cut(NG_OBS, tmp_path / "b1c.obs", 2, relabel(NG_BDS_CODES, NG_BDS_UNKNOWN))
    msg = one_line_error(read_rinex_obs, b1c, "C")
    assert msg.startswith(f"scenario.obs '{b1c}'") and "C: X1 C1X L1X" in msg and "BeiDou: C2I" in msg
    # a static point 150 km from the log's own fixes (Nagoya, 1.35 deg further east)
    far = "35.13469901,138.32757549,104.8626"
    msg = one_line_error(load_rinex, cut(NG_OBS, tmp_path / "g.obs", 5), NG_NAV, far)
    assert msg.startswith(f"scenario.truth '{far}': positions are 12") and "km from the log's single-point fixes" in msg


def test_scenario_rinex_requires_its_files_and_simulate_refuses_real_logs(tmp_path: Path) -> None:
    cfg = scenario_settings(compose_config(["scenario=rinex", "scenario.obs=a.obs"]))
    msg = one_line_error(check_scenario, cfg)
    assert msg.startswith("scenario.nav: no file given for a rinex scenario (missing: nav, truth)")
    assert "python -m simbench scenario=rinex scenario.nav=a.20n scenario.truth=ref.csv" in msg
    for name in ("rinex", "hk_tst_2019"):
        msg = one_line_error(simbench.simulate, name)
        assert msg.startswith(f"scenario: '{name}' is read by source 'rinex'") and "simbench.scenario(" in msg
    with pytest.raises(SimbenchError, match="scenario.obs: no file given"):
        simbench.scenario("rinex")


def test_zero_observation_fields_are_missing(tmp_path: Path) -> None:
    """RINEX writes a missing observation as blanks or as 0.0: a 0.000 code is no range of zero metres."""
    clean = read_rinex_obs(cut(NG_OBS, tmp_path / "clean.obs", 3), "G")

    def zero_first_code(lines: list[str]) -> list[str]:
        out, done = list(lines), False
        body = next(i for i, ln in enumerate(out) if "END OF HEADER" in ln) + 1
        for i, ln in enumerate(out[body:], start=body):
            # the second field: Nagoya's GPS types are X1 (the channel) then C1C
            if not done and ln.startswith("G") and len(ln) > 33 and not ln[19:33].isspace():
                out[i], done = ln[:19] + f"{0.0:14.3f}" + ln[33:], True
        return out

    src = cut(NG_OBS, tmp_path / "zeros.obs", 3)
    src.write_text("\n".join(zero_first_code(src.read_text().splitlines())) + "\n")
    zeros = read_rinex_obs(src, "G")
    np.testing.assert_array_equal(zeros.sat, clean.sat)
    assert np.isnan(zeros.code[0]) and np.isfinite(clean.code[0])
    np.testing.assert_array_equal(zeros.code[1:], clean.code[1:])
    np.testing.assert_array_equal(zeros.phase_cycles, clean.phase_cycles)


def insert_before_epoch(lines: list[str], k: int, record: list[str], rinex2_file: bool = False) -> list[str]:
    """``lines`` with ``record`` inserted before the ``k``-th epoch header (0-based)."""
    body = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    if rinex2_file:
        starts = [i for i in range(body, len(lines)) if lines[i][:1] == " " and lines[i][29:32].strip().isdigit()]
        starts = [i for i in starts if lines[i][1:3].strip().isdigit() and lines[i][26:29].strip() in ("0", "1")]
    else:
        starts = [i for i in range(body, len(lines)) if lines[i].startswith(">")]
    return lines[: starts[k]] + record + lines[starts[k] :]


def test_event_records_are_skipped_as_the_standard_says(tmp_path: Path) -> None:
    """Epoch flags 2-5 carry header lines (a teqc splice writes flag 4 with blank date fields and comments,
    a GEONET file refused before): skipped; RINEX 2 and 3 alike, the observations unchanged."""
    columns = {"G": ["C1C", "L1C", "D1C", "S1C", "C2W", "L2W"]}
    plain2 = read_rinex_obs(rinex2(NG_OBS, tmp_path / "plain.11o", 4, columns), "G")
    splice = [
        f"{'':28s}4  2",
        f"{'RINEX FILE SPLICE; teqc':60s}COMMENT",
        f"{'     6    C1    L1    D1    S1    P2    L2':60s}# / TYPES OF OBSERV",
    ]
    src = tmp_path / "splice.11o"
    src.write_text("\n".join(insert_before_epoch((tmp_path / "plain.11o").read_text().splitlines(), 2, splice, True)))
    spliced = read_rinex_obs(src, "G")
    assert spliced.epoch_t_int.size == plain2.epoch_t_int.size == 4
    for name in ("sat", "code", "phase_cycles", "code_l2", "lli"):
        np.testing.assert_array_equal(getattr(spliced, name), getattr(plain2, name), err_msg=name)
    # RINEX 3: a new-site event (flag 3, blank date) and an external event (flag 5, dated, no lines)
    plain3 = read_rinex_obs(cut(NG_OBS, tmp_path / "plain.obs", 4), "G")
    events = [f">{'':30s}3  1", f"{'NEW SITE':60s}MARKER NAME", "> 2024 01 01 00 00  0.0000000  5  0"]
    src3 = cut(NG_OBS, tmp_path / "events.obs", 4)
    src3.write_text("\n".join(insert_before_epoch(src3.read_text().splitlines(), 1, events)) + "\n")
    np.testing.assert_array_equal(read_rinex_obs(src3, "G").code, plain3.code)
    # a redefinition of the columns mid-file cannot be read with one set of columns: one line
    changed = [f"{'':28s}4  1", f"{'     2    C1    L1':60s}# / TYPES OF OBSERV"]
    src.write_text("\n".join(insert_before_epoch((tmp_path / "plain.11o").read_text().splitlines(), 2, changed, True)))
    assert "redefines its observation types" in one_line_error(read_rinex_obs, src, "G")
    # RINEX 3: a header line repeating GPS's own types passes, one with other types is refused
    header = src3.read_text().splitlines()
    first = next(i for i, ln in enumerate(header) if ln.startswith("G") and "OBS TYPES" in ln)
    gps_types = header[first : first + 2]  # Nagoya's 17 GPS types: a line and its continuation
    same = [f">{'':30s}4  2", *gps_types]
    other = [f">{'':30s}4  1", f"{'G    2 C1C L1C':60s}SYS / # / OBS TYPES"]
    for record, refused in ((same, False), (other, True)):
        edited = tmp_path / "types.obs"
        edited.write_text("\n".join(insert_before_epoch(src3.read_text().splitlines(), 2, record)) + "\n")
        if refused:
            assert "redefines its G observation types" in one_line_error(read_rinex_obs, edited, "G")
        else:
            np.testing.assert_array_equal(read_rinex_obs(edited, "G").code, plain3.code)


def test_cycle_slip_and_power_failure_records_set_loss_of_lock(tmp_path: Path) -> None:
    """Flag 6 (cycle slips, observation layout) marks the phases it names at its epoch; flag 1 (power failure
    since the previous epoch) every phase of its epoch; nothing else moves."""
    plain = read_rinex_obs(cut(NG_OBS, tmp_path / "plain.obs", 4), "G")
    src = cut(NG_OBS, tmp_path / "slips.obs", 4)
    lines = src.read_text().splitlines()
    body = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    starts = [i for i in range(body, len(lines)) if lines[i].startswith(">")]
    second = lines[starts[1]]
    gps = next(ln for ln in lines[starts[1] + 1 : starts[2]] if ln.startswith("G"))
    slip = [second[:31] + "6  1", gps]  # the satellite's own line as its slip record: every phase slipped
    lines[starts[2]] = lines[starts[2]][:31] + "1" + lines[starts[2]][32:]  # the third epoch: power failure
    src.write_text("\n".join(lines[: starts[2]] + slip + lines[starts[2] :]) + "\n")
    slipped = read_rinex_obs(src, "G")
    np.testing.assert_array_equal(slipped.code, plain.code)
    expect = plain.lli.copy()
    expect[(plain.row_epoch == 1) & (plain.sat == gps[:3].replace(" ", "0"))] = True
    expect[plain.row_epoch == 2] = True
    assert expect.sum() > plain.lli.sum() + 8
    np.testing.assert_array_equal(slipped.lli, expect)
    assert slipped.lli_l2[(plain.row_epoch == 1) & (plain.sat == gps[:3].replace(" ", "0"))].all()


def test_rinex_4_and_305_beidou_c2x_and_unread_systems(tmp_path: Path) -> None:
    """RINEX 4.00 observation files are 3.05's layout; BeiDou B1I written C2X (I+Q, RINEX 3.05) is B1I;
    SBAS lines are counted as a system simbench does not read."""
    plain = read_rinex_obs(cut(NG_OBS, tmp_path / "plain.obs", 3), "GC")
    v4 = read_rinex_obs(cut(NG_OBS, tmp_path / "v4.obs", 3, lambda h: [h[0].replace("3.04", "4.00")] + h[1:]), "GC")
    np.testing.assert_array_equal(v4.code, plain.code)
    assert v4.version == 4.0
    c2x = read_rinex_obs(cut(NG_OBS, tmp_path / "c2x.obs", 3, relabel("C2I L2I D2I S2I", "C2X L2X D2X S2X")), "GC")
    assert plain.signals["C"] == "2I" and c2x.signals["C"] == "2X"
    np.testing.assert_array_equal(c2x.code, plain.code)
    # GLONASS lines relabelled as SBAS (Nagoya's file has none): counted, and the read rows unchanged
    src = cut(NG_OBS, tmp_path / "sbas.obs", 3)
    text = src.read_text().splitlines()
    body = next(i for i, ln in enumerate(text) if "END OF HEADER" in ln) + 1
    text[body:] = ["S" + ln[1:] if ln.startswith("R") else ln for ln in text[body:]]
    src.write_text("\n".join(text) + "\n")
    sbas = read_rinex_obs(src, "GC")
    n_glonass = sum(ln.startswith("S") for ln in text[body:])
    assert plain.unread_systems == {} and n_glonass > 10 and sbas.unread_systems == {"S": n_glonass}
    np.testing.assert_array_equal(sbas.code, plain.code)

"""Navigation coverage checked only where it is used, and bad input in one line (issue 44, item 2).

Each test cuts the real logs (Hong Kong u-blox M8T, RINEX 3.03; Nagoya Septentrio, RINEX 3.04 with a
mixed navigation file) into ``tmp_path``, with the helpers of ``test_rinex_wild``; the files of another
day are real: the WVU drives' GPS file (2018-12-21) and an EUREF station's mixed file of 2020-06-25
(``rinex_corpus/NAV/V3/MOJN00DNK_R_20201770000_01D_MN.rnx.gz``, with QZSS records).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from conftest import one_line_error
from test_rinex_wild import HK_BDS, HK_NAV, HK_OBS, NG_NAV, NG_OBS, cut, split_nav

from simbench.data.rinex import load_rinex, read_rinex_obs
from simbench.errors import SimbenchWarning
from simbench.gnss.navigation import read_gps_navigation

pytestmark = pytest.mark.usefixtures("shared_data")


def without_system_from(letter: str, second_of_day: float) -> Callable[[list[str]], list[str]]:
    """An edit of RINEX 3 epoch records: the satellite lines of system ``letter`` dropped from the epochs at
    or after ``second_of_day`` (GPS), each epoch line's satellite count fixed."""

    def edit(body: list[str]) -> list[str]:
        starts = [i for i, ln in enumerate(body) if ln.startswith(">")] + [len(body)]
        out: list[str] = []
        for a, b in zip(starts[:-1], starts[1:]):
            head, sats = body[a], body[a + 1 : b]
            if int(head[13:15]) * 3600 + int(head[16:18]) * 60 + float(head[18:29]) >= second_of_day:
                sats = [ln for ln in sats if ln[:1] != letter]
            out += [f"{head[:32]}{len(sats):3d}{head[35:]}", *sats]
        return out

    return edit


def edit_body(src: Path, dst: Path, edit: Callable[[list[str]], list[str]]) -> Path:
    """Write RINEX file ``src`` with its lines after the header passed through ``edit``."""
    lines = src.read_text().splitlines()
    end = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    dst.write_text("\n".join(lines[:end] + edit(lines[end:])) + "\n")
    return dst


def without_records_of(letter: str) -> Callable[[list[str]], list[str]]:
    """An edit of RINEX 3 navigation records: those of system ``letter`` dropped."""

    def edit(body: list[str]) -> list[str]:
        out, take = [], True
        for ln in body:
            if ln[:1] != " ":
                take = ln[:1] != letter
            if take:
                out.append(ln)
        return out

    return edit


def loaded_with_warnings(*args, **kwargs):  # type: ignore[no-untyped-def]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sc = load_rinex(*args, **kwargs)
    return sc, [str(w.message) for w in caught if issubclass(w.category, SimbenchWarning)]


def test_a_gap_in_a_systems_records_where_it_is_not_observed_is_no_gap(tmp_path: Path) -> None:
    """The issue's EUREF case on the Hong Kong log: BeiDou records (hourly, +- 2 h) up to 11:00 and from 16:00
    BDT leave 13:00:15 .. 13:01:13 GPS uncovered, and in that minute no BeiDou satellite is observed.
    Refused before ("covers ... leaving 13:00:14 .. 13:01:13 GPS of the observations uncovered")."""
    hk = cut(HK_OBS, tmp_path / "hk.obs", 1000)  # 12:44:33 .. 13:01:13 GPS
    no_bds_at_the_end = edit_body(hk, tmp_path / "hk_c.obs", without_system_from("C", 13 * 3600 + 14))
    early = split_nav(HK_BDS, tmp_path / "a.19b", lambda hour: hour <= 11)
    late = split_nav(HK_BDS, tmp_path / "b.19b", lambda hour: hour >= 16)
    split = load_rinex(no_bds_at_the_end, HK_NAV, None, systems="GC", nav_bds_path=[early, late])
    whole = load_rinex(no_bds_at_the_end, HK_NAV, None, systems="GC", nav_bds_path=HK_BDS)
    o, w = split.observations, whole.observations
    bds = o["sat"].str.startswith("C")
    assert (len(o), int(bds.sum()), int(o.loc[bds, "epoch"].max())) == (12_270, 6_127, 939)
    np.testing.assert_array_equal(o[["epoch", "sat"]].to_numpy(), w[["epoch", "sat"]].to_numpy())
    # the older records of the split files serve the same satellites within metres
    moved = np.linalg.norm(
        o[["sat_x", "sat_y", "sat_z"]].to_numpy() - w[["sat_x", "sat_y", "sat_z"]].to_numpy(), axis=1
    )
    assert 0.1 < moved.max() < 3.0
    # the same files with BeiDou observed in that minute: refused, naming the stretch
    msg = one_line_error(load_rinex, hk, HK_NAV, None, systems="GC", nav_bds_path=[early, late])
    assert "within 2 h of 59 epochs at which BeiDou satellites are observed, first 2019-04-28 13:00:15 .." in msg


def test_navigation_files_of_another_day_are_refused_in_one_line(tmp_path: Path, shared_data: Path) -> None:
    hk = cut(HK_OBS, tmp_path / "hk.obs", 20)
    wvu = shared_data / "wvu_drives" / "brdc.18n"  # 2018-12-21
    msg = one_line_error(load_rinex, hk, wvu, None, systems="G")
    assert msg == (
        f"scenario.nav '{wvu}': its GPS records serve 2018-12-20 22:00:00 .. 2018-12-22 01:59:44 GPS, none of the "
        "20 epochs at which GPS is observed (2019-04-28 12:44:33 .. 2019-04-28 12:44:52 GPS) -- pass the "
        "navigation file(s) of the observation day, 2019-04-28 (day of year 118)"
    )
    # QZSS served by scenario.nav: the message names scenario.nav (it said "(no scenario.nav given)")
    nagoya = cut(NG_OBS, tmp_path / "ng.obs", 10)
    no_qzss = edit_body(NG_NAV, tmp_path / "no_j.nav", without_records_of("J"))
    mojn = shared_data / "rinex_corpus" / "NAV" / "V3" / "MOJN00DNK_R_20201770000_01D_MN.rnx.gz"  # 2020-06-25
    msg = one_line_error(load_rinex, nagoya, [no_qzss, mojn], None, systems="GJ")
    assert msg.startswith(
        f"scenario.nav ['{no_qzss}', '{mojn}']: its QZSS records serve 2020-06-24 22:00:00 .. 2020-06-26 02:00:00 GPS, "
        "none of the 10 epochs at which QZSS is observed (2024-06-24 08:20:00 .. 2024-06-24 08:20:09 GPS)"
    )
    assert msg.endswith("2024-06-24 (day of year 176)")
    msg = one_line_error(load_rinex, nagoya, no_qzss, None, systems="GJ")
    assert msg.startswith(f"scenario.nav '{no_qzss}': contains no QZSS records -- ")


def test_observed_satellites_without_a_record_are_left_out_with_one_warning_each(tmp_path: Path) -> None:
    """Dropped without a word before (counted in meta only): G04 has no healthy record in the Hong Kong file;
    C05, C23 (all their epochs) and C28 (some) have none within 2 h while other BeiDou satellites have."""
    hk = cut(HK_OBS, tmp_path / "hk.obs", 1000)
    sc, messages = loaded_with_warnings(hk, HK_NAV, None, systems="GC", nav_bds_path=HK_BDS)
    assert messages == [
        f"scenario.nav '{HK_NAV}': GPS satellites G04: no healthy record in the file(s); 670 observed rows, the "
        "first at 2019-04-28 12:45:04 GPS -- those rows are left out",
        f"scenario.nav_bds '{HK_BDS}': BeiDou satellites C05, C23, C28: no record within 2 h of these rows' epochs "
        "(other BeiDou satellites have one); 899 observed rows, the first at 2019-04-28 12:44:33 GPS -- those rows "
        "are left out",
    ]
    obs = read_rinex_obs(hk, "GC")
    observed = int(np.isfinite(obs.code).sum())
    assert observed - len(sc.observations) == 670 + 899
    assert not set(sc.observations["sat"]) & {"G04", "C05", "C23"} and "C28" in set(sc.observations["sat"])


@pytest.mark.parametrize(
    ("name", "content", "expected"),
    [
        ("nul", b"\0" * 8192, "holds only NUL bytes (8,192): the file was never written -- copy the file again"),
        ("zeros", b"0" * 80 * 100, "has no RINEX header -- "),
    ],
    ids=["nul_bytes", "zero_digits"],
)
def test_a_file_of_zeros_is_refused_in_one_line(tmp_path: Path, name: str, content: bytes, expected: str) -> None:
    obs, nav = tmp_path / f"{name}.obs", tmp_path / f"{name}.nav"
    obs.write_bytes(content)
    nav.write_bytes(content)
    assert one_line_error(read_rinex_obs, obs, "G").startswith(f"scenario.obs '{obs}': {expected}")
    if name == "nul":
        assert one_line_error(read_gps_navigation, nav).startswith(f"nav_file '{nav}': {expected}")


def test_a_log_whose_copy_ends_in_nul_bytes_is_refused_in_one_line(tmp_path: Path) -> None:
    """An interrupted copy: the first 200 kB of the Nagoya log, then 8 kB of NULs (the RINEX 2 reader took such
    a file's readable epochs without a word)."""
    raw = NG_OBS.read_bytes()[:200_000]
    damaged = tmp_path / "cut.obs"
    damaged.write_bytes(raw + b"\0" * 8192)
    line = raw.count(b"\n") + 1
    assert one_line_error(read_rinex_obs, damaged, "G").startswith(
        f"scenario.obs '{damaged}': ends in 8,192 NUL bytes after line {line}: the file was not completely written"
    )


def test_a_log_of_event_records_only_is_refused_in_one_line(tmp_path: Path) -> None:
    """Header, then special records only (flag 4: header lines follow; flag 5: an external event): no epoch to
    read, and the message says so."""
    lines = NG_OBS.read_text().splitlines()
    end = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    events = ["> 2024 06 24 08 20 00.0000000  5  0"] + [
        ">                              4  1",
        f"{'a comment in a special record':60s}COMMENT",
    ] * 3
    path = tmp_path / "events.obs"
    path.write_text("\n".join(lines[:end] + events) + "\n")
    msg = one_line_error(read_rinex_obs, path, "G")
    assert msg.startswith(f"scenario.obs '{path}': has no observation epochs: its 4 epoch records are all event")

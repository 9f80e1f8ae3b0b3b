"""Reader conformance on the RINEX corpus (issue 44): each observation file of ``../shared/data/rinex_corpus``
(RINEX 2.0-4.00, plain, gzip and Hatanaka, IGS/EUREF stations, a phone, Septentrio and software receivers)
is read with the values an independent reader reads, per system, signal and satellite, or refused in one line.

The independent reader is georinex 1.16: ``tests/data/rinex_corpus_counts.json`` holds its counts of present
values (neither blank nor 0.000) per observable and satellite, made by ``tests/data/make_rinex_corpus_counts.py``
(the six one-day files over their first two hours). The small files are also compared value by value with
georinex run here.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import georinex
import numpy as np
import pytest
import xarray as xr
from conftest import one_line_error

from simbench.core.gpstime import gps_to_datetime64
from simbench.data.broadcast import NAV_SYSTEMS, read_navigation
from simbench.data.rinex import SIGNALS, RinexObs, read_rinex_obs
from simbench.gnss.navigation import read_gps_navigation

# georinex 1.16 merges with xarray defaults that are about to change: not ours to fix
pytestmark = pytest.mark.filterwarnings("ignore::FutureWarning")

REFERENCE = json.loads((Path(__file__).parent / "data" / "rinex_corpus_counts.json").read_text())
#: Navigation readers per system.
NAV_READERS = {"G": read_gps_navigation, **{s: functools.partial(read_navigation, s) for s in NAV_SYSTEMS}}
#: RINEX 4 navigation files ('> EPH' frames), refused in one line.
RINEX4_NAV = ("NAV/V4/BRD400DLR_S_20230710000_01D_MN.rnx.gz", "NAV/V4/KMS300DNK_R_20221591000_01H_MN.rnx.gz")
OBSERVATION_FILES = sorted(n for n in REFERENCE if not n.startswith("NAV/"))
#: Files compared value by value with georinex run in the test (each reads in well under a second); the
#: larger ones are compared by counts only (georinex reads the largest in minutes).
SMALL_BYTES = 100_000


@pytest.fixture
def corpus(shared_dir: Path) -> Path:
    return shared_dir / "data" / "rinex_corpus"


def georinex_name(version: float, kind: str, code: str) -> str:
    """georinex's name of observable ``kind`` (C, L, D, S) of RINEX 3 signal ``code`` (``'2W'``): RINEX 2 files
    keep their own types, whose P code is ``P`` (simbench reads it as the W or P attribute)."""
    if version >= 3:
        return f"{kind}{code}"
    return ("P" if kind == "C" and code[1] in "WP" else kind) + code[0]


def in_window(obs: RinexObs, window: list[str] | None) -> np.ndarray:
    """Which rows fall in georinex's reading window (all without one)."""
    if window is None:
        return np.ones(obs.sat.size, bool)
    t = gps_to_datetime64(obs.epoch_t_int + obs.epoch_t_frac)[obs.row_epoch]
    return (t >= np.datetime64(window[0])) & (t <= np.datetime64(window[1]))


def per_satellite(sats: np.ndarray, present: np.ndarray) -> dict[str, int]:
    names, n = np.unique(sats[present], return_counts=True)
    return dict(zip(names.tolist(), n.tolist()))


def reference_counts(ref: dict, name: str, sats: set[str]) -> dict[str, int]:
    return {s: n for s, n in ref["counts"].get(name, {}).items() if s in sats}


@pytest.mark.usefixtures("shared_data")
@pytest.mark.parametrize("name", OBSERVATION_FILES)
def test_every_corpus_file_reads_what_georinex_reads(corpus: Path, name: str) -> None:
    ref = REFERENCE[name]
    obs = read_rinex_obs(corpus / name, "".join(SIGNALS))
    rows = in_window(obs, ref["window"])
    epochs = np.unique(obs.row_epoch[rows]).size if ref["window"] else obs.epoch_t_int.size
    assert epochs == ref["epochs"]
    letters = np.array([s[:1] for s in obs.sat.tolist()])
    in_file = {s for per_sat in ref["counts"].values() for s in per_sat}
    for system, band in obs.signals.items():
        mine = rows & (letters == system)
        sats = {s for s in in_file if s[0] == system}
        for kind, values in zip("CLDS", (obs.code, obs.phase_cycles, obs.doppler_hz, obs.cn0_dbhz)):
            theirs = reference_counts(ref, georinex_name(obs.version, kind, band), sats)
            assert per_satellite(obs.sat[mine], np.isfinite(values[mine])) == theirs, (system, kind + band)
    # the second signal: each satellite's one code (signal_l2) against the same code in georinex
    assert obs.signal_l2 is not None and obs.code_l2 is not None and obs.phase_l2_cycles is not None
    for sat, code in sorted(set(zip(obs.sat[rows].tolist(), obs.signal_l2[rows].tolist()))):
        mine = rows & (obs.sat == sat)
        for kind, values in (("C", obs.code_l2), ("L", obs.phase_l2_cycles)):
            theirs = ref["counts"].get(georinex_name(obs.version, kind, code), {}).get(sat, 0) if code else 0
            assert int(np.isfinite(values[mine]).sum()) == theirs, (sat, kind + code)
    # systems simbench does not read (SBAS, NavIC) are counted, not dropped in silence
    assert set(obs.unread_systems) == {s[0] for s in in_file} - set(SIGNALS)


@pytest.mark.usefixtures("shared_data")
@pytest.mark.parametrize("name", [n for n in OBSERVATION_FILES if REFERENCE[n]["bytes"] <= SMALL_BYTES])
def test_small_corpus_files_have_georinex_values(corpus: Path, name: str) -> None:
    path = corpus / name
    assert path.stat().st_size == REFERENCE[name]["bytes"]  # the file the reference was made from
    obs = read_rinex_obs(path, "".join(SIGNALS))
    ds = georinex.load(path, fast=False)
    times = gps_to_datetime64(obs.epoch_t_int + obs.epoch_t_frac)[obs.row_epoch].astype("datetime64[ns]")
    for system, band in obs.signals.items():
        mine = np.flatnonzero(np.char.startswith(obs.sat.astype(str), system))
        for kind, values in zip("CLS", (obs.code, obs.phase_cycles, obs.cn0_dbhz)):
            var = georinex_name(obs.version, kind, band)
            if var not in ds:
                assert np.isnan(values[mine]).all()
                continue
            at = {"time": xr.DataArray(times[mine], dims="row"), "sv": xr.DataArray(obs.sat[mine], dims="row")}
            theirs = ds[var].sel(at).values
            theirs = np.where(theirs == 0, np.nan, theirs)
            np.testing.assert_allclose(values[mine], theirs, atol=5e-4, rtol=0, err_msg=f"{system} {var}")


@pytest.mark.usefixtures("shared_data")
@pytest.mark.parametrize("name", sorted(n for n in REFERENCE if n.startswith("NAV/")) + list(RINEX4_NAV))
def test_every_corpus_navigation_file_reads_or_is_refused_in_one_line(corpus: Path, name: str) -> None:
    """Each system's reader gives the satellites georinex finds a healthy record of (a subset of those with a
    record where georinex parses none of the system's numbers), or one line saying why not."""
    healthy = REFERENCE.get(name, {}).get("healthy", {})
    present = REFERENCE.get(name, {}).get("present", {})
    for system, read in NAV_READERS.items():
        if system in healthy:
            assert sorted(set(read(corpus / name).sats.tolist())) == healthy[system], system
        elif system in present:
            mine = set(read(corpus / name).sats.tolist())
            assert mine and mine <= set(present[system]), system
        else:
            msg = one_line_error(read, corpus / name)
            assert ("RINEX 4" in msg) == (name in RINEX4_NAV), msg


def test_an_empty_navigation_file_is_one_line_for_every_reader(tmp_path: Path) -> None:
    empty = tmp_path / "empty.rnx"
    empty.write_text("")
    for system, read in NAV_READERS.items():
        assert str(empty) in one_line_error(read, empty), system

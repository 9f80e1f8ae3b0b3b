"""RINEX navigation files: GPS via georinex, and the fixed-column RINEX 3 record reader.

GPS (RINEX 2 or 3, also the GPS records of a mixed RINEX 3 file) is parsed by
georinex; :func:`read_gps_navigation` turns its (time, satellite) grid into
the flat per-record arrays the ephemeris evaluator takes. The orbit and clock
computation itself (IS-GPS-200) lives in :mod:`simbench.core.orbits`.

:func:`read_rinex3_records` is the one reader of RINEX 3 navigation records
for the other systems (BeiDou, Galileo, GLONASS, QZSS; :mod:`simbench.data.broadcast`), from a
single-system or a mixed (``M``) file: georinex 1.16 returns all-NaN records
for files whose spare fields are blank (as in ``hksc1180.19b``).

:data:`GroupDelays` carries the broadcast group delays an ephemeris object does not
keep (the second signals' ones), one value per satellite (:func:`satellite_medians`).
"""

from __future__ import annotations

import io
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import hatanaka
import lazy_loader
import numpy as np

from simbench.core.constants import SECONDS_PER_WEEK
from simbench.core.gpstime import datetime64_to_gps
from simbench.core.orbits import FIT_HALF_WINDOW_S, BroadcastEphemeris
from simbench.errors import SimbenchError

# xarray and georinex cost ~1 s to import: loaded on first use
georinex = lazy_loader.load("georinex")

__all__ = [
    "read_gps_navigation",
    "read_rinex3_records",
    "read_rinex_lines",
    "NavRecords",
    "NavPaths",
    "SYSTEM_NAMES",
    "UNREAD_SYSTEM_NAMES",
    "nav_paths",
    "nav_header_system",
    "files_field",
    "unique_rows",
    "satellite_medians",
    "GroupDelays",
    "KEPLER_CLOCK_FIELDS",
    "kepler_layout",
    "record_columns",
    "complete_kepler_records",
    "kepler_records",
]

#: Leading bytes of gzip, Unix compress, bzip2 and zip files.
_PACKED = (b"\x1f\x8b", b"\x1f\x9d", b"BZh", b"PK\x03\x04")
#: RINEX system letter -> name used in messages.
SYSTEM_NAMES = {"G": "GPS", "R": "GLONASS", "E": "Galileo", "C": "BeiDou", "J": "QZSS"}
#: Systems a RINEX file may hold that simbench recognises but does not read (counted, never dropped in silence).
UNREAD_SYSTEM_NAMES = {"S": "SBAS", "I": "NavIC", "L": "LEO"}
#: One navigation file or several (records merged): what ``scenario.nav`` and the per-system settings hold.
NavPaths = str | os.PathLike[str] | Sequence[str | os.PathLike[str]]

#: Keplerian orbit and clock-polynomial quantities of a GPS-like record (GPS, QZSS, Galileo, BeiDou),
#: the names :class:`~simbench.core.orbits.BroadcastEphemeris` and its subclasses read.
KEPLER_CLOCK_FIELDS = (
    "af0",
    "af1",
    "af2",
    "crs",
    "dn",
    "m0",
    "cuc",
    "e",
    "cus",
    "sqrta",
    "cic",
    "omega0",
    "cis",
    "i0",
    "crc",
    "w",
    "omegadot",
    "idot",
)


def kepler_layout(issue: str, *rest: str) -> tuple[str, ...]:
    """Order of the numbers of a RINEX 3 GPS-like record: the 20 shared ones, then ``rest``.

    Parameters
    ----------
    issue : str
        Name of the system's issue-of-data number (the 4th: ``iode``, ``iod``, ``aode``).
    rest : str
        The system's numbers after ``idot`` ('' for one this reader skips).
    """
    return ("af0", "af1", "af2", issue, "crs", "dn", "m0", "cuc", "e", "cus", "sqrta", "toe",
            "cic", "omega0", "cis", "i0", "crc", "w", "omegadot", "idot", *rest)  # fmt: skip


#: Broadcast group-delay fields of one system, each one value per satellite of its ephemeris
#: (aligned with ``sats``) [s], NaN where the records carry none: ``tgd`` (GPS and QZSS TGD, BeiDou
#: TGD1), ``tgd2`` (BeiDou TGD2), ``bgd_e5a`` and ``bgd_e5b`` (Galileo BGD(E1,E5a), BGD(E1,E5b)).
GroupDelays = dict[str, np.ndarray]

#: georinex variable of each record quantity that :class:`BroadcastEphemeris` takes.
_RECORD_SOURCE = {
    "af0": "SVclockBias",
    "af1": "SVclockDrift",
    "af2": "SVclockDriftRate",
    "crs": "Crs",
    "dn": "DeltaN",
    "m0": "M0",
    "cuc": "Cuc",
    "e": "Eccentricity",
    "cus": "Cus",
    "sqrta": "sqrtA",
    "cic": "Cic",
    "omega0": "Omega0",
    "cis": "Cis",
    "i0": "Io",
    "crc": "Crc",
    "w": "omega",
    "omegadot": "OmegaDot",
    "idot": "IDOT",
    "tgd": "TGD",
}
#: Every georinex variable a complete GPS record needs.
_NAV_FIELDS = (*_RECORD_SOURCE.values(), "Toe", "GPSWeek", "health")


_NAV_FIX = "pass a RINEX 2/3 GPS navigation file (e.g. brdc<doy>0.<yy>n)"


def _nav_error(path: str, problem: str) -> SimbenchError:
    return SimbenchError(f"nav_file '{path}'", problem, _NAV_FIX)


def nav_paths(value: NavPaths | None) -> tuple[str, ...]:
    """The navigation files of a setting: one path or a list of paths, empty entries dropped, in order."""
    if value is None:
        return ()
    items = [value] if isinstance(value, (str, os.PathLike)) else list(value)
    return tuple(dict.fromkeys(os.fspath(v) for v in items if os.fspath(v)))


def files_field(setting: str, paths: Sequence[str]) -> str:
    """The field of an error about ``setting``'s files: ``"scenario.nav 'a.19n'"`` or ``"scenario.nav ['a', 'b']"``."""
    return f"{setting} '{paths[0]}'" if len(paths) == 1 else f"{setting} {list(paths)}"


def nav_header_system(path: str) -> str:
    """System letter of a RINEX navigation file's header ('M' mixed, 'G', 'R', ...), '' if unreadable.

    The file may be compressed (:func:`read_rinex_lines`); an unreadable one is left to the
    navigation reader, whose error names the problem.
    """
    try:
        lines = read_rinex_lines(path, f"nav_file '{path}'", "pass a RINEX navigation file")
    except (OSError, SimbenchError):
        return ""
    first = lines[0] if lines else ""
    if first[:9].strip().startswith(("3", "4")) and first[20:21] == "N":  # RINEX 4: refused by the readers
        return first[40:41]
    return {"N": "G", "G": "R"}.get(first[20:21], "")  # RINEX 2: N is GPS, G is GLONASS


def _serves(path: str, system: str) -> bool:
    """Whether file ``path`` may hold records of ``system``: mixed, that system's own, or of unknown kind."""
    return nav_header_system(path) in ("", "M", system)


def unique_rows(matrix: np.ndarray) -> np.ndarray:
    """Indices of the first occurrence of each distinct row of ``matrix`` (NaN equal to NaN), increasing.

    Merging navigation files: a record broadcast in two files is kept once.
    """
    keys = [row.tobytes() for row in np.ascontiguousarray(matrix, dtype=float)]
    first: dict[bytes, int] = {}
    for k, key in enumerate(keys):
        first.setdefault(key, k)
    return np.array(sorted(first.values()), dtype=np.intp)


def satellite_medians(record_sat: np.ndarray, values: np.ndarray, n_sats: int) -> np.ndarray:
    """Median of the finite ``values`` of each satellite's records, NaN for a satellite without one.

    The per-satellite reduction :class:`~simbench.core.orbits.BroadcastEphemeris` applies to ``tgd``,
    for the group delays it does not keep (:data:`GroupDelays`).

    Parameters
    ----------
    record_sat : np.ndarray of int, shape (R,)
        Satellite (index into the ephemeris' ``sats``) of each record.
    values : np.ndarray, shape (R,)
        One number per record [any unit]; NaN where the record has none.
    n_sats : int
        Number of satellites.

    Returns
    -------
    np.ndarray, shape (n_sats,)
    """
    ok = np.isfinite(values)
    sat, v = record_sat[ok], values[ok]
    order = np.lexsort((v, sat))
    sat, v = sat[order], v[order]
    start = np.searchsorted(sat, np.arange(n_sats), side="left")
    count = np.searchsorted(sat, np.arange(n_sats), side="right") - start
    lo = start + np.maximum(count - 1, 0) // 2
    hi = start + count // 2
    out = np.full(n_sats, np.nan)
    has = count > 0
    out[has] = 0.5 * (v[lo[has]] + v[hi[has]])
    return out


def _gps_records(p: str) -> tuple[dict[str, np.ndarray] | None, np.ndarray | None]:
    """The healthy complete GPS records of one file as flat arrays (None when it has none), and its Klobuchar."""
    if not os.path.isfile(p):
        raise _nav_error(p, "file does not exist")
    # georinex reads the unpacked, line-ending-normalized text: it misreads CR CR LF files
    lines = read_rinex_lines(p, f"nav_file '{p}'", _NAV_FIX)
    _refuse_rinex4(lines, f"nav_file '{p}'", _NAV_FIX)
    text = io.StringIO("\n".join(lines) + "\n")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            info = georinex.rinexinfo(text)
            text.seek(0)
            kind = info.get("rinextype")
            if kind != "nav":
                what = {"obs": "a RINEX observation file", "sp3": "an SP3 orbit file"}.get(
                    str(kind), "not a RINEX file"
                )
                raise _nav_error(p, f"is {what}, not RINEX navigation data")
            ds = georinex.load(text, use={"G"})  # a mixed RINEX 3 file holds other systems too
    except SimbenchError:
        raise
    except Exception as exc:  # georinex raises many types on malformed text
        msg = " ".join(str(exc).split()) or type(exc).__name__
        msg = msg if len(msg) <= 60 else msg[:57] + "..."
        raise _nav_error(p, f"cannot be parsed as RINEX navigation data (georinex: {msg})") from None
    if "sv" not in ds.coords or not all(k in ds for k in _NAV_FIELDS):
        return None, None
    is_gps = np.char.startswith(ds.sv.values.astype(str), "G")
    if not is_gps.any():
        return None, None
    ds = ds.isel(sv=np.flatnonzero(is_gps))

    # (time, sv) grid -> flat record list; georinex leaves NaN where a sat has no record.
    v = {k: ds[k].values.astype(float).ravel() for k in _NAV_FIELDS}
    n_t, n_s = ds.sizes["time"], ds.sizes["sv"]
    toc = np.repeat(datetime64_to_gps(ds.time.values), n_s)
    sv_all = np.tile(ds.sv.values.astype(str), n_t)
    complete = np.all(np.isfinite(np.stack(list(v.values()))), axis=0)
    keep = complete & (v["health"] == 0) & (v["sqrtA"] > 1000.0)
    toe = v["GPSWeek"][keep] * SECONDS_PER_WEEK + v["Toe"][keep]
    toc = toc[keep]
    # GPSWeek belongs to Toe, but some writers use Toc's week; Toe and Toc are
    # within hours of each other, so fix a one-week mismatch from Toc.
    toe += SECONDS_PER_WEEK * np.round((toc - toe) / SECONDS_PER_WEEK)
    records = {k: v[src][keep] for k, src in _RECORD_SOURCE.items()}
    records.update(sv=sv_all[keep], toe=toe, toc=toc)
    iono = ds.attrs.get("ionospheric_corr_GPS")
    klobuchar = None
    if iono is not None and np.size(iono) == 8 and np.all(np.isfinite(iono)):
        klobuchar = np.asarray(iono, float)
    return records, klobuchar


def read_gps_navigation(
    path: NavPaths,
    max_age_s: float = FIT_HALF_WINDOW_S,
    *,
    setting: str = "nav_file",
) -> BroadcastEphemeris:
    """Read GPS ephemerides from RINEX 2 or 3 navigation files (via georinex), records merged.

    Parameters
    ----------
    path : str, PathLike or sequence of them
        RINEX navigation file(s) (``.yyn``, ``.rnx``; compressed and any line
        ending allowed, :func:`read_rinex_lines`). Only GPS records are kept;
        unhealthy or incomplete records are dropped, and a record found in several
        files is kept once; files whose header names another system are skipped.
    max_age_s : float
        Largest |t - Toe| at which a record may be used [s]; default 7200.
    setting : str
        Config setting that named the files, for error messages.

    Returns
    -------
    BroadcastEphemeris
        With the Klobuchar coefficients of the first header that has them.

    Raises
    ------
    SimbenchError
        Missing file, not a navigation file, or no healthy GPS record.
    """
    paths = nav_paths(path)
    if not paths:
        raise SimbenchError(setting, "no navigation file given", _NAV_FIX)
    single = len(paths) == 1
    found = [_gps_records(p) for p in paths if single or _serves(p, "G")]
    parts = [r for r, _ in found if r is not None]
    field = files_field(setting, paths)
    if not parts:
        raise SimbenchError(field, "contains no GPS ephemerides (e.g. GLONASS/BeiDou-only file)", _NAV_FIX)
    merged = {k: np.concatenate([r[k] for r in parts]) for k in parts[0]}
    if not merged["sv"].size:
        raise SimbenchError(field, "has no complete healthy GPS ephemeris record", _NAV_FIX)
    sats, sat_idx = np.unique(merged.pop("sv"), return_inverse=True)
    numbers = np.column_stack([sat_idx, *merged.values()])
    rows = unique_rows(numbers)
    records = {k: x[rows] for k, x in merged.items()}
    records["sat"] = sat_idx[rows]
    klobuchar = next((k for _, k in found if k is not None), None)
    alpha, beta = (klobuchar[:4], klobuchar[4:]) if klobuchar is not None else (None, None)
    return BroadcastEphemeris(sats, records, alpha, beta, source=source_label(paths), max_age_s=max_age_s)


@dataclass(frozen=True)
class NavRecords:
    """The records of one system from a RINEX 3 navigation file, as flat arrays.

    Attributes
    ----------
    sv : np.ndarray of str, shape (R,)
        Satellite id of each record (``'E11'``).
    epoch : np.ndarray of datetime64[s], shape (R,)
        Record epoch (Toc; for GLONASS tb) as written, in the system's own time scale label.
    values : np.ndarray, shape (R, K)
        The numbers after the epoch, in file order (3 on the first line, 4 per further line),
        NaN where blank or beyond the record's end [units of the RINEX field].
    """

    sv: np.ndarray
    epoch: np.ndarray
    values: np.ndarray


def _field(text: str) -> float:
    text = text.strip().replace("D", "E").replace("d", "e")
    return float(text) if text else np.nan


def read_rinex_lines(path: str, field: str, fix: str) -> list[str]:
    """The text lines of a RINEX file, unpacked and without line endings.

    gzip, zip, bzip2 and Unix compress files and Hatanaka-compressed (Compact
    RINEX, ``.crx``, ``.yyd``) files are unpacked, told by their first bytes,
    not their name. LF, CR LF, CR alone and CR CR LF (a CR LF file converted once more)
    all give the same lines: RINEX columns are fixed, so a stray CR would
    shift nothing but would add an empty line that ends an epoch record early.

    Parameters
    ----------
    path : str
        An existing file.
    field : str
        The setting and file, for error messages (``"scenario.obs 'x.obs'"``).
    fix : str
        What the user should pass instead, for error messages.

    Returns
    -------
    list of str
        Line ``k`` of the file (1-based) is element ``k - 1``; a file that ends
        in a line break has no empty last element.

    Raises
    ------
    SimbenchError
        A compressed file that cannot be unpacked (cut or damaged); a file of NUL bytes, or
        one that ends in them (an interrupted copy).
    """
    with open(path, "rb") as fh:
        raw = fh.read()
    if raw.startswith(_PACKED) or b"CRINEX VERS" in raw[:80]:
        try:
            raw = hatanaka.decompress(raw)
        except (hatanaka.HatanakaException, ValueError, OSError, EOFError) as exc:
            msg = " ".join(str(exc).split())[:60] or type(exc).__name__
            raise SimbenchError(
                field, f"cannot be unpacked ({msg}); the compressed file is damaged or cut", fix
            ) from None
    _refuse_nul_bytes(raw, field)
    text = raw.decode("utf-8", errors="replace")
    lines = [ln.rstrip("\r") for ln in text.split("\n" if "\n" in text else "\r")]
    if lines and not lines[-1]:
        lines.pop()
    return lines


def _refuse_nul_bytes(raw: bytes, field: str) -> None:
    """Raise a one-line error for a file of NUL bytes, or one that ends in a run of them.

    Such a file was allocated but not (completely) written: an interrupted copy or download, a disk
    that lost its last blocks. Read as text, the NULs would pass for blanks (missing values) or end
    the file without a word. NULs among other bytes (a binary file) are left to the reader's checks.
    """
    body = raw.rstrip(b"\0")
    tail = len(raw) - len(body)
    if not tail:
        return
    fix = "copy the file again from its source"
    if not body:
        raise SimbenchError(field, f"holds only NUL bytes ({tail:,}): the file was never written", fix)
    if b"\0" not in body:
        line = body.count(b"\n") + 1
        raise SimbenchError(
            field, f"ends in {tail:,} NUL bytes after line {line}: the file was not completely written", fix
        )


def record_columns(nav: NavRecords, layout: Sequence[str], system: str, field: str, fix: str) -> dict[str, np.ndarray]:
    """Each named number of the records, by the system's ``layout`` ('' for a skipped one).

    Raises
    ------
    SimbenchError
        Naming ``field`` when the records hold fewer numbers than ``layout``.
    """
    a = nav.values
    if a.shape[1] < len(layout):
        raise SimbenchError(
            field, f"has {SYSTEM_NAMES[system]} records of {a.shape[1]} numbers, not {len(layout)}", fix
        )
    return {name: a[:, k] for k, name in enumerate(layout) if name}


def source_label(paths: Sequence[str]) -> str:
    """The file names of ``paths``, comma-separated: an ephemeris's ``source``."""
    return ", ".join(os.path.basename(p) for p in paths)


@dataclass(frozen=True)
class SystemNav:
    """One system's records of RINEX 3 navigation files, by name, with what its errors name.

    Attributes
    ----------
    records : NavRecords
    columns : dict of str to ndarray
        :func:`record_columns` of ``records`` by the system's layout.
    system : str
        The system letter.
    field : str
        The setting and files, for errors (:func:`files_field`).
    fix : str
        What the user should pass instead, for errors.
    source : str
        :func:`source_label` of the files.
    """

    records: NavRecords
    columns: dict[str, np.ndarray]
    system: str
    field: str
    fix: str
    source: str

    def healthy(self, keep: np.ndarray) -> np.ndarray:
        """``keep``, or a one-line error when it keeps no record."""
        if not keep.any():
            raise SimbenchError(self.field, f"has no complete healthy {SYSTEM_NAMES[self.system]} record", self.fix)
        return keep


def read_system_nav(path: NavPaths, system: str, layout: Sequence[str], setting: str, fix: str) -> SystemNav:
    """Read one system's records from RINEX 3 navigation files (:func:`read_rinex3_records`) and name
    their numbers by ``layout`` (:func:`record_columns`); errors name ``setting`` and say ``fix``."""
    paths = nav_paths(path)
    field = files_field(setting, paths) if paths else setting
    records = read_rinex3_records(paths, system, setting, fix)
    columns = record_columns(records, layout, system, field, fix)
    return SystemNav(records, columns, system, field, fix, source_label(paths))


def complete_kepler_records(columns: dict[str, np.ndarray], fields: Sequence[str]) -> np.ndarray:
    """Records whose ``fields``, week and Toe are finite and whose sqrt(a) is an orbit's (> 1000 sqrt(m))."""
    finite = np.all(np.isfinite(np.stack([columns[f] for f in fields])), axis=0)
    return finite & np.isfinite(columns["week"]) & np.isfinite(columns["toe"]) & (columns["sqrta"] > 1000.0)


def kepler_records(
    nav: NavRecords,
    columns: dict[str, np.ndarray],
    fields: Sequence[str],
    keep: np.ndarray,
    toe: np.ndarray,
    toc: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """The kept records as an ephemeris takes them, Toe moved into Toc's week.

    Parameters
    ----------
    nav : NavRecords
    columns : dict of str to ndarray
        :func:`record_columns` of ``nav``.
    fields : sequence of str
        The columns the ephemeris reads.
    keep : ndarray of bool
        Records to use.
    toe, toc : ndarray
        Toe and Toc of the kept records [s, continuous GPS time].

    Returns
    -------
    sats : ndarray of str
        Satellite ids, sorted.
    sat_idx : ndarray of int
        Index into ``sats`` of each kept record.
    records : dict of str to ndarray
        ``fields`` of the kept records, with ``sat``, ``toe`` and ``toc``.
    """
    toe = toe + SECONDS_PER_WEEK * np.round((toc - toe) / SECONDS_PER_WEEK)
    sats, sat_idx = np.unique(nav.sv[keep], return_inverse=True)
    records = {k: columns[k][keep] for k in fields}
    records.update(sat=sat_idx, toe=toe, toc=toc)
    return sats, sat_idx, records


def _refuse_rinex4(lines: list[str], field: str, fix: str) -> None:
    """One line for a RINEX 4 navigation file: its records (``> EPH``, ``> ION`` frames) are not read yet."""
    if lines and "RINEX VERSION / TYPE" in lines[0] and lines[0][:9].strip().startswith("4"):
        raise SimbenchError(
            field,
            f"is RINEX {lines[0][:9].strip()} navigation data, which simbench does not read (its records are "
            "framed by '> EPH' lines)",
            "pass the day's RINEX 3 broadcast file (e.g. BRDC00IGS_R_<yyyyddd>0000_01D_MN.rnx) or convert it "
            "with 'gfzrnx -finp FILE -fout OUT -vo 3'; " + fix,
        )


def read_rinex3_records(path: NavPaths, system: str, setting: str, fix: str) -> NavRecords:
    """Read the records of one system from RINEX 3 navigation files (single-system or mixed), merged.

    A record is a line starting with the satellite id (``'E11 2019 04 28 ...'``)
    and the indented lines after it, so records of every system and of any
    RINEX 3.0x length are skipped correctly. Of several files, those whose header
    names another system are skipped, and a record found in several files is kept once.

    Parameters
    ----------
    path : str, PathLike or sequence of them
        RINEX 3 navigation file(s) (plain text or compressed, :func:`read_rinex_lines`).
    system : str
        System letter to keep (``'C'``, ``'E'``, ``'R'``, ``'J'``).
    setting : str
        Config setting that named the files, for error messages (``'scenario.nav_gal'``).
    fix : str
        What the user should pass instead, for error messages.

    Returns
    -------
    NavRecords

    Raises
    ------
    SimbenchError
        Missing file, not RINEX 3 navigation data, a malformed epoch or number, or no record of ``system``.
    """
    paths = nav_paths(path)
    if not paths:
        raise SimbenchError(setting, "no navigation file given", fix)
    single = len(paths) == 1
    parts = [_rinex3_records(p, system, setting, fix) for p in paths if single or _serves(p, system)]
    sv = np.concatenate([pt[0] for pt in parts]) if parts else np.zeros(0, str)
    if not sv.size:
        raise SimbenchError(files_field(setting, paths), f"contains no {SYSTEM_NAMES.get(system, system)} records", fix)
    width = max(len(r) for pt in parts for r in pt[2])
    values = np.array([r + [np.nan] * (width - len(r)) for pt in parts for r in pt[2]], dtype=float)
    epoch = np.concatenate([np.array(pt[1], dtype="datetime64[s]") for pt in parts])
    sat_code = np.unique(sv, return_inverse=True)[1]
    keep = unique_rows(np.column_stack([sat_code, epoch.astype(np.int64), values]))
    return NavRecords(sv=sv[keep], epoch=epoch[keep], values=values[keep])


def _rinex3_records(p: str, system: str, setting: str, fix: str) -> tuple[np.ndarray, list[str], list[list[float]]]:
    """Satellite ids, epoch stamps and numbers of the ``system`` records of one RINEX 3 navigation file
    (or of a RINEX 2 GLONASS one, type ``G``: two-digit years, satellite numbers without a letter)."""
    field = f"{setting} '{p}'"
    if not os.path.isfile(p):
        raise SimbenchError(field, "file does not exist", fix)
    lines = read_rinex_lines(p, field, fix)
    _refuse_rinex4(lines, field, fix)
    top = lines[0] if lines else ""
    version, kind = top[:9].strip(), top[20:21]
    rinex2_glonass = version.startswith("2") and kind == "G"
    if not (version.startswith("3") and kind == "N") and not rinex2_glonass:
        what = f"RINEX {version} '{top[20:40].strip()}'" if "RINEX VERSION / TYPE" in top else "not RINEX"
        raise SimbenchError(field, f"is {what}, not RINEX 3 (or RINEX 2 GLONASS) navigation data", fix)
    body = next((i + 1 for i, ln in enumerate(lines) if "END OF HEADER" in ln), None)
    if body is None:
        raise SimbenchError(field, "has no END OF HEADER line", fix)
    if rinex2_glonass and system != "R":
        return np.zeros(0, str), [], []
    # RINEX 3: 'R05 2019 04 28 ...', numbers from column 23, continued from 4; RINEX 2: ' 5 19  4 28 ...', 22, 3
    date, first, cont = ((3, 22), 22, 3) if rinex2_glonass else ((4, 23), 23, 4)
    sv, stamps, rows = [], [], []
    i, n_lines = body, len(lines)
    while i < n_lines:  # text parsing: one Python step per line is unavoidable
        head = lines[i]
        i += 1
        if not (head[:2].strip().isdigit() if rinex2_glonass else head[:1] == system):
            continue
        stop = i  # continuation lines start with blanks (RINEX 2: three, then a signed number)
        while stop < n_lines and lines[stop][:1] == " " and not (rinex2_glonass and lines[stop][:2].strip()):
            stop += 1
        try:
            f = head[date[0] : date[1]].split()
            year = int(f[0])
            if rinex2_glonass:  # two digits: 80-99 are 1980-1999
                year += 1900 if year >= 80 else 2000
            stamps.append(
                f"{year:04d}-{int(f[1]):02d}-{int(f[2]):02d}T{int(f[3]):02d}:{int(f[4]):02d}:{int(float(f[5])):02d}"
            )
            rec = [_field(head[first + 19 * k : first + 19 + 19 * k]) for k in range(3)]
            for ln in lines[i:stop]:
                rec += [_field(ln[cont + 19 * k : cont + 19 + 19 * k]) for k in range(4)]
        except (ValueError, IndexError):
            raise SimbenchError(
                field, f"has a malformed {head[:3].strip()} record at line {i}: '{head[:42].strip()}'", fix
            ) from None
        sv.append(f"R{int(head[:2]):02d}" if rinex2_glonass else head[:3].replace(" ", "0"))
        rows.append(rec)
        i = stop
    return np.array(sv, dtype=str), stamps, rows

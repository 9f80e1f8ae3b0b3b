"""Android GnssLogger "Raw" text files (the Google Smartphone Decimeter Challenge format) as a scenario.

A GnssLogger file is comma-separated text: ``# Raw,utcTimeMillis,TimeNanos,...`` names the
fields of the ``Raw,...`` lines (one per tracked signal and epoch, the
`GnssMeasurement <https://developer.android.com/reference/android/location/GnssMeasurement>`_
and ``GnssClock`` fields of Android); ``Fix``, ``Status``, ``UncalAccel``, ``Nav`` and the other
record types may be interleaved and are ignored. :func:`read_gnsslogger` turns the Raw lines into a
:class:`~simbench.data.rinex.RinexObs` and :func:`load_gnsslogger` hands it to the pipeline of RINEX
logs (:func:`simbench.data.rinex.rinex_scenario`: broadcast ephemerides from a RINEX navigation file,
satellite states at transmit time, rough fix, observation and truth tables).

**The phone's clock**, as Google's gps-measurement-tools (``ProcessGnssMeas.m``) and gnss_lib_py
(``AndroidRawGnss``) handle it. ``TimeNanos`` is the receiver's free-running hardware clock;
``FullBiasNanos + BiasNanos`` is the phone's per-epoch estimate of hardware clock minus GPS time
(it drifts with the oscillator). The pseudorange takes the estimate of one reference epoch for
every epoch, ``t_rx = TimeNanos + TimeOffsetNanos - (FullBiasNanos_ref + BiasNanos_ref)``, so that
it keeps the hardware clock's drift since that epoch, the clock the carrier phase
(``AccumulatedDeltaRangeMeters``) is accumulated on: code and phase stay on one clock. The
reference is the first epoch of each stretch of constant ``HardwareClockDiscontinuityCount``
(Google's tools take the file's first epoch; a discontinuity restarts the clock) whose
``BiasUncertaintyNanos`` is below 40 ns (gnss_lib_py's threshold; else the stretch's first epoch
with a FullBiasNanos), ``BiasNanos`` of the same epoch as gnss_lib_py does (``ProcessGnssMeas.m``
takes each row's own, which differs by under 1 ns). ``TimeOffsetNanos`` is added, the sign of the Android API
(``ProcessGnssMeas.m`` subtracts it; phones mostly write 0).

``ReceivedSvTimeNanos`` is the satellite's time of transmission within a period that depends on
the constellation and the tracking state (``State``): a GPS, QZSS or Galileo week, a BeiDou week in
BDT (GPS - 14 s), a GLONASS day in UTC(SU) (UTC + 3 h), 100 ms for Galileo E1 with only the
secondary code locked. The transit time is ``t_rx - ReceivedSvTimeNanos`` brought into the period
(the week, day or 100 ms rollover) with the phone's own estimate of GPS time at that epoch, which is
within microseconds of the truth, then referred to the reference epoch's clock: the pseudorange is
``c ((t_est - ReceivedSvTimeNanos) mod period + (FullBiasNanos + BiasNanos) - (FullBiasNanos_ref +
BiasNanos_ref))``; for GPS this is ``ProcessGnssMeas.m``'s value, and the rollover cannot slip on a
clock that drifted by more than half a period. Integer nanoseconds are kept as int64 throughout
(a float64 of GPS nanoseconds would round to 256 ns).

Each epoch is tagged with the reference-clock receive time (the clock of its pseudoranges, as a
RINEX file of a receiver that does not steer its clock), so the transmit time the pipeline takes
(tag minus code / c) is ``ReceivedSvTimeNanos`` itself. The tag differs from GPS time by the
hardware clock's drift since the reference epoch; the truth is looked up at the tag, which moves a
moving phone's reference by its speed times that offset (``meta['phone_clock']`` gives the largest).

What is used of each measurement (thresholds from Google's ``GnssThresholds.m`` and gnss_lib_py):

* the code where ``State`` has code lock and the time of week (GLONASS: time of day) decoded or
  known, or Galileo's secondary code locked; not where the millisecond is ambiguous, where
  ``ReceivedSvTimeUncertaintyNanos`` exceeds 500 ns, the epoch's ``FullBiasNanos`` is missing or
  not negative, or the transit time falls outside 50 .. 200 ms (no GNSS satellite is that near or
  far); a row with no usable code is dropped by the pipeline (its satellite cannot be placed);
* Doppler ``-PseudorangeRateMetersPerSecond / wavelength`` (Android's rate is positive for a
  receding satellite), not where its uncertainty exceeds 10 m/s;
* the carrier phase ``AccumulatedDeltaRangeMeters`` where ``AccumulatedDeltaRangeState`` has
  ``ADR_STATE_VALID``; ``ADR_STATE_RESET`` or ``ADR_STATE_CYCLE_SLIP``, and the first epoch after a
  hardware clock discontinuity, set the loss-of-lock flag;
* C/N0 from ``Cn0DbHz``;
* the signal from ``CarrierFrequencyHz`` (the band: L1/E1/B1C 1575.42, B1I 1561.098, L5/E5a/B2a
  1176.45 MHz, ...; a missing frequency is the system's first band) and ``CodeType`` (the RINEX
  attribute letter; a missing one the band's usual phone signal): the first and second signals of
  each system are those of the RINEX reader (:func:`~simbench.data.rinex.first_signals`,
  :data:`~simbench.data.rinex.SECOND_SIGNALS`; BeiDou B1I is ``2I`` as in RINEX 3.03+), e.g. GPS
  L1 C/A with L5 and Galileo E1 with E5a on dual-frequency phones.

Systems: GPS, GLONASS (satellites by slot; rows that name only the frequency channel, ``Svid``
93-106, are left out), Galileo, BeiDou and QZSS (``Svid`` 193-202 is J01-J10); SBAS, NavIC and
unknown constellations are counted and left out.
"""

from __future__ import annotations

import dataclasses
import io
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from simbench.contract import Scenario
from simbench.core.constants import C_LIGHT, F_B1I, F_L1, F_L2, SECONDS_PER_DAY, SECONDS_PER_WEEK
from simbench.core.glonass_orbits import GLO_F1_BASE_HZ, GLO_F1_STEP_HZ
from simbench.core.gpstime import gps_to_datetime64, utc_to_gps
from simbench.data.rinex import (
    F_B3I,
    F_E5B,
    F_L5,
    GLO_F2_OVER_F1,
    SECOND_SIGNALS,
    SIGNALS,
    LogInputs,
    RinexObs,
    first_signals,
    rinex_scenario,
    second_frequency,
)
from simbench.errors import SimbenchError, warn
from simbench.gnss.navigation import SYSTEM_NAMES

__all__ = [
    "REQUIRED_FIELDS",
    "CONSTELLATIONS",
    "PhoneClock",
    "GnssLoggerObs",
    "read_gnsslogger",
    "load_gnsslogger",
]

#: Raw fields the reader cannot do without; the others are optional (missing: NaN, 0 or the default).
REQUIRED_FIELDS = (
    "TimeNanos",
    "FullBiasNanos",
    "BiasNanos",
    "Svid",
    "State",
    "ReceivedSvTimeNanos",
    "Cn0DbHz",
    "ConstellationType",
)
#: Raw fields read as exact 64-bit integers (nanoseconds since 1980 do not fit a float64's 53 bits).
_INT_FIELDS = ("TimeNanos", "FullBiasNanos", "ReceivedSvTimeNanos")
#: Android ``GnssStatus.CONSTELLATION_*`` -> RINEX system letter ('' for those the pipeline cannot use).
CONSTELLATIONS: dict[int, str] = {1: "G", 3: "R", 4: "J", 5: "C", 6: "E"}
_CONSTELLATION_NAMES = {0: "unknown", 2: "SBAS", 7: "NavIC"}

# GnssMeasurement.STATE_* and ADR_STATE_* bits (Android API).
_CODE_LOCK = 1
_TOW_DECODED = 8
_MSEC_AMBIGUOUS = 16
_GLO_TOD_DECODED = 128
_GAL_E1C_2ND_CODE_LOCK = 2048
_TOW_KNOWN = 16384
_GLO_TOD_KNOWN = 32768
_2ND_CODE_LOCK = 65536
_ADR_VALID = 1
_ADR_RESET = 2
_ADR_CYCLE_SLIP = 4

#: Google's GnssThresholds.MAXTOWUNCNS: a larger ReceivedSvTimeUncertaintyNanos gives no code [ns].
MAX_SV_TIME_UNCERTAINTY_NS = 500.0
#: Google's GnssThresholds.MAXPRRUNCMPS: a larger PseudorangeRateUncertaintyMetersPerSecond gives no Doppler [m/s].
MAX_PRR_UNCERTAINTY_MPS = 10.0
#: gnss_lib_py's BiasUncertaintyNanos threshold: a clock reference epoch should be below it [ns].
REFERENCE_BIAS_UNCERTAINTY_NS = 40.0
#: Plausible transit times of a GNSS signal (MEO ~67-90 ms, BeiDou GEO/IGSO up to ~135 ms) [s].
TRANSIT_RANGE_S = (0.05, 0.2)
_NS = 1_000_000_000
_WEEK_NS = int(SECONDS_PER_WEEK) * _NS
_DAY_NS = int(SECONDS_PER_DAY) * _NS
_GALILEO_SECONDARY_NS = 100_000_000  #: Galileo E1C / E5a-Q secondary code period [ns]
_BDT_MINUS_GPST_NS = -14 * _NS  #: BeiDou time = GPS time - 14 s
_GLONASS_UTC_OFFSET_NS = 3 * 3600 * _NS  #: UTC(SU) = UTC + 3 h

#: Carrier [Hz] -> RINEX band digit per system; a measurement's band is the nearest within 1 MHz
#: (phones write e.g. 1575420030 Hz). GLONASS FDMA bands are ranges (:func:`_bands`).
_BANDS: dict[str, dict[float, str]] = {
    "G": {F_L1: "1", F_L2: "2", F_L5: "5"},
    "J": {F_L1: "1", F_L2: "2", F_L5: "5"},
    "E": {F_L1: "1", F_L5: "5", F_E5B: "7"},
    "C": {F_B1I: "2", F_L1: "1", F_L5: "5", F_E5B: "7", F_B3I: "6"},
}
_BAND_TOLERANCE_HZ = 1.0e6
#: GLONASS G1 and G2 FDMA bands [Hz].
_GLO_BANDS = {"1": (1_597.0e6, 1_607.0e6), "2": (1_240.0e6, 1_250.0e6)}
#: The attribute of a phone's usual signal per (system, band) where CodeType is missing.
_DEFAULT_ATTRIBUTE = {
    ("G", "1"): "C",
    ("G", "2"): "X",
    ("G", "5"): "Q",
    ("J", "1"): "C",
    ("J", "2"): "X",
    ("J", "5"): "Q",
    ("E", "1"): "C",
    ("E", "5"): "Q",
    ("E", "7"): "Q",
    ("C", "2"): "I",
    ("C", "1"): "P",
    ("C", "5"): "P",
    ("C", "7"): "I",
    ("C", "6"): "I",
    ("R", "1"): "C",
    ("R", "2"): "C",
}
#: The RINEX version whose signal codes the rows follow (BeiDou B1I is band 2, ``2I``, as from 3.03).
_SIGNAL_CONVENTION = 3.04
_FIX = "pass an Android GnssLogger log (the text file with '# Raw,...' and 'Raw,...' lines)"


@dataclass(frozen=True)
class PhoneClock:
    """How the phone's clock was handled, for ``meta['phone_clock']``.

    Attributes
    ----------
    segments : int
        Stretches of constant ``HardwareClockDiscontinuityCount`` (each has its own reference epoch).
    reference_epochs : list of int
        Epoch (0-based, of the epochs kept) whose ``FullBiasNanos + BiasNanos`` each stretch's
        pseudoranges use.
    tag_minus_phone_time_max_s : float
        Largest difference between an epoch's tag (the reference-clock time) and the phone's own
        estimate of GPS time at that epoch: the hardware clock's drift since its reference [s].
    drift_ns_per_s : float
        Median of ``DriftNanosPerSecond`` (NaN when the file has none) [ns/s].
    """

    segments: int
    reference_epochs: list[int]
    tag_minus_phone_time_max_s: float
    drift_ns_per_s: float


@dataclass(frozen=True)
class GnssLoggerObs:
    """A GnssLogger log read into the RINEX reader's rows, and what was left out.

    Attributes
    ----------
    obs : RinexObs
        One row per (epoch, satellite) with the first signal and the satellite's one second signal.
    clock : PhoneClock
    refused : dict of str -> int
        Measurements of the requested systems whose code is not used, by reason.
    skipped_constellations : dict of str -> int
        Raw lines of constellations the pipeline does not take (SBAS, NavIC, unknown, or not
        requested), by name.
    raw_lines : int
        Number of Raw lines in the file.
    """

    obs: RinexObs
    clock: PhoneClock
    refused: dict[str, int]
    skipped_constellations: dict[str, int]
    raw_lines: int


def _error(path: str, problem: str, fix: str = _FIX) -> SimbenchError:
    return SimbenchError(f"scenario.obs '{path}'", problem, fix)


def _read_raw(path: str) -> pd.DataFrame:
    """The Raw lines as a table (header names of the ``# Raw,`` line) with their 1-based line numbers."""
    try:
        lines = Path(path).read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError as exc:
        raise _error(path, f"cannot be read ({exc.strerror})", "check the path and its permissions") from None
    header = next((ln for ln in lines if ln.startswith("#") and ln.lstrip("# ").startswith("Raw,")), None)
    # one Python step per line to pick the record type: the rest is pandas' C parser
    numbers = [i for i, ln in enumerate(lines, start=1) if ln.startswith("Raw,")]
    if not numbers:
        kinds = sorted({ln.split(",", 1)[0] for ln in lines if ln and not ln.startswith("#")})[:6]
        raise _error(path, f"has no Raw lines (record types in the file: {', '.join(kinds) or 'none'})")
    if header is None:
        raise _error(path, "has Raw lines but no '# Raw,...' header line naming their fields")
    names = [f.strip() for f in header.lstrip("# ").split(",")]
    missing = [f for f in REQUIRED_FIELDS if f not in names]
    if missing:
        raise _error(
            path,
            f"Raw header lacks the field(s) {', '.join(missing)}",
            "log with GnssLogger's Raw measurements enabled (its header has " + ", ".join(REQUIRED_FIELDS) + ")",
        )
    text = "\n".join(lines[i - 1] for i in numbers)
    dtypes: dict[str, Any] = {f: "Int64" for f in _INT_FIELDS} | {"CodeType": str}
    try:
        raw = pd.read_csv(io.StringIO(text), header=None, names=names, dtype=dtypes)
    except (ValueError, pd.errors.ParserError) as exc:
        raise _error(path, f"has a malformed Raw line ({str(exc).splitlines()[0][:120]})") from None
    raw["line"] = np.asarray(numbers)
    # every field but CodeType is a number: text where one belongs is a damaged line, not a missing value
    for f in names[1:]:
        if f != "CodeType" and raw[f].dtype.kind not in "iuf":
            bad = raw[f][pd.to_numeric(raw[f], errors="coerce").isna() & raw[f].notna()]
            if len(bad):
                raise _error(path, f"Raw line {raw['line'][bad.index[0]]} has a non-numeric {f} ('{bad.iloc[0]}')")
    return raw


def _column(raw: pd.DataFrame, name: str, default: float = np.nan) -> np.ndarray:
    """A float column, ``default`` where it is empty or absent."""
    if name not in raw:
        return np.full(len(raw), default)
    return np.nan_to_num(pd.to_numeric(raw[name], errors="coerce").to_numpy(float), nan=default)


def _bands(letters: np.ndarray, freq: np.ndarray) -> np.ndarray:
    """RINEX band digit of each measurement from its system and carrier [Hz]; '' when none matches."""
    out = np.full(letters.size, "", dtype="<U1")
    for system, bands in _BANDS.items():
        rows = letters == system
        for f, band in bands.items():
            out[rows & (np.abs(freq - f) < _BAND_TOLERANCE_HZ)] = band
    for band, (lo, hi) in _GLO_BANDS.items():
        out[(letters == "R") & (freq >= lo) & (freq <= hi)] = band
    missing = ~np.isfinite(freq)
    out[missing] = _per_key(letters[missing], lambda s: SIGNALS[s][0][0] if s in SIGNALS else "")
    return out


def _satellites(letters: np.ndarray, svid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """RINEX satellite ids ('G05', QZSS 193-202 -> J01-J10) and whether each is usable."""
    prn = np.where(letters == "J", svid - 192, svid)
    ok = (letters != "") & (prn >= 1) & (prn <= 63)
    ok &= (letters != "R") | (prn <= 24)  # GLONASS 93-106: frequency channel only, no slot
    ids = np.char.add(letters, np.char.zfill(np.where(ok, prn, 0).astype(str), 2))
    return np.where(ok, ids, ""), ok


def _epochs(raw: pd.DataFrame) -> np.ndarray:
    """Epoch index of each Raw line: consecutive lines of one GnssClock (TimeNanos, discontinuity count)."""
    time_nanos = raw["TimeNanos"].to_numpy("int64", na_value=np.iinfo(np.int64).min)
    disc = _column(raw, "HardwareClockDiscontinuityCount", 0.0)
    new = np.r_[True, (time_nanos[1:] != time_nanos[:-1]) | (disc[1:] != disc[:-1])]
    return np.cumsum(new) - 1


def _clock_references(bias_unc: np.ndarray, disc: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per epoch: its hardware-clock segment and the reference epoch of that segment.

    The reference of a segment is its first valid epoch with ``BiasUncertaintyNanos`` below
    :data:`REFERENCE_BIAS_UNCERTAINTY_NS` (or not reported), else its first valid epoch; 0 for a
    segment without a valid epoch (whose epochs are all dropped).
    """
    segment = np.cumsum(np.r_[True, disc[1:] != disc[:-1]]) - 1
    ref = np.zeros(segment.max() + 1, dtype=np.int64)
    # the first valid epoch of each segment, overwritten by its first good one
    for mask in (valid, valid & ~(bias_unc >= REFERENCE_BIAS_UNCERTAINTY_NS)):
        idx = np.flatnonzero(mask)
        seg, first = np.unique(segment[idx], return_index=True)
        ref[seg] = idx[first]
    return segment, ref[segment]


def _leap_seconds(t_gps_s: float) -> int:
    """GPS - UTC at GPS time ``t_gps_s`` [s], from simbench's leap-second table."""
    day = gps_to_datetime64(np.array([t_gps_s])).astype("datetime64[s]")
    return int(round(float(utc_to_gps(day)[0] - t_gps_s)))


def _transit_ns(
    letters: np.ndarray,
    state: np.ndarray,
    band: np.ndarray,
    t_est_int: np.ndarray,
    t_est_frac: np.ndarray,
    sv_time: np.ndarray,
    leap_s: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Transit time [ns] of each measurement with its rollover resolved, and whether its time is decoded.

    ``t_est`` (whole GPS nanoseconds since 1980 and a float part) is the phone's estimate of GPS time
    at the measurement; ``ReceivedSvTimeNanos`` counts in the constellation's time scale within a
    period that the tracking state gives (module docstring).
    """
    tow = (state & (_TOW_DECODED | _TOW_KNOWN)) != 0
    tod = (state & (_GLO_TOD_DECODED | _GLO_TOD_KNOWN)) != 0
    secondary = (state & (_GAL_E1C_2ND_CODE_LOCK | _2ND_CODE_LOCK)) != 0
    is_r, is_e = letters == "R", letters == "E"
    period = np.where(is_r, _DAY_NS, _WEEK_NS)
    period = np.where(is_e & ~tow & secondary, _GALILEO_SECONDARY_NS, period)
    decoded = np.where(is_r, tod, tow | (is_e & secondary & np.isin(band, ("1", "5"))))
    decoded &= ((state & _CODE_LOCK) != 0) & ((state & _MSEC_AMBIGUOUS) == 0)
    shift = np.where(letters == "C", _BDT_MINUS_GPST_NS, 0)
    shift = np.where(is_r, _GLONASS_UTC_OFFSET_NS - leap_s * _NS, shift)
    # whole nanoseconds modulo the period in int64, then the sub-nanosecond part
    whole = np.mod(t_est_int + shift - sv_time, period)
    return whole.astype(float) + t_est_frac, decoded


def _per_key(keys: np.ndarray, value: Any) -> np.ndarray:
    """``value(key)`` for each element of ``keys``, called once per distinct key."""
    distinct, inverse = np.unique(keys, return_inverse=True)
    return np.array([value(k) for k in distinct.tolist()])[inverse] if keys.size else np.array([])


def _signal_codes(raw: pd.DataFrame, letters: np.ndarray, band: np.ndarray) -> np.ndarray:
    """RINEX band + attribute of each measurement (``'1C'``), '' without a band."""
    system_band = np.char.add(letters.astype("<U1"), band)
    default = _per_key(system_band, lambda k: _DEFAULT_ATTRIBUTE.get((k[:1], k[1:]), "")).astype("<U1")
    attr = default
    if "CodeType" in raw:
        given = raw["CodeType"].fillna("").astype(str).str.strip().str[:1].to_numpy().astype("<U1")
        attr = np.where((given == "") | (given == "U"), default, given)  # 'UNKNOWN': the usual signal
    return np.where(band != "", np.char.add(band, attr), "")


def read_gnsslogger(path: str | os.PathLike[str], systems: str = "G") -> GnssLoggerObs:
    """Read the Raw measurements of an Android GnssLogger file into RINEX-reader rows.

    Parameters
    ----------
    path : str or PathLike
        GnssLogger text file (``gnss_log.txt`` of the Google Smartphone Decimeter Challenge).
    systems : str
        System letters to keep, of ``'GRECJ'``.

    Returns
    -------
    GnssLoggerObs

    Raises
    ------
    SimbenchError
        A missing or unreadable file; no Raw lines, or no ``# Raw,`` header, or a header
        without :data:`REQUIRED_FIELDS`; a malformed Raw line; no measurement of ``systems``
        (naming the constellations the file has); no usable pseudorange (naming why); epochs out
        of time order.

    Warns
    -----
    SimbenchWarning
        Measurements of ``systems`` whose code is refused (counts by reason), and systems asked
        for without rows (also in ``obs.system_notes``).
    """
    p = os.fspath(path)
    if not os.path.isfile(p):
        raise _error(p, "file does not exist", "check the path (relative paths start at the working directory)")
    unknown = sorted(set(systems) - set(SIGNALS))
    if unknown or not systems:
        raise SimbenchError(
            "scenario.systems", f"'{systems}' has no known system letters", f"use a subset of '{''.join(SIGNALS)}'"
        )
    raw = _read_raw(p)
    n_raw = len(raw)
    constellation = _column(raw, "ConstellationType", 0.0).astype(int)
    letters = np.array([CONSTELLATIONS.get(c, "") for c in constellation.tolist()])
    sat, sat_ok = _satellites(letters, _column(raw, "Svid", 0.0).astype(int))
    wanted = sat_ok & np.isin(letters, list(systems))
    skipped = _skipped(constellation, letters, sat_ok, wanted)
    if not wanted.any():
        raise _error(
            p,
            f"has no measurement of systems '{systems}' ({n_raw} Raw lines: "
            + ", ".join(f"{k} {v}" for k, v in skipped.items())
            + ")",
            "set scenario.systems to the letters of the constellations the phone tracked (GRECJ)",
        )
    raw, letters, sat = raw[wanted].reset_index(drop=True), letters[wanted], sat[wanted]
    return _measurements(p, raw, letters, sat, systems, skipped, n_raw)


def _skipped(constellation: np.ndarray, letters: np.ndarray, sat_ok: np.ndarray, wanted: np.ndarray) -> dict[str, int]:
    """Raw lines not taken, by constellation name (and GLONASS rows without a slot number)."""
    out: dict[str, int] = {}
    for c in np.unique(constellation[~wanted]).tolist():
        rows = ~wanted & (constellation == c)
        letter = CONSTELLATIONS.get(c, "")
        name = SYSTEM_NAMES[letter] if letter else _CONSTELLATION_NAMES.get(c, f"ConstellationType {c}")
        no_slot = int((rows & (letters == "R") & ~sat_ok).sum())
        if no_slot:
            out["GLONASS without slot number"] = no_slot
        if int(rows.sum()) - no_slot:
            out[name] = int(rows.sum()) - no_slot
    return out


@dataclass(frozen=True)
class _EpochClock:
    """Per epoch (consecutive Raw lines of one GnssClock): the phone's times, int64 + float nanoseconds.

    ``estimate`` is the phone's own GPS time, ``TimeNanos - (FullBiasNanos + BiasNanos)``; ``tag`` the
    receive time on the reference epoch's clock; ``shift = tag - estimate`` [ns].
    """

    estimate_int: np.ndarray
    estimate_frac: np.ndarray
    tag_int: np.ndarray
    tag_frac: np.ndarray
    shift: np.ndarray
    valid: np.ndarray  #: the epoch has a TimeNanos and a negative FullBiasNanos
    segment: np.ndarray  #: hardware clock segment (HardwareClockDiscontinuityCount stretch)
    ref: np.ndarray  #: reference epoch of the segment
    leap_s: np.ndarray  #: GPS - UTC [s]
    line: np.ndarray  #: Raw line of the epoch's first measurement


def _epoch_clock(path: str, raw: pd.DataFrame, first_row: np.ndarray) -> _EpochClock:
    """The clock of each epoch, its segment and the segment's reference (module docstring)."""
    time_nanos = raw["TimeNanos"].to_numpy("int64", na_value=0)[first_row]
    full_bias = raw["FullBiasNanos"].to_numpy("int64", na_value=0)[first_row]
    bias = _column(raw, "BiasNanos", 0.0)[first_row]
    known = (raw["TimeNanos"].notna() & raw["FullBiasNanos"].notna()).to_numpy()[first_row]
    valid = known & (full_bias < 0)
    if not valid.any():
        raise _error(path, "has no epoch with a valid FullBiasNanos (the phone never knew GPS time)")
    disc = _column(raw, "HardwareClockDiscontinuityCount", 0.0)[first_row]
    segment, ref = _clock_references(_column(raw, "BiasUncertaintyNanos")[first_row], disc, valid)
    estimate_int = time_nanos - full_bias
    table_leap = _leap_seconds(float(estimate_int[valid][0]) / _NS)
    leap = np.nan_to_num(_column(raw, "LeapSecond")[first_row], nan=table_leap).astype(np.int64)
    return _EpochClock(
        estimate_int=estimate_int,
        estimate_frac=-bias,
        tag_int=time_nanos - full_bias[ref],
        tag_frac=-bias[ref],
        shift=(full_bias - full_bias[ref]).astype(float) + (bias - bias[ref]),
        valid=valid,
        segment=segment,
        ref=ref,
        leap_s=leap,
        line=raw["line"].to_numpy()[first_row],
    )


def _pseudoranges(
    raw: pd.DataFrame, letters: np.ndarray, band: np.ndarray, clock: _EpochClock, epoch: np.ndarray
) -> tuple[np.ndarray, dict[str, int]]:
    """Pseudorange of each measurement [m] (NaN where refused) and the refused counts by reason."""
    transit, decoded = _transit_ns(
        letters,
        _column(raw, "State", 0.0).astype(np.int64),
        band,
        clock.estimate_int[epoch],
        clock.estimate_frac[epoch] + _column(raw, "TimeOffsetNanos", 0.0),
        raw["ReceivedSvTimeNanos"].to_numpy("int64", na_value=0),
        clock.leap_s[epoch],
    )
    low, high = TRANSIT_RANGE_S
    reasons = {
        "the epoch has no valid FullBiasNanos": ~clock.valid[epoch],
        "ReceivedSvTimeNanos missing": raw["ReceivedSvTimeNanos"].isna().to_numpy(),
        "no time of week / day decoded (State)": ~decoded,
        f"ReceivedSvTimeUncertaintyNanos > {MAX_SV_TIME_UNCERTAINTY_NS:.0f} ns": (
            _column(raw, "ReceivedSvTimeUncertaintyNanos") > MAX_SV_TIME_UNCERTAINTY_NS
        ),
        f"transit time outside {low * 1e3:.0f}-{high * 1e3:.0f} ms": (transit < low * _NS) | (transit > high * _NS),
    }
    # each refused measurement is counted under the first reason that applies
    refused, usable = {}, np.ones(len(raw), bool)
    for reason, hit in reasons.items():
        if n := int((hit & usable).sum()):
            refused[reason] = n
        usable &= ~hit
    # the transit time on the phone's estimate, referred to the reference epoch's clock
    return np.where(usable, (transit + clock.shift[epoch]) * (C_LIGHT / _NS), np.nan), refused


def _measurements(
    path: str,
    raw: pd.DataFrame,
    letters: np.ndarray,
    sat: np.ndarray,
    systems: str,
    skipped: dict[str, int],
    n_raw: int,
) -> GnssLoggerObs:
    """Clock handling, pseudorange, phase, Doppler and flags of the measurements of the requested systems."""
    epoch = _epochs(raw)
    first_row = np.flatnonzero(np.r_[True, epoch[1:] != epoch[:-1]])
    clock = _epoch_clock(path, raw, first_row)
    freq = _column(raw, "CarrierFrequencyHz")
    band = _bands(letters, freq)
    code_m, refused = _pseudoranges(raw, letters, band, clock, epoch)
    why = "; ".join(f"{k}: {n}" for k, n in refused.items())
    if not np.isfinite(code_m).any():
        raise _error(
            path,
            f"has no usable pseudorange of systems '{systems}' ({len(raw)} measurements: {why})",
            "log longer (until the phone decodes the time of week), or choose other scenario.systems",
        )
    adr_state = _column(raw, "AccumulatedDeltaRangeState", 0.0).astype(np.int64)
    restarted = np.r_[False, clock.segment[1:] != clock.segment[:-1]]  # after a hardware clock discontinuity
    prr = _column(raw, "PseudorangeRateMetersPerSecond")
    rows = pd.DataFrame(
        {
            "epoch": epoch,
            "sat": sat,
            "code": _signal_codes(raw, letters, band),
            "code_m": code_m,
            "adr_m": np.where((adr_state & _ADR_VALID) != 0, _column(raw, "AccumulatedDeltaRangeMeters"), np.nan),
            "prr": np.where(
                _column(raw, "PseudorangeRateUncertaintyMetersPerSecond") > MAX_PRR_UNCERTAINTY_MPS, np.nan, prr
            ),
            "cn0": _column(raw, "Cn0DbHz"),
            "lli": ((adr_state & (_ADR_RESET | _ADR_CYCLE_SLIP)) != 0) | restarted[epoch],
            "freq": freq,
        }
    )
    obs = _rinex_rows(path, rows, systems, clock)
    if refused:
        warn(
            f"scenario.obs '{path}'",
            f"{sum(refused.values())} of {len(raw)} measurements of systems '{systems}' have no usable "
            f"pseudorange ({why})",
            "their code is not used, as Google's gps-measurement-tools drops them",
        )
    kept = np.flatnonzero(clock.valid)
    drift = _column(raw, "DriftNanosPerSecond")
    summary = PhoneClock(
        segments=int(np.unique(clock.segment[kept]).size),
        reference_epochs=np.searchsorted(kept, np.unique(clock.ref[kept])).tolist(),
        tag_minus_phone_time_max_s=float(np.abs(clock.shift[kept]).max()) / _NS,
        drift_ns_per_s=float(np.nanmedian(drift)) if np.isfinite(drift).any() else np.nan,
    )
    return GnssLoggerObs(obs=obs, clock=summary, refused=refused, skipped_constellations=skipped, raw_lines=n_raw)


def _carriers(nominal: np.ndarray, letters: np.ndarray, measured: np.ndarray, ratio: float) -> np.ndarray:
    """The carrier [Hz] the pipeline converts phase cycles and Doppler back with: the band's nominal one,
    for GLONASS that of the FDMA channel of the measured carrier (``ratio``: band over G1, 1 or 7/9)."""
    out = nominal.astype(float).copy()
    is_r = letters == "R"
    k = np.round((measured[is_r] / ratio - GLO_F1_BASE_HZ) / GLO_F1_STEP_HZ)
    out[is_r] = (GLO_F1_BASE_HZ + k * GLO_F1_STEP_HZ) * ratio
    return out


def _rinex_rows(path: str, rows: pd.DataFrame, systems: str, clock: _EpochClock) -> RinexObs:
    """One row per (epoch, satellite) of the epochs with a clock: its first signal, and the satellite's
    one second signal; epochs tagged with the reference-clock receive time."""
    second_codes = {s: [c for codes, _ in SECOND_SIGNALS.get(s, ()) for c in codes] for s in SIGNALS}
    key = np.char.add(rows["sat"].str[0].to_numpy().astype("<U1"), rows["code"].to_numpy().astype("<U2"))
    rows = rows.assign(
        rank1=_per_key(key, lambda k: _rank(k[1:], first_signals(k[:1], _SIGNAL_CONVENTION))),
        rank2=_per_key(key, lambda k: _rank(k[1:], second_codes[k[:1]])),
    )
    rows = rows[clock.valid[rows["epoch"].to_numpy()]]
    # per (epoch, satellite) the preferred first signal that has a pseudorange
    one = rows[rows["rank1"] >= 0].assign(no_code=rows["code_m"].isna())
    one = one.sort_values(["epoch", "sat", "no_code", "rank1"], kind="stable").drop_duplicates(["epoch", "sat"])
    one = one.reset_index(drop=True)
    notes = [_system_note(s, rows, one) for s in dict.fromkeys(systems)]
    notes = [n for n in notes if n]
    if one.empty or not np.isfinite(one["code_m"].to_numpy()).any():
        raise _error(
            path,
            "has no usable pseudorange of systems '" + systems + "'" + (": " + "; ".join(notes) if notes else ""),
            "log longer (until the phone decodes the time of week), or choose other scenario.systems",
        )
    two = _second_signal(rows[rows["rank2"] >= 0])
    both = one.merge(two, on=["epoch", "sat"], how="left", suffixes=("", "_2"))
    used_epochs, row_epoch = np.unique(both["epoch"].to_numpy(), return_inverse=True)
    tag_int, tag_frac = clock.tag_int[used_epochs], clock.tag_frac[used_epochs]
    t_int = np.floor_divide(tag_int, _NS)
    t_frac = (np.mod(tag_int, _NS) + tag_frac) / _NS
    carry = np.floor(t_frac)
    t_int, t_frac = t_int + carry.astype(np.int64), t_frac - carry
    d = np.diff(t_int) + np.diff(t_frac)
    if (d <= 0).any():
        at = clock.line[used_epochs[np.flatnonzero(d <= 0)[0] + 1]]
        raise _error(path, f"the epoch at Raw line {at} is not later than the epoch before it", "sort the log by time")
    b_letters = both["sat"].str[0].to_numpy()
    f1 = _carriers(
        pd.Series(b_letters).map(lambda s: SIGNALS[s][1]).to_numpy(), b_letters, both["freq"].to_numpy(), 1.0
    )
    f2 = _carriers(both["f_nominal"].to_numpy(float), b_letters, both["freq_2"].to_numpy(float), GLO_F2_OVER_F1)
    # the first signal per system with code values (a system without any is in the notes)
    coded = one[one["code_m"].notna()]
    signals = coded.groupby(coded["sat"].str[0])["code"].agg(lambda c: c.mode().iloc[0]).to_dict()
    codes = rows.groupby(rows["sat"].str[0])["code"].unique()
    header = {s: sorted(o + c for c in codes[s] if c for o in "CLDS") for s in signals}
    return RinexObs(
        epoch_t_int=t_int.astype(np.int64),
        epoch_t_frac=t_frac,
        row_epoch=row_epoch,
        sat=both["sat"].to_numpy().astype(str),
        code=both["code_m"].to_numpy(float),
        phase_cycles=both["adr_m"].to_numpy(float) * f1 / C_LIGHT,
        doppler_hz=-both["prr"].to_numpy(float) * f1 / C_LIGHT,
        cn0_dbhz=both["cn0"].to_numpy(float),
        lli=both["lli"].to_numpy(bool),
        approx_position=np.zeros(3),
        interval_s=float(np.median(d)) if d.size else 1.0,
        path=path,
        code_l2=both["code_m_2"].to_numpy(float),
        phase_l2_cycles=both["adr_m_2"].to_numpy(float) * f2 / C_LIGHT,
        lli_l2=both["lli_2"].fillna(False).to_numpy(bool),
        signal_l2=both["code_2"].fillna("").to_numpy().astype("<U2"),
        signals={s: signals[s] for s in dict.fromkeys(systems) if s in signals},
        version=_SIGNAL_CONVENTION,
        header_codes=header,
        system_notes=notes,
    )


def _rank(code: str, preferred: tuple[str, ...] | list[str]) -> int:
    return preferred.index(code) if code in preferred else -1


def _second_signal(rows: pd.DataFrame) -> pd.DataFrame:
    """Each satellite's one second signal over the whole log (the RINEX reader's rule: the candidate with
    the most code values, ties to the preferred one), as columns ``*_2`` per (epoch, satellite)."""
    if rows.empty:
        kinds = {"epoch": "int64", "sat": object, "code_2": object, "lli_2": bool}
        cols = ["epoch", "sat", "code_2", "code_m_2", "adr_m_2", "lli_2", "freq_2", "f_nominal"]
        return pd.DataFrame({c: pd.Series(dtype=kinds.get(c, float)) for c in cols})
    counts = rows.groupby(["sat", "code"], sort=False).agg(n=("code_m", "count"), rank=("rank2", "first"))
    counts = counts.reset_index().sort_values(["sat", "n", "rank"], ascending=[True, False, True], kind="stable")
    chosen = counts.drop_duplicates("sat")
    chosen = chosen[chosen["n"] > 0]
    picked = rows.merge(chosen[["sat", "code"]], on=["sat", "code"])
    picked = picked.sort_values(["epoch", "sat"], kind="stable").drop_duplicates(["epoch", "sat"])
    key = np.char.add(picked["sat"].str[0].to_numpy().astype("<U1"), picked["code"].to_numpy().astype("<U2"))
    return pd.DataFrame(
        {
            "epoch": picked["epoch"].to_numpy(),
            "sat": picked["sat"].to_numpy(),
            "code_2": picked["code"].to_numpy(),
            "code_m_2": picked["code_m"].to_numpy(float),
            "adr_m_2": picked["adr_m"].to_numpy(float),
            "lli_2": picked["lli"].to_numpy(bool),
            "freq_2": picked["freq"].to_numpy(float),
            "f_nominal": _per_key(key, lambda k: second_frequency(k[:1], k[1:])),
        }
    )


def _system_note(system: str, rows: pd.DataFrame, one: pd.DataFrame) -> str:
    """Why ``system`` gives no rows ('' when it gives some with code)."""
    name = SYSTEM_NAMES[system]
    mine = rows["sat"].str[0] == system
    if not mine.any():
        return f"no {name} measurements in the file"
    firsts = one[one["sat"].str[0] == system]
    if firsts.empty:
        have = " ".join(sorted(set(rows.loc[mine, "code"]) - {""})) or "none"
        wanted = " or ".join(first_signals(system, _SIGNAL_CONVENTION))
        return f"no {name} measurement of {wanted} (signals in the file: {have})"
    if not np.isfinite(firsts["code_m"].to_numpy()).any():
        return f"no {name} measurement with a usable pseudorange"
    return ""


def load_gnsslogger(obs_path: str | os.PathLike[str], inputs: LogInputs) -> Scenario:
    """Ingest an Android GnssLogger file, RINEX navigation files and a reference trajectory or point.

    Parameters
    ----------
    obs_path : str or PathLike
        GnssLogger text file (:func:`read_gnsslogger`).
    inputs : LogInputs
        Navigation files, reference, systems and name as for :func:`simbench.data.rinex.load_rinex`: the
        phone's log carries no ephemerides, so the broadcast orbits come from RINEX navigation files of the
        day, as for a RINEX log.

    Returns
    -------
    Scenario
        As :func:`~simbench.data.rinex.load_rinex`'s, with ``meta['source'] = 'gnsslogger'``,
        ``meta['phone_clock']`` (:class:`PhoneClock`), ``meta['refused_measurements']`` and
        ``meta['skipped_constellations']``; no RINEX files for external tools (``rinex=None``).

    Raises
    ------
    SimbenchError
        The errors of :func:`read_gnsslogger` and of the RINEX pipeline (navigation files that do
        not cover the log, a reference far from the log's own fixes).
    """
    read = read_gnsslogger(obs_path, inputs.systems)
    scenario = rinex_scenario(read.obs, inputs)
    meta = {k: v for k, v in scenario.meta.items() if k != "rinex_version"}
    meta |= {
        "source": "gnsslogger",
        "raw_lines": read.raw_lines,
        "phone_clock": dataclasses.asdict(read.clock),
        "refused_measurements": read.refused,
        "skipped_constellations": read.skipped_constellations,
        "corrections": meta["corrections"] + "; pseudorange from TimeNanos, the reference epoch's FullBiasNanos + "
        "BiasNanos, TimeOffsetNanos and ReceivedSvTimeNanos (simbench.data.gnsslogger)",
    }
    return dataclasses.replace(scenario, meta=meta, rinex=None)

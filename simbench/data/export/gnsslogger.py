"""A receiver's view as an Android GnssLogger "Raw" log (:func:`write_gnsslogger`), with a phone's clock.

The file has GnssLogger's header (the ``# Raw,...`` field list of gps-measurement-tools'
LOGGING_FORMAT.md and the other record types' lines) and one ``Raw`` line per signal and epoch: the
first signal (``code_l1`` ...) and, where the row has one, the second (``code_l2``, carrier
``f_L1 / f1_f2_ratio``). :mod:`simbench.data.gnsslogger` reads it back.

**The phone's clock** (:class:`PhoneClockModel`). A phone counts receive time on a free-running
hardware clock (``TimeNanos``) and reports its own estimate of hardware minus GPS time per epoch
(``FullBiasNanos + BiasNanos``). The writer invents both: at true GPS time ``T`` (the scenario's
epoch tag, as the RINEX export) the hardware clock reads ``boot + (T - T0) + w(T - T0)`` nanoseconds,
``w`` a drift and a drift rate; the phone's estimate is off the truth by a slow wobble ``e``, so
``FullBiasNanos + BiasNanos = TimeNanos - T + e`` drifts from epoch to epoch as on a real phone.
The simulated observables carry the simulated receiver clock ``dt_r``; the phone adds its hardware
clock on top, so that a reader taking the first epoch's ``FullBiasNanos + BiasNanos`` as Google's
tools do gets

    code = code_l1 + K,   phase = phase_l1 + K,   K = c ((TimeNanos - FullBiasNanos_0 - BiasNanos_0) - T)

(``K = c (w - w0 - e0)``, the reference clock's offset from GPS time: known from the file), Doppler
minus ``c dw/dt / wavelength``, and the receive times ``T + w - w0``. ``ReceivedSvTimeNanos`` is the
whole nanoseconds of ``t_rx - code / c`` within the constellation's week (GPS time; BeiDou's BDT is
14 s behind) and ``TimeOffsetNanos`` (the API's
per-measurement sub-nanosecond offset) keeps the fraction, so the code comes back to well under a
millimetre. As in the RINEX export, the transmit time this implies holds ``dt_r`` (the truth the
receiver view lacks), which places a satellite ``v dt_r`` off (centimetres, module docstring of
:mod:`simbench.data.export.rinex`).

Also written: ``State`` 16431 (code lock, bit and subframe sync, time of week decoded and known) on
rows with code, 1 (code lock only) without; ``AccumulatedDeltaRangeState`` ``ADR_STATE_VALID`` with a
phase, plus ``ADR_STATE_CYCLE_SLIP`` where ``lli`` is set; uncertainties from C/N0;
``ConstellationType`` and ``Svid`` of G, E, C and J (QZSS PRN + 192); ``CodeType`` the RINEX attribute
of the signal (GPS L2 ``W`` as the RINEX export). GLONASS rows are refused (the table has no
frequency channel).
"""

from __future__ import annotations

import datetime as dt
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from simbench.contract import ReceiverData
from simbench.core.constants import C_LIGHT, SECONDS_PER_WEEK
from simbench.core.gpstime import gps_to_datetime64, utc_to_gps
from simbench.data.rinex import SIGNALS, second_frequency
from simbench.errors import SimbenchError

__all__ = ["RAW_FIELDS", "PhoneClockModel", "write_gnsslogger", "gps_nanoseconds"]

#: Fields of a GnssLogger v3 Raw line (gps-measurement-tools LOGGING_FORMAT.md), in file order.
RAW_FIELDS = (
    "utcTimeMillis,TimeNanos,LeapSecond,TimeUncertaintyNanos,FullBiasNanos,BiasNanos,BiasUncertaintyNanos,"
    "DriftNanosPerSecond,DriftUncertaintyNanosPerSecond,HardwareClockDiscontinuityCount,Svid,TimeOffsetNanos,"
    "State,ReceivedSvTimeNanos,ReceivedSvTimeUncertaintyNanos,Cn0DbHz,PseudorangeRateMetersPerSecond,"
    "PseudorangeRateUncertaintyMetersPerSecond,AccumulatedDeltaRangeState,AccumulatedDeltaRangeMeters,"
    "AccumulatedDeltaRangeUncertaintyMeters,CarrierFrequencyHz,CarrierCycles,CarrierPhase,CarrierPhaseUncertainty,"
    "MultipathIndicator,SnrInDb,ConstellationType,AgcDb,BasebandCn0DbHz,FullInterSignalBiasNanos,"
    "FullInterSignalBiasUncertaintyNanos,SatelliteInterSignalBiasNanos,SatelliteInterSignalBiasUncertaintyNanos,"
    "CodeType,ChipsetElapsedRealtimeNanos"
).split(",")
#: The header lines of the other record types GnssLogger declares (they carry no data here).
_OTHER_RECORDS = (
    "UncalAccel,utcTimeMillis,elapsedRealtimeNanos,UncalAccelXMps2,UncalAccelYMps2,UncalAccelZMps2,"
    "BiasXMps2,BiasYMps2,BiasZMps2",
    "Fix,Provider,LatitudeDegrees,LongitudeDegrees,AltitudeMeters,SpeedMps,AccuracyMeters,BearingDegrees,"
    "UnixTimeMillis,SpeedAccuracyMps,BearingAccuracyDegrees,elapsedRealtimeNanos,VerticalAccuracyMeters,MockLocation",
    "Status,UnixTimeMillis,SignalCount,SignalIndex,ConstellationType,Svid,CarrierFrequencyHz,Cn0DbHz,"
    "AzimuthDegrees,ElevationDegrees,UsedInFix,HasAlmanacData,HasEphemerisData,BasebandCn0DbHz",
)
_CONSTELLATION = {"G": 1, "J": 4, "C": 5, "E": 6}
#: CodeType of each system's second signal by RINEX band (the first signal's is in SIGNALS).
_SECOND_CODE_TYPE = {("G", "2"): "W", ("G", "5"): "Q", ("J", "2"): "L", ("J", "5"): "Q", ("E", "5"): "Q"}
_SECOND_CODE_TYPE |= {("E", "7"): "Q", ("C", "6"): "I", ("C", "7"): "I"}
_STATE_TRACKED = 16431  #: CODE_LOCK | BIT_SYNC | SUBFRAME_SYNC | TOW_DECODED | SYMBOL_SYNC | TOW_KNOWN
_STATE_CODE_LOCK = 1
_ADR_VALID, _ADR_CYCLE_SLIP = 1, 4
_NS = 1_000_000_000
_WEEK_NS = int(SECONDS_PER_WEEK) * _NS
_BDT_MINUS_GPST_NS = -14 * _NS  #: BeiDou time = GPS time - 14 s
_GPS_MINUS_UNIX_S = 315_964_800  #: 1980-01-06 in Unix seconds


@dataclass(frozen=True)
class PhoneClockModel:
    """The clock of the phone the writer pretends to be (values of a TCXO in a phone).

    Attributes
    ----------
    boot_ns : int
        ``TimeNanos`` at the first epoch: the hardware counter since boot [ns].
    drift_ns_per_s : float
        Frequency offset of the hardware clock [ns/s] (-275 ns/s: 82 m/s of range).
    drift_rate_ns_per_s2 : float
        Its change, e.g. the oscillator warming up [ns/s^2].
    estimate_error_ns : float
        Amplitude of the error of the phone's GPS-time estimate (``FullBiasNanos + BiasNanos``) [ns].
    estimate_period_s : float
        Period of that error [s].
    discontinuity_count : int
        ``HardwareClockDiscontinuityCount`` (constant: the clock never restarts).
    """

    boot_ns: int = 32_083_712_000_000
    drift_ns_per_s: float = -275.0
    drift_rate_ns_per_s2: float = 0.05
    estimate_error_ns: float = 12.0
    estimate_period_s: float = 47.0
    discontinuity_count: int = 7

    def wander_ns(self, tau: np.ndarray) -> np.ndarray:
        """Hardware clock error since the first epoch at ``tau`` seconds after it [ns]."""
        return self.drift_ns_per_s * tau + 0.5 * self.drift_rate_ns_per_s2 * tau**2

    def drift(self, tau: np.ndarray) -> np.ndarray:
        """Hardware clock drift [ns/s]."""
        return self.drift_ns_per_s + self.drift_rate_ns_per_s2 * tau

    def estimate_error(self, tau: np.ndarray) -> np.ndarray:
        """Phone's estimate of hardware minus GPS time, minus the truth [ns]."""
        return self.estimate_error_ns * np.sin(2.0 * np.pi * tau / self.estimate_period_s + 0.7)


def gps_nanoseconds(t0_gps: float, t: np.ndarray) -> np.ndarray:
    """Whole GPS nanoseconds since 1980 of scenario times ``t`` [s] after ``t0_gps`` [s], as int64 (rounded).

    Split into whole seconds first: a float64 of nanoseconds since 1980 would round to 256 ns.
    """
    whole = np.floor(t0_gps)
    sec = np.floor(t)
    frac_ns = np.round(((t0_gps - whole) + (t - sec)) * _NS).astype(np.int64)
    return (int(whole) + sec.astype(np.int64)) * _NS + frac_ns


def _leap_seconds(t_gps: float) -> int:
    day = gps_to_datetime64(np.array([t_gps])).astype("datetime64[s]")
    return int(round(float(utc_to_gps(day)[0] - t_gps)))


def _signal_rows(data: ReceiverData) -> pd.DataFrame:
    """One row per (epoch, satellite, signal): code, phase, Doppler, C/N0, loss of lock, carrier, CodeType."""
    obs = data.observations.sort_values(["epoch", "sat"], kind="stable")
    if obs.empty:
        raise SimbenchError("export", "the scenario has no observations", "export a scenario with observations")
    letters = obs["sat"].str[0].to_numpy()
    bad = sorted(set(letters.tolist()) - set(_CONSTELLATION))
    if bad:
        raise SimbenchError(
            "export",
            f"systems {bad} cannot be written as GnssLogger Raw lines (GLONASS needs the frequency channel, "
            "which the observation table lacks)",
            f"export a scenario of systems {''.join(_CONSTELLATION)} (scenario.systems)",
        )
    f1 = np.array([SIGNALS[s][1] for s in letters.tolist()])
    first = pd.DataFrame(
        {
            "epoch": obs["epoch"].to_numpy(),
            "t": obs["t"].to_numpy(float),
            "sat": obs["sat"].to_numpy(),
            "code": obs["code_l1"].to_numpy(float),
            "phase": obs["phase_l1"].to_numpy(float),
            "doppler": obs["doppler_l1"].to_numpy(float),
            "cn0": obs["cn0_l1"].to_numpy(float),
            "lli": obs["lli_l1"].to_numpy(bool),
            "freq": f1,
            "code_type": [SIGNALS[s][0][1] for s in letters.tolist()],
        }
    )
    f2 = f1 / obs["f1_f2_ratio"].to_numpy(float)
    band2 = np.array([_band(s, f) for s, f in zip(letters.tolist(), f2.tolist())])
    has2 = np.isfinite(obs["code_l2"].to_numpy(float)) & (band2 != "")
    second = first[has2].assign(
        code=obs["code_l2"].to_numpy(float)[has2],
        phase=obs["phase_l2"].to_numpy(float)[has2],
        doppler=np.nan,  # the table has no second-frequency Doppler or C/N0
        cn0=first["cn0"].to_numpy()[has2],
        lli=obs["lli_l2"].to_numpy(bool)[has2],
        freq=f2[has2],
        code_type=[_SECOND_CODE_TYPE[(s, b)] for s, b in zip(letters[has2].tolist(), band2[has2].tolist())],
    )
    return pd.concat([first, second], ignore_index=True).sort_values(["epoch", "sat", "freq"], ascending=[1, 1, 0])


def _band(system: str, freq: float) -> str:
    """RINEX band digit of a second carrier [Hz] the reader takes, '' for another."""
    for (s, band), attr in _SECOND_CODE_TYPE.items():
        if s == system and abs(second_frequency(s, band + attr) - freq) < 1e3:
            return band
    return ""


def write_gnsslogger(path: str | os.PathLike[str], data: ReceiverData, clock: PhoneClockModel | None = None) -> Path:
    """Write the observation table of ``data`` as a GnssLogger Raw log with a phone's clock (module docstring).

    Parameters
    ----------
    path : str or PathLike
        Output file (``.txt``, as GnssLogger names its logs).
    data : ReceiverData
        The receiver's view (no truth is read).
    clock : PhoneClockModel, optional
        The phone's clock; default :class:`PhoneClockModel()`.

    Returns
    -------
    Path
        The GnssLogger log written (``path``).

    Raises
    ------
    SimbenchError
        An empty table or GLONASS rows.
    """
    clock = clock or PhoneClockModel()
    rows = _signal_rows(data)
    t0_gps = data.nav.gps_week * SECONDS_PER_WEEK + data.nav.start_sow_s
    t = rows["t"].to_numpy(float)
    tau = t - t.min()
    true_ns = gps_nanoseconds(t0_gps, t)
    time_nanos = clock.boot_ns + (true_ns - true_ns.min()) + np.round(clock.wander_ns(tau)).astype(np.int64)
    # the phone's estimate of hardware minus GPS time: whole nanoseconds and the sub-nanosecond BiasNanos
    estimate = clock.estimate_error(tau)
    full_bias = time_nanos - true_ns + np.floor(estimate).astype(np.int64)
    bias = estimate - np.floor(estimate)
    ref = int(np.argmin(t))
    # the reader's receive time on the first epoch's clock: whole ns since 1980 and a float part
    rx_int, rx_frac = time_nanos - full_bias[ref], -bias[ref]
    clock_m = ((rx_int - true_ns).astype(float) + rx_frac) * (C_LIGHT / _NS)
    code = rows["code"].to_numpy(float) + clock_m
    y = rx_frac - code / C_LIGHT * _NS  # receive minus transit time, float part [ns]
    whole = np.round(np.nan_to_num(y)).astype(np.int64)
    letters = rows["sat"].str[0].to_numpy()
    # the transmit time in the constellation's own week: BeiDou counts BDT = GPS time - 14 s
    sv_time = np.mod(rx_int + whole + np.where(letters == "C", _BDT_MINUS_GPST_NS, 0), _WEEK_NS)
    has_code = np.isfinite(code)
    lam = C_LIGHT / rows["freq"].to_numpy(float)
    phase = rows["phase"].to_numpy(float) + clock_m
    lli = rows["lli"].to_numpy(bool)
    cn0 = rows["cn0"].to_numpy(float)
    weak = 10.0 ** ((35.0 - np.nan_to_num(cn0, nan=35.0)) / 20.0)  # noise amplitude relative to 35 dB-Hz
    prn = rows["sat"].str[1:].astype(int).to_numpy()
    leap = _leap_seconds(t0_gps + float(t.min()))
    table = {
        "utcTimeMillis": (true_ns // 1_000_000 + (_GPS_MINUS_UNIX_S - leap) * 1000).astype(np.int64),
        "TimeNanos": time_nanos,
        "LeapSecond": np.full(t.size, leap),
        "FullBiasNanos": full_bias,
        "BiasNanos": bias,
        "BiasUncertaintyNanos": np.full(t.size, 15.0),
        "DriftNanosPerSecond": clock.drift(tau),
        "DriftUncertaintyNanosPerSecond": np.full(t.size, 1.0),
        "HardwareClockDiscontinuityCount": np.full(t.size, clock.discontinuity_count),
        "Svid": np.where(letters == "J", prn + 192, prn),
        "TimeOffsetNanos": np.where(has_code, whole - y, 0.0),  # the sub-nanosecond part of the code
        "State": np.where(has_code, _STATE_TRACKED, _STATE_CODE_LOCK),
        "ReceivedSvTimeNanos": np.where(has_code, sv_time, 0),
        "ReceivedSvTimeUncertaintyNanos": np.round(np.where(has_code, 10.0 * weak, 1e6)),
        "Cn0DbHz": cn0,
        "PseudorangeRateMetersPerSecond": -rows["doppler"].to_numpy(float) * lam + clock.drift(tau) * C_LIGHT / _NS,
        "PseudorangeRateUncertaintyMetersPerSecond": 0.05 * weak,
        "AccumulatedDeltaRangeState": np.where(np.isfinite(phase), _ADR_VALID, 0) + np.where(lli, _ADR_CYCLE_SLIP, 0),
        "AccumulatedDeltaRangeMeters": np.nan_to_num(phase),
        "AccumulatedDeltaRangeUncertaintyMeters": np.where(np.isfinite(phase), 0.003 * weak, 0.0),
        "CarrierFrequencyHz": rows["freq"].to_numpy(float),
        "MultipathIndicator": np.zeros(t.size, np.int64),
        "ConstellationType": np.array([_CONSTELLATION[s] for s in letters.tolist()]),
        "CodeType": rows["code_type"].to_numpy(),
    }
    frame = pd.DataFrame({f: table.get(f, np.full(t.size, np.nan)) for f in RAW_FIELDS})
    frame.insert(0, "record", "Raw")
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(_header() + frame.to_csv(header=False, index=False, na_rep="", lineterminator="\n"))
    return out


def _header() -> str:
    stamp = f"{dt.datetime.now(dt.timezone.utc):%Y-%m-%d %H:%M:%S} UTC"
    lines = [
        "# ",
        "# Header Description:",
        "# ",
        f"# Version: simbench.data.export.gnsslogger ({stamp}) Platform: simulated Manufacturer: simbench "
        "Model: phone clock of simbench.data.export.gnsslogger.PhoneClockModel",
        "# ",
        "# Raw," + ",".join(RAW_FIELDS),
        "# ",
        *(f"# {record}\n# " for record in _OTHER_RECORDS),
    ]
    return "\n".join(lines) + "\n"

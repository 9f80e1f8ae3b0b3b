"""Sim-vs-real statistics: how much a simulated world looks like a real log.

One procedure for every scenario with a reference trajectory (simulated truth or
a real log's reference): the per-observation code residual ::

    raw_j = code_j + sat_clock_j - sagnac_range(sat_j, reference)
            - ZHD m_h(el_j) - ZWD0 m_w(el_j) - Klobuchar_j
    residual_j = raw_j - median over the epoch's satellites of the same system

with the corrections of the estimators' measurement model
(:mod:`estimators.model.measurement`): the product satellite clock (TGD in it), the
Sagnac range (:func:`simbench.gnss.geometry.sagnac_range`), the Saastamoinen
hydrostatic delay with the Niell mapping (:func:`simbench.gnss.troposphere.troposphere_terms`),
the broadcast Klobuchar delay unless the log is already corrected. Where the
estimators estimate the zenith wet delay, a fixed a priori value (Saastamoinen
in the standard atmosphere, ``ZWD0``) is removed; what is left of it is common
to an epoch's satellites up to the mapping and goes into the per-epoch clock.
Elevation, azimuth and the pierce point are evaluated at the reference
position, not at the receiver's rough fix. The per-epoch, per-system median is
a robust receiver clock: NLOS and multipath outliers do not move it the way a
least-squares clock would, so the residual shows each observation's own error.

On these rows :func:`world_statistics` gives the typed statistics (tracked
satellites per epoch, residual percentiles and tail shares, C/N0 percentiles,
phase availability, arc lengths, LLI rate), :func:`cn0_by_elevation` the C/N0
against elevation, and :func:`comparison_table` several worlds side by side with
the two-sample Kolmogorov-Smirnov distances (:func:`scipy.stats.ks_2samp`) of
the absolute residual and the C/N0 distributions against a reference world.
Figures are drawn by :mod:`simbench.report.figures`; ``python -m simbench validate``
is the command line.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, fields

import numpy as np
import pandas as pd
from scipy.stats import ks_2samp

from simbench.contract import Scenario
from simbench.core import atmosphere
from simbench.core.frames import geodetic_from_ecef
from simbench.core.gpstime import day_of_year
from simbench.errors import SimbenchError
from simbench.gnss.arcs import arc_ids
from simbench.gnss.geometry import elevation_azimuth, sagnac_range
from simbench.gnss.troposphere import troposphere_terms

__all__ = [
    "MIN_ROWS_PER_CLOCK",
    "RESIDUAL_COLUMNS",
    "TAIL_THRESHOLDS_M",
    "ValidationSample",
    "WorldStatistics",
    "cn0_by_elevation",
    "comparison_table",
    "ks_distances",
    "residual_sample",
    "world_label",
    "world_statistics",
]

#: Columns of :attr:`ValidationSample.rows`, one row per observation at an epoch with a reference.
RESIDUAL_COLUMNS: dict[str, str] = {
    "epoch": "int, GNSS epoch index",
    "t": "s, receive time since scenario start",
    "sat": "str, satellite id",
    "system": "str, RINEX system letter (G, R, E, C)",
    "el": "deg, elevation seen from the reference position",
    "cn0": "dB-Hz, L1 C/N0 (NaN when the log has none)",
    "has_phase": "bool, a finite L1 carrier phase",
    "lli": "bool, L1 loss-of-lock flag on a row with phase",
    "arc": "int, continuous phase arc id (gaps and LLI break it); -1 without phase",
    "raw": "m, code minus the modelled range, delays and satellite clock (receiver clock still in it)",
    "clock": "m, median of raw over the epoch's rows of the same system (robust receiver clock)",
    "residual": "m, raw minus clock; NaN where the epoch has fewer than min_rows_per_clock rows of the system",
}

#: Default of :func:`residual_sample`'s ``min_rows_per_clock``: the fewest rows of a system at an epoch
#: whose median ignores one outlier.
MIN_ROWS_PER_CLOCK = 3

#: The tail shares of :class:`WorldStatistics`: |residual| above these [m].
TAIL_THRESHOLDS_M = (10.0, 30.0)


@dataclass(frozen=True)
class ValidationSample:
    """The residual rows of one world and what is needed to summarise them.

    Attributes
    ----------
    name : str
        How tables and figures label the world.
    rows : pandas.DataFrame
        :data:`RESIDUAL_COLUMNS`, rows at epochs with a reference.
    reference_epochs : numpy.ndarray of int
        Epoch indices with a reference position (tracked satellites are counted
        over these, an epoch without observations counting 0).
    interval_s : float
        Epoch interval [s] (arc lengths).
    real : bool
        A real log (no error labels) rather than a simulation.
    """

    name: str
    rows: pd.DataFrame
    reference_epochs: np.ndarray
    interval_s: float
    real: bool

    @property
    def abs_residual(self) -> np.ndarray:
        """|residual| of the rows that have one [m]."""
        r = self.rows["residual"].to_numpy(float)
        return np.abs(r[np.isfinite(r)])

    @property
    def tracked_per_epoch(self) -> np.ndarray:
        """Observations (tracked satellites) at each reference epoch, 0 where there are none."""
        return self.rows.groupby("epoch").size().reindex(self.reference_epochs, fill_value=0).to_numpy(np.int64)

    @property
    def cn0(self) -> np.ndarray:
        """C/N0 of the rows that report one [dB-Hz]."""
        c = self.rows["cn0"].to_numpy(float)
        return c[np.isfinite(c)]


@dataclass(frozen=True)
class WorldStatistics:
    """Summary statistics of one world (:func:`world_statistics`); NaN where undefined.

    Calibration tests compare these fields with tolerances (e.g. an ``urban_deep``
    preset against the Hong Kong log).
    """

    name: str
    real: bool
    n_epochs: int  #: epochs with a reference
    n_rows: int  #: observations at those epochs
    n_residuals: int  #: rows with a residual
    sats_median: float  #: tracked satellites per reference epoch, median
    sats_mean: float  #: tracked satellites per reference epoch, mean
    residual_p50_m: float  #: |code residual| median [m]
    residual_p90_m: float  #: |code residual| 90th percentile [m]
    residual_p99_m: float  #: |code residual| 99th percentile [m]
    share_over_10m: float  #: share of |residual| > 10 m
    share_over_30m: float  #: share of |residual| > 30 m
    cn0_p10: float  #: C/N0 10th percentile [dB-Hz]
    cn0_p50: float  #: C/N0 median [dB-Hz]
    cn0_p90: float  #: C/N0 90th percentile [dB-Hz]
    phase_availability: float  #: share of rows with a carrier phase
    arc_median_s: float  #: median length of the continuous phase arcs [s]
    arc_mean_s: float  #: mean length of the continuous phase arcs [s]
    lli_rate: float  #: share of the rows with phase that carry a loss-of-lock flag

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


def world_label(scenario: Scenario) -> str:
    """How tables and figures name a world: ``hk_tst_2019 (real, G)``, ``urban low seed 0``."""
    meta = scenario.meta
    name = str(meta.get("name", "scenario"))
    if scenario.labels is None:
        return f"{name} (real, {meta['systems']})" if meta.get("systems") else f"{name} (real)"
    config = meta.get("config") or {}
    receiver = (config.get("receiver") or {}).get("name", "")
    return " ".join(str(p) for p in (name, receiver, f"seed {meta.get('seed', config.get('seed', ''))}") if p)


def residual_sample(
    scenario: Scenario,
    *,
    name: str | None = None,
    elevation_mask_deg: float = 0.0,
    min_rows_per_clock: int = MIN_ROWS_PER_CLOCK,
) -> ValidationSample:
    """Code residuals of every observation at an epoch with a reference position.

    Parameters
    ----------
    scenario : Scenario
        Simulated or real; ``truth`` gives the reference (rows with finite
        ``x, y, z``).
    name : str, optional
        Label of the world (default :func:`world_label`).
    elevation_mask_deg : float
        Rows at or below this elevation (seen from the reference) are left out [deg].
    min_rows_per_clock : int
        An epoch's rows of one system get a residual only when the system has at
        least this many rows there. A lone satellite's residual would be 0 by
        construction, and with two the median is the mean, which splits one
        satellite's error over both; three is the fewest where the median
        ignores one outlier.

    Returns
    -------
    ValidationSample

    Raises
    ------
    SimbenchError
        When the scenario has no epoch with a reference position, or
        ``min_rows_per_clock`` is below 1.
    """
    if min_rows_per_clock < 1:
        raise SimbenchError(
            "min_rows_per_clock",
            f"must be at least 1, got {min_rows_per_clock}",
            "give the smallest number of satellites per epoch and system for a clock",
        )
    label = name or world_label(scenario)
    truth = scenario.truth
    ref_ok = np.isfinite(truth[["x", "y", "z"]].to_numpy(float)).all(axis=1) if len(truth) else np.zeros(0, bool)
    if not ref_ok.any():
        raise SimbenchError(
            f"scenario {label}",
            "has no epoch with a reference position",
            "give the log's reference trajectory (scenario.truth)",
        )
    ref = truth.loc[ref_ok, ["epoch", "x", "y", "z"]]
    obs = scenario.observations
    used = ["epoch", "t", "sat", "code_l1", "phase_l1", "lli_l1", "cn0_l1", "sat_x", "sat_y", "sat_z", "sat_clock"]
    rows = obs.reindex(columns=used).merge(ref, on="epoch", how="inner")
    rx = rows[["x", "y", "z"]].to_numpy(float)
    sat_pos = rows[["sat_x", "sat_y", "sat_z"]].to_numpy(float)
    el, az = (a[:, 0] for a in elevation_azimuth(rx, sat_pos[:, None, :]))
    keep = el > np.deg2rad(elevation_mask_deg)
    rows, rx, sat_pos, el, az = rows.loc[keep].reset_index(drop=True), rx[keep], sat_pos[keep], el[keep], az[keep]

    lat, lon, h = geodetic_from_ecef(rx)
    nav = scenario.nav
    slant_hydrostatic, m_wet = troposphere_terms(el, lat, h, day_of_year(nav.gps_week, nav.start_sow_s))
    zwd0 = atmosphere.saastamoinen_zenith_m(lat, h)[1]
    t = rows["t"].to_numpy(float)
    iono = (
        np.zeros(len(rows))
        if nav.iono_corrected
        else atmosphere.klobuchar_l1_delay_m(
            nav.start_sow_s + t, lat, lon, el, az, np.asarray(nav.iono_alpha), np.asarray(nav.iono_beta)
        )
    )
    raw = (
        rows["code_l1"].to_numpy(float)
        + rows["sat_clock"].to_numpy(float)
        - sagnac_range(sat_pos, rx)
        - slant_hydrostatic
        - zwd0 * m_wet
        - iono
    )

    system = rows["sat"].astype(str).str[0]
    epoch = rows["epoch"].to_numpy(np.int64)
    valid = pd.Series(np.isfinite(raw))
    group = [rows["epoch"], system]
    clock = pd.Series(np.where(valid, raw, np.nan)).groupby(group).transform("median").to_numpy(float)
    count = valid.groupby(group).transform("sum").to_numpy(int)
    residual = np.where(valid & (count >= min_rows_per_clock), raw - clock, np.nan)

    phase = np.isfinite(rows["phase_l1"].to_numpy(float))
    lli = rows["lli_l1"].fillna(False).to_numpy(bool) & phase
    arc = np.full(len(rows), -1, np.int64)
    arc[phase] = arc_ids(rows.loc[phase, ["epoch", "sat", "lli_l1"]])
    out = pd.DataFrame(
        {
            "epoch": epoch,
            "t": t,
            "sat": rows["sat"].astype(str).to_numpy(),
            "system": system.to_numpy(),
            "el": np.rad2deg(el),
            "cn0": rows["cn0_l1"].to_numpy(float),
            "has_phase": phase,
            "lli": lli,
            "arc": arc,
            "raw": raw,
            "clock": clock,
            "residual": residual,
        }
    )
    epoch_t = truth["t"].to_numpy(float)
    steps = np.diff(epoch_t) / np.maximum(np.diff(truth["epoch"].to_numpy(np.int64)), 1)
    interval = float(np.median(steps)) if len(steps) else 1.0
    return ValidationSample(
        name=label,
        rows=out,
        reference_epochs=ref["epoch"].to_numpy(np.int64),
        interval_s=interval,
        real=scenario.labels is None,
    )


def world_statistics(sample: ValidationSample) -> WorldStatistics:
    """The summary statistics of one world (see :class:`WorldStatistics`)."""
    rows = sample.rows
    per_epoch = sample.tracked_per_epoch.astype(float)
    res = sample.abs_residual
    cn0 = sample.cn0
    phase = rows["has_phase"].to_numpy(bool)
    arcs = rows.loc[rows["arc"] >= 0].groupby("arc").size().to_numpy(float) * sample.interval_s

    def pct(values: np.ndarray, q: float) -> float:
        return float(np.percentile(values, q)) if len(values) else np.nan

    def share(values: np.ndarray, threshold: float) -> float:
        return float(np.mean(values > threshold)) if len(values) else np.nan

    return WorldStatistics(
        name=sample.name,
        real=sample.real,
        n_epochs=len(per_epoch),
        n_rows=len(rows),
        n_residuals=len(res),
        sats_median=pct(per_epoch, 50),
        sats_mean=float(per_epoch.mean()) if len(per_epoch) else np.nan,
        residual_p50_m=pct(res, 50),
        residual_p90_m=pct(res, 90),
        residual_p99_m=pct(res, 99),
        share_over_10m=share(res, TAIL_THRESHOLDS_M[0]),
        share_over_30m=share(res, TAIL_THRESHOLDS_M[1]),
        cn0_p10=pct(cn0, 10),
        cn0_p50=pct(cn0, 50),
        cn0_p90=pct(cn0, 90),
        phase_availability=float(phase.mean()) if len(phase) else np.nan,
        arc_median_s=pct(arcs, 50),
        arc_mean_s=float(arcs.mean()) if len(arcs) else np.nan,
        lli_rate=float(rows.loc[phase, "lli"].mean()) if phase.any() else np.nan,
    )


def cn0_by_elevation(sample: ValidationSample, bin_deg: float = 10.0) -> pd.DataFrame:
    """C/N0 percentiles per elevation bin.

    Parameters
    ----------
    sample : ValidationSample
    bin_deg : float
        Bin width [deg]; bins start at 0.

    Returns
    -------
    pandas.DataFrame
        One row per bin with rows: ``world``, ``el_low``, ``el_high`` [deg], ``n``,
        ``cn0_p10``, ``cn0_p50``, ``cn0_p90`` [dB-Hz].
    """
    if not bin_deg > 0:
        raise SimbenchError("bin_deg", f"must be positive, got {bin_deg}", "give an elevation bin width in degrees")
    rows = sample.rows[np.isfinite(sample.rows["cn0"].to_numpy(float))]
    low = np.floor(rows["el"].to_numpy(float) / bin_deg) * bin_deg
    grouped = rows["cn0"].groupby(low)
    out = pd.DataFrame(
        {
            "n": grouped.size(),
            "cn0_p10": grouped.quantile(0.1),
            "cn0_p50": grouped.median(),
            "cn0_p90": grouped.quantile(0.9),
        }
    )
    out.insert(0, "el_high", out.index + bin_deg)
    out.insert(0, "el_low", out.index.to_numpy(float))
    out.insert(0, "world", sample.name)
    return out.reset_index(drop=True)


def ks_distances(a: ValidationSample, b: ValidationSample) -> tuple[float, float]:
    """Two-sample Kolmogorov-Smirnov distances between two worlds.

    Parameters
    ----------
    a, b : ValidationSample

    Returns
    -------
    ks_residual : float
        Of the |code residual| distributions (NaN when one world has none).
    ks_cn0 : float
        Of the C/N0 distributions (NaN when one world reports none).
    """

    def ks(x: np.ndarray, y: np.ndarray) -> float:
        return float(ks_2samp(x, y).statistic) if len(x) and len(y) else np.nan

    return ks(a.abs_residual, b.abs_residual), ks(a.cn0, b.cn0)


def comparison_table(samples: Sequence[ValidationSample], reference: str | None = None) -> pd.DataFrame:
    """The worlds side by side: :class:`WorldStatistics` per row, KS distances against a reference.

    Parameters
    ----------
    samples : sequence of ValidationSample
    reference : str, optional
        Name of the world the KS distances are measured against; default the
        first real log among ``samples``, else the first sample.

    Returns
    -------
    pandas.DataFrame
        One row per sample: the :class:`WorldStatistics` fields, then
        ``ks_residual`` and ``ks_cn0`` (0 on the reference's own row) and ``ks_against``.
    """
    if not samples:
        raise SimbenchError("samples", "is empty", "give at least one world")
    names = [s.name for s in samples]
    if reference is None:
        reference = next((s.name for s in samples if s.real), names[0])
    if reference not in names:
        raise SimbenchError("reference", f"unknown world '{reference}'", f"choose from {', '.join(names)}")
    ref = samples[names.index(reference)]
    rows = []
    for sample in samples:
        ks_res, ks_cn0 = ks_distances(sample, ref)
        rows.append(
            {**world_statistics(sample).as_dict(), "ks_residual": ks_res, "ks_cn0": ks_cn0, "ks_against": reference}
        )
    return pd.DataFrame(
        rows, columns=[f.name for f in fields(WorldStatistics)] + ["ks_residual", "ks_cn0", "ks_against"]
    )

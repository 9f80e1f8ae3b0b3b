"""Per-epoch GNSS measurements for the GNSS/INS estimators: corrected code, Doppler, first fixes.

The code is :func:`estimators.model.measurement.prepare_ppp`'s corrected L1 code
(satellite clock and broadcast ionosphere removed, elevation-dependent sigma)
minus the modelled troposphere; the Doppler becomes an observed range rate
``-lambda D + satellite drift`` with a C/N0-dependent sigma (elevation-dependent without C/N0). All epochs' single
point solutions come from one call of :func:`simbench.gnss.spp.solve_epochs`:
they place the troposphere and give the filter its first fix.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from estimators.gnss_ins.config import GnssInsConfig
from estimators.model.measurement import prepare_ppp, sigma_factor
from estimators.model.ppp_config import IonosphereMode, MeasurementMode, SigmaModel
from simbench.contract import ReceiverData
from simbench.core import atmosphere
from simbench.core.frames import geodetic_from_ecef
from simbench.gnss.troposphere import troposphere_terms

__all__ = ["GnssEpoch", "GnssInsData", "SinglePointFix", "prepare_gnss_ins"]


@dataclass(frozen=True)
class GnssEpoch:
    """One epoch's GNSS measurements, ready for the window (arrays of shape (k,) or (k, 3))."""

    sat_pos: np.ndarray  #: m, satellite ECEF position at transmit time
    sat_vel: np.ndarray  #: m/s, satellite ECEF velocity
    code: np.ndarray  #: m, corrected code minus the modelled troposphere
    w_code: np.ndarray  #: 1/m, code weights (1/sigma; 0 = not used)
    rr: np.ndarray  #: m/s, observed range rate plus receiver drift (-lambda D + satellite drift)
    w_rr: np.ndarray  #: s/m, Doppler weights (0 = missing or not used)
    sat: np.ndarray  #: satellite ids


class SinglePointFix(NamedTuple):
    """A trusted single point solution of one epoch."""

    pos: np.ndarray  #: m, ECEF position, shape (3,)
    clock_m: float  #: m, receiver clock times c


@dataclass(frozen=True)
class GnssInsData:
    """What the GNSS/INS driver reads from the receiver's GNSS observations."""

    t: np.ndarray  #: s, time of every epoch index 0..n-1 (filled where the receiver had nothing)
    gnss: dict[int, GnssEpoch]  #: epochs with at least 4 usable satellites, by epoch index
    fixes: dict[int, SinglePointFix]  #: trusted single point solutions, by epoch index
    #: rows without C/N0, whose Doppler sigma follows the elevation instead
    rows_without_cn0: int = 0


def prepare_gnss_ins(data: ReceiverData, cfg: GnssInsConfig) -> GnssInsData:
    """Corrected code (prepare_ppp) joined with Doppler, satellite velocity and drift, per epoch.

    The modelled troposphere (Saastamoinen + Niell, hydrostatic and wet) is
    subtracted from the code here, at the epoch's single point solution: a few
    metres of position change it by far less than a millimetre. An epoch whose
    single point solution is not trusted takes the troposphere at the nearest
    trusted one and gets no entry in ``fixes``.

    Parameters
    ----------
    data : ReceiverData
    cfg : GnssInsConfig
        Code and Doppler sigmas and the elevation mask.

    Returns
    -------
    GnssInsData
    """
    obs = prepare_ppp(
        data,
        ionosphere=IonosphereMode.broadcast,
        code_sigma_m=cfg.code_sigma_m,
        phase_sigma_m=1.0,
        elevation_mask_deg=cfg.elevation_mask_deg,
        min_satellites=4,
        max_gap_epochs=1,
        measurements=MeasurementMode.code,
    )  # code and Doppler only: code-only logs run
    assert obs.range_rate is not None and obs.sat_vel is not None  # prepare_ppp always sets them
    # the C/N0 model (1/sin(elevation) on a row without C/N0, as for the code)
    sig_rr = cfg.doppler_sigma_mps * sigma_factor(obs.el, obs.cn0, SigmaModel.cn0, cfg.doppler_ref_cn0_dbhz)
    # range rates as prepare_ppp forms them (NaN where unusable, e.g. GLONASS FDMA rows)
    ok_rr = np.isfinite(obs.range_rate) & np.isfinite(sig_rr)
    w_rr = np.where(ok_rr, 1.0 / np.where(ok_rr, sig_rr, 1.0), 0.0)
    rr = np.where(ok_rr, obs.range_rate, 0.0)
    sat_vel = np.where(ok_rr[:, None], obs.sat_vel, 0.0)

    # one receiver clock for all rows, as in the window (no inter-system bias state)
    k = obs.row_epoch
    spp = obs.single_point(system_index=None, fill_untrusted=True)
    lat, _, h = geodetic_from_ecef(spp.pos)
    hydro, m_w = troposphere_terms(obs.el, lat[k], h[k], obs.doy)
    zwd = atmosphere.saastamoinen_zenith_m(lat, h)[1]
    code = obs.code - hydro - zwd[k] * m_w

    gnss = {}
    for i, rows in obs.iter_epochs():
        gnss[int(obs.epoch_ids[i])] = GnssEpoch(
            sat_pos=obs.sat_pos[rows],
            sat_vel=sat_vel[rows],
            code=code[rows],
            w_code=1.0 / obs.sigma_code[rows],
            rr=rr[rows],
            w_rr=w_rr[rows],
            sat=obs.sat[rows],
        )
    fixes = {
        int(obs.epoch_ids[i]): SinglePointFix(spp.pos[i].copy(), float(spp.clock_m[i, 0]))
        for i in np.flatnonzero(spp.trusted)
    }

    times = data.epoch_times
    idx = np.arange(len(times))
    good = np.isfinite(times)
    t = np.interp(idx, idx[good], times[good]) if good.sum() > 1 else np.where(good, times, 0.0)
    return GnssInsData(t=t, gnss=gnss, fixes=fixes, rows_without_cn0=int(np.isnan(obs.cn0).sum()))

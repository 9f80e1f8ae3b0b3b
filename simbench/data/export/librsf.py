"""A scenario in the libRSF GNSS text format that :func:`simbench.data.librsf.read_librsf` reads.

Lines (time ``t`` is the scenario's, seconds since its start)::

    pseudorange3 t rho var_rho satX satY satZ satID system elevation_deg cn0
    odom3 t vx vy vz wx wy wz var_vx var_vy var_vz var_wx var_wy var_wz
    point3 t X Y Z c11 c12 ... c33

:func:`write_librsf` writes what a receiver gives (``pseudorange3`` and, when the
vehicle has odometry, ``odom3``) from :class:`~simbench.contract.ReceiverData`;
:func:`append_librsf_truth` adds the reference (``point3``) from the truth table.

The format wants pseudoranges with the satellite clock and the atmosphere
removed, so ``rho = code_l1 + sat_clock - I_klobuchar - T_model`` with the
broadcast Klobuchar delay (the scenario's coefficients) and the modelled
Saastamoinen/Niell slant delay (hydrostatic and wet, standard atmosphere) at
the receiver's own single-point fix; the reader adds the modelled hydrostatic
part back for the shared model (:mod:`simbench.data.librsf`).
``var_rho = 0.09 + 0.09 / sin^2(el)`` m^2 is RTKLIB's default code variance
(0.3 m, 0.3 m / sin el); ``system`` is the libRSF bit flag and ``satID`` the PRN.
``odom3``: ``vx = speed``, ``wz = -yaw_rate`` (libRSF's z is up), the other
rates and velocities 0, their variances those of speed and yaw rate.
``point3``: ECEF antenna position with a zero covariance.

To read an export back: ``python -m simbench scenario=librsf scenario.obs=<file>
scenario.gps_week=<week> scenario.start_sow_s=<seconds of week of t = 0>``
(the command line :mod:`simbench.data.export` prints).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd

from simbench.contract import ReceiverData
from simbench.core import atmosphere
from simbench.core.constants import DEG
from simbench.core.frames import geodetic_from_ecef
from simbench.core.gpstime import day_of_year
from simbench.data.librsf import LIBRSF_AXES, SYSTEM_FLAGS
from simbench.errors import SimbenchError
from simbench.gnss.spp import ROUGH_FIX_MAX_RMS_M, solve_epochs
from simbench.gnss.troposphere import troposphere_terms

__all__ = ["write_librsf", "append_librsf_truth", "CODE_VARIANCE_M2"]

#: RTKLIB's default code error model: sigma^2 = a^2 + b^2 / sin^2(el) with a = b = 0.3 m [m^2].
CODE_VARIANCE_M2 = 0.09


def _corrected_ranges(data: ReceiverData) -> tuple[pd.DataFrame, np.ndarray]:
    """Rows with code and satellite position, and their pseudoranges with clock and atmosphere removed [m]."""
    obs = data.observations
    o = obs[np.isfinite(obs["code_l1"].to_numpy(float)) & np.isfinite(obs["sat_x"].to_numpy(float))]
    o = o.sort_values(["epoch", "sat"], kind="stable")
    if o.empty:
        raise SimbenchError("export", "the scenario has no code observations", "export a scenario with observations")
    code = o["code_l1"].to_numpy(float) + o["sat_clock"].to_numpy(float)
    if data.nav.iono_corrected:
        return o, code
    epochs, row_epoch = np.unique(o["epoch"].to_numpy(), return_inverse=True)
    sat_pos = o[["sat_x", "sat_y", "sat_z"]].to_numpy(float)
    system_index = np.unique(o["sat"].str[0].to_numpy(), return_inverse=True)[1]
    el = o["el"].to_numpy(float) * DEG
    doy = day_of_year(data.nav.gps_week, data.nav.start_sow_s)
    fix = solve_epochs(
        row_epoch,
        sat_pos,
        code,
        n_epochs=epochs.size,
        system_index=system_index,
        el=el,
        doy=doy,
        max_rms_m=ROUGH_FIX_MAX_RMS_M,
        fill_untrusted=True,
    )
    lat, lon, h = geodetic_from_ecef(fix.pos[row_epoch])
    t = o["t"].to_numpy(float)
    iono = atmosphere.klobuchar_l1_delay_m(
        data.nav.start_sow_s + t,
        lat,
        lon,
        el,
        o["az"].to_numpy(float) * DEG,
        np.asarray(data.nav.iono_alpha),
        np.asarray(data.nav.iono_beta),
    )
    hydro, m_w = troposphere_terms(el, lat, h, doy)
    _, zwd = atmosphere.saastamoinen_zenith_m(lat, h)
    return o, code - iono - hydro - zwd * m_w


def write_librsf(path: str | os.PathLike[str], data: ReceiverData) -> Path:
    """Write the receiver view as libRSF ``pseudorange3`` (and ``odom3``) lines.

    Parameters
    ----------
    path : str or PathLike
    data : ReceiverData

    Returns
    -------
    Path
        The libRSF file written (``path``).

    Raises
    ------
    SimbenchError
        No code observations, or a system libRSF has no flag for.
    """
    o, rho = _corrected_ranges(data)
    letters = o["sat"].str[0].to_numpy()
    unknown = sorted(set(letters.tolist()) - set(SYSTEM_FLAGS))
    if unknown:
        raise SimbenchError(
            "export", f"libRSF has no system flag for {unknown}", f"export systems of '{''.join(SYSTEM_FLAGS)}'"
        )
    prn = o["sat"].str[1:].astype(int).to_numpy()
    flag = np.array([SYSTEM_FLAGS[s] for s in letters.tolist()])
    el = o["el"].to_numpy(float)
    var = CODE_VARIANCE_M2 * (1.0 + 1.0 / np.sin(np.maximum(el, 1.0) * DEG) ** 2)
    sat = o[["sat_x", "sat_y", "sat_z"]].to_numpy(float)
    lines = [
        f"pseudorange3 {t:.7f} {r:.4f} {v:.4f} {x:.4f} {y:.4f} {z:.4f} {p} {f} {e:.6f} {c:.4f}"
        for t, r, v, (x, y, z), p, f, e, c in zip(
            o["t"].to_numpy(float).tolist(),
            rho.tolist(),
            var.tolist(),
            sat.tolist(),
            prn.tolist(),
            flag.tolist(),
            el.tolist(),
            o["cn0_l1"].to_numpy(float).tolist(),
        )
    ]
    lines += odom3_lines(data.odometry)
    out = Path(path)
    out.write_text("\n".join(lines) + "\n")
    return out


def odom3_lines(odometry: pd.DataFrame) -> list[str]:
    """One ``odom3`` line per odometry sample, in libRSF's x forward, y left, z up.

    A component the vehicle did not report (NaN: a simulated car gives wheel speed and yaw rate only)
    is written as libRSF's car writes it, 0, at the speed's (or yaw rate's) variance: a car does not
    move sideways or vertically in its own frame, nor roll or pitch much.
    """
    o = odometry
    speed, yaw, var_speed, var_yaw = (o[c].to_numpy(float) for c in ("speed", "yaw_rate", "var_speed", "var_yaw_rate"))

    def given(column: str, default: np.ndarray | float) -> np.ndarray:
        values = o[column].to_numpy(float)
        return np.where(np.isfinite(values), values, default)

    # + 0.0: a flipped zero is written 0, not -0
    vel = np.column_stack([speed, given("vel_right", 0.0), given("vel_down", 0.0)]) * LIBRSF_AXES + 0.0
    rate = np.column_stack([given("roll_rate", 0.0), given("pitch_rate", 0.0), yaw]) * LIBRSF_AXES + 0.0
    var_vel = np.column_stack([var_speed, given("var_vel_right", var_speed), given("var_vel_down", var_speed)])
    var_rate = np.column_stack([given("var_roll_rate", var_yaw), given("var_pitch_rate", var_yaw), var_yaw])
    return [
        f"odom3 {t:.7f} {v[0]:.6f} {v[1]:.6f} {v[2]:.6f} {w[0]:.9f} {w[1]:.9f} {w[2]:.9f} "
        + " ".join(f"{x:.6g}" for x in (*vv, *vw))
        for t, v, w, vv, vw in zip(o["t"].to_numpy(float).tolist(), vel, rate, var_vel, var_rate)
    ]


def append_librsf_truth(path: str | os.PathLike[str], truth: pd.DataFrame) -> Path:
    """Append the truth positions (:data:`simbench.contract.TRUTH_COLUMNS`) as ``point3`` lines.

    Parameters
    ----------
    path : str or PathLike
        A file written by :func:`write_librsf`.
    truth : pandas.DataFrame
        ``t`` [s] and ECEF ``x, y, z`` [m]; rows without a position are left out.

    Returns
    -------
    Path
    """
    tr = truth[truth[["x", "y", "z"]].notna().all(axis=1)]
    zeros = " ".join(["0"] * 9)
    lines = [
        f"point3 {t:.7f} {x:.4f} {y:.4f} {z:.4f} {zeros}"
        for t, x, y, z in tr[["t", "x", "y", "z"]].to_numpy(float).tolist()
    ]
    out = Path(path)
    with out.open("a") as fh:
        fh.write("\n".join(lines) + "\n")
    return out

"""SP3-c/d precise orbit files -> satellite positions and clocks on the file's epochs.

Used as the reference the broadcast ephemeris is checked against; the
simulator itself never needs precise orbits.
"""

from __future__ import annotations

import gzip
import os
from dataclasses import dataclass

import numpy as np

from simbench.core.gpstime import datetime64_to_gps
from simbench.errors import SimbenchError

__all__ = ["Sp3Orbits", "read_sp3"]


@dataclass(frozen=True)
class Sp3Orbits:
    """Precise orbits and clocks from an SP3 file (NaN where missing).

    Attributes
    ----------
    t_gps : np.ndarray, shape (k,)
        Epochs, continuous GPS seconds [s].
    sats : np.ndarray of str, shape (m,)
        Satellite ids, e.g. ``'G01'``.
    pos : np.ndarray, shape (k, m, 3)
        Centre-of-mass positions in ECEF(t) [m].
    clock : np.ndarray, shape (k, m)
        Satellite clock offsets [s].
    """

    t_gps: np.ndarray
    sats: np.ndarray
    pos: np.ndarray
    clock: np.ndarray


def read_sp3(path: str | os.PathLike[str], systems: str = "G") -> Sp3Orbits:
    """Read an SP3-c/d precise orbit file (positions and clocks).

    A small own parser: georinex's reader returns uninitialised memory for the
    clock rates and does not flag the 999999.999999 "bad clock" value.

    Parameters
    ----------
    path : str or PathLike
        SP3-c or SP3-d file in the GPS time scale.
    systems : str
        System letters to keep (``'G'`` = GPS only; ``''`` keeps all).

    Returns
    -------
    Sp3Orbits

    Raises
    ------
    SimbenchError
        Missing file, not SP3, or an unsupported time system.
    """
    p = os.fspath(path)
    field = f"sp3_file '{p}'"
    if not os.path.isfile(p):
        raise SimbenchError(field, "file does not exist", "pass an SP3 precise orbit file")
    opener = gzip.open if p.endswith(".gz") else open
    with opener(p, "rt", errors="replace") as fh:
        lines = fh.read().splitlines()
    if not lines or not lines[0].startswith("#") or lines[0][1:2] not in ("a", "b", "c", "d"):
        raise SimbenchError(field, "is not an SP3 file (first line must start with #c or #d)", "pass an SP3-c/d file")
    for ln in lines:
        if ln.startswith("%c"):
            tsys = ln[9:12].strip()
            if tsys not in ("GPS", "ccc", ""):
                raise SimbenchError(field, f"time system '{tsys}' is not supported", "use an SP3 file in GPS time")
            break
    epochs: list[float] = []
    recs: list[tuple[int, str, float, float, float, float]] = []
    for ln in lines:  # text parsing: one line per (epoch, sat) record, unavoidable
        if ln.startswith("* "):
            f = ln[1:].split()
            sec = float(f[5])
            iso = f"{int(f[0]):04d}-{int(f[1]):02d}-{int(f[2]):02d}T{int(f[3]):02d}:{int(f[4]):02d}:00"
            epochs.append(float(datetime64_to_gps(np.datetime64(iso))[()]) + sec)
        elif ln.startswith("P") and epochs:
            sv = ln[1:4].replace(" ", "0")
            if systems and sv[0] not in systems:
                continue
            try:
                x, y, z = float(ln[4:18]), float(ln[18:32]), float(ln[32:46])
                c = float(ln[46:60]) if len(ln.rstrip()) > 46 else 999999.999999
            except ValueError:
                raise SimbenchError(field, f"malformed position record '{ln[:30]}'", "check the SP3 file") from None
            recs.append((len(epochs) - 1, sv, x, y, z, c))
        elif ln.startswith("EOF"):
            break
    if not epochs or not recs:
        raise SimbenchError(field, "contains no position records", "pass an SP3 file with 'P' records")
    k_idx = np.array([r[0] for r in recs])
    sats, s_idx = np.unique(np.array([r[1] for r in recs]), return_inverse=True)
    xyzc = np.array([r[2:] for r in recs], dtype=float)
    pos = np.full((len(epochs), sats.size, 3), np.nan)
    clock = np.full((len(epochs), sats.size), np.nan)
    # SP3 marks a missing position with 0.0 and a missing clock with >= 999999.
    pos_ok = np.any(xyzc[:, :3] != 0.0, axis=1)
    clk_ok = xyzc[:, 3] < 999_999.0
    pos[k_idx[pos_ok], s_idx[pos_ok]] = xyzc[pos_ok, :3] * 1e3
    clock[k_idx[clk_ok], s_idx[clk_ok]] = xyzc[clk_ok, 3] * 1e-6
    return Sp3Orbits(t_gps=np.array(epochs), sats=sats, pos=pos, clock=clock)

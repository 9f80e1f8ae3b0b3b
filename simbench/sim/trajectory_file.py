"""Recorded trajectory files: ``SOW X Y Z`` text (GPS seconds of week, ECEF metres).

:func:`simbench.sim.trajectory.replay` turns the samples into a trajectory.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from simbench.errors import SimbenchError

__all__ = ["read_xyz_trajectory", "REPLAY_PATH_FIELD"]

#: Config field that names a replay file; errors about the file point at it.
REPLAY_PATH_FIELD = "scenario.trajectory.replay.path"


def read_xyz_trajectory(path: str | Path) -> np.ndarray:
    """Read a ``SOW X Y Z`` trajectory file (GPS seconds of week, ECEF metres).

    Blank lines and lines starting with ``#`` are ignored.

    Parameters
    ----------
    path : str or Path
        Text file, one epoch per line (e.g. ``wvu_drives/drive_1.xyz``).

    Returns
    -------
    ndarray, shape (n, 4)
        Seconds of week [s] (strictly increasing) and ECEF position [m].

    Raises
    ------
    SimbenchError
        Missing file, a malformed line (its number is given), non-increasing
        time or fewer than 2 epochs.
    """
    p = Path(path)
    if not p.is_file():
        raise SimbenchError(
            REPLAY_PATH_FIELD,
            f"file '{path}' not found",
            "give an existing 'SOW X Y Z' file, e.g. ../shared/data/wvu_drives/drive_1.xyz",
        )
    try:
        lines = p.read_text().splitlines()
    except UnicodeDecodeError:
        raise SimbenchError(
            REPLAY_PATH_FIELD, f"'{path}' is not a text file", "give a text file with 'SOW X Y Z' per line"
        ) from None
    numbered = [(n, ln) for n, ln in enumerate(lines, 1) if ln.strip() and not ln.lstrip().startswith("#")]
    try:
        data = np.array([[float(x) for x in ln.split()] for _, ln in numbered], dtype=float)
        ok = data.ndim == 2 and (len(data) == 0 or data.shape[1] == 4) and np.isfinite(data).all()
    except ValueError:
        ok = False
    if not ok:
        for n, ln in numbered:  # slow path only to name the offending line
            fields = ln.split()
            try:
                good = len(fields) == 4 and all(math.isfinite(float(x)) for x in fields)
            except ValueError:
                good = False
            if not good:
                raise SimbenchError(
                    REPLAY_PATH_FIELD,
                    f"line {n} of '{path}' is not 'SOW X Y Z': {ln.strip()[:60]!r}",
                    "fix or remove that line",
                )
    if len(numbered) < 2:
        raise SimbenchError(REPLAY_PATH_FIELD, f"'{path}' has {len(numbered)} epoch(s)", "need at least 2 epochs")
    bad = np.nonzero(np.diff(data[:, 0]) <= 0.0)[0]
    if bad.size:
        raise SimbenchError(
            REPLAY_PATH_FIELD,
            f"time does not increase at line {numbered[bad[0] + 1][0]} of '{path}'",
            "sort the epochs and remove duplicates (week rollovers are not supported)",
        )
    return data

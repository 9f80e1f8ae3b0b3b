"""Carrier wavelengths of the first-frequency signals the observation table carries (``*_l1`` columns).

The table gives Doppler in Hz; turning it into a range rate needs the carrier of
the satellite's system. GLONASS L1 is frequency-division multiplexed: its
wavelength depends on the satellite's channel, which the table does not carry,
so it is NaN here (a row without a usable Doppler).
"""

from __future__ import annotations

import numpy as np

from simbench.core.constants import C_LIGHT, F_B1I, F_L1

__all__ = ["L1_FREQUENCY_HZ", "l1_wavelength_m"]

#: First-frequency carrier per system letter [Hz]: GPS L1 C/A, Galileo E1, QZSS L1, BeiDou B1I.
L1_FREQUENCY_HZ: dict[str, float] = {"G": F_L1, "E": F_L1, "J": F_L1, "C": F_B1I}


def l1_wavelength_m(sat: np.ndarray) -> np.ndarray:
    """Carrier wavelength [m] of each row's first-frequency signal, from its satellite id ('G05', 'C11', ...).

    Parameters
    ----------
    sat : array of str, shape (N,)
        Satellite ids; the first letter is the RINEX system letter.

    Returns
    -------
    ndarray, shape (N,)
        Wavelength [m]; NaN for systems without a fixed carrier (GLONASS) or unknown letters.
    """
    letters = np.array([str(s)[:1] for s in np.asarray(sat).tolist()])
    out = np.full(len(letters), np.nan)
    for letter, freq in L1_FREQUENCY_HZ.items():
        out[letters == letter] = C_LIGHT / freq
    return out

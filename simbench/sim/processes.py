"""Random processes sampled on a uniform time grid, vectorised over channels.

Every function takes an explicit :class:`numpy.random.Generator`; the generator
gives each error source its own stream (see :func:`stream`) so that switching
one source off does not change the random numbers of the others.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.signal import lfilter


def stream(seed: int, name: str) -> np.random.Generator:
    """Independent, reproducible random stream for one error source.

    Parameters
    ----------
    seed : int
        Scenario seed.
    name : str
        Name of the error source; hashed with CRC-32 (stable across runs and
        Python versions, unlike ``hash``).
    """
    return np.random.default_rng([int(seed), zlib.crc32(name.encode())])


def gauss_markov(
    n_steps: int,
    n_channels: int,
    sigma: float | np.ndarray,
    tau_s: float,
    dt_s: float,
    rng: np.random.Generator,
    channels: np.ndarray | None = None,
) -> np.ndarray:
    """Stationary first-order Gauss-Markov processes, exact discretisation.

    ``x[k+1] = a x[k] + sigma sqrt(1 - a^2) w[k]`` with ``a = exp(-dt/tau)``,
    started from the stationary distribution ``x[0] ~ N(0, sigma^2)``.

    Parameters
    ----------
    n_steps : int
        Number of samples along time.
    n_channels : int
        Number of independent processes (e.g. satellites).
    sigma : float or array of shape (n_channels,)
        Stationary standard deviation, in the unit of the result.
    tau_s : float
        Correlation time [s]; the autocorrelation at lag ``tau_s`` is ``1/e``.
    dt_s : float
        Sample interval [s].
    rng : numpy.random.Generator
    channels : ndarray of int, optional
        The only channels the caller wants, in the order wanted. The random numbers of all
        ``n_channels`` are drawn all the same, so the wanted channels, and every later draw
        from ``rng``, do not depend on which are wanted.

    Returns
    -------
    ndarray, shape (n_steps, n_channels), or (n_steps, len(channels))
    """
    a = float(np.exp(-dt_s / tau_s))
    w = rng.standard_normal((n_steps, n_channels))
    sigma = np.asarray(sigma)
    if channels is None:
        return _unit_gauss_markov(w, a) * sigma
    return _unit_gauss_markov(w[:, channels], a) * (sigma[channels] if sigma.ndim else sigma)


@dataclass(frozen=True)
class Columns:
    """The satellites (columns) a generator grid keeps out of the ``width`` its random draws span.

    Every (epochs, satellites) draw is taken ``width`` wide and cut to ``keep``, so that the
    numbers a kept satellite gets do not depend on which others are kept.
    """

    width: int  #: satellites the draws span (the whole constellation)
    keep: np.ndarray  #: int, ascending: the constellation index of each grid column

    @classmethod
    def every(cls, m: int) -> Columns:
        """All ``m`` satellites kept."""
        return cls(m, np.arange(m))

    def draw(self, sample: Callable[..., np.ndarray], n: int, *args: Any) -> np.ndarray:
        """``sample(*args, size=(n, width))`` cut to the kept columns, e.g. ``draw(rng.standard_normal, n)``."""
        return sample(*args, size=(n, self.width))[:, self.keep]


def _unit_gauss_markov(w: np.ndarray, a: float) -> np.ndarray:
    """Unit-variance processes of pole ``a`` driven by the standard normal columns of ``w`` (modified in place)."""
    w[0] = w[0] / np.sqrt(1.0 - a * a)  # so that x[0] has unit variance
    return lfilter([np.sqrt(1.0 - a * a)], [1.0, -a], w, axis=0)


def random_walk(
    n_steps: int, n_channels: int, density: float, dt_s: float, rng: np.random.Generator, x0: np.ndarray | float = 0.0
) -> np.ndarray:
    """Random walk ``x[k+1] = x[k] + density sqrt(dt) w[k]``.

    Parameters
    ----------
    density : float
        Noise density [unit/sqrt(s)].

    Returns
    -------
    ndarray, shape (n_steps, n_channels)
    """
    steps = density * np.sqrt(dt_s) * rng.standard_normal((n_steps, n_channels))
    steps[0] = 0.0
    return np.cumsum(steps, axis=0) + x0


def receiver_clock(
    t_s: np.ndarray, bias0_sigma_s: float, drift0_sigma_sps: float, h0: float, h_2: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Two-state receiver clock (bias and drift) driven by Allan-variance coefficients.

    The standard discretisation (Brown & Hwang) uses the white-frequency
    coefficient ``h0`` for the phase state and the random-walk-frequency
    coefficient ``h_2`` for the frequency state:
    ``q_bias = h0/2 dt``, ``q_drift = 2 pi^2 h_2 dt``.

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Epoch times [s], strictly increasing.

    Returns
    -------
    bias_s, drift_sps : ndarray, shape (n,)
        Clock offset [s] and drift [s/s].
    """
    n = len(t_s)
    dt = np.diff(t_s, prepend=t_s[0])
    drift = drift0_sigma_sps * rng.standard_normal() + np.cumsum(
        np.sqrt(2.0 * np.pi**2 * h_2 * dt) * rng.standard_normal(n)
    )
    # trapezoidal integration of the drift keeps bias and drift consistent at any rate
    bias_steps = 0.5 * (drift + np.concatenate(([drift[0]], drift[:-1]))) * dt
    bias = (
        bias0_sigma_s * rng.standard_normal()
        + np.cumsum(bias_steps)
        + np.cumsum(np.sqrt(0.5 * h0 * dt) * rng.standard_normal(n))
    )
    return bias, drift

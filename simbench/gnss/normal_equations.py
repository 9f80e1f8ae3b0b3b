"""Stacks of small per-epoch normal equations: solved and inverted as the pseudo-inverse would.

Single point (:mod:`simbench.gnss.spp`) and Doppler velocity (:mod:`simbench.gnss.doppler`)
solve one 4-7 parameter system per epoch for thousands of epochs at once. The
pseudo-inverse (an SVD per matrix) was their answer to an absent system's clock,
whose row and column are zero; an hour at 1 Hz then cost 9 ms per single point
iteration, most of a batch estimator's set-up. A parameter with a zero row is
given a unit pivot instead and comes out 0 (its right-hand side is 0), so LU solves
the stack in a fifth of the time; a member that is singular even so (an epoch with
too few satellites) still gets the pseudo-inverse.
"""

from __future__ import annotations

import numpy as np

__all__ = ["pinv_solve", "pinv_stack"]

#: Members whose determinant is below this fraction of their diagonal's product take the pseudo-inverse.
_SINGULAR = 1e-10


def _unit_pivots(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Zero-row parameters given a unit pivot; which are unused; which members are singular even so."""
    unused = ~np.any(normal != 0.0, axis=2)
    pivoted = normal + unused[:, :, None] * np.eye(normal.shape[-1])
    # det / prod(diag) is 1 for a diagonal matrix and falls with the condition number (Hadamard);
    # rank-deficient members (an epoch with too few satellites) sit at round-off, ~1e-16
    diagonal = np.einsum("kii->ki", pivoted)
    singular = ~(np.linalg.det(pivoted) > _SINGULAR * np.prod(np.abs(diagonal), axis=1))
    return pivoted, unused, singular


def pinv_solve(normal: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``pinv(N_k) b_k`` for every ``k``.

    Parameters
    ----------
    normal : ndarray, shape (K, p, p)
        Symmetric positive semi-definite normal matrices.
    rhs : ndarray, shape (K, p)
        Right-hand sides (0 wherever the matching row of ``normal`` is 0).

    Returns
    -------
    ndarray, shape (K, p)
    """
    pivoted, unused, singular = _unit_pivots(normal)
    x = np.empty(rhs.shape)
    ok = ~singular
    x[ok] = np.linalg.solve(pivoted[ok], rhs[ok][..., None])[..., 0]
    x[unused & ok[:, None]] = 0.0
    x[singular] = np.einsum("kij,kj->ki", np.linalg.pinv(normal[singular]), rhs[singular])
    return x


def pinv_stack(normal: np.ndarray) -> np.ndarray:
    """``pinv(N_k)`` for every ``k`` (shape (K, p, p), ``normal`` as in :func:`pinv_solve`)."""
    pivoted, unused, singular = _unit_pivots(normal)
    inverse = np.empty(normal.shape)
    ok = ~singular
    inverse[ok] = np.linalg.inv(pivoted[ok])
    inverse[unused & ok[:, None]] = 0.0
    inverse[singular] = np.linalg.pinv(normal[singular])
    return inverse

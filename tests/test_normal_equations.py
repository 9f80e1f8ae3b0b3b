"""Stacked per-epoch normal equations agree with the pseudo-inverse, absent parameters and too few rows included."""

from __future__ import annotations

import numpy as np

from simbench.gnss.normal_equations import pinv_solve, pinv_stack


def _stack() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(1000)
    a = rng.normal(size=(60, 8, 5))
    a[:10, :, 4] = 0.0  # an absent system's clock column
    a[10:13, 2:, :] = 0.0  # two rows for five parameters: rank 2
    a[13:15, :, 0] = 1e-6 * a[13:15, :, 1] + a[13:15, :, 0] * 1e-12  # nearly dependent columns
    normal = np.einsum("kri,krj->kij", a, a)
    rhs = np.einsum("kri,kr->ki", a, rng.normal(size=(60, 8)))
    return normal, rhs


def test_solve_and_inverse_match_the_pseudo_inverse() -> None:
    normal, rhs = _stack()
    reference = np.linalg.pinv(normal)
    x = pinv_solve(normal, rhs)
    assert np.abs(x - np.einsum("kij,kj->ki", reference, rhs)).max() < 1e-9
    assert np.all(x[:10, 4] == 0.0)
    assert np.abs(pinv_stack(normal) - reference).max() < 1e-9 * np.abs(reference).max()

"""Re-weighting a batch PPP graph on its linearised rows instead of rebuilding its factors.

Used by BCE / BCE-AD, DCS and batch max-mixtures. BCE gives every satellite-epoch
a new 2x2 (code, phase) covariance and a new mean at every iteration. Rebuilding
the 2 x n_obs native factors for that (Python loop, 0.11 s per iteration on an hour
of 1 Hz urban data), evaluating the graph's error twice and the residuals once more
cost more than the factorisation itself. Here the graph is built once with *unit*
measurement noise: GTSAM linearises its native factors (Jacobians and residuals
exactly as the factors define them), and the iteration's noise model is applied to
the linearised rows in numpy: each observation's (code, phase) row pair is whitened
by its covariance and shifted by its mean, and a robust kernel (:class:`DcsKernel`)
scales each row as GTSAM's robust linearisation does. A step moves the residuals
along the rows; GTSAM linearises again only after a receiver has moved by a metre
(:data:`RELINEARIZE_M`): 4-5 times in a BCE run of 17 iterations, 20 in DCS's 80.
The normal equations, the error and the step are those of the graph that
:meth:`PppGraph.measurement_factors` builds from the same arguments, including its
exact factorisation of the pair into a marginal and a conditional and the clipping
of ``rho`` near 1 (``tests/test_batch_estimators.py`` compares errors and steps).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gtsam
import numpy as np
import scipy.sparse as sp

from estimators.batch.gauss_newton import GaussNewton
from estimators.model.ppp_graph import PppGraph, conditional_split, pos_key

__all__ = ["RELINEARIZE_M", "DcsKernel", "RowsState", "WhitenedRows"]


#: Position change [m] of any epoch since GTSAM last linearised after which the rows are
#: linearised afresh. Every factor is linear but the ranges' geometry: moving a receiver by
#: ``d`` changes a range's curvature term by ``d^2 / (2 * 2e7 m)`` and its line of sight by
#: ``d / 2e7 m`` (2.5e-8 m and 5e-8 m per metre of step for d = 1 m), far below any sigma.
RELINEARIZE_M = 1.0


@dataclass(frozen=True)
class RowsState:
    """A point of :class:`WhitenedRows` to return to (:meth:`WhitenedRows.restore`)."""

    base: gtsam.Values
    dx: np.ndarray
    values: gtsam.Values | None
    a: tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix]
    b: tuple[np.ndarray, np.ndarray, np.ndarray]
    base_positions: np.ndarray


class WhitenedRows:
    """The batch graph with unit measurement noise, linearised at one point at a time.

    A step moves the point along the linearised rows: the residuals follow as
    ``b - A dx`` (exact for every factor but the ranges, whose geometry changes by
    micrometres over a metre) and GTSAM linearises afresh only once an epoch's position
    has moved by :data:`RELINEARIZE_M` since it last did. A re-weighting iteration then
    costs the factorisation and no round trip through GTSAM's 46k keys (linearise, hand
    over the Jacobian, build the increment: two thirds of a BCE iteration on an hour of
    1 Hz urban data).

    Parameters
    ----------
    g : PppGraph
    structure : gtsam.NonlinearFactorGraph
        Priors and motion factors (:meth:`PppGraph.structure_factors`).
    steps : GaussNewton
        Solver of the normal equations (its symbolic factorisation is reused).
    values : gtsam.Values
        First linearisation point.
    """

    def __init__(
        self, g: PppGraph, structure: gtsam.NonlinearFactorGraph, steps: GaussNewton, values: gtsam.Values
    ) -> None:
        n = g.obs.n_obs
        self._graph = gtsam.NonlinearFactorGraph(structure)
        self._graph.push_back(g.measurement_factors(code_sigma=np.ones(n), phase_sigma=np.ones(n)))
        self._has_phase = g.has_phase.copy()
        self._phase_rows = phase = np.flatnonzero(self._has_phase)
        # spreads the phase rows to one per observation (empty rows where a row has no phase)
        self._expand = sp.csr_matrix((np.ones(len(phase)), (phase, np.arange(len(phase)))), shape=(n, len(phase)))
        self._g, self._structure = g, structure
        self._steps = steps
        #: linearisations by GTSAM so far (the first, then one per RELINEARIZE_M of travel or fall-back)
        self.linearizations = 0
        self.linearize(values)
        # the columns of every epoch's position in the rows' layout (fixed for the run)
        epochs = range(g.obs.n_epochs)
        self._position_index = self._steps.columns([pos_key(k) for k in epochs])[:, None] + np.arange(3)

    def linearize(self, values: gtsam.Values) -> None:
        """Linearise at ``values`` by GTSAM (the point of :attr:`residuals`, :meth:`error` and :meth:`step`)."""
        system = self._steps.jacobian(self._graph.linearize(values), values)
        if system is None:
            raise RuntimeError("the unit-noise graph's keys differ from the values'")
        a, b = system
        self.linearizations += 1
        n, n_phase = self._expand.shape
        ns = a.shape[0] - n - n_phase
        self._base = values
        self._values: gtsam.Values | None = values
        self._base_positions = self._g.positions(values)
        self._dx = np.zeros(a.shape[1])
        self._struct_a, self._struct_b = a[:ns], b[:ns]
        self._code_a, self._code_b = a[ns : ns + n], b[ns : ns + n]
        self._phase_a = sp.csr_matrix(self._expand @ a[ns + n :])
        self._phase_b = np.full(n, np.nan)
        self._phase_b[self._phase_rows] = b[ns + n :]

    def snapshot(self) -> RowsState:
        """The current point, to :meth:`restore` after a rejected step."""
        return RowsState(
            self._base,
            self._dx,
            self._values,
            (self._struct_a, self._code_a, self._phase_a),
            (self._struct_b, self._code_b, self._phase_b),
            self._base_positions,
        )

    def restore(self, state: RowsState) -> None:
        """Return to a :meth:`snapshot` (steps and linearisations replace arrays, never modify them)."""
        self._base, self._dx, self._values = state.base, state.dx, state.values
        self._struct_a, self._code_a, self._phase_a = state.a
        self._struct_b, self._code_b, self._phase_b = state.b
        self._base_positions = state.base_positions

    @property
    def residuals(self) -> tuple[np.ndarray, np.ndarray]:
        """Code and phase residuals ``measured - predicted`` per row [m] at the current point (NaN: no phase)."""
        return self._code_b, self._phase_b

    def positions(self) -> np.ndarray:
        """Position of every solved epoch at the current point, shape (n_epochs, 3) [m]."""
        return self._base_positions + self._dx[self._position_index]

    def _whitened(self, noise: dict[str, Any], *, rows: bool = True) -> tuple[sp.csr_matrix | None, np.ndarray]:
        """Measurement rows (None unless ``rows``) and right-hand side whitened by ``noise``
        (:meth:`PppGraph.measurement_factors`'s per-row arguments)."""
        n = len(self._has_phase)
        zeros = np.zeros(n)
        code_sigma, rho_c, phase_sigma, rho_p = conditional_split(
            noise["code_sigma"], noise["phase_sigma"], noise.get("code_phase_cov"), self._has_phase
        )
        bc = self._code_b - noise.get("code_offset", zeros)
        bp = np.where(self._has_phase, self._phase_b - noise.get("phase_offset", zeros), 0.0)
        # code row (code - rho_c phase) / sigma_c|p, phase row (phase - rho_p code) / sigma_p|c
        wc, wp = 1.0 / code_sigma, 1.0 / phase_sigma
        keep = self._phase_rows
        b = np.r_[wc * (bc - rho_c * bp), (wp * (bp - rho_p * bc))[keep]]
        if not rows:  # the error needs the residuals only
            return None, b
        code = sp.diags(wc) @ self._code_a - sp.diags(wc * rho_c) @ self._phase_a
        phase = sp.diags(wp) @ self._phase_a - sp.diags(wp * rho_p) @ self._code_a
        return sp.vstack([code, phase[keep]], format="csr"), b

    @property
    def fallbacks(self) -> int:
        """Steps that GTSAM's elimination took over from the sparse factorisation."""
        return self._steps.fallbacks

    @property
    def values(self) -> gtsam.Values:
        """The current point as GTSAM values."""
        if self._values is None:
            self._values = self._base.retract(self._steps.vector_values(self._dx))
        return self._values

    def error(self, noise: dict[str, Any], kernel: DcsKernel | None = None) -> float:
        """GTSAM's error of the graph with ``noise`` (and ``kernel`` on every measurement factor) at the
        current point (``0.5 * sum`` of squared whitened residuals, or the kernel's loss of them;
        dimensionless)."""
        _, b = self._whitened(noise, rows=False)
        measurement = 0.5 * np.dot(b, b) if kernel is None else np.sum(kernel.loss(np.abs(b)))
        return float(measurement + 0.5 * np.dot(self._struct_b, self._struct_b))

    def solve(self, noise: dict[str, Any], *, relative_tol: float, max_iterations: int) -> bool:
        """Gauss-Newton steps with ``noise`` until the relative error decrease is below ``relative_tol``.

        Returns False, back at the start, where a step raised the error (a start too far for an
        undamped step: the caller damps, e.g. by Levenberg-Marquardt).
        """
        start, err = self.snapshot(), self.error(noise)
        for _ in range(max_iterations):
            self.step(noise)
            stepped_err = self.error(noise)
            if stepped_err > err * (1.0 + 1e-9):
                self.restore(start)
                return False
            converged = err - stepped_err <= relative_tol * err
            err = stepped_err
            if converged:
                break
        return True

    def step(self, noise: dict[str, Any], kernel: DcsKernel | None = None) -> None:
        """One Gauss-Newton step of the graph with ``noise`` (and ``kernel``) from the current point,
        which then moves to the stepped point.

        With a kernel the step is GTSAM's robust linearisation: each measurement row and its
        residual scaled by the square root of the kernel's weight (one IRLS iteration). Where the
        sparse factorisation fails, the graph is built with ``noise`` and stepped by GTSAM's
        elimination (:meth:`GaussNewton.eliminate`).
        """
        a, b = self._whitened(noise)
        assert a is not None
        if kernel is not None:
            root = np.sqrt(kernel.weight(np.abs(b)))
            a, b = sp.csr_matrix(sp.diags(root) @ a), root * b
        dx = self._steps.increment(sp.vstack([self._struct_a, a], format="csr"), np.r_[self._struct_b, b])
        if dx is None:
            graph = gtsam.NonlinearFactorGraph(self._structure)
            robust = None if kernel is None else kernel.model
            graph.push_back(self._g.measurement_factors(**noise, robust=robust))
            self.linearize(self._steps.eliminate(graph, self.values)[0])
            return
        self._dx = self._dx + dx
        self._values = None
        if np.abs(self._dx[self._position_index]).max(initial=0.0) > RELINEARIZE_M:
            self.linearize(self.values)
            return
        self._struct_b = self._struct_b - self._struct_a @ dx
        self._code_b = self._code_b - self._code_a @ dx
        phase_b = self._phase_b.copy()
        phase_b[self._phase_rows] -= (self._phase_a @ dx)[self._phase_rows]
        self._phase_b = phase_b


class DcsKernel:
    """GTSAM's dynamic covariance scaling m-estimator, vectorised over rows.

    ``weight(d) = (2 c / (c + d^2))^2`` and ``loss(d) = c (3 d^2 - c) / (2 (c + d^2))`` where
    ``d^2 > c``, else 1 and ``d^2 / 2`` (``gtsam.noiseModel.mEstimator.DCS``; ``c`` the kernel
    width, phi in the DCS papers; ``d`` a whitened residual). The test compares both with GTSAM's.

    Parameters
    ----------
    width : float
        Kernel width ``c`` [whitened units, squared].
    """

    def __init__(self, width: float) -> None:
        self.width = float(width)
        #: the same kernel as a GTSAM noise-model wrapper (for graphs GTSAM evaluates)
        self.model = gtsam.noiseModel.mEstimator.DCS.Create(self.width)

    def weight(self, d: np.ndarray) -> np.ndarray:
        """IRLS weight of whitened residuals ``d``."""
        c, d2 = self.width, np.square(d)
        return np.where(d2 > c, np.square(2.0 * c / (c + d2)), 1.0)

    def loss(self, d: np.ndarray) -> np.ndarray:
        """Loss of whitened residuals ``d`` (GTSAM's factor error)."""
        c, d2 = self.width, np.square(d)
        return np.where(d2 > c, c * (3.0 * d2 - c) / (2.0 * (c + d2)), 0.5 * d2)

"""ICE's late-signal model: one :class:`~estimators.model.nlos_mixture.NlosMixture` per run, learned on a window.

ICE's own mixture (:mod:`estimators.incremental.ice`) is a zero-mean scale mixture: it widens the
model for the rows a street delays but never learns that they are late, nor which rows are. This
model does (``IceConfig.nlos_model = conditioned``): the :class:`NlosMixture` of the batch
``mm_em``, a LOS component and a late-only NLOS component whose prior weight and mean depend on
the row's C/N0 and elevation, refitted by a few EM iterations at every epoch, warm-started from
the last fit, on the predicted code residuals of the last ``nlos_window_s`` seconds.

Each new code row is then assigned, from its predicted residual, to its more likely component
(the max-mixture, as ``mm_em``): a NLOS row enters the graph with the NLOS mean ``mu(z)``
subtracted and the NLOS spread, a LOS row stays ICE's. The residuals are innovations (``measured
- predicted`` of a filter), so the variance of the predicted position along the line of sight
(``u' P u``) is added to both components' variances when a row is assigned and when the window is
fitted, as ICE's z-test adds it; the factor's sigma is the component's alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from estimators.model.nlos_mixture import NlosMixture, quartile_table

__all__ = ["NlosAssignment", "NlosWindow"]

#: Bounds of the logit of the NLOS prior weight at the predictors' centre (weights 0.001 to 0.999): a
#: window without a late row drives the logistic intercept to minus infinity, and a model warm-started
#: from there would call no row NLOS again (Hong Kong: -9e11 after a clean minute)
_LOGIT_BOUNDS = (-6.9, 6.9)


@dataclass(frozen=True)
class NlosAssignment:
    """The NLOS model's verdict on one epoch's code rows.

    Attributes
    ----------
    nlos : ndarray of bool, shape (m,)
        Rows more likely NLOS than LOS.
    sigma : ndarray, shape (m,)
        Code sigma of a NLOS row's factor [m] (the NLOS component's: LOS variance plus ``tau^2``).
    offset : ndarray, shape (m,)
        NLOS mean ``mu(z)`` [m], subtracted from a NLOS row's code.
    z : ndarray, shape (m,)
        ``|r - mu| / sqrt(var_N + u' P u)``: a NLOS row's code z-score [-].
    """

    nlos: np.ndarray
    sigma: np.ndarray
    offset: np.ndarray
    z: np.ndarray


@dataclass
class NlosWindow:
    """The windowed NLOS mixture of one run.

    Parameters
    ----------
    window_s : float
        Rows of the last this many seconds are fitted [s].
    min_rows : int
        No model before the window holds this many rows (and no NLOS row).
    em_iterations : int
        EM iterations per epoch, from the last fit.
    weight_init : float
        Prior NLOS weight of the first fit [-].
    names : tuple of str
        Predictor names (:func:`~estimators.model.nlos_mixture.predictors`).
    """

    window_s: float
    min_rows: int
    em_iterations: int
    weight_init: float
    names: tuple[str, ...]
    model: NlosMixture | None = field(init=False, default=None)
    #: every epoch's (time, residuals, a-priori sigmas, u' P u, predictors); the window is the tail
    _epochs: list[tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = field(
        init=False, default_factory=list
    )
    _first: int = field(init=False, default=0)
    _count: int = field(init=False, default=0)
    #: every epoch's predictors and the model as applied to its rows: prior weight, mean, called NLOS
    _applied: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = field(init=False, default_factory=list)

    def assign(self, r: np.ndarray, sigma: np.ndarray, los_var: np.ndarray, x: np.ndarray) -> NlosAssignment:
        """Each row's more likely component (:class:`NlosAssignment`); every row LOS before the first fit.

        Parameters
        ----------
        r : ndarray, shape (m,)
            Predicted code residuals [m].
        sigma : ndarray, shape (m,)
            A-priori code sigmas [m].
        los_var : ndarray, shape (m,)
            Variance of the predicted position along each line of sight [m^2].
        x : ndarray, shape (m, P)
            Predictors (:func:`~estimators.model.nlos_mixture.predictors`).
        """
        m = len(r)
        if self.model is None:
            zeros = np.zeros(m)
            self._applied.append((x, np.full(m, np.nan), np.full(m, np.nan), np.zeros(m, bool)))
            return NlosAssignment(np.zeros(m, bool), zeros, zeros, zeros)
        mdl = self.model
        mu = mdl.mean(x, m)
        nlos = mdl.responsibility(r, self._innovation_sigma(sigma, los_var), x) > 0.5
        _, var_n = mdl.variances(sigma)
        z = np.abs(r - mu) / np.sqrt(var_n + los_var)
        self._applied.append((x, mdl.weight(x, m), mu, nlos))
        return NlosAssignment(nlos, np.sqrt(var_n), mu, z)

    def add(self, t: float, r: np.ndarray, sigma: np.ndarray, los_var: np.ndarray, x: np.ndarray) -> None:
        """Put one epoch's rows into the window, let those older than ``window_s`` go, refit the model."""
        self._epochs.append((t, r, sigma, los_var, x))
        self._count += len(r)
        while self._epochs[self._first][0] < t - self.window_s:
            self._count -= len(self._epochs[self._first][1])
            self._first += 1
        if self._count < self.min_rows:
            return
        r_w, s_w, x_w = self._stack(self._epochs[self._first :])
        if self.model is None:
            self.model = NlosMixture.start(r_w, s_w, x_w, self.names, weight=self.weight_init)
        fitted = self.model.fit(r_w, s_w, x_w, iterations=self.em_iterations)
        coef = fitted.weight_coef.copy()
        coef[0] = np.clip(coef[0], *_LOGIT_BOUNDS)
        self.model = replace(fitted, weight_coef=coef)

    def _stack(self, epochs: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Residuals, innovation sigmas (:meth:`_innovation_sigma`) and predictors of ``epochs``, stacked."""
        r = np.concatenate([e[1] for e in epochs])
        sigma = np.concatenate([e[2] for e in epochs])
        los_var = np.concatenate([e[3] for e in epochs])
        return r, self._innovation_sigma(sigma, los_var), np.vstack([e[4] for e in epochs])

    def _innovation_sigma(self, sigma: np.ndarray, los_var: np.ndarray) -> np.ndarray:
        """The sigma whose scaled LOS variance ``(k s)^2 + t^2`` is the a-priori one plus ``u' P u``
        (the prediction's part is not the receiver's: the LOS scale ``k`` does not apply to it)."""
        k = 1.0 if self.model is None else self.model.los_scale
        return np.sqrt(sigma**2 + los_var / k**2)

    def summary(self) -> dict[str, Any]:
        """What the model did over the run: the last fit's parameters, and per predictor quartile the
        mean prior NLOS weight and NLOS mean of the model each row was assigned under (rows before the
        first fit left out) and the share of rows that entered as NLOS."""
        out: dict[str, Any] = {"predictors": list(self.names)}
        if self.model is not None:
            out.update(self.model.parameters())
        if not self._applied:
            return out
        x, pi, mu, nlos = (np.concatenate([a[i] for a in self._applied]) for i in range(4))
        out.update(nlos_rows=int(nlos.sum()), nlos_share=float(nlos.mean()))
        out.update(quartile_table(self.names, x, pi, mu, nlos))
        return out

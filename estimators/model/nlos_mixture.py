"""A self-tuning NLOS mixture of the code residuals, conditioned on what predicts the delay.

A street's reflected (NLOS) signals arrive late, never early, and the weak, low ones are the
late ones. One mixture over all residuals (BCE's DP-GMM, MM's fixed zero-mean pair) does not
see either. Per code row ``i`` with a-priori sigma ``s_i`` [m] and predictors ``x_i`` (C/N0
[dB-Hz] and elevation [deg], standardised to ``z_i``) the model is two components::

    LOS   r_i ~ N(0, v_i),  v_i = (k s_i)^2 + t^2   prior weight 1 - pi(z_i)
    NLOS  r_i ~ N(mu(z_i), v_i + tau^2)             prior weight pi(z_i)

    pi(z) = 1 / (1 + exp(-w . [1, z]))              (logistic in the predictors)
    mu(z) = max(0, b . [1, z])                      (late only: one-sided)

with, when one-sided, the slopes of ``w`` and ``b`` held at or below 0: a reflection is no more
likely and no longer for a stronger or higher signal. Where no predictor's weight slope is below 0
the data do not say which rows are late, and the NLOS component keeps mean 0 (a broad outlier
component, as MM's, with learned weight and spread).

The LOS component keeps mean 0: it anchors the receiver clock, which would otherwise take up any
common shift of the components. ``k`` (the LOS scale on the a-priori sigmas), ``t`` [m] (a LOS
spread the a-priori sigmas do not have: without it, where they are too small for the street, the
NLOS component, the only one with an additive spread, fits the LOS rows better, takes them one
re-solve after another and the receiver clock follows it), ``tau`` [m], ``w`` and ``b`` are
learned by expectation-maximisation from the residuals of the whole graph (:meth:`NlosMixture.fit`),
alternating with the solve, as libRSF's EM-tuned mixtures do (Pfeifer and Protzel, ICRA 2019), with
the weights and means conditioned on the predictors. The E-step is
each row's NLOS responsibility (:meth:`NlosMixture.responsibility`); the M-step a weighted
logistic regression for ``w`` (Newton steps, a small ridge), a weighted least-squares line for
``b`` and bounded 1-D searches for ``k``, ``t`` and ``tau``. ``conditioned = False`` drops the predictors (one
weight and one mean for every row: the unconditioned mixture, for comparison); ``one_sided =
False`` lets the NLOS mean take either sign.

How a solve uses the model (:meth:`NlosMixture.code_noise`): ``max``, the max-mixture, gives each
row the sigma and mean of its more likely component; ``soft``, the EM step of the state, gives each
row the single Gaussian that the responsibility-weighted sum of both components' squared errors is,
precision ``(1 - g)/var_L + g/var_N`` and offset ``g mu/var_N`` over that precision.

Any graph estimator can use it: the batch ``mm_em`` (:mod:`estimators.batch.robust`) refits it on
every re-solve; an incremental one (ICE) can keep one model, refit it on its window's code
residuals with ``previous=`` the last fit (a warm start, a few EM iterations each) and give each
new row :meth:`NlosMixture.code_noise` from its predicted residual.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

from estimators.model.robust_models import Assignment

__all__ = [
    "NlosMixture",
    "predictors",
    "quartile_table",
]

#: Floor of the NLOS spread tau [m]: a component narrower than a code sigma is no longer a delay model.
_TAU_FLOOR_M = 1.0
#: Floor of the LOS spread t [m] (the 1-D search needs a positive lower bound; a centimetre is none).
_LOS_SPREAD_FLOOR_M = 0.01
#: Ceiling of tau [m]: far beyond any street's reflection delay.
_TAU_CEILING_M = 500.0
#: Bounds of the LOS scale k on the a-priori sigmas: the max-mixture's own fit shrinks the LOS residuals
#: (the states follow them), and an unbounded k would follow that down iteration after iteration.
_K_BOUNDS = (0.5, 3.0)
#: Ridge on the logistic slopes (standardised predictors): keeps the weights finite where a predictor
#: separates the components completely (every weak row NLOS).
_RIDGE = 1e-2
#: Responsibilities are kept within (eps, 1 - eps) so the logistic fit never sees a certain label.
_EPS = 1e-6


def predictors(el_rad: np.ndarray, cn0_dbhz: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """The predictor columns of every row and their names: C/N0 [dB-Hz] and elevation [deg].

    Rows without C/N0 take the median of the others; without any C/N0 the column is left out
    (a RINEX file without S observables), so the weights depend on elevation alone.
    """
    el = np.degrees(np.asarray(el_rad, float))
    cn0 = np.asarray(cn0_dbhz, float)
    missing = ~np.isfinite(cn0)
    if missing.all():
        return el[:, None], ["elevation_deg"]
    cn0 = np.where(missing, np.median(cn0[~missing]), cn0)
    return np.c_[cn0, el], ["cn0_dbhz", "elevation_deg"]


def _sigmoid(a: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * a))


def _log_normal(r: np.ndarray, mean: np.ndarray | float, var: np.ndarray) -> np.ndarray:
    return -0.5 * (np.log(2.0 * np.pi * var) + (r - mean) ** 2 / var)


@dataclass(frozen=True)
class NlosMixture:
    """A learned LOS/NLOS model of code residuals (module notes).

    Attributes
    ----------
    names : tuple of str
        Predictor names (columns of ``x`` in every method), empty when unconditioned.
    center, scale : ndarray, shape (P,)
        Standardisation of the predictors, fixed at the first fit so a model applies to new rows.
    weight_coef : ndarray, shape (P + 1,)
        Logistic coefficients ``w`` of the NLOS prior weight on ``[1, z]``.
    mean_coef : ndarray, shape (P + 1,)
        Coefficients ``b`` of the NLOS mean [m] on ``[1, z]``.
    tau : float
        Spread of the NLOS delay beyond the code noise [m].
    los_scale : float
        ``k``: the LOS variance is ``k`` times the a-priori sigma, squared, plus ``los_spread^2`` [-].
    los_spread : float
        ``t``: the LOS spread beyond the scaled a-priori sigma [m].
    one_sided : bool
        The NLOS mean is clipped at 0 (late only).
    """

    names: tuple[str, ...]
    center: np.ndarray
    scale: np.ndarray
    weight_coef: np.ndarray
    mean_coef: np.ndarray
    tau: float
    los_scale: float
    los_spread: float = 0.0
    one_sided: bool = True

    # ------------------------------------------------------------------ construction

    @classmethod
    def start(
        cls,
        r: np.ndarray,
        sigma: np.ndarray,
        x: np.ndarray | None,
        names: list[str] | tuple[str, ...] = (),
        *,
        weight: float = 0.2,
        one_sided: bool = True,
    ) -> NlosMixture:
        """A first model from residuals ``r`` [m] and a-priori sigmas ``sigma`` [m]: constant weight
        ``weight``, the LOS scale of the residuals' core, the NLOS mean and spread of the rows beyond
        3 LOS sigmas (those above, when one-sided).

        ``x`` (N, P) are the predictors (:func:`predictors`), None for an unconditioned model.
        """
        p = 0 if x is None else x.shape[1]
        center = np.zeros(p) if x is None else x.mean(axis=0)
        scale = np.ones(p) if x is None else np.where(x.std(axis=0) > 0, x.std(axis=0), 1.0)
        # the LOS scale from the core of the residuals (their median absolute value, a normal's 0.674
        # sigma): started at 1, a LOS component narrower than the data's core leaves most LOS rows to
        # the NLOS component, and EM stays in that split
        k = float(np.clip(np.median(np.abs(r / sigma)) / 0.6745, *_K_BOUNDS))
        far = r > 3.0 * k * sigma if one_sided else np.abs(r) > 3.0 * k * sigma
        tail = r[far] if far.sum() >= 3 else r
        mean = float(np.median(tail))
        spread = float(np.std(tail)) if len(tail) > 1 else _TAU_FLOOR_M
        return cls(
            names=tuple(names) if x is not None else (),
            center=center,
            scale=scale,
            weight_coef=np.r_[np.log(weight / (1.0 - weight)), np.zeros(p)],
            mean_coef=np.r_[max(mean, 0.0) if one_sided else mean, np.zeros(p)],
            tau=max(spread, _TAU_FLOOR_M),
            los_scale=k,
            one_sided=one_sided,
        )

    # ------------------------------------------------------------------ the model at rows

    def _design(self, x: np.ndarray | None, n: int) -> np.ndarray:
        if not self.names or x is None:
            return np.ones((n, 1))
        return np.c_[np.ones(n), (x - self.center) / self.scale]

    def weight(self, x: np.ndarray | None, n: int) -> np.ndarray:
        """Prior NLOS weight pi of each of ``n`` rows [-]."""
        return _sigmoid(self._design(x, n) @ self.weight_coef)

    def mean(self, x: np.ndarray | None, n: int) -> np.ndarray:
        """NLOS mean delay mu of each of ``n`` rows [m] (>= 0 when one-sided)."""
        mu = self._design(x, n) @ self.mean_coef
        return np.maximum(mu, 0.0) if self.one_sided else mu

    def variances(self, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """LOS and NLOS variances [m^2] of rows with a-priori sigmas ``sigma`` [m]: ``(k s)^2 + t^2`` and
        that plus ``tau^2``."""
        los = (self.los_scale * sigma) ** 2 + self.los_spread**2
        return los, los + self.tau**2

    def responsibility(self, r: np.ndarray, sigma: np.ndarray, x: np.ndarray | None) -> np.ndarray:
        """E-step: the posterior probability that each row is NLOS given its residual ``r`` [m]."""
        n = len(r)
        var_l, var_n = self.variances(sigma)
        logit = self._design(x, n) @ self.weight_coef
        log_ratio = _log_normal(r, self.mean(x, n), var_n) - _log_normal(r, 0.0, var_l)
        return _sigmoid(logit + log_ratio)

    def code_noise(
        self, r: np.ndarray, sigma: np.ndarray, x: np.ndarray | None, assignment: Assignment = Assignment.max
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per-row code sigma [m], code offset [m] (the mean subtracted from the measurement) and the
        NLOS responsibility, for residuals ``r`` [m] at the current solution (module notes)."""
        n = len(r)
        g = self.responsibility(r, sigma, x)
        var_l, var_n = self.variances(sigma)
        mu = self.mean(x, n)
        if Assignment(assignment) == Assignment.max:
            nlos = g > 0.5
            return np.sqrt(np.where(nlos, var_n, var_l)), np.where(nlos, mu, 0.0), g
        precision = (1.0 - g) / var_l + g / var_n
        return 1.0 / np.sqrt(precision), g * mu / var_n / precision, g

    # ------------------------------------------------------------------ learning

    def fit(
        self,
        r: np.ndarray,
        sigma: np.ndarray,
        x: np.ndarray | None,
        *,
        iterations: int = 5,
        learn_los_scale: bool = True,
    ) -> NlosMixture:
        """``iterations`` EM iterations from this model on residuals ``r`` [m] with a-priori sigmas
        ``sigma`` [m] and predictors ``x``; returns the new model (this one is unchanged)."""
        model = self
        design = self._design(x, len(r))
        for _ in range(iterations):
            g = np.clip(model.responsibility(r, sigma, x), _EPS, 1.0 - _EPS)
            model = model._m_step(r, sigma, design, g, learn_los_scale)
        return model

    def _m_step(
        self, r: np.ndarray, sigma: np.ndarray, design: np.ndarray, g: np.ndarray, learn_los_scale: bool
    ) -> NlosMixture:
        los = 1.0 - g
        k, t = self.los_scale, self.los_spread
        if learn_los_scale:
            k = _scale_search(r, sigma, t, los)
            t = _spread_search(r, (k * sigma) ** 2, los, floor=_LOS_SPREAD_FLOOR_M)
        var_l = (k * sigma) ** 2 + t**2
        # mean and spread of the NLOS rows' likelihood, heteroscedastic (each row its own variance)
        mean_coef, tau = self.mean_coef, self.tau
        for _ in range(2):  # alternate the two conditional maxima (each exact given the other)
            mean_coef = _weighted_line(design, r, g / (var_l + tau**2), falling=self.one_sided)
            mu = design @ mean_coef
            if self.one_sided:
                mu = np.maximum(mu, 0.0)
            tau = _spread_search(r - mu, var_l, g, floor=_TAU_FLOOR_M)
        weight_coef = _logistic_fit(design, g, self.weight_coef, falling=self.one_sided)
        if self.one_sided and self.names and not np.any(weight_coef[1:] < 0.0):
            # no predictor says which rows are late: a late mode is then the clock's and the height's
            # to take (a shift of the rows it picks, not a reflection), so the component stays at mean 0
            mean_coef = np.zeros_like(mean_coef)
        return replace(self, weight_coef=weight_coef, mean_coef=mean_coef, tau=tau, los_scale=k, los_spread=t)

    # ------------------------------------------------------------------ reporting

    def parameters(self) -> dict[str, Any]:
        """JSON record of the learned parameters."""
        return {
            "predictors": list(self.names),
            "los_scale": self.los_scale,
            "los_spread_m": self.los_spread,
            "nlos_tau_m": self.tau,
            "weight_coef": self.weight_coef.tolist(),
            "mean_coef_m": self.mean_coef.tolist(),
        }

    def summary(self, r: np.ndarray, sigma: np.ndarray, x: np.ndarray | None) -> dict[str, Any]:
        """JSON record: the parameters, and per predictor bin the mean prior weight, mean NLOS delay
        and the share of rows the model calls NLOS (responsibility > 0.5)."""
        n = len(r)
        record = self.parameters()
        record["nlos_weight_mean"] = float(self.weight(x, n).mean())
        record["nlos_share"] = float(np.mean(self.responsibility(r, sigma, x) > 0.5))
        if x is None or not self.names:
            record["nlos_mean_m"] = float(self.mean(x, n).mean())
            return record
        pi, mu, nlos = self.weight(x, n), self.mean(x, n), self.responsibility(r, sigma, x) > 0.5
        record.update(quartile_table(self.names, x, pi, mu, nlos))
        return record


def quartile_table(
    names: tuple[str, ...] | list[str], x: np.ndarray, weight: np.ndarray, mean_m: np.ndarray, nlos: np.ndarray
) -> dict[str, list[dict[str, Any]]]:
    """Per predictor (``by_<name>``), its quartile bins of the rows with the mean NLOS prior weight, the
    mean NLOS delay [m] (of the finite values; None without any: JSON has no NaN) and the share of rows
    called NLOS.

    Parameters
    ----------
    names : sequence of str
        Predictor names, one per column of ``x``.
    x : ndarray, shape (n, len(names))
        Predictor values of the rows.
    weight, mean_m : ndarray, shape (n,)
        Each row's NLOS prior weight and NLOS mean [m].
    nlos : ndarray of bool, shape (n,)
        Whether the row was called NLOS.
    """
    out: dict[str, list[dict[str, Any]]] = {}
    for j, name in enumerate(names):
        edges = np.unique(np.quantile(x[:, j], np.linspace(0.0, 1.0, 5)))
        bins = np.clip(np.searchsorted(edges, x[:, j], side="right") - 1, 0, len(edges) - 2)
        out[f"by_{name}"] = [
            {
                "low": float(edges[b]),
                "high": float(edges[b + 1]),
                "rows": int(np.sum(bins == b)),
                "nlos_weight": _finite_mean(weight[bins == b]),
                "nlos_mean_m": _finite_mean(mean_m[bins == b]),
                "nlos_share": float(nlos[bins == b].mean()),
            }
            for b in range(len(edges) - 1)
            if np.any(bins == b)
        ]
    return out


def _finite_mean(values: np.ndarray) -> float | None:
    """Mean of the finite values, None without any."""
    finite = values[np.isfinite(values)]
    return float(finite.mean()) if len(finite) else None


def _weighted_line(design: np.ndarray, y: np.ndarray, w: np.ndarray, *, falling: bool) -> np.ndarray:
    """Weighted least-squares coefficients of ``y`` on the columns of ``design`` (the first the
    constant; a tiny ridge on the slopes keeps a constant predictor harmless). ``falling``: slopes
    that come out positive are set to 0 and the others refitted (see :func:`_logistic_fit`)."""
    free = np.ones(design.shape[1], bool)
    coef = np.zeros(design.shape[1])
    for _ in range(design.shape[1]):
        a = design[:, free].T @ (w[:, None] * design[:, free])
        ridge = np.full(int(free.sum()), 1e-9 * np.trace(a))
        ridge[0] = 0.0
        coef[:] = 0.0
        coef[free] = np.linalg.solve(a + np.diag(ridge), design[:, free].T @ (w * y))
        rising = falling & (coef > 0.0) & (np.arange(len(coef)) > 0)
        if not rising.any():
            break
        free &= ~rising
    return coef


def _spread_search(d: np.ndarray, var0: np.ndarray, g: np.ndarray, *, floor: float) -> float:
    """The spread t [m], at least ``floor``, maximising ``sum g log N(d; 0, var0 + t^2)`` (bounded 1-D search)."""

    def cost(log_t: float) -> float:
        var = var0 + np.exp(2.0 * log_t)
        return float(np.sum(g * (np.log(var) + d**2 / var)))

    best = minimize_scalar(cost, bounds=(np.log(floor), np.log(_TAU_CEILING_M)), method="bounded")
    return float(np.exp(best.x))


def _scale_search(r: np.ndarray, sigma: np.ndarray, spread: float, g: np.ndarray) -> float:
    """The LOS scale k within :data:`_K_BOUNDS` maximising ``sum g log N(r; 0, (k sigma)^2 + spread^2)``."""

    def cost(k: float) -> float:
        var = (k * sigma) ** 2 + spread**2
        return float(np.sum(g * (np.log(var) + r**2 / var)))

    return float(minimize_scalar(cost, bounds=_K_BOUNDS, method="bounded").x)


def _logistic_fit(
    design: np.ndarray, target: np.ndarray, start: np.ndarray, *, falling: bool, steps: int = 5
) -> np.ndarray:
    """Logistic regression of soft labels ``target`` on ``design`` by Newton steps from ``start``,
    with :data:`_RIDGE` on the slopes (per row, so it does not grow with the data).

    ``falling``: a slope may not be positive (a NLOS weight that rose with C/N0 or elevation would be
    no reflection model but a second LOS component, e.g. where code noise the a-priori sigmas miss
    looks like a late mode); a positive one is held at 0 and the others refitted.
    """
    n = len(target)
    ridge = np.full(design.shape[1], _RIDGE * n)
    ridge[0] = 0.0
    w = np.where(falling & (np.arange(len(start)) > 0), np.minimum(start, 0.0), start)
    free = np.ones(len(w), bool)
    for _ in range(steps):
        p = _sigmoid(design @ w)
        grad = (design.T @ (target - p) - ridge * w)[free]
        hess = design[:, free].T @ ((p * (1.0 - p))[:, None] * design[:, free]) + np.diag(ridge[free])
        w[free] = w[free] + np.linalg.solve(hess + 1e-9 * np.eye(int(free.sum())), grad)
        rising = falling & (w > 0.0) & (np.arange(len(w)) > 0)
        w[rising] = 0.0
        free &= ~rising
    return w

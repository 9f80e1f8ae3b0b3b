"""The published claims of the source papers, checked against a run's results.

Each :class:`Claim` names the sweep whose rows it reads, computes one number
from them (``measured``) with a bootstrap confidence interval over seeds, and
decides ``holds`` by a stated rule. Statistics are paired over seeds: every
estimator saw byte-identical data for a given (scenario, seed). A claim whose
rows are missing is ``not measured`` -- never ``holds``. Estimator settings
(window length, prior scale) come from the structured ``overrides`` column
(:mod:`simbench.analysis.variants`).

A claim is evaluated once per *world*: each scenario preset its sweep ran on
(the ``scenario`` column), on that world's rows alone, so the thesis studies
run on ``urban``, ``urban_deep`` and ``morgantown1`` give one verdict per world
(:func:`claims_table` rows, :func:`claims_by_world` one column per world).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

from simbench.analysis.variants import config_defaults, is_default, override_value

#: Columns of ``claims.csv``.
CLAIM_COLUMNS = [
    "claim_id",
    "world",
    "source",
    "statement",
    "metric",
    "measured",
    "published",
    "rule",
    "holds",
    "ci_low",
    "ci_high",
    "n_seeds",
    "vacuous",
    "note",
]

#: The three verdicts of a measured claim (``holds`` column); ``not measured`` when it was not.
HOLDS, DOES_NOT_HOLD, INCONCLUSIVE = "holds", "does not hold", "inconclusive"
NOT_MEASURED = "not measured"

BOOTSTRAP_RESAMPLES = 2000
CONFIDENCE = 0.95
#: The result column that names a world: the scenario preset a sweep ran on.
WORLD = "scenario"
#: Cell of :func:`claims_by_world` for a claim whose sweep did not run on that world.
NOT_RUN = "—"

#: Convergence window of the Ch.4 tables (Table 4.4.5: the first 15 minutes) [s].
CONVERGENCE_S = 900.0


@dataclass(frozen=True)
class Outcome:
    """One claim measured on one world.

    ``holds`` is the verdict of the rule on ``measured``; ``inconclusive`` overrides it when the
    95 % CI straddles the rule's threshold (the seeds do not decide), and ``vacuous`` marks a
    pass that says nothing (e.g. 0 adaptations against 6: nothing was adapted at all).
    """

    measured: float
    holds: bool
    ci_low: float = np.nan
    ci_high: float = np.nan
    n_seeds: int = 0
    note: str = ""
    inconclusive: bool = False
    vacuous: bool = False

    @property
    def verdict(self) -> str:
        """:data:`HOLDS`, :data:`DOES_NOT_HOLD` or :data:`INCONCLUSIVE`."""
        return INCONCLUSIVE if self.inconclusive else HOLDS if self.holds else DOES_NOT_HOLD


#: (summary, epochs, diagnostics by estimator) -> outcome, or None when not measured
Evaluate = Callable[[pd.DataFrame, pd.DataFrame, dict], Outcome | None]


@dataclass(frozen=True)
class Claim:
    claim_id: str
    source: str
    statement: str
    metric: str
    published: str
    #: the verdict's rule on ``measured``, beside the published number
    rule: str
    evaluate: Evaluate
    #: the sweep (conf/sweep/<name>.yaml) whose rows measure it
    sweep: str


# --------------------------------------------------------------------------- statistics helpers


def per_seed(
    summary: pd.DataFrame,
    sweep: str,
    estimators: list[str],
    column: str,
    receiver: str | None = None,
    default_only: bool = True,
) -> pd.DataFrame | None:
    """Seeds x estimators table of one summary column, only seeds where every estimator is ``ok``.

    ``default_only`` keeps the rows whose estimator ran with its default settings (no overrides).
    Returns None when any estimator has no usable row (the claim is then not measured).
    """
    rows = summary[(summary["sweep"] == sweep) & summary["estimator"].isin(estimators)]
    if receiver is not None:
        rows = rows[rows["receiver"] == receiver]
    if default_only:
        rows = rows[is_default(rows["overrides"])]
    rows = rows[rows["status"] == "ok"]
    if rows.empty:
        return None
    table = rows.pivot_table(index=["scenario", "seed"], columns="estimator", values=column, aggfunc="first")
    table = table.dropna()
    if table.empty or set(estimators) - set(table.columns):
        return None
    return table[estimators]


def ratio_of_means(table: pd.DataFrame, a: str, b: str | list[str]) -> tuple[float, float, float]:
    """mean(a) / mean(b) over seeds (b: the per-seed minimum over several), with a paired bootstrap CI."""
    num = table[a].to_numpy()
    den = table[b].min(axis=1).to_numpy() if isinstance(b, list) else table[b].to_numpy()
    value = float(num.mean() / den.mean())
    if len(num) < 3:
        return value, np.nan, np.nan
    res = stats.bootstrap(
        (num, den),
        lambda x, y, axis=-1: x.mean(axis=axis) / y.mean(axis=axis),
        paired=True,
        n_resamples=BOOTSTRAP_RESAMPLES,
        confidence_level=CONFIDENCE,
        method="percentile",
        random_state=np.random.default_rng(0),
    )
    return value, float(res.confidence_interval.low), float(res.confidence_interval.high)


def _below(table: pd.DataFrame | None, a: str, others: list[str]) -> Outcome | None:
    """Claim 'a is below each of others': ratio of a to the best other < 1 with the CI below 1."""
    if table is None:
        return None
    value, lo, hi = ratio_of_means(table, a, others)
    significant = np.isfinite(hi) and hi < 1.0
    return Outcome(
        value,
        bool(value < 1.0 and (significant or not np.isfinite(hi))),
        lo,
        hi,
        len(table),
        "ratio of mean per-seed medians to the best competitor; holds if < 1 with the 95 % CI below 1",
        inconclusive=straddles(lo, hi, 1.0),
    )


def _lowest_median(sweep: str, best: str, others: list[str], receiver: str | None = None) -> Evaluate:
    """Claim 'best has a lower median horizontal error than each of others' on ``sweep``'s rows (of one
    ``receiver`` quality, or all): :func:`_below` on the :func:`per_seed` table."""
    return lambda s, e, d: _below(per_seed(s, sweep, [best, *others], "horizontal_median", receiver), best, others)


def straddles(ci_low: float, ci_high: float, threshold: float) -> bool:
    """True when a finite CI holds ``threshold`` strictly inside: the seeds decide neither way."""
    return bool(np.isfinite(ci_low) and np.isfinite(ci_high) and ci_low < threshold < ci_high)


def _spread_within(table: pd.DataFrame | None, tolerance: float) -> Outcome | None:
    """Claim 'all within tolerance': (max - min) / min of the mean per-seed medians."""
    if table is None:
        return None
    means = table.mean(axis=0)
    spread = float(means.max() / means.min() - 1.0)
    return Outcome(
        spread,
        spread <= tolerance,
        n_seeds=len(table),
        note=f"relative spread of mean per-seed medians; holds if <= {tolerance:.0%}",
    )


def _comparable_medians(sweep: str, names: list[str], receiver: str, tolerance: float) -> Evaluate:
    """Claim 'names' median horizontal errors lie within ``tolerance`` of each other' on ``sweep``'s rows
    of one ``receiver`` quality: :func:`_spread_within` on the :func:`per_seed` table."""
    return lambda s, e, d: _spread_within(per_seed(s, sweep, names, "horizontal_median", receiver), tolerance)


# --------------------------------------------------------------------------- the claims


def _ch4_convergence(summary: pd.DataFrame, epochs: pd.DataFrame, diagnostics: dict) -> Outcome | None:
    rows = epochs[
        (epochs["sweep"] == "ch4_convergence")
        & (epochs["t"] < CONVERGENCE_S)
        & epochs["estimator"].isin(["isam2_ppp", "ekf_ppp"])
    ]
    if rows.empty or rows["estimator"].nunique() < 2:
        return None
    table = rows.groupby(["seed", "estimator"])["error_3d"].mean().unstack().dropna()
    value, lo, hi = ratio_of_means(table, "isam2_ppp", "ekf_ppp")
    return Outcome(
        value,
        bool(np.isfinite(hi) and hi < 1.0),
        lo,
        hi,
        len(table),
        "mean 3-D error in the first 15 min, iSAM2 / EKF; holds if the 95 % CI is below 1",
        inconclusive=straddles(lo, hi, 1.0),
    )


def _ch4_medians(summary: pd.DataFrame, epochs: pd.DataFrame, diagnostics: dict) -> Outcome | None:
    # the sweep runs both in ionosphere-free mode: its one variant, not the default's
    table = per_seed(summary, "ch4_convergence", ["isam2_ppp", "ekf_ppp"], "error_3d_median", default_only=False)
    if table is None:
        return None
    value, lo, hi = ratio_of_means(table, "isam2_ppp", "ekf_ppp")
    return Outcome(
        value,
        bool(0.8 <= value <= 1.25),
        lo,
        hi,
        len(table),
        "median 3-D error over all epochs, iSAM2 / EKF; holds if within 0.8..1.25",
        inconclusive=straddles(lo, hi, 0.8) or straddles(lo, hi, 1.25),
    )


def _ch5_sensitivity(summary: pd.DataFrame, epochs: pd.DataFrame, diagnostics: dict) -> Outcome | None:
    names = ["bce", "l2", "dcs", "mm"]
    rows = summary[
        (summary["sweep"] == "ch5_sensitivity") & summary["estimator"].isin(names) & (summary["status"] == "ok")
    ]
    if rows.empty or set(names) - set(rows["estimator"]):
        return None
    means = rows.groupby(["estimator", "overrides"])["horizontal_median"].mean()
    spread = {name: float(means[name].max() / means[name].min()) for name in names}
    others = min(v for k, v in spread.items() if k != "bce")
    return Outcome(
        spread["bce"] / others,
        spread["bce"] <= others,
        n_seeds=int(rows["seed"].nunique()),
        note="max/min of mean median over prior scales: BCE's spread / the least-sensitive "
        "competitor's; holds if <= 1 (" + ", ".join(f"{k} {v:.2f}" for k, v in spread.items()) + ")",
    )


def _ch5_runtime(summary: pd.DataFrame, epochs: pd.DataFrame, diagnostics: dict) -> Outcome | None:
    table = per_seed(summary, "ch5_bce", ["bce", "l2", "dcs", "mm"], "time_per_obs_s", receiver="low")
    if table is None:
        return None
    means = table.mean(axis=0)
    return Outcome(
        float(means["bce"] / means.drop("bce").max()),
        bool(means.idxmax() == "bce"),
        n_seeds=len(table),
        note="BCE run time per observation / the slowest other; "
        "holds if BCE is the slowest (" + ", ".join(f"{k} {v * 1e6:.1f} us" for k, v in means.items()) + ")",
    )


def _crt_window(summary: pd.DataFrame, epochs: pd.DataFrame, diagnostics: dict) -> Outcome | None:
    rows = summary[
        (summary["sweep"] == "crt_window") & (summary["estimator"] == "crt_lss") & (summary["status"] == "ok")
    ]
    if rows.empty:
        return None
    window = override_value(rows["overrides"], "window", config_defaults("crt_lss")["window"])
    per_l = rows.assign(L=window).groupby("L")["error_3d_p95"].mean()
    if len(per_l) < 3:
        return None
    rho = float(stats.spearmanr(per_l.index, per_l.to_numpy()).statistic)
    return Outcome(
        rho,
        rho < 0.0,
        n_seeds=int(rows["seed"].nunique()),
        note="Spearman correlation of window length L with mean p95 3-D error; holds if < 0 ("
        + ", ".join(f"L={k}: {v:.2f} m" for k, v in per_l.items())
        + ")",
    )


# --------------------------------------------------------------------------- the claims of a quality study


#: Rule of a claim that one estimator's median is below the others' (:func:`_below`).
LOWER_RULE = "< 1, 95 % CI < 1"
#: How far apart the medians of comparable estimators may lie (relative spread).
COMPARABLE_TOLERANCE = 0.15


@dataclass(frozen=True)
class QualityStudy:
    """A thesis study of a proposed estimator against its competitors on a low- and a high-quality receiver.

    Ch.5 (BCE) and Ch.7 (ICE) each publish two tables on three data collects: the median horizontal
    errors on the low-quality receiver, where the proposed estimator is the lowest, and on the
    high-quality one, where all are comparable. :func:`_study_claims` makes the two claims of a study.
    """

    #: the thesis tables of the low- and the high-quality receiver (``"5.3.3"``: Ch.5)
    tables: tuple[str, str]
    #: the proposed estimator first, then its competitors, each with its label in the statements
    labels: dict[str, str]
    #: per collect, the published median of the proposed estimator and of its best competitor [m]
    low: tuple[tuple[float, float], ...]
    #: per collect, the largest and the smallest published median [m]
    high: tuple[tuple[float, float], ...]


def _published(template: str, pairs: tuple[tuple[float, float], ...], measure: Callable[[float, float], float]) -> str:
    """The published numbers of a claim, e.g. ``6.70/9.13 = 0.73, ... (collects 1-3)``: each collect's
    pair and ``measure`` of it, formatted by ``template``."""
    shown = ", ".join(template.format(a, b, measure(a, b)) for a, b in pairs)
    return f"{shown} (collects 1-{len(pairs)})"


def _and(labels: list[str]) -> str:
    return ", ".join(labels[:-1]) + " and " + labels[-1]


def _study_claims(study: QualityStudy) -> list[Claim]:
    """The low-quality claim (``ch<N>_<proposed>_low``: the proposed estimator's median below each
    competitor's) and the high-quality claim (``ch<N>_high_comparable``: all medians within
    :data:`COMPARABLE_TOLERANCE`) of ``study``, measured on the sweep ``ch<N>_<proposed>``."""
    chapter = study.tables[0].split(".")[0]
    (proposed, label), *competitors = study.labels.items()
    others, other_labels = [name for name, _ in competitors], [lab for _, lab in competitors]
    sweep = f"ch{chapter}_{proposed}"
    low = Claim(
        f"{sweep}_low",
        f"Watson 2019, Ch.{chapter} Table {study.tables[0]}",
        f"on low-quality data {label} has a lower median horizontal error than {_and(other_labels)}",
        f"median horizontal error, {label} / best of {', '.join(other_labels)}",
        _published("{:.2f}/{:.2f} = {:.2f}", study.low, lambda a, b: a / b),
        LOWER_RULE,
        _lowest_median(sweep, proposed, others, "low"),
        sweep=sweep,
    )
    tolerance = COMPARABLE_TOLERANCE
    all_labels = _and([*other_labels, label])
    high = Claim(
        f"ch{chapter}_high_comparable",
        f"Watson 2019, Ch.{chapter} Table {study.tables[1]}",
        f"on high-quality data {all_labels} perform comparably (within about {100 * tolerance:.0f} %)",
        "relative spread of median horizontal error",
        _published("{:.2f}/{:.2f} - 1 = {:.2f}", study.high, lambda a, b: a / b - 1),
        f"<= {tolerance}",
        _comparable_medians(sweep, list(study.labels), "high", tolerance),
        sweep=sweep,
    )
    return [low, high]


#: Ch.5: BCE against batch L2, DCS and MM (Tables 5.3.3-5.3.4).
BCE_STUDY = QualityStudy(
    tables=("5.3.3", "5.3.4"),
    labels={"bce": "BCE", "l2": "L2", "dcs": "DCS", "mm": "MM"},
    low=((6.70, 9.13), (3.58, 4.11), (7.31, 8.02)),
    high=((0.75, 0.67), (0.81, 0.42), (1.44, 1.20)),
)
#: Ch.7: ICE against incremental (iSAM2) L2, DCS and MM (Tables 7.3.1-7.3.2).
ICE_STUDY = QualityStudy(
    tables=("7.3.1", "7.3.2"),
    labels={"ice": "ICE", "isam2_ppp": "iSAM2 L2", "isam2_dcs": "iSAM2 DCS", "isam2_mm": "iSAM2 MM"},
    low=((0.56, 0.64), (0.93, 1.94), (1.48, 2.82)),
    high=((0.37, 0.35), (0.84, 0.81), (1.00, 0.89)),
)


CLAIMS: list[Claim] = [
    Claim(
        "ch4_convergence",
        "Watson 2019, Ch.4 Table 4.4.5",
        "iSAM2-PPP converges faster than EKF-PPP with identical stochastic models: far lower mean error "
        "in the first 15 minutes",
        "mean 3-D error t<15 min, iSAM2/EKF",
        "188.79/665.35 cm = 0.28",
        "95 % CI < 1",
        _ch4_convergence,
        sweep="ch4_convergence",
    ),
    Claim(
        "ch4_overall_median",
        "Watson 2019, Ch.4 Table 4.4.4",
        "over all epochs the medians of iSAM2-PPP and EKF-PPP are similar",
        "median 3-D error, iSAM2/EKF",
        "40.01/39.7 cm = 1.01",
        "0.8 to 1.25",
        _ch4_medians,
        sweep="ch4_convergence",
    ),
    *_study_claims(BCE_STUDY),
    Claim(
        "ch5_sensitivity",
        "Watson 2019, Ch.5 Fig. 5.3.7",
        "BCE is the least sensitive to the a priori covariance scale s in {0.1, 0.3, 1, 3, 10, 100}",
        "spread of median over s: BCE / least-sensitive other",
        "no number (figure only)",
        "<= 1",
        _ch5_sensitivity,
        sweep="ch5_sensitivity",
    ),
    Claim(
        "ch5_runtime",
        "Watson 2019, Ch.5 Fig. 5.3.8",
        "BCE has the largest run time of the batch estimators",
        "run time per observation, BCE / slowest other",
        "no number (figure only)",
        "> 1 (BCE the slowest)",
        _ch5_runtime,
        sweep="ch5_bce",
    ),
    Claim(
        "ch6_bce_ad",
        "Watson 2019, Ch.6 Tables 6.3.1",
        "BCE-AD is at or below BCE when errors correlate with C/N0 or elevation",
        "median horizontal error, BCE-AD / BCE",
        _published("{:.2f}/{:.2f} = {:.2f}", ((2.14, 6.70), (3.58, 3.58), (3.25, 7.31)), lambda a, b: a / b),
        LOWER_RULE,
        _lowest_median("ch6_bce_ad", "bce_ad", ["bce"]),
        sweep="ch6_bce_ad",
    ),
    *_study_claims(ICE_STUDY),
    Claim(
        "ch7_adaptations",
        "Watson 2019, Ch.7 Sec. 7.3",
        "merging by statistical tests needs fewer model adaptations than adapting every T_c outliers",
        "ICE adaptations / naive adaptations",
        "no number (text only)",
        "< 1 (vacuous with no adaptation)",
        lambda s, e, d: adaptation_outcome(d),
        sweep="ch7_ice",
    ),
    Claim(
        "crt_accuracy_order",
        "Roysdon & Farrell 2019, Fig. 2",
        "accuracy improves from EKF to IEKF to CRT-LSS",
        "p95 3-D error, CRT-LSS / EKF (IEKF between)",
        "no number (figure only)",
        "ordered, 95 % CI < 1",
        lambda s, e, d: _ordered(per_seed(s, "crt_window", ["crt_lss", "iekf_ins", "ekf_ins"], "error_3d_p95")),
        sweep="crt_window",
    ),
    Claim(
        "crt_window",
        "Roysdon & Farrell 2019, Fig. 2",
        "CRT-LSS accuracy improves with the window length L",
        "Spearman(L, p95 3-D error)",
        "no number (figure only)",
        "< 0",
        _crt_window,
        sweep="crt_window",
    ),
]


def _ordered(table: pd.DataFrame | None) -> Outcome | None:
    """crt_lss < iekf_ins < ekf_ins in mean per-seed p95 error, CRT-LSS / EKF significantly below 1."""
    if table is None:
        return None
    means = table.mean(axis=0)
    value, lo, hi = ratio_of_means(table, "crt_lss", "ekf_ins")
    ordered = bool(means["crt_lss"] < means["iekf_ins"] < means["ekf_ins"])
    significant = not np.isfinite(hi) or hi < 1.0
    return Outcome(
        value,
        ordered and significant,
        lo,
        hi,
        len(table),
        inconclusive=ordered and straddles(lo, hi, 1.0),
        note="holds if ordered and the 95 % CI of CRT-LSS / EKF is below 1; mean per-seed p95 3-D error: "
        + ", ".join(f"{k} {v:.2f} m" for k, v in means.items()),
    )


def adaptation_outcome(diagnostics: dict[str, list[dict]]) -> Outcome | None:
    """ICE adaptations vs the naive count, summed over the ch7_ice jobs' diagnostics."""
    jobs = [d for d in diagnostics.get("ice", []) if d["job"].get("sweep") == "ch7_ice"]
    counts = [(d["diagnostics"].get("n_adaptations"), d["diagnostics"].get("naive_adaptations")) for d in jobs]
    counts = [(a, b) for a, b in counts if a is not None and b]
    if not counts:
        return None
    ice, naive = map(float, np.sum(counts, axis=0))
    # no adaptation at all is fewer than any naive count, but says nothing about merging by tests
    vacuous = ice == 0
    return Outcome(
        ice / naive,
        ice < naive,
        n_seeds=len(counts),
        note=f"{ice:.0f} adaptations vs {naive:.0f} naive over {len(counts)} jobs"
        + ("; vacuous: ICE never adapted, so there was nothing to merge" if vacuous else ""),
        vacuous=vacuous,
    )


def claims_table(
    summary: pd.DataFrame, epochs: pd.DataFrame, diagnostics: dict[str, list[dict]] | None = None
) -> pd.DataFrame:
    """Evaluate every claim on every world its sweep ran on; rows in :data:`CLAIM_COLUMNS` order.

    A claim whose sweep ran on no world has one ``not measured`` row with an empty ``world``.
    Rows are in :data:`CLAIMS` order, the worlds of one claim sorted by name.
    """
    rows = []
    for claim in CLAIMS:
        base = {
            "claim_id": claim.claim_id,
            "source": claim.source,
            "statement": claim.statement,
            "metric": claim.metric,
            "published": claim.published,
            "rule": claim.rule,
        }
        worlds = claim_worlds(summary, claim.sweep)
        if not worlds:
            rows.append({**base, "world": "", **_not_measured(f"its sweep {claim.sweep} was not run")})
        for world in worlds:
            outcome = claim.evaluate(
                in_world(summary, world), in_world(epochs, world), _diagnostics_in_world(diagnostics or {}, world)
            )
            if outcome is None:
                rows.append(
                    {
                        **base,
                        "world": world,
                        **_not_measured(f"its sweep {claim.sweep} had no ok rows for this claim here"),
                    }
                )
            else:
                rows.append(
                    {
                        **base,
                        "world": world,
                        "measured": outcome.measured,
                        "holds": outcome.verdict,
                        "ci_low": outcome.ci_low,
                        "ci_high": outcome.ci_high,
                        "n_seeds": outcome.n_seeds,
                        "vacuous": outcome.vacuous,
                        "note": outcome.note,
                    }
                )
    return pd.DataFrame(rows, columns=CLAIM_COLUMNS)


def claim_worlds(summary: pd.DataFrame, sweep: str) -> list[str]:
    """The worlds (scenario presets) that ``sweep`` has result rows on, sorted."""
    if summary.empty:
        return []
    return sorted(summary.loc[summary["sweep"] == sweep, WORLD].dropna().astype(str).unique())


def in_world(frame: pd.DataFrame, world: str) -> pd.DataFrame:
    """The rows of ``frame`` on ``world``; a frame without a :data:`WORLD` column is one world (all rows)."""
    return frame[frame[WORLD] == world] if WORLD in frame.columns else frame


def _diagnostics_in_world(diagnostics: dict[str, list[dict]], world: str) -> dict[str, list[dict]]:
    # a diagnostics record whose job row is missing (no summary file) is one world, as in in_world
    return {name: [d for d in jobs if d["job"].get(WORLD, world) == world] for name, jobs in diagnostics.items()}


def _not_measured(note: str) -> dict[str, Any]:
    return {
        "measured": np.nan,
        "holds": NOT_MEASURED,
        "ci_low": np.nan,
        "ci_high": np.nan,
        "n_seeds": 0,
        "vacuous": False,
        "note": note,
    }


def claims_by_world(claims: pd.DataFrame) -> pd.DataFrame:
    """One row per claim, one column per world: ``measured`` and the verdict in one cell.

    Parameters
    ----------
    claims : pandas.DataFrame
        :func:`claims_table` (or ``claims.csv``; one written before the ``rule`` column has none).

    Returns
    -------
    pandas.DataFrame
        Columns ``claim_id``, ``published``, ``rule``, then one per world (sorted by name) with
        cells like ``0.84 holds`` / ``1.07 [0.91, 1.23] inconclusive``, ``not measured``,
        or :data:`NOT_RUN` where the claim's sweep did not run on that world. No world
        columns when no claim's sweep ran.
    """
    claims = claims.assign(
        rule=claims["rule"] if "rule" in claims else "",
        vacuous=claims["vacuous"].fillna(False).astype(bool) if "vacuous" in claims else False,
    )
    measured = claims[claims["world"].fillna("") != ""]
    worlds = sorted(measured["world"].astype(str).unique())
    cells = {(r.claim_id, r.world): _cell(r) for r in measured.itertuples()}
    order = list(dict.fromkeys(claims["claim_id"]))
    first = claims.drop_duplicates("claim_id").set_index("claim_id")
    return pd.DataFrame(
        [
            {
                "claim_id": cid,
                "published": first.loc[cid, "published"],
                "rule": first.loc[cid, "rule"],
                **{w: cells.get((cid, w), NOT_RUN) for w in worlds},
            }
            for cid in order
        ],
        columns=["claim_id", "published", "rule", *worlds],
    )


def _cell(row: Any) -> str:
    """``measured [ci] verdict`` of one :func:`claims_table` row (an ``itertuples`` record)."""
    if row.holds == NOT_MEASURED:
        return row.holds
    ci = f" [{row.ci_low:.3g}, {row.ci_high:.3g}]" if np.isfinite(row.ci_low) and np.isfinite(row.ci_high) else ""
    return f"{row.measured:.3g}{ci} {row.holds}" + (" (vacuous)" if row.vacuous else "")

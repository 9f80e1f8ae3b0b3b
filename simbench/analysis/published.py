"""Published numbers the report sets our results beside (``../shared/REFERENCE.md``).

Only numbers that are compared row by row live here; claims with a verdict are
in :mod:`simbench.analysis.claims`.
"""

from __future__ import annotations

from typing import Literal

Receiver = Literal["low", "high"]
PublishedEstimator = Literal["L2", "DCS", "MM", "ICE", "BCE", "BCE-AD"]

#: Dissertation drives as scenarios of ``conf/scenario`` (morgantownN replays drive_N.xyz).
DRIVE_SCENARIOS: dict[str, int] = {"morgantown1": 1, "morgantown2": 2, "morgantown3": 3}

#: Median horizontal error [m] on the three Morgantown drives, dissertation Ch.7 tables and the ICE paper.
DRIVE_MEDIANS_M: dict[tuple[Receiver, int], dict[PublishedEstimator, float]] = {
    ("low", 1): {"L2": 2.57, "DCS": 0.64, "MM": 1.63, "ICE": 0.56, "BCE": 1.05},
    ("low", 2): {"L2": 2.48, "DCS": 2.08, "MM": 1.94, "ICE": 0.93, "BCE": 1.78},
    ("low", 3): {"L2": 4.41, "DCS": 2.82, "MM": 3.62, "ICE": 1.48, "BCE": 5.54},
    ("high", 1): {"L2": 0.37, "DCS": 0.36, "MM": 0.35, "ICE": 0.35, "BCE": 0.66},
    ("high", 2): {"L2": 0.82, "DCS": 0.81, "MM": 0.84, "ICE": 0.83, "BCE": 0.56},
    ("high", 3): {"L2": 0.96, "DCS": 0.95, "MM": 1.00, "ICE": 0.89, "BCE": 0.82},
}

#: Median horizontal error [m] on the drives with the low-quality receiver, dissertation Ch.6 Table 6.3.1
#: (BCE-AD's study; the same collects processed again, hence other L2 to BCE medians than Ch.5 and Ch.7's).
CH6_DRIVE_MEDIANS_M: dict[tuple[Receiver, int], dict[PublishedEstimator, float]] = {
    ("low", 1): {"L2": 9.84, "DCS": 10.82, "MM": 9.13, "BCE": 6.70, "BCE-AD": 2.14},
    ("low", 2): {"L2": 5.09, "DCS": 5.02, "MM": 4.11, "BCE": 3.58, "BCE-AD": 3.58},
    ("low", 3): {"L2": 10.98, "DCS": 9.88, "MM": 8.02, "BCE": 7.31, "BCE-AD": 3.25},
}

#: The published drive table each sweep is set beside; any other sweep: :data:`DRIVE_MEDIANS_M`.
DRIVE_MEDIANS_BY_SWEEP: dict[str, dict[tuple[Receiver, int], dict[PublishedEstimator, float]]] = {
    "ch6_bce_ad": CH6_DRIVE_MEDIANS_M,
}

#: Which published column each of our estimators is compared with (batch and incremental variants alike).
PUBLISHED_FAMILY: dict[str, PublishedEstimator] = {
    "l2": "L2",
    "isam2_ppp": "L2",
    "dcs": "DCS",
    "isam2_dcs": "DCS",
    "mm": "MM",
    "isam2_mm": "MM",
    "ice": "ICE",
    "bce": "BCE",
    "bce_ad": "BCE-AD",
}

#: Dissertation Table 5.3.2: zero-baseline mean 3-D error [m] of each preset's single-point solution
#: against the geodetic receiver, per collect (drive).
ZERO_BASELINE_MEAN_3D_M: dict[tuple[Receiver, int], float] = {
    ("low", 1): 16.20,
    ("low", 2): 37.44,
    ("low", 3): 29.43,
    ("high", 1): 0.59,
    ("high", 2): 18.03,
    ("high", 3): 17.48,
}

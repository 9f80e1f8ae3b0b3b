"""What the terminal shows of a result row."""

from __future__ import annotations

#: Summary columns printed after a run or a scored solution.
SHOWN = [
    "estimator",
    "variant",
    "status",
    "availability",
    "horizontal_median",
    "horizontal_mean",
    "horizontal_p95",
    "horizontal_max",
    "error_3d_median",
    "update_median_s",
    "message",
]

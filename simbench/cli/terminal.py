"""What the terminal shows: result rows, and simbench's warnings as one line each."""

from __future__ import annotations

import sys
import warnings
from typing import TextIO

from simbench.errors import SimbenchWarning

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


def one_line_warnings() -> None:
    """Print every :class:`~simbench.errors.SimbenchWarning` as ``warning: <message>`` on stderr.

    Python's default format adds the file, line and source line of the ``warn`` call, which
    points into simbench rather than at the user's input. Other warnings keep that format.
    """
    default = warnings.showwarning

    def show(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        if issubclass(category, SimbenchWarning):
            print(f"warning: {message}", file=file or sys.stderr)
        else:
            default(message, category, filename, lineno, file, line)

    warnings.showwarning = show

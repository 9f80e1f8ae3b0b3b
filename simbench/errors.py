"""The one exception type users see.

Every check of user input raises :class:`SimbenchError` with a one-line message
that names the offending field and says how to fix it; the CLI prints the
message alone instead of a traceback.
"""
from __future__ import annotations


class SimbenchError(ValueError):
    """Bad input (config value, file, estimator name) with a one-line explanation."""

    def __init__(self, field: str, problem: str, fix: str) -> None:
        self.field = field
        super().__init__(f"{field}: {problem} -- {fix}")

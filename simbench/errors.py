"""The one exception type users see, and the one warning type.

Every check of user input raises :class:`SimbenchError` with a one-line message
that names the offending field and says how to fix it; the CLI prints the
message alone instead of a traceback. Input that is used after a repair (a
dropped duplicate epoch, a system without rows) is never silent: :func:`warn`
issues a one-line :class:`SimbenchWarning` naming the field and what was done,
which the CLI prints as ``warning: ...``.
"""

from __future__ import annotations

import difflib
import traceback
import warnings
from collections.abc import Iterable


class SimbenchError(ValueError):
    """Bad input (config value, file, estimator name) with a one-line explanation."""

    def __init__(self, field: str, problem: str, fix: str) -> None:
        self.field, self.problem, self.fix = field, problem, fix
        super().__init__(f"{field}: {problem} -- {fix}")


class SimbenchWarning(UserWarning):
    """Input simbench used after a repair, or a request it could only partly meet; one line."""


def warn(field: str, problem: str, consequence: str) -> None:
    """Issue a one-line :class:`SimbenchWarning`: ``field: problem -- consequence``.

    Parameters
    ----------
    field : str
        The setting or file the warning is about, e.g. ``scenario.obs``.
    problem : str
        What was found, e.g. ``2 duplicate epochs``.
    consequence : str
        What simbench did about it, e.g. ``kept the first of each``.
    """
    warnings.warn(f"{field}: {problem} -- {consequence}", SimbenchWarning, stacklevel=2)


def require_positive(field: str, value: float, fix: str) -> None:
    """Raise a one-line :class:`SimbenchError` naming ``field`` unless ``value > 0`` (NaN fails)."""
    if not value > 0:
        raise SimbenchError(field, f"must be positive, got {value}", fix)


def require_at_least(field: str, value: float, low: float, fix: str) -> None:
    """Raise a one-line :class:`SimbenchError` naming ``field`` unless ``value >= low`` (NaN fails)."""
    if not value >= low:
        raise SimbenchError(field, f"must be at least {low}, got {value}", fix)


def require_elevation_mask(field: str, value: float, fix: str) -> None:
    """Raise a one-line :class:`SimbenchError` naming ``field`` unless ``0 <= value < 90`` degrees (NaN fails)."""
    if not 0.0 <= value < 90.0:
        raise SimbenchError(field, f"must be within [0, 90) deg, got {value}", fix)


def one_line(exc: BaseException) -> str:
    """``exc`` as one line: a :class:`SimbenchError` as it is, anything else as type, message and where it rose."""
    if isinstance(exc, SimbenchError):
        return str(exc)
    where = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
    loc = f" (at {where.filename.rsplit('/', 1)[-1]}:{where.lineno})" if where else ""
    return f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}{loc}"


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """`` (did you mean 'dcs'?)`` for the closest known name, or ``''`` when none is close."""
    close = difflib.get_close_matches(name, list(known), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""

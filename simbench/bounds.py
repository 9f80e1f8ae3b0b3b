"""Physical bounds of every number in a typed config, declared once by the field's name.

The config dataclasses carry their unit in each field's name (``_m``, ``_s``, ``_deg``,
``_sigma_m``, ``_probability``...), so one table of rules (:data:`RULES`, first match
wins; a length, duration or sigma is never negative, any number is finite) bounds every
numeric field of a scenario, receiver or source config, including
those a plug-in source adds: a NaN, a negative sigma or a multipath sigma of 1e9 m stops
at the door (:func:`check_bounds`) instead of running every estimator on a broken world.
Checks that need more than one field (acquisition above lock threshold, memory, epochs)
stay with their config's ``validate``.
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any

from simbench.errors import SimbenchError

__all__ = ["Bound", "RULES", "FINITE_ONLY", "check_bounds"]

#: Seconds in a GPS week: ``start_sow_s`` lies in ``[0, WEEK_S)``.
WEEK_S = 604_800.0


@dataclasses.dataclass(frozen=True)
class Bound:
    """A closed range ``low .. high`` (``positive``: ``low`` excluded), with why a value beyond it is wrong."""

    low: float = -math.inf
    high: float = math.inf
    positive: bool = False  #: ``low`` itself is refused (a rate, a correlation time, a length that divides)
    why: str = ""  #: said after the range, e.g. "more is not a ranging error"

    def holds(self, value: float) -> bool:
        """True when ``value`` is finite and inside the range (NaN and infinities are refused)."""
        above_low = value > self.low if self.positive else value >= self.low
        return math.isfinite(value) and above_low and value <= self.high

    def describe(self) -> str:
        if self.positive and self.low == 0 and self.high == math.inf:
            text = "must be positive and finite"
        elif self.low == -math.inf and self.high == math.inf:
            text = "must be finite"
        elif self.high == math.inf:
            text = f"must be at least {self.low:g} and finite"
        else:
            text = f"must be within {self.low:g} .. {self.high:g}"
        return f"{text} ({self.why})" if self.why else text


FINITE = Bound()
NON_NEGATIVE = Bound(low=0.0)
POSITIVE = Bound(low=0.0, positive=True)

#: (regular expression matched against the field's name, its bound); the first match wins.
RULES: tuple[tuple[str, Bound], ...] = (
    (r"lat_deg$", Bound(-90.0, 90.0, why="a latitude in degrees")),
    (r"lon_deg$", Bound(-180.0, 180.0, why="a longitude in degrees")),
    (r"(^|_)h_m$", Bound(-500.0, 10_000.0, why="an ellipsoidal height on or near the ground in metres")),
    (r"(offset|clock|bias)_(m|s)$", FINITE),  # a clock offset or bias takes either sign
    (r"^start_sow_s$", Bound(0.0, WEEK_S - 1e-9, why="GPS seconds of the week, below 604800")),
    (r"gps_week$", Bound(0.0, 9_999.0, why="a GPS week number counted from 1980, e.g. 2032 for December 2018")),
    (r"^iono_(alpha|beta)$", FINITE),  # Klobuchar coefficients take either sign
    (r"^received_power_dbw$", Bound(-200.0, -100.0, why="a GNSS signal at the antenna in dBW, about -160")),
    (r"^constant_db$", FINITE),
    (r"_dbhz$", Bound(0.0, 100.0, why="a carrier-to-noise density in dB-Hz")),
    (r"(probability|fraction)$", Bound(0.0, 1.0, why="a probability")),
    (r"sigma_m$", Bound(0.0, 1_000.0, why="more is not a ranging error; check the unit")),
    # a rate, a correlation time or a length the models divide by, or a motion that must happen
    (r"(tau_s|rate_hz|max_gap_s|speed_mps|rate_mps|accel_mps2|radius_m|length_m|segment_m|^el_c_deg)$", POSITIVE),
    (r"_deg$", Bound(0.0, 180.0, why="an angle in degrees")),
    (r"^n_", Bound(1.0)),
    (r"^max_jump_cycles$", Bound(1.0)),
    # every other sigma, noise, loss, length, duration, rate or count in this project's units
    (r"(sigma|^h0|^h_2|_db|_m|_s|_per_s|_mps|_sps|_rps|_hz|_mhz|_chips|_rthz|_dph|_mps2|_cycles)$", NON_NEGATIVE),
    (r"", FINITE),  # a field without a unit in its name (a plug-in's offset may be negative)
)


#: Only finiteness: for an estimator's parameters, whose sigmas may be huge on purpose (a receiver clock
#: prior of 3e6 m) and whose own ``validate`` checks their ranges.
FINITE_ONLY: tuple[tuple[str, Bound], ...] = (("", FINITE),)


def bound_of(name: str, rules: tuple[tuple[str, Bound], ...] = RULES) -> Bound:
    """The first bound of ``rules`` whose pattern matches the field name ``name``."""
    return next(bound for pattern, bound in rules if re.search(pattern, name))


def check_bounds(config: Any, where: str, rules: tuple[tuple[str, Bound], ...] = RULES) -> None:
    """Raise a one-line :class:`SimbenchError` for the first number of ``config`` outside its :data:`RULES` bound.

    Walks the dataclass tree: ints and floats (not bools), and tuples of them, which must also be
    ordered (a ``(low, high)`` range). Strings, Enums and bools are the types' and choices' business.

    Parameters
    ----------
    config : dataclass instance
        A typed config node (e.g. :class:`simbench.sim.config.ScenarioConfig`).
    where : str
        Its key in the composed config, prefixed to the field in the message (e.g. ``scenario``).
    rules : tuple of (pattern, Bound)
        :data:`RULES`, or :data:`FINITE_ONLY`.

    Raises
    ------
    SimbenchError
        Naming the full key, the value, the range and the field's default as an example.
    """
    for field in dataclasses.fields(config):
        value = getattr(config, field.name)
        key = f"{where}.{field.name}"
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            check_bounds(value, key, rules)
        elif is_number(value):
            check_value(key, field, (value,), rules)
        elif isinstance(value, (tuple, list)) and value and all(is_number(v) for v in value):
            check_value(key, field, tuple(value), rules)


def is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def check_value(
    key: str, field: dataclasses.Field, values: tuple[float, ...], rules: tuple[tuple[str, Bound], ...] = RULES
) -> None:
    """Raise for the first of ``values`` outside the field's bound, or a ``(low, high)`` pair out of order.

    A field's own ``metadata={"bound": Bound(...)}`` wins over :data:`RULES` (for a plug-in's field whose
    name does not follow the unit convention).
    """
    bound = field.metadata.get("bound") or bound_of(field.name, rules)
    for value in values:
        if not bound.holds(value):
            got = value if len(values) == 1 else list(values)
            raise SimbenchError(key, f"{bound.describe()}, got {got}", f"give e.g. {key}={example(field)}")
    if len(values) == 2 and values[0] > values[1]:
        raise SimbenchError(key, f"low {values[0]:g} is above high {values[1]:g}", f"give e.g. {key}={example(field)}")


def example(field: dataclasses.Field) -> str:
    """The field's default, written as on the command line (``[10.0,40.0]`` for a tuple)."""
    default = field.default_factory() if field.default_factory is not dataclasses.MISSING else field.default
    if isinstance(default, (tuple, list)):
        return "[" + ",".join(f"{v:g}" for v in default) + "]"
    return f"{default:g}" if isinstance(default, float) else str(default)

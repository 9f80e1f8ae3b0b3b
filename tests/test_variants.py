"""Variants as typed data: overrides against the Config dataclass, canonical JSON, typed columns."""

from __future__ import annotations

import json

import pandas as pd

from estimators.filters.configs import EkfPppConfig
from estimators.gnss_ins.config import CrtLssConfig
from simbench.analysis.variants import (
    NO_OVERRIDES,
    config_defaults,
    is_default,
    override_value,
    overrides_json,
    overrides_of,
    variant_label,
)


def test_overrides_are_the_fields_that_differ_from_the_dataclass_defaults() -> None:
    assert overrides_of(CrtLssConfig()) == {}
    assert overrides_of(CrtLssConfig(window=5, tol=1e-3)) == {"window": 5}  # tol is the default
    changed = overrides_of(EkfPppConfig(clock_model="random_walk", ionosphere="free"))
    assert changed == {"clock_model": "random_walk", "ionosphere": "free"}
    assert type(changed["clock_model"]) is str  # the Enum becomes its YAML word


def test_json_is_canonical_and_the_label_is_for_display() -> None:
    a = overrides_json({"window": 5, "lambda_d": 2.0})
    b = overrides_json({"lambda_d": 2.0, "window": 5})
    assert a == b == '{"lambda_d":2.0,"window":5}'
    assert overrides_json({}) == NO_OVERRIDES
    assert json.loads(a) == {"lambda_d": 2.0, "window": 5}
    assert variant_label({"window": 5, "lambda_d": 2.0}) == "lambda_d=2.0,window=5"
    assert variant_label({"ionosphere": "free"}) == "ionosphere=free" and variant_label({}) == ""


def test_override_value_is_a_typed_column_with_the_default_filled_in() -> None:
    col = pd.Series(['{"window":5}', "{}", None, '{"lambda_d":2.0,"window":20}'], index=[3, 4, 5, 6])
    window = override_value(col, "window", config_defaults("crt_lss")["window"])
    assert window.tolist() == [5, 10, 10, 20] and window.dtype.kind == "i"
    assert list(window.index) == [3, 4, 5, 6]
    lam = override_value(col, "lambda_d", 1.0)
    assert lam.dtype.kind == "f" and lam.tolist() == [1.0, 1.0, 1.0, 2.0]
    assert is_default(col).tolist() == [False, True, True, False]


def test_config_defaults_are_json_scalars() -> None:
    defaults = config_defaults("l2")
    assert defaults["prior_scale"] == 1.0 and defaults["clock_model"] == "white"
    assert type(defaults["clock_model"]) is str and "window" not in defaults

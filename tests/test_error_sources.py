"""The generator's pipeline of error sources: its declarations, and adding a source (scintillation) to it."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import simbench
from simbench.contract import LABEL_COLUMNS, Scenario
from simbench.sim.error_sources import SIGNAL_SOURCES, TRACKING_SOURCES

SHORT = {"scenario.duration_s": 120}
FADES = {
    "scenario.errors.scintillation.enabled": True,
    "scenario.errors.scintillation.rate_per_s": 0.01,
    "scenario.errors.scintillation.depth_db": 6.0,
    "scenario.errors.scintillation.duration_s": 10.0,
}


def test_streams_are_unique_and_labels_cover_the_contract() -> None:
    sources = SIGNAL_SOURCES + TRACKING_SOURCES
    names = [source.name for source in sources]
    assert len(set(names)) == len(names), "two sources would draw the same random numbers"
    declared = [column for source in sources for column in source.labels]
    assert len(set(declared)) == len(declared), "a label column belongs to one source"
    assert set(LABEL_COLUMNS) - {"epoch", "sat"} <= set(declared)


@pytest.fixture(scope="module")
def plain() -> Scenario:
    return simbench.simulate("urban", "low", seed=3, **SHORT)


@pytest.fixture(scope="module")
def faded() -> Scenario:
    return simbench.simulate("urban", "low", seed=3, **SHORT, **FADES)


def test_scintillation_is_off_by_default(plain: Scenario) -> None:
    assert list(plain.labels.columns) == list(LABEL_COLUMNS)


def test_scintillation_lowers_cn0_by_its_depth_on_faded_rows_only(plain: Scenario, faded: Scenario) -> None:
    assert list(faded.labels.columns) == [*LABEL_COLUMNS, "scintillation_fade_db"]
    keys = ["epoch", "sat"]
    before = plain.observations[[*keys, "cn0_l1", "code_l1"]]
    after = faded.observations[[*keys, "cn0_l1", "code_l1"]].assign(fade=faded.labels["scintillation_fade_db"])
    rows = before.merge(after, on=keys, suffixes=("_before", "_after"))
    hit = rows["fade"].to_numpy() > 0
    assert set(np.unique(rows["fade"])) == {0.0, 6.0}
    assert 0.02 < hit.mean() < 0.5, "a 10 s fade every 100 s per satellite fades about a tenth of the rows"
    np.testing.assert_array_equal(rows["cn0_l1_after"][hit], rows["cn0_l1_before"][hit] - 6.0)
    # elsewhere bit for bit what it was, C/N0 and the code error that follows from it
    calm = rows[~hit]
    pd.testing.assert_series_equal(calm["cn0_l1_after"], calm["cn0_l1_before"], check_names=False, check_exact=True)
    pd.testing.assert_series_equal(calm["code_l1_after"], calm["code_l1_before"], check_names=False, check_exact=True)
    # the loops lose faded channels, and gain none
    assert len(rows) == len(faded.observations) < len(plain.observations)

"""libRSF's published statistic: each estimate against the nearest reference point, whatever its time."""

from __future__ import annotations

import numpy as np
import pytest
from omegaconf import OmegaConf

import simbench
from simbench.analysis.metrics import nearest_reference_distance, rmse
from simbench.analysis.tables import with_rmse
from simbench.runs.compose import compose_config
from simbench.runs.runner import run_estimators


def test_an_error_along_the_track_costs_nothing() -> None:
    """A straight track sampled every 0.1 m: 3 m ahead and 4 m aside is 4 m from the track (5 m from its
    own epoch's point); a NaN estimate stays NaN."""
    track = np.c_[np.arange(0.0, 100.0, 0.1), np.zeros(1000), np.zeros(1000)]
    estimate = np.array([[53.0, 4.0, 0.0], [np.nan, 0.0, 0.0], [-3.0, 0.0, 0.0]])
    assert nearest_reference_distance(estimate, track) == pytest.approx([4.0, np.nan, 3.0], nan_ok=True)


def test_nearest_is_never_above_the_time_matched_error() -> None:
    """On a simulated drive every epoch's own reference point is among the reference points: the nearest
    distance is at most the 3-D error, below it somewhere, and the report's RMSE is the epochs' RMS."""
    sc = simbench.simulate("urban", "low", seed=1000, **{"scenario.duration_s": 60})
    l2 = OmegaConf.to_container(compose_config([]).estimator.l2, resolve=True)
    res = run_estimators(sc, {"l2": l2}, progress=False)
    near, full = res.epochs["error_3d_nearest"].to_numpy(), res.epochs["error_3d"].to_numpy()
    assert np.all(near <= full + 1e-9)
    assert np.any(near < full - 0.1)
    job = {"sweep": "", "scenario_key": "k", "gnss_model": "urban", "overrides": "{}"}  # as a stored run has
    summary = with_rmse(res.summary.assign(**job), res.epochs.assign(**job))
    assert summary["error_3d_nearest_rmse"].iloc[0] == pytest.approx(rmse(near))

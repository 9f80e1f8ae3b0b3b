"""Child process of ``tests/test_reproducible.py``: every registered estimator's positions, hashed.

    python tests/position_digests.py sim|hk

Prints one JSON object ``{estimator: [status, sha256 of the float64 x, y, z bytes]}``. Runs from any
folder (the Hong Kong preset reads the data home, :mod:`simbench.paths`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import sys

import numpy as np
from omegaconf import OmegaConf

import estimators
import simbench
from simbench.runs.compose import compose_config
from simbench.runs.runner import run_estimators

#: Hong Kong epochs kept: from this many before the first reference epoch to this many after it, enough
#: for the fixed-lag window to marginalise many times
HK_EPOCHS = (30, 150)


def scenario(which: str) -> simbench.Scenario:
    """The simulated street (urban, low receiver, seed 0, 120 s) or the first epochs of the Hong Kong log."""
    if which == "sim":
        return simbench.simulate("urban", "low", seed=0, **{"scenario.duration_s": 120})
    log = simbench.scenario("hk_tst_2019")
    first = int(log.truth["epoch"].min())
    keep = np.arange(first - HK_EPOCHS[0], first + HK_EPOCHS[1])
    cut = {"observations": log.observations[log.observations["epoch"].isin(keep)]}
    cut["truth"] = log.truth[log.truth["epoch"].isin(keep)]
    if log.labels is not None:
        cut["labels"] = log.labels[log.labels["epoch"].isin(keep)]
    return dataclasses.replace(log, **cut)


def main() -> None:
    sc = scenario(sys.argv[1])
    default = compose_config([]).estimator
    configs = {name: OmegaConf.to_container(default[name], resolve=True) for name in sorted(estimators.registered())}
    res = run_estimators(sc, configs, progress=False)
    out = {}
    for row in res.summary.itertuples():
        xyz = res.epochs.loc[res.epochs["estimator"] == row.estimator, ["x", "y", "z"]].to_numpy(np.float64)
        out[row.estimator] = [row.status, hashlib.sha256(np.ascontiguousarray(xyz).tobytes()).hexdigest()]
    print(json.dumps(out))


if __name__ == "__main__":
    main()

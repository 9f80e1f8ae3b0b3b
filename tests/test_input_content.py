"""Inputs by content (issue 45, item 1): every file a source reads enters the scenario's cache key by its content,
so a file edited in place, or a relative path naming another file from another folder, is read again; an
unchanged file reuses the cached scenario and results; a cached scenario is used only under the key it was
saved under."""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd
import pytest
from test_rinex_wild import NG_NAV, NG_OBS, cut

import simbench
from simbench.contract import read_parquet_metadata
from simbench.errors import SimbenchWarning
from simbench.paths import file_digest
from simbench.runs.compose import compose_config
from simbench.runs.scenarios import scenario_key, scenario_settings
from simbench.runs.store import cache_problem, cached_scenario

#: The surveyed Nagoya antenna (rover_position.txt) and the same point 0.001 deg (111 m) further north.
POINT = "35.13469901,136.97757549,104.8626\n"
NORTH = "35.13569901,136.97757549,104.8626\n"


def key_of(overrides: dict[str, object]) -> str:
    return scenario_key(scenario_settings(compose_config([f"{k}={v}" for k, v in overrides.items()])))


@pytest.mark.usefixtures("shared_data")
def test_a_file_edited_in_place_changes_the_key_and_the_result(tmp_path: Path) -> None:
    obs = cut(NG_OBS, tmp_path / "rover.obs", 10)
    truth = tmp_path / "point.txt"
    truth.write_text(POINT)
    overrides = {"scenario.obs": obs, "scenario.nav": NG_NAV, "scenario.truth": truth, "scenario.systems": "G"}
    run = {"scenario": "rinex", "estimators": ["wls_spp"], "results_dir": tmp_path / "run", "progress": False}
    first = simbench.run(overrides=overrides, **run).summary["horizontal_median"].iloc[0]
    key = key_of({"scenario": "rinex", **overrides})
    truth.write_text(NORTH)  # the same path, another point
    moved = simbench.run(overrides=overrides, **run).summary["horizontal_median"].iloc[0]
    new_key = key_of({"scenario": "rinex", **overrides})
    assert new_key != key
    assert first < 5.0 and abs(moved - first) > 100.0  # scored against the new point, not the cached one
    stored = next((tmp_path / "run" / "jobs" / new_key).glob("wls_spp-*.summary.parquet"))
    inputs = read_parquet_metadata(stored)["simbench.inputs"]  # the provenance names what was read
    assert inputs["scenario.truth"] == [file_digest(str(truth))] and len(inputs["scenario.obs"]) == 1
    # each input kind: observations and navigation edited in place change the key too
    for path in (obs, Path(NG_NAV)):
        edited = tmp_path / f"edited_{path.name}"
        edited.write_bytes(path.read_bytes())
        settings = overrides | ({"scenario.obs": edited} if path == obs else {"scenario.nav": edited})
        before = key_of({"scenario": "rinex", **settings})
        with edited.open("a") as fh:
            fh.write("\n")
        assert key_of({"scenario": "rinex", **settings}) != before, path.name


@pytest.mark.usefixtures("shared_data")
def test_an_unchanged_file_keeps_its_key_and_a_relative_path_follows_the_folder(tmp_path: Path) -> None:
    obs = cut(NG_OBS, tmp_path / "rover.obs", 10)
    overrides = {"scenario.obs": obs, "scenario.nav": NG_NAV, "scenario.truth": "point.txt", "scenario.systems": "G"}
    here, there = tmp_path / "a", tmp_path / "b"
    for folder, text in ((here, POINT), (there, NORTH)):
        folder.mkdir()
        (folder / "point.txt").write_text(text)
    keys = {}
    start = os.getcwd()
    try:
        for folder in (here, there, here):
            os.chdir(folder)
            keys.setdefault(folder, set()).add(key_of({"scenario": "rinex", **overrides}))
    finally:
        os.chdir(start)
    assert len(keys[here]) == 1 and keys[here] != keys[there]  # same file, same key; another file, another key
    # a touched but unchanged file keeps the key (content, not time)
    key = key_of({"scenario": "rinex", **overrides | {"scenario.truth": here / "point.txt"}})
    os.utime(here / "point.txt", ns=(1, 1))
    assert key_of({"scenario": "rinex", **overrides | {"scenario.truth": here / "point.txt"}}) == key


def test_a_cache_folder_under_another_key_is_rebuilt_not_used(tmp_path: Path) -> None:
    """Two cached scenarios swapped (or one copied under another key) passed every manifest check and an
    estimator ran on the other seed's data; the manifest now names the key its folder was saved under."""
    seeds = {seed: simbench.simulate("open_sky", seed=seed, **{"scenario.duration_s": 5}) for seed in (0, 1)}
    for key, seed in (("a" * 16, 0), ("b" * 16, 1)):
        cached_scenario(tmp_path, key, lambda s=seed: seeds[s])
    cache = tmp_path / "cache"
    (cache / ("a" * 16)).rename(cache / "swap")
    (cache / ("b" * 16)).rename(cache / ("a" * 16))
    (cache / "swap").rename(cache / ("b" * 16))
    assert "holds scenario bbbbbbbbbbbbbbbb, not aaaaaaaaaaaaaaaa" in cache_problem(cache / ("a" * 16))
    with pytest.warns(SimbenchWarning, match="a cache folder moved or swapped"):
        again = cached_scenario(tmp_path, "a" * 16, lambda: seeds[0])
    pd.testing.assert_frame_equal(again.observations, seeds[0].observations)
    assert cache_problem(cache / ("a" * 16)) == ""  # rebuilt under its own key

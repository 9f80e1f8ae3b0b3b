"""Same inputs, same positions, in any process: every registered estimator run twice in separate processes.

Two runs of one command are two processes with different memory layouts and hash seeds.
GTSAM's own fixed-lag smoother chose what to re-eliminate by iterating over cliques hashed by
address, and iSAM2-DCS turned that last-bit difference into metres (9.9 m on the Hong Kong log);
one process running twice could not see it. Each child hashes every estimator's positions
(``tests/position_digests.py``); the two processes must agree bit for bit.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import REPO_ROOT

CHILD = Path(__file__).with_name("position_digests.py")


def digests(which: str, hash_seeds: tuple[str, str]) -> list[dict[str, list[str]]]:
    """Run the child for ``which`` once per hash seed, concurrently, each in its own process."""
    children = [
        subprocess.Popen(
            [sys.executable, str(CHILD), which],
            cwd=REPO_ROOT,
            env={**os.environ, "PYTHONHASHSEED": seed},
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for seed in hash_seeds
    ]
    out = []
    for child in children:
        stdout, stderr = child.communicate(timeout=600)
        assert child.returncode == 0, stderr[-2000:]
        out.append(json.loads(stdout.strip().splitlines()[-1]))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("which", ["sim", "hk"])
def test_every_estimator_gives_identical_positions_in_two_processes(which: str, request: pytest.FixtureRequest) -> None:
    if which == "hk":
        request.getfixturevalue("shared_data")  # one line when ../shared is missing
    first, second = digests(which, ("1", "2"))
    assert first.keys() == second.keys()
    differ = {name: (first[name], second[name]) for name in first if first[name] != second[name]}
    assert not differ, differ
    ran = [name for name, (status, _) in first.items() if status == "ok"]
    # the incremental family is where it broke; a run that skipped them would prove nothing
    assert {"isam2_ppp", "isam2_dcs", "isam2_mm", "ice"} <= set(ran), first

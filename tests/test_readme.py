"""README stays true: its test command is what CI runs, and it documents every column."""

from __future__ import annotations

import re
from pathlib import Path

from simbench.contract import IMU_COLUMNS, LABEL_COLUMNS, OBSERVATION_COLUMNS, ODOMETRY_COLUMNS, TRUTH_COLUMNS
from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()


def test_ci_runs_readme_test_command() -> None:
    ci_command = [ln for ln in (ROOT / ".ci/run").read_text().splitlines() if ln.startswith("pip install")]
    assert len(ci_command) == 1
    assert ci_command[0] in README


def test_readme_has_exactly_two_setup_commands() -> None:
    block = re.search(r"## Set-up\n.*?```bash\n(.*?)```", README, re.S)
    assert block is not None
    commands = [ln for ln in block.group(1).splitlines() if ln.strip() and not ln.startswith("#")]
    assert len(commands) == 2
    assert commands[0].startswith("pip install -e . &&") and "python -m simbench" in commands[0]


def test_readme_documents_every_column() -> None:
    for table in (
        OBSERVATION_COLUMNS,
        IMU_COLUMNS,
        ODOMETRY_COLUMNS,
        TRUTH_COLUMNS,
        LABEL_COLUMNS,
        SUMMARY_COLUMNS,
        EPOCH_COLUMNS,
    ):
        for column in table:
            assert f"`{column}`" in README, column

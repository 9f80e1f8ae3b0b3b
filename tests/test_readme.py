"""README and docs/ stay true.

README.md is the guide: its set-up commands are what CI runs, it keeps the sections
other files cite, and it stays short. docs/contract.md documents every column of the
data contract. Every subcommand, module, file and in-repository link that README.md
or docs/*.md names exists.
"""

from __future__ import annotations

import dataclasses
import importlib
import re
from pathlib import Path

import pytest

from estimators import ENTRY_POINT_GROUP
from simbench.cli.main import SUBCOMMANDS
from simbench.contract import (
    IMU_COLUMNS,
    LABEL_COLUMNS,
    OBSERVATION_COLUMNS,
    ODOMETRY_COLUMNS,
    TRUTH_COLUMNS,
    NavInfo,
    Need,
    Scenario,
)
from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS
from simbench.source_registry import ENTRY_POINT_GROUP as SOURCE_ENTRY_POINT_GROUP

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()
CONTRACT = (ROOT / "docs" / "contract.md").read_text()
DOCS = {"README.md": README} | {f"docs/{p.name}": p.read_text() for p in sorted((ROOT / "docs").glob("*.md"))}

#: README's length limit: a guide, the notebook and the reference live in docs/.
MAX_README_LINES = 350
#: Sections other files cite by name (error messages, config comments, CI): (section, cited by).
CITED_SECTIONS = (
    ("Set-up", "conf/config.yaml help, .ci/run"),
    ("Add your estimator", "estimators/__init__.py, simbench/runs/compose.py error messages"),
    ("Which GNSS model", "conf/gnss_model/urban.yaml"),
    ("Add a source", "the guide's outline"),
    ("Add an error source", "the guide's outline"),
    ("Develop", "the guide's outline"),
)
DEVELOP_COMMAND = "ruff check . && ruff format --check . && mypy && python -m pytest -n 2"
#: Dotted names in backticks that are not modules or attributes: the estimators' entry-point
#: group and the Parquet key-value metadata key of a saved scenario.
NOT_MODULES = {ENTRY_POINT_GROUP, SOURCE_ENTRY_POINT_GROUP, "simbench.scenario"}
#: Top-level folders whose paths, cited in backticks, must exist.
REPO_FOLDERS = ("simbench/", "estimators/", "tests/", "benchmarks/", "conf/", "examples/", "docs/", ".ci/")


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


def test_contract_documents_every_column() -> None:
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
            assert f"`{column}`" in CONTRACT, column


def test_contract_documents_scenario_navinfo_and_needs() -> None:
    for cls in (Scenario, NavInfo):
        for f in dataclasses.fields(cls):
            assert f"| `{f.name}` |" in CONTRACT, f"{cls.__name__}.{f.name}"
    for need in Need:
        assert f"| `{need.value}` |" in CONTRACT, need


def test_readme_is_a_short_guide_with_the_cited_sections() -> None:
    assert len(README.splitlines()) <= MAX_README_LINES
    headings = re.findall(r"^#+ (.*)$", README, re.M)
    for section, cited_by in CITED_SECTIONS:
        assert any(h.startswith(section) for h in headings), f"section {section!r} (cited by {cited_by})"


def test_readme_develop_section_has_the_one_command() -> None:
    develop = README.split("## Develop", 1)[1]
    block = re.search(r"```bash\n(.*?)```", develop, re.S)
    assert block is not None and block.group(1).strip() == DEVELOP_COMMAND


@pytest.mark.parametrize("name", sorted(DOCS))
def test_documented_subcommands_exist(name: str) -> None:
    # `python -m simbench WORD`: WORD is a subcommand unless it is an override, a sweep or a flag
    words = set(re.findall(r"python -m simbench ([A-Za-z][\w-]*)(?=[\s`]|$)", DOCS[name], re.M))
    assert words <= set(SUBCOMMANDS), sorted(words - set(SUBCOMMANDS))
    assert "python -m simbench." not in DOCS[name]  # the old module forms are gone


def resolves(dotted: str) -> bool:
    """True when ``dotted`` is an importable module or an attribute chain of one."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for attr in parts[i:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return False
        return True
    return False


@pytest.mark.parametrize("name", sorted(DOCS))
def test_cited_modules_exist(name: str) -> None:
    cited = set(re.findall(r"`((?:simbench|estimators)(?:\.\w+)+)`", DOCS[name])) - NOT_MODULES
    missing = sorted(d for d in cited if not resolves(d))
    assert not missing, missing


@pytest.mark.parametrize("name", sorted(DOCS))
def test_cited_paths_exist(name: str) -> None:
    cited = {
        token.split(":")[0].split(" ")[0]
        for token in re.findall(r"`([^`\s]+)`", DOCS[name])
        if token.startswith(REPO_FOLDERS) and not re.search(r"[<*{]", token)
    }
    missing = sorted(p for p in cited if not (ROOT / p).exists())
    assert not missing, missing


def anchor(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


@pytest.mark.parametrize("name", sorted(DOCS))
def test_links_between_readme_and_docs_exist(name: str) -> None:
    here = (ROOT / name).parent
    for target, fragment in re.findall(r"\]\(([^)#\s]*\.md)(?:#([^)\s]+))?\)", DOCS[name]):
        path = (here / target).resolve()
        assert path.is_file(), f"{name}: link to {target}"
        if fragment:
            headings = re.findall(r"^#+ (.*)$", path.read_text(), re.M)
            assert fragment in {anchor(h) for h in headings}, f"{name}: link to {target}#{fragment}"

"""Locating ``shared/``: fail loudly when it is missing, skip only on request."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import ALLOW_MISSING_SHARED, REPO_ROOT, require_shared, shared_path

TESTS = Path(__file__).resolve().parent


def test_shared_sits_beside_the_repository_root(tmp_path: Path) -> None:
    assert shared_path(tmp_path / "repo") == tmp_path / "shared"
    assert (REPO_ROOT / "pyproject.toml").is_file() and REPO_ROOT == TESTS.parent
    assert shared_path() == REPO_ROOT.parent / "shared"


def test_present_directory_is_returned(tmp_path: Path) -> None:
    assert require_shared(tmp_path, {}) == tmp_path


@pytest.mark.parametrize("environ", [{}, {ALLOW_MISSING_SHARED: ""}, {ALLOW_MISSING_SHARED: "0"}])
def test_missing_directory_fails_in_one_line(tmp_path: Path, environ: dict[str, str]) -> None:
    missing = shared_path(tmp_path / "repo")
    with pytest.raises(pytest.fail.Exception) as info:
        require_shared(missing, environ)
    msg = str(info.value)
    assert "\n" not in msg and str(missing) in msg and ALLOW_MISSING_SHARED in msg


def test_missing_directory_skips_with_the_switch(tmp_path: Path) -> None:
    missing = shared_path(tmp_path / "repo")
    with pytest.raises(pytest.skip.Exception, match="not found"):
        require_shared(missing, {ALLOW_MISSING_SHARED: "1"})


def test_no_test_hard_codes_the_shared_path() -> None:
    offenders = [
        p.name for p in TESTS.glob("*.py") if p.name != Path(__file__).name and "/work/shared" in p.read_text()
    ]
    assert offenders == []

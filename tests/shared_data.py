"""The data sets some tests read from ../shared/data next to the checkout (nerf_synthetic/lego, real/maryrose,
real/buddha). A user's fresh clone has none of it: those tests skip, saying so. CI has it: .ci/run sets
NERFKIT_REQUIRE_SHARED=1, and then a missing data set fails the test that needs it (a skip there would hide
that the tests did not run)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
REQUIRE = "NERFKIT_REQUIRE_SHARED"


def required() -> bool:
    """Whether missing shared data is a failure (CI) rather than a skip (a user's clone)."""
    return os.environ.get(REQUIRE, "").strip().lower() not in ("", "0", "false", "no")


def require_shared(path: Path) -> None:
    """Skip the calling test (or fixture) when `path` (a file or folder under ../shared/data) is absent; fail
    instead, with the same reason, where $NERFKIT_REQUIRE_SHARED is set."""
    path = Path(path)
    if path.exists():
        return
    reason = f"{path} not present (the shared data, ../shared/data next to the checkout)"
    if required():
        pytest.fail(f"{reason}; ${REQUIRE} is set (CI: .ci/run), so the tests that need it must run", pytrace=False)
    pytest.skip(reason)


def needs_shared(path: Path) -> pytest.MarkDecorator:
    """Mark a test (or a fixture parameter, pytest.param(..., marks=...)) as needing `path`: conftest.py calls
    require_shared(path) before the test's fixtures are set up."""
    return pytest.mark.needs_shared(Path(path))

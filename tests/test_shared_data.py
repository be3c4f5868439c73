"""The rule for tests that need ../shared/data (shared_data.py): a user's clone without it skips them, CI
($NERFKIT_REQUIRE_SHARED, set by .ci/run) fails them. Needs no shared data itself."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
import shared_data
from shared_data import REQUIRE, needs_shared, require_shared

# tests/conftest.py itself, by path: in a whole-suite run the module name "conftest" may be another folder's
_spec = importlib.util.spec_from_file_location("tests_root_conftest", Path(__file__).with_name("conftest.py"))
conftest = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(conftest)


@pytest.mark.parametrize("value", [None, "", "0"])
def test_absent_shared_data_skips_in_a_users_clone(tmp_path, monkeypatch, value):
    if value is None:
        monkeypatch.delenv(REQUIRE, raising=False)
    else:
        monkeypatch.setenv(REQUIRE, value)
    with pytest.raises(pytest.skip.Exception, match="not present"):
        require_shared(tmp_path / "absent")


@pytest.mark.parametrize("value", ["1", "yes"])
def test_absent_shared_data_fails_in_ci(tmp_path, monkeypatch, value):
    monkeypatch.setenv(REQUIRE, value)
    with pytest.raises(pytest.fail.Exception, match=f"absent not present.*{REQUIRE} is set"):
        require_shared(tmp_path / "absent")


def test_present_shared_data_neither_skips_nor_fails(tmp_path, monkeypatch):
    (tmp_path / "lego").mkdir()
    for value in ("1", ""):
        monkeypatch.setenv(REQUIRE, value)
        require_shared(tmp_path / "lego")


class _Item:
    def __init__(self, *marks):
        self.marks = [m.mark for m in marks]

    def iter_markers(self, name):
        return (m for m in self.marks if m.name == name)


def test_the_needs_shared_mark_is_enforced_before_setup(tmp_path, monkeypatch):
    """conftest.py's setup hook applies the rule to every needs_shared mark (a test's or a fixture parameter's)."""
    item = _Item(pytest.mark.slow, needs_shared(tmp_path), needs_shared(tmp_path / "absent"))
    monkeypatch.setenv(REQUIRE, "1")
    with pytest.raises(pytest.fail.Exception, match="absent"):
        conftest.pytest_runtest_setup(item)
    monkeypatch.delenv(REQUIRE)
    with pytest.raises(pytest.skip.Exception, match="absent"):
        conftest.pytest_runtest_setup(item)
    conftest.pytest_runtest_setup(_Item(needs_shared(tmp_path)))  # present: runs


def test_every_shared_path_in_the_tests_goes_through_the_rule():
    """No test finds ../shared on its own (a bare skipif would skip in CI too)."""
    tests = Path(__file__).parent
    assert shared_data.SHARED_DATA == tests.parent.parent / "shared" / "data"
    for path in tests.rglob("*.py"):
        text = path.read_text()
        if path.name != "shared_data.py" and ('"shared' in text or "/ \"shared\"" in text):
            assert "shared_data" in text, path

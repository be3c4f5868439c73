"""The house's rules, checked: import-linter's contracts (pipeline layers, no cycles; pyproject.toml),
modules of a readable size, and tests that mirror the source."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "nerfkit"
MAX_LINES = 430  # "no module over ~400 lines"; the largest today is cli/args.py (the verbs' typed arguments)

pytestmark = pytest.mark.smoke


def test_layers_and_no_cycles():
    lint = Path(sys.executable).with_name("lint-imports")
    r = subprocess.run([str(lint)], cwd=ROOT, capture_output=True, text=True, timeout=300,
                       env={**os.environ, "PYTHONPATH": str(ROOT / "src")})
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
    assert "2 kept, 0 broken" in r.stdout


def test_no_module_is_long():
    sizes = {p.relative_to(SRC): len(p.read_text().splitlines()) for p in SRC.rglob("*.py")}
    assert max(sizes.values()) > 100  # the walk found the modules
    assert {str(p): n for p, n in sizes.items() if n > MAX_LINES} == {}


def test_each_package_has_its_tests_folder():
    packages = {p.name for p in SRC.iterdir() if p.is_dir() and (p / "__init__.py").is_file()}
    missing = sorted(p for p in packages if not (ROOT / "tests" / p).is_dir())
    assert missing == []

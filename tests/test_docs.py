"""The documentation: the MkDocs site builds in strict mode (a broken link or anchor fails), and the
README is the front door (short, its links resolve, its commands are the ones the tests run)."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.smoke  # also at the lowest allowed mkdocs / mkdocs-material (.ci/run)


def test_site_builds_strictly(tmp_path):
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-d", str(tmp_path / "site")],
                       cwd=ROOT, capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stdout + r.stderr
    site = tmp_path / "site"
    # Generated, not copied: each verb page holds its --help, the measurements page every record.
    assert "usage: nerfkit eval" in (site / "verbs" / "eval" / "index.html").read_text()
    measurements = (site / "measurements" / "index.html").read_text()
    for record in (ROOT / "benchmarks" / "results").glob("*.json"):
        assert record.name in measurements
    assert (site / "results" / "maryrose_eval_test.jpg").is_file()
    assert not (site / "hooks").exists()


def test_readme_is_the_front_door():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) < 200
    links = re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", text)
    assert links, "the README links to the manual"
    for link in links:
        assert (ROOT / link).exists(), link
    commands = re.findall(r"```bash\n(.*?)```", text, re.S)
    assert 'pip install -e ".[test]" && python -m pytest' in commands[1]  # what .ci/run runs
    assert "nerfkit demo" in commands[0]

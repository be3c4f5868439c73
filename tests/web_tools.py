"""Third-party JavaScript the tests run in Node or Chromium, installed from the npm registry into tests/web
(package.json, package-lock.json: pinned) by `npm ci --prefix tests/web` (.ci/run does it). A user's clone
without it skips those tests, saying how to install it; CI ($NERFKIT_REQUIRE_SHARED set) fails instead."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest
from shared_data import REQUIRE, required

WEB = Path(__file__).resolve().parent / "web"


def node_module(name: str) -> Path:
    """tests/web/node_modules/NAME; skips the calling test (fails in CI) when it or Node is missing."""
    path = WEB / "node_modules" / name
    if path.is_dir() and shutil.which("node"):
        return path
    reason = f"{path} not installed (npm ci --prefix {WEB}; .ci/run does it)"
    if required():
        pytest.fail(f"{reason}; ${REQUIRE} is set (CI), so the tests that need it must run", pytrace=False)
    pytest.skip(reason)


def validate_gltf(path: Path) -> dict:
    """The Khronos glTF validator's report of a .glb or .gltf (its JSON: issues.numErrors, issues.messages)."""
    node_module("gltf-validator")
    out = subprocess.run(["node", str(WEB / "validate.js"), str(path)], capture_output=True, text=True, timeout=120,
                         check=True)
    return json.loads(out.stdout)

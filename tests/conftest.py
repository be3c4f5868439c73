"""Test-session set-up: one persistent JAX compilation cache for the whole session (in a temporary
folder, not the user's ~/.cache), so functions that several tests compile alike compile once."""

import os
import tempfile

import pytest
from chromium import CHROMIUM_NAMES, find_chromium
from shared_data import require_shared


def pytest_configure(config):
    config.addinivalue_line("markers", "needs_shared(path): needs path under ../shared/data (shared_data.py): skips "
                                       "when it is absent, fails there where $NERFKIT_REQUIRE_SHARED is set (CI)")


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    for mark in item.iter_markers("needs_shared"):
        require_shared(mark.args[0])


@pytest.fixture(scope="session", autouse=True)
def compile_cache():
    with tempfile.TemporaryDirectory(prefix="nerfkit-jax-cache-") as path:
        old = os.environ.get("NERFKIT_COMPILE_CACHE")
        os.environ["NERFKIT_COMPILE_CACHE"] = path
        from nerfkit.cli.main import enable_compile_cache

        enable_compile_cache()
        yield path
        if old is None:
            os.environ.pop("NERFKIT_COMPILE_CACHE", None)
        else:
            os.environ["NERFKIT_COMPILE_CACHE"] = old


SPLAT_TRAIN = ["--preset", "splat", "--no-progress", "--capacity", "2000", "--max-steps", "200", "--val-every", "100",
               "--ckpt-every", "100", "--log-every", "50"]


@pytest.fixture(scope="session")
def splat_run(tmp_path_factory):
    """(procedural scene at 32 px, run folder of 200 steps of --preset splat with 2,000 Gaussians), shared by
    the splat, web-page and viewer tests."""
    from nerfkit.cli.main import main
    from nerfkit.data.procedural.scene import make_scene

    root = tmp_path_factory.mktemp("splat_run")
    scene = make_scene(root / "scene", size=32, n_train=8, n_val=2, n_test=2)
    assert main(["train", str(scene), "--out", str(root / "run"), *SPLAT_TRAIN]) == 0
    return scene, root / "run"


@pytest.fixture(scope="session")
def procedural_run(tmp_path_factory):
    """(run, moved copy, training poses) of the shared procedural-scene run (procedural_run.py)."""
    from procedural_run import train_scene

    return train_scene(tmp_path_factory.mktemp("procedural_run"))


@pytest.fixture
def chromium():
    """The headless Chromium binary for the real-browser tests (skips, saying how to install it, when absent)."""
    binary = find_chromium()
    if binary is None:
        pytest.skip("no Chromium found (looked for " + ", ".join(CHROMIUM_NAMES) + " and $NERFKIT_CHROMIUM); "
                    "install the Debian package: apt-get install chromium (.ci/run does this)")
    return binary

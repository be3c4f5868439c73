"""One small splat run through the command line, shared by the CLI and web-page tests."""

import pytest

from nerfkit.cli.main import main
from nerfkit.data.procedural.scene import make_scene

TRAIN = ["--preset", "splat", "--no-progress", "--capacity", "2000", "--max-steps", "200", "--val-every", "100",
         "--ckpt-every", "100", "--log-every", "50"]


@pytest.fixture(scope="session")
def splat_run(tmp_path_factory):
    """(procedural scene at 32 px, run folder of 200 steps of --preset splat with 2,000 Gaussians)."""
    root = tmp_path_factory.mktemp("splat_run")
    scene = make_scene(root / "scene", size=32, n_train=8, n_val=2, n_test=2)
    assert main(["train", str(scene), "--out", str(root / "run"), *TRAIN]) == 0
    return scene, root / "run"

"""`nerfkit view RUN`'s scene: the training cameras it draws."""

from __future__ import annotations

import numpy as np

from nerfkit.rays.correction import pose_error, refined_poses
from nerfkit.run.folder import RunFolder
from nerfkit.viewer.run import scene_view_of_run


def test_a_pose_refined_run_shows_its_cameras_where_refinement_put_them(procedural_run):
    run = procedural_run[0]
    cfg = RunFolder(run).config()
    given = scene_view_of_run(run, cfg).poses
    assert np.allclose(scene_view_of_run(run, cfg, {"other": 0}).poses, given)
    xi = np.random.default_rng(0).normal(0.0, 0.02, (len(given), 6)).astype(np.float32)
    shown = scene_view_of_run(run, cfg, {"cam_pose": xi}).poses
    assert np.allclose(shown, refined_poses(given, xi), atol=1e-5)
    assert np.median(pose_error(shown, given)[0]) > 0.5  # degrees: moved, not drawn at the given poses

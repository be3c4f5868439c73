"""Reading SfM points (data/points.py) and moving them by a similarity."""

import numpy as np
import trimesh

from nerfkit.data.points import read_points, transform_points


def test_read_points_ply_with_transform(tmp_path):
    pts = np.random.default_rng(1).normal(size=(30, 3))
    rgba = np.concatenate([np.random.default_rng(2).integers(0, 256, (30, 3)), np.full((30, 1), 255)], 1)
    trimesh.PointCloud(pts, colors=rgba.astype(np.uint8)).export(tmp_path / "sparse_pc.ply")
    m = np.diag([2.0, 2.0, 2.0, 1.0])
    m[:3, 3] = [1, 2, 3]
    xyz, col = read_points(tmp_path / "sparse_pc.ply", transform=m)
    np.testing.assert_allclose(xyz, 2 * pts + [1, 2, 3], atol=2e-6)  # float32 in the file
    np.testing.assert_allclose(col, rgba[:, :3] / 255.0, atol=1e-6)
    np.testing.assert_allclose(transform_points(pts, m), 2 * pts + [1, 2, 3])

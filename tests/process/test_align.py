import numpy as np
import pytest

from nerfkit.data.procedural.captures import ring_poses
from nerfkit.process.align import pose_errors, umeyama


def random_rotation(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def test_umeyama_recovers_a_known_similarity():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(20, 3))
    rot, s, t = random_rotation(rng), 3.7, np.array([1.0, -2.0, 0.5])
    s2, rot2, t2 = umeyama(a, s * a @ rot.T + t)
    assert s2 == pytest.approx(s, rel=1e-10)
    np.testing.assert_allclose(rot2, rot, atol=1e-10)
    np.testing.assert_allclose(t2, t, atol=1e-10)


def test_pose_errors_zero_for_a_similar_copy_and_exact_for_a_known_perturbation():
    rng = np.random.default_rng(1)
    ref = ring_poses(12, seed=2)
    rot, s = random_rotation(rng), 0.3
    moved = ref.copy()
    moved[:, :3, :3] = rot @ ref[:, :3, :3]
    moved[:, :3, 3] = s * ref[:, :3, 3] @ rot.T + 5.0
    e = pose_errors(moved, ref)
    assert e["centre_max"] < 1e-9 and e["rotation_max_deg"] < 1e-6
    # Turn one camera by 2 degrees about its own axis: only it has a rotation error, of exactly 2 degrees.
    a = np.radians(2.0)
    spin = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    moved[3, :3, :3] = moved[3, :3, :3] @ spin
    e = pose_errors(moved, ref)
    assert e["rotation_max_deg"] == pytest.approx(2.0, abs=1e-6) and e["rotation_median_deg"] < 1e-6

"""Per-photo corrections (rays/correction.py): the rotation map against scipy, the pose and colour corrections at
and away from the identity, and the perturbation the procedural captures use."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from nerfkit.rays.correction import (
    aligned_pose_error,
    apply_similarity,
    camera_extent,
    corrected_color,
    corrected_composite,
    corrected_pose,
    fit_color,
    fit_composite,
    mean_color,
    perturb_poses,
    pose_error,
    rotation_angle,
    refinement_similarity,
    similarity_fit,
    so3_exp,
)


@pytest.mark.parametrize("angle", [0.0, 1e-5, 1e-3, 0.02, 1.0, 3.0])
def test_so3_exp_is_the_rotation_of_its_axis_angle(angle):
    rng = np.random.default_rng(0)
    axis = rng.normal(size=(4, 3))
    w = angle * axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    r = np.asarray(so3_exp(jnp.asarray(w, jnp.float32)))
    assert np.allclose(r, Rotation.from_rotvec(w).as_matrix(), atol=2e-6)
    assert np.allclose(r @ np.swapaxes(r, -1, -2), np.eye(3), atol=2e-6)


def test_so3_exp_has_the_generators_as_its_gradient_at_the_identity():
    """d R / d w_k at w = 0 is [e_k]x, finite (the Taylor branch), and the far branch's gradient is finite too."""
    for k in range(3):
        jac = jax.jacfwd(lambda w: so3_exp(w))(jnp.zeros(3))[..., k]
        e = np.zeros(3)
        e[k] = 1.0
        assert np.allclose(jac, np.cross(e, np.eye(3)).T, atol=1e-6)  # [e_k]x: its column i is e_k x e_i
    g = jax.grad(lambda w: so3_exp(w)[0, 1])(jnp.array([0.3, -0.2, 0.5]))
    assert np.all(np.isfinite(g)) and np.abs(g).sum() > 0


def test_pose_correction_turns_and_moves_in_the_camera_frame():
    c2w = np.eye(4)
    c2w[:3, :3] = Rotation.from_rotvec([0.2, 0.1, -0.3]).as_matrix()
    c2w[:3, 3] = [1.0, 2.0, 3.0]
    assert np.allclose(corrected_pose(jnp.asarray(c2w, jnp.float32), jnp.zeros(6)), c2w, atol=1e-6)
    xi = jnp.array([0.0, 0.0, 0.1, 0.5, 0.0, 0.0])
    out = np.asarray(corrected_pose(jnp.asarray(c2w, jnp.float32), xi, scale=2.0))
    # the centre moves 2 x 0.5 along the camera's own x axis; the axes turn 0.1 rad about its own z
    assert np.allclose(out[:3, 3], c2w[:3, 3] + 1.0 * c2w[:3, 0], atol=1e-5)
    assert np.allclose(out[:3, :3], c2w[:3, :3] @ Rotation.from_rotvec([0, 0, 0.1]).as_matrix(), atol=1e-6)
    deg, dist = pose_error(out[None], c2w[None])
    assert deg[0] == pytest.approx(np.degrees(0.1), abs=1e-3) and dist[0] == pytest.approx(1.0, abs=1e-5)


def test_colour_correction_is_affine_and_the_mean_transform_is_the_mean():
    rgb = np.random.default_rng(1).uniform(size=(5, 7, 3)).astype(np.float32)
    assert np.allclose(corrected_color(jnp.asarray(rgb), jnp.zeros((3, 4))), rgb)
    m = np.zeros((3, 4), np.float32)
    m[:, :3] = np.diag([0.2, -0.1, 0.0])
    m[:, 3] = [0.0, 0.05, -0.02]
    out = np.asarray(corrected_color(jnp.asarray(rgb), jnp.asarray(m)))
    assert np.allclose(out, rgb * [1.2, 0.9, 1.0] + [0.0, 0.05, -0.02], atol=1e-6)
    assert np.allclose(mean_color(np.stack([m, -m])), 0.0)
    # composited: the background's share keeps its colour, the scene's share is transformed
    alpha = np.random.default_rng(2).uniform(size=(5, 7)).astype(np.float32)
    bg = np.array([1.0, 1.0, 1.0], np.float32)
    scene = rgb * alpha[..., None]
    out = np.asarray(corrected_composite(jnp.asarray(scene + (1 - alpha[..., None]) * bg), jnp.asarray(alpha),
                                         jnp.asarray(bg), jnp.asarray(m)))
    want = scene * [1.2, 0.9, 1.0] + alpha[..., None] * [0.0, 0.05, -0.02] + (1 - alpha[..., None]) * bg
    assert np.allclose(out, want, atol=1e-6)


def test_a_colour_transform_is_recovered_from_the_pixels_it_is_fitted_on_only():
    """fit_color undoes a known transform (full 3x3 and offset); pixels of weight 0 (the other half, corrupted)
    change nothing; a render of one colour still maps that colour onto the target (the ridge picks a small m); the
    gain form fits the diagonal alone;
    fit_composite recovers the transform of a composite and leaves the background's share as it is."""
    rng = np.random.default_rng(3)
    rgb = rng.uniform(size=(6, 10, 3)).astype(np.float32)
    m = np.array([[0.1, 0.05, 0.0, 0.02], [-0.03, -0.1, 0.02, 0.0], [0.0, 0.04, 0.15, -0.05]], np.float32)
    target = np.asarray(corrected_color(jnp.asarray(rgb), jnp.asarray(m)))
    assert np.allclose(fit_color(jnp.asarray(rgb), jnp.asarray(target)), m, atol=2e-3)  # the ridge's pull
    left = np.broadcast_to(np.arange(10) < 5, (6, 10)).astype(np.float32)
    spoiled = target.copy()
    spoiled[:, 5:] = rng.uniform(size=(6, 5, 3))
    assert np.allclose(fit_color(jnp.asarray(rgb), jnp.asarray(spoiled), weight=jnp.asarray(left)), m, atol=3e-3)
    assert not np.allclose(fit_color(jnp.asarray(rgb), jnp.asarray(spoiled)), m, atol=3e-2)  # it sees them all
    flat = np.full((4, 4, 3), 0.5, np.float32)
    fit = fit_color(jnp.asarray(flat), jnp.full((4, 4, 3), 0.6))
    assert np.allclose(corrected_color(jnp.asarray(flat), fit), 0.6, atol=1e-3) and np.abs(fit).max() < 0.2
    # a gain per channel only: the diagonal of m comes back, every other entry stays zero
    gains = np.diag([0.1, -0.1, 0.15]).astype(np.float32)
    fit = np.asarray(fit_color(jnp.asarray(rgb), jnp.asarray(rgb * [1.1, 0.9, 1.15]), form="gain"))
    assert np.allclose(fit[:, :3], gains, atol=2e-3) and np.all(fit[:, 3] == 0)
    fit = np.asarray(fit_color(jnp.asarray(rgb), jnp.asarray(target), form="gain"))  # m has more than gains
    assert np.all(fit[~np.eye(3, 4, dtype=bool)] == 0) and not np.allclose(fit, m, atol=1e-2)
    alpha = rng.uniform(size=(6, 10)).astype(np.float32)
    bg = np.array([1.0, 1.0, 1.0], np.float32)
    comp = rgb * alpha[..., None] + (1 - alpha[..., None]) * bg
    photo = corrected_composite(jnp.asarray(comp), jnp.asarray(alpha), jnp.asarray(bg), jnp.asarray(m))
    assert np.allclose(fit_composite(jnp.asarray(comp), jnp.asarray(alpha), jnp.asarray(bg), photo), m, atol=3e-3)


def test_perturbed_poses_are_off_by_exactly_the_amounts_asked():
    poses = np.stack([np.eye(4)] * 6)
    poses[:, :3, 3] = np.random.default_rng(2).normal(size=(6, 3))
    out = perturb_poses(poses, 1.0, 0.08, seed=4)
    deg, dist = pose_error(out, poses)
    assert np.allclose(deg, 1.0, atol=1e-3) and np.allclose(dist, 0.08, atol=1e-6)
    assert not np.allclose(out[0, :3, :3], out[1, :3, :3])  # random directions
    # a similar copy (turned, moved, scaled) aligns back to no error; the perturbed one keeps its own
    turn = np.eye(4)
    turn[:3, :3] = Rotation.from_rotvec([0.3, -0.5, 0.2]).as_matrix()
    moved = turn @ poses
    moved[:, :3, 3] = 2.5 * moved[:, :3, 3] + [1.0, -2.0, 0.5]
    assert np.allclose(aligned_pose_error(moved, poses), 0.0, atol=1e-6)
    deg, dist = aligned_pose_error(out, poses)
    assert 0.5 < deg <= 1.0 + 1e-6 and 0.0 < dist <= 0.08 + 1e-6


def _angle(r):
    """Rotation angle of R [3, 3] in degrees (rotation_angle)."""
    return float(rotation_angle(np.asarray(r)[None])[0])


def _rig(n=7, seed=5):
    rng = np.random.default_rng(seed)
    poses = np.stack([np.eye(4)] * n)
    poses[:, :3, :3] = Rotation.from_rotvec(rng.normal(0, 0.6, (n, 3))).as_matrix()
    poses[:, :3, 3] = rng.normal(size=(n, 3))
    return poses


def test_refinement_that_moves_the_whole_rig_maps_other_views_along():
    """Corrections xi_k that amount to one rigid motion G of every camera (c2w_k T(xi_k) = G c2w_k): the similarity
    from the given to the refined training poses is G, so another view's given pose is rendered from G c2w; per-photo
    corrections with no common part leave other views nearly where they were."""
    train, views = _rig(), _rig(3, seed=9)
    g = np.eye(4)
    g[:3, :3] = Rotation.from_rotvec([0.02, -0.01, 0.015]).as_matrix()
    g[:3, 3] = [0.03, -0.02, 0.01]
    extent = camera_extent(train)
    rel = np.linalg.inv(train) @ g @ train  # T(xi_k) = c2w_k^-1 G c2w_k
    xi = np.concatenate([Rotation.from_matrix(rel[:, :3, :3]).as_rotvec(), rel[:, :3, 3] / extent], -1)
    assert np.allclose(np.asarray(corrected_pose(jnp.asarray(train, jnp.float32), jnp.asarray(xi, jnp.float32),
                                                 extent)), g @ train, atol=1e-5)
    s, r, t = refinement_similarity(train, xi)
    assert abs(s - 1.0) < 1e-5 and np.allclose(r, g[:3, :3], atol=1e-5) and np.allclose(t, g[:3, 3], atol=1e-5)
    assert np.allclose(apply_similarity(views, s, r, t), g @ views, atol=1e-5)
    assert abs(_angle(r) - np.degrees(np.linalg.norm([0.02, -0.01, 0.015]))) < 1e-3 and np.linalg.norm(t) > 0
    # independent corrections (no common motion to speak of): other views stay nearly put
    many = _rig(40, seed=3)  # each corrected by ~0.3 degrees, their common part ~0.3 / sqrt(40)
    noise = np.random.default_rng(1).normal(0, 0.003, (len(many), 6))
    noise -= noise.mean(0)
    s, r, t = refinement_similarity(many, noise)
    deg, dist = pose_error(apply_similarity(views, s, r, t), views)
    assert _angle(r) < 0.1 and deg.max() < 0.1 and dist.max() < 0.01 * camera_extent(many)


def test_similarity_fit_undoes_a_similarity_and_not_noise():
    poses = _rig()
    s0, r0, t0 = 1.7, Rotation.from_rotvec([0.4, 0.1, -0.3]).as_matrix(), np.array([0.5, 1.0, -2.0])
    moved = apply_similarity(poses, s0, r0, t0)
    s, r, t = similarity_fit(poses, moved)
    assert abs(s - s0) < 1e-9 and np.allclose(r, r0) and np.allclose(t, t0)
    assert np.allclose(moved[:, :3, 3], s0 * poses[:, :3, 3] @ r0.T + t0)  # centres: s R o + t
    assert np.allclose(pose_error(apply_similarity(poses, *similarity_fit(poses, poses)), poses), 0.0, atol=1e-5)
    # independent errors of each pose (1 degree, 2% of the rig's size, random directions) are not a similarity:
    # the fit over 40 poses stays near the identity, and a similarity on top of them is still found
    many = _rig(40, seed=2)
    noisy = perturb_poses(many, 1.0, 0.02 * camera_extent(many), seed=4)
    s, r, t = similarity_fit(many, noisy)
    assert abs(s - 1) < 0.01 and _angle(r) < 0.5 and np.linalg.norm(t) < 0.01 * camera_extent(many)
    s, r, t = similarity_fit(many, apply_similarity(noisy, s0, r0, t0))
    assert abs(s - s0) < 0.02 and _angle(r.T @ r0) < 0.5


def test_pose_error_keeps_small_angles_between_float32_rotations():
    # arccos of the trace loses angles under a few hundredths of a degree to float32's 1e-7 (rotation_angle)
    rng = np.random.default_rng(5)
    base = Rotation.random(8, random_state=6).as_matrix()
    for deg in (0.0, 0.004, 0.01, 0.07, 1.0, 120.0, 179.9):
        axes = rng.normal(size=(8, 3))
        turn = Rotation.from_rotvec(np.radians(deg) * axes / np.linalg.norm(axes, axis=1, keepdims=True)).as_matrix()
        a, b = np.stack([np.eye(4)] * 8), np.stack([np.eye(4)] * 8)
        a[:, :3, :3], b[:, :3, :3] = base.astype(np.float32), (base @ turn).astype(np.float32)
        assert np.allclose(pose_error(a, b)[0], deg, atol=2e-4), deg
        assert np.allclose(rotation_angle(np.einsum("nji,njk->nik", base, base @ turn)), deg, atol=1e-9)

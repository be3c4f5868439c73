"""Per-photo corrections learned with a scene: a camera pose correction and a colour transform.

Pose (nerfstudio's "SO3xR3" parameterisation): xi = (w, v) [6], w an axis-angle rotation (radians)
and v a translation in units of `scale` (the scene extent, so one learning rate suits every scene),
applied in the camera's own frame:

    c2w' = c2w T(xi),    T(xi) = [[R(w), scale v], [0, 1]],
    R(w) = I + a [w]x + b [w]x^2,   a = sin(t) / t,  b = (1 - cos(t)) / t^2,  t = |w|  (Rodrigues)

(a and b by their Taylor series near t = 0, so R and its gradient are exact at the identity, where
every correction starts.)

Colour (an affine map of linear RGB per photo: exposure, white balance, a camera's tone curve to first
order): m [3, 4] starts at zero and

    rgb' = (I + m[:, :3]) rgb + m[:, 3]

applied to what the scene renders, not to a background colour composited behind it (masked captures and
Blender scenes paint their background white in every photo whatever the exposure): with opacity a and
background b, the rendered c = f + (1 - a) b of the scene's part f becomes (I + m[:, :3]) f + a m[:, 3] + (1 - a) b.

Held-out photos, which have no transform of their own, use the mean of the training photos' (the fields'
appearance embeddings do the same: fields/ngp.py), or one fitted to a part of the photo (fit_color, in closed
form since the error is linear in m: `nerfkit eval --fit-colour`).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

SMALL_ANGLE = 1e-3  # below this |w| (radians) the Taylor series of a and b (error < 1e-13)


def skew(w: jnp.ndarray) -> jnp.ndarray:
    """[w]x [..., 3, 3] of w [..., 3]: [w]x u = w x u."""
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    o = jnp.zeros_like(x)
    return jnp.stack([jnp.stack([o, -z, y], -1), jnp.stack([z, o, -x], -1), jnp.stack([-y, x, o], -1)], -2)


def so3_exp(w: jnp.ndarray) -> jnp.ndarray:
    """R(w) [..., 3, 3] of axis-angle w [..., 3] (Rodrigues; see the module docstring)."""
    t2 = jnp.sum(w * w, axis=-1)[..., None, None]
    small = t2 < SMALL_ANGLE ** 2
    t2_safe = jnp.where(small, 1.0, t2)  # keeps the unused branch's gradient finite
    t = jnp.sqrt(t2_safe)
    a = jnp.where(small, 1.0 - t2 / 6.0 + t2 * t2 / 120.0, jnp.sin(t) / t)
    b = jnp.where(small, 0.5 - t2 / 24.0 + t2 * t2 / 720.0, (1.0 - jnp.cos(t)) / t2_safe)
    k = skew(w)
    return jnp.eye(3, dtype=w.dtype) + a * k + b * (k @ k)


def corrected_pose(c2w: jnp.ndarray, xi: jnp.ndarray, scale: float = 1.0) -> jnp.ndarray:
    """c2w' = c2w T(xi) [..., 4, 4] of c2w [..., 4, 4] and xi [..., 6] (module docstring)."""
    r = so3_exp(xi[..., :3])
    t = scale * xi[..., 3:]
    top = jnp.concatenate([c2w[..., :3, :3] @ r, (c2w[..., :3, :3] @ t[..., None]) + c2w[..., :3, 3:]], -1)
    return jnp.concatenate([top, c2w[..., 3:, :]], -2)


def corrected_color(rgb: jnp.ndarray, m: jnp.ndarray, coverage=1.0) -> jnp.ndarray:
    """rgb' [..., 3] = (I + m[:, :3]) rgb + coverage m[:, 3] of rgb [..., 3] and one photo's m [3, 4]; coverage
    [..., 1] (or 1) scales the offset to the share of the pixel the scene covers (corrected_composite)."""
    return rgb + rgb @ m[:, :3].T + coverage * m[:, 3]


def corrected_composite(rgb: jnp.ndarray, alpha: jnp.ndarray, background: jnp.ndarray, m: jnp.ndarray):
    """rgb [..., 3] = f + (1 - alpha) background, with the scene's part f transformed by m [3, 4] and the
    background kept (module docstring); alpha [...]."""
    rest = (1.0 - alpha)[..., None] * background
    return corrected_color(rgb - rest, m, alpha[..., None]) + rest


COLOR_RIDGE = 1e-4  # per unit of pixel weight: holds at zero what the pixels leave free (a render of one colour)


COLOR_FORMS = {  # the entries of m [3, 4] a colour transform may use
    "affine": np.ones((3, 4), np.float32),  # a 3x3 matrix and an offset: 12 numbers
    "gain": np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]], np.float32),  # a gain per channel: 3
}


def fit_color(rgb: jnp.ndarray, target: jnp.ndarray, coverage=1.0, weight=None, form: str = "affine") -> jnp.ndarray:
    """The transform m [3, 4] (its entries outside COLOR_FORMS[form] zero) for which corrected_color(rgb, m,
    coverage) best matches target [..., 3] (rgb [..., 3]; coverage [..., 1] or 1) in the least-squares sense over
    the pixels, each weighted by weight [...] (None: all alike), with a ridge that keeps m at zero where the pixels
    leave it free. Row c of m (output channel c) is, with D_c = diag(COLOR_FORMS[form][c]) the entries it may use,

        m_c = (D_c X^T W X D_c + eps I + (I - D_c))^-1 D_c X^T W (target_c - rgb_c),
        X = [rgb, coverage] [P, 4],   eps = COLOR_RIDGE sum_p w_p

    (closed form: the error is linear in m)."""
    x = jnp.concatenate([rgb, jnp.broadcast_to(jnp.asarray(coverage, rgb.dtype), rgb.shape[:-1] + (1,))], -1)
    x, y = x.reshape(-1, 4), (target - rgb).reshape(-1, 3)
    w = jnp.ones(x.shape[0], x.dtype) if weight is None else jnp.asarray(weight, x.dtype).reshape(-1)
    xw = x * w[:, None]
    d = jnp.asarray(COLOR_FORMS[form], x.dtype)  # [3, 4]: D_c's diagonals
    eye = jnp.eye(4, dtype=x.dtype)
    a = d[:, :, None] * (xw.T @ x)[None] * d[:, None, :] + COLOR_RIDGE * jnp.sum(w) * eye + (1.0 - d)[:, :, None] * eye
    return jnp.linalg.solve(a, (d * (xw.T @ y).T)[..., None])[..., 0]


def fit_composite(rgb: jnp.ndarray, alpha: jnp.ndarray, background: jnp.ndarray, target: jnp.ndarray,
                  weight=None, form: str = "affine") -> jnp.ndarray:
    """m [3, 4] for which corrected_composite(rgb, alpha, background, m) best matches target [..., 3]: fit_color
    of the scene's part f = rgb - (1 - alpha) background, its offset scaled by alpha [...]."""
    rest = (1.0 - alpha)[..., None] * background
    return fit_color(rgb - rest, target - rest, alpha[..., None], weight, form)


def mean_color(m: np.ndarray) -> np.ndarray:
    """The held-out photos' transform [3, 4]: the mean of the training photos' m [V, 3, 4]."""
    return np.asarray(m, np.float32).mean(axis=0)


def rotation_angle(rel: np.ndarray) -> np.ndarray:
    """The angle in degrees [N] of rotations rel [N, 3, 3]: theta = atan2(|w|, (tr rel - 1) / 2) with w = vee(rel -
    rel^T) / 2 (|w| = sin theta). arccos((tr rel - 1) / 2) alone loses small angles: float32 rotations are orthonormal
    to about 1e-7, an error in the cosine that arccos turns into up to 0.026 degrees near theta = 0 and up to about
    0.01 at the 0.05-0.15 degrees pose refinement leaves; the sine carries theta to that 1e-7 itself."""
    rel = np.asarray(rel, np.float64)
    w = np.stack([rel[:, 2, 1] - rel[:, 1, 2], rel[:, 0, 2] - rel[:, 2, 0], rel[:, 1, 0] - rel[:, 0, 1]], -1) / 2.0
    return np.degrees(np.arctan2(np.linalg.norm(w, axis=-1), (np.trace(rel, axis1=1, axis2=2) - 1.0) / 2.0))


def pose_error(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rotation angle in degrees [N] (rotation_angle of R_a^T R_b), camera-centre distance [N]) between poses a and
    b [N, 4, 4]."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    rel = np.einsum("nji,njk->nik", a[:, :3, :3], b[:, :3, :3])
    return rotation_angle(rel), np.linalg.norm(a[:, :3, 3] - b[:, :3, 3], axis=-1)


def similarity_fit(p: np.ndarray, q: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(s, R [3, 3], t [3]) of the similarity x -> s R x + t that best maps the poses p onto q [N, 4, 4]:
    R the rotation closest to the camera rotations' (argmin sum_k |R P_k - Q_k|^2, an SVD of sum_k Q_k P_k^T),
    then s and t by least squares on the camera centres (s = 1 for a single camera)."""
    p, q = np.asarray(p, np.float64), np.asarray(q, np.float64)
    u, _, vt = np.linalg.svd(np.einsum("nij,nkj->ik", q[:, :3, :3], p[:, :3, :3]))
    r = u @ np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))]) @ vt
    a = (p[:, :3, 3] - p[:, :3, 3].mean(0)) @ r.T
    b = q[:, :3, 3] - q[:, :3, 3].mean(0)
    s = float(np.sum(a * b) / np.sum(a * a)) if np.sum(a * a) > 1e-24 else 1.0
    return s, r, q[:, :3, 3].mean(0) - s * r @ p[:, :3, 3].mean(0)


def apply_similarity(poses: np.ndarray, s: float, r: np.ndarray, t: np.ndarray) -> np.ndarray:
    """poses [N, 4, 4] moved by x -> s R x + t: rotations R P_k, centres s R o_k + t (similarity_fit)."""
    out = np.array(poses, np.float64)
    out[:, :3, :3] = r @ out[:, :3, :3]
    out[:, :3, 3] = s * out[:, :3, 3] @ r.T + t
    return out


def aligned_pose_error(poses: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Median (degrees, distance) between poses and truth [N, 4, 4] after the similarity that best aligns the
    first set to the second (similarity_fit: the frame refined poses live in is free; only their relative errors
    count). Distances in the truth's units."""
    deg, dist = pose_error(apply_similarity(poses, *similarity_fit(poses, truth)), truth)
    return float(np.median(deg)), float(np.median(dist))


def camera_extent(poses: np.ndarray) -> float:
    """E = 1.1 max_k |o_k - mean(o)| of camera centres o_k = poses[:, :3, 3] (3DGS's cameras_extent): the
    unit of the pose corrections' translations."""
    centres = np.asarray(poses, np.float64)[:, :3, 3]
    return float(1.1 * np.linalg.norm(centres - centres.mean(0), axis=-1).max())


def refined_poses(train: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """The training photos' refined poses c2w_k T(xi_k) [N, 4, 4] float64 of their given ones train [N, 4, 4] and
    corrections xi [N, 6] (translations in units of camera_extent(train))."""
    return np.asarray(corrected_pose(jnp.asarray(train, jnp.float32), jnp.asarray(xi, jnp.float32),
                                     camera_extent(train)), np.float64)


def refinement_similarity(train: np.ndarray, xi: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(s, R, t): the similarity (similarity_fit) that best maps the given training poses train [N, 4, 4] onto the
    refined ones (refined_poses(train, xi)). Refinement may move the whole rig (nothing pins the frame) besides
    mending each pose, so views that are no training photo are rendered from apply_similarity(their given poses,
    s, R, t): in the refined frame, with their own errors kept."""
    return similarity_fit(train, refined_poses(train, xi))


def run_poses(params: dict, train: np.ndarray, views: np.ndarray | None = None) -> np.ndarray:
    """The poses [M, 4, 4] float32 a run's scene is seen from. With pose corrections in params ("cam_pose" [N, 6]):
    when views is None, the training photos' own refined poses (train [N, 4, 4]: their given poses); else the
    views' given poses [M, 4, 4] mapped by refinement_similarity(train, xi) (ValueError when xi and train differ
    in length). Without corrections, the given poses."""
    if not isinstance(params, dict) or "cam_pose" not in params:
        return np.asarray(train if views is None else views, np.float32)
    xi = np.asarray(params["cam_pose"], np.float32)
    if len(xi) != len(train):
        raise ValueError(f"{len(xi)} pose corrections for {len(train)} training photos")
    if views is None:
        return refined_poses(train, xi).astype(np.float32)
    return apply_similarity(views, *refinement_similarity(train, xi)).astype(np.float32)


def perturb_poses(poses: np.ndarray, degrees: float, distance: float, seed: int = 0) -> np.ndarray:
    """poses [N, 4, 4] each turned by `degrees` about a random axis and moved by `distance` in a random
    direction (a fixed size, random directions: what a test of pose refinement perturbs by)."""
    rng = np.random.default_rng(seed)
    out = np.array(poses, np.float64)
    for k in range(len(out)):
        axis = rng.normal(size=3)
        w = np.radians(degrees) * axis / np.linalg.norm(axis)
        move = rng.normal(size=3)
        out[k, :3, :3] = np.asarray(so3_exp(jnp.asarray(w)), np.float64) @ out[k, :3, :3]
        out[k, :3, 3] += distance * move / np.linalg.norm(move)
    return out

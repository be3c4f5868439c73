"""How far recovered cameras are from reference ones, after the best similarity transform.

umeyama (Umeyama 1991): the scale s, rotation R and translation t minimising
sum_k |b_k - (s R a_k + t)|^2 over corresponding points a_k, b_k, from the SVD of their
cross-covariance (with the reflection fix). pose_errors aligns camera centres that way,
then reports centre errors as a fraction of the reference cameras' radius (median distance
to their centroid) and rotation errors as the angle of R R_a R_b^T, in degrees.
"""

from __future__ import annotations

import numpy as np

from nerfkit.rays.correction import rotation_angle


def umeyama(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(s, R [3, 3], t [3]) minimising |dst - (s R src + t)|^2 for points [N, 3]."""
    src, dst = np.asarray(src, np.float64), np.asarray(dst, np.float64)
    mu_s, mu_d = src.mean(0), dst.mean(0)
    xs, xd = src - mu_s, dst - mu_d
    u, sig, vt = np.linalg.svd(xd.T @ xs / len(src))
    fix = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        fix[2, 2] = -1
    rot = u @ fix @ vt
    s = float(np.trace(np.diag(sig) @ fix) / np.mean(np.sum(xs**2, axis=1)))
    return s, rot, mu_d - s * rot @ mu_s


def pose_errors(pred: np.ndarray, ref: np.ndarray) -> dict:
    """Errors of camera-to-world poses pred [N, 4, 4] against ref [N, 4, 4] (same order, same
    camera convention) after aligning centres with umeyama."""
    s, rot, t = umeyama(pred[:, :3, 3], ref[:, :3, 3])
    centres = s * pred[:, :3, 3] @ rot.T + t
    radius = float(np.median(np.linalg.norm(ref[:, :3, 3] - ref[:, :3, 3].mean(0), axis=1)))
    c_err = np.linalg.norm(centres - ref[:, :3, 3], axis=1) / radius
    rel = np.einsum("ij,njk,nlk->nil", rot, pred[:, :3, :3], ref[:, :3, :3])  # R R_a R_b^T
    r_err = rotation_angle(rel)
    return {"n": len(pred), "centre_median": float(np.median(c_err)), "centre_max": float(c_err.max()),
            "rotation_median_deg": float(np.median(r_err)), "rotation_max_deg": float(r_err.max()), "scale": s}

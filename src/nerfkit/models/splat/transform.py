"""Similarity transforms of Gaussians: x -> s R x + t applied to positions, rotations, scales and SH colours.

For M = [[s R, t], [0, 1]] (s > 0, R a rotation), a Gaussian (mu, Sigma = R_q S^2 R_q^T, colour
c(d) of the view direction d) becomes

    mu' = s R mu + t,   R_q' = R R_q (q' = q_R q, w-first),   log_scales' = log_scales + log s,
    c'(d') = c(R^T d')  (the view direction turns with the scene).

SH colours: each band l of the real SH basis is closed under rotation, Y_l(R^T d) = D_l Y_l(d)
with D_l [2l+1, 2l+1], so c'(d) = sum_k c'_k Y_k(d) holds for the band's coefficients
c'_l = D_l^T c_l [2l+1, C]. D_l is obtained exactly (to float64 rounding) by least squares over
64 directions: Y_l(X R) = Y_l(X) D_l^T, X the directions as rows. Band 0 is invariant. The basis
is encoding/sh.py's (3DGS's), written here in float64 numpy.

Reflections (det R < 0) cannot be expressed by a quaternion and are refused, as are
non-uniform scales (not a similarity).
"""

from __future__ import annotations

import numpy as np

_C1 = 0.48860251190291987
_C2 = (1.0925484305920792, -1.0925484305920792, 0.94617469575755997, 0.31539156525251999, 0.54627421529603959)
_C3 = (0.59004358992664352, 2.8906114426405538, 0.45704579946446572, 0.3731763325901154, 1.4453057213202769)


def sh_basis(d: np.ndarray) -> np.ndarray:
    """Real SH Y_k(d) [M, 16] of unit directions d [M, 3], bands 0..3 (encoding/sh.py's order, signs)."""
    d = np.asarray(d, np.float64)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    x2, y2, z2 = x * x, y * y, z * z
    return np.stack([
        np.full_like(x, 0.28209479177387814),
        -_C1 * y, _C1 * z, -_C1 * x,
        _C2[0] * x * y, _C2[1] * y * z, _C2[2] * z2 - _C2[3], _C2[1] * x * z, _C2[4] * (x2 - y2),
        _C3[0] * y * (-3 * x2 + y2), _C3[1] * x * y * z, _C3[2] * y * (1 - 5 * z2), _C3[3] * z * (5 * z2 - 3),
        _C3[2] * x * (1 - 5 * z2), _C3[4] * z * (x2 - y2), _C3[0] * x * (-x2 + 3 * y2),
    ], axis=-1)


def fibonacci_sphere(n: int = 64) -> np.ndarray:
    """n roughly uniform unit directions [n, 3] (golden-angle spiral)."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = np.pi * (1 + 5**0.5) * k
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)


def sh_rotation(rot: np.ndarray) -> np.ndarray:
    """Block-diagonal T [16, 16] with c' = T c for SH coefficients c [16, C] under rotation rot [3, 3]:
    c'(d) = c(rot^T d). Blocks: 1 (band 0), then D_l^T for l = 1, 2, 3."""
    x = fibonacci_sphere()
    a, b = sh_basis(x), sh_basis(x @ np.asarray(rot, np.float64))  # rows: Y(x_i), Y(rot^T x_i)
    t = np.zeros((16, 16))
    for lo, hi in ((0, 1), (1, 4), (4, 9), (9, 16)):
        t[lo:hi, lo:hi] = np.linalg.lstsq(a[:, lo:hi], b[:, lo:hi], rcond=None)[0]
    return t


def rotate_sh(sh: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """SH coefficients sh [N, K, C] (K = 1, 4, 9 or 16; bands from 0) turned by rot [3, 3]."""
    k = sh.shape[1]
    t = sh_rotation(rot)[:k, :k]
    return np.einsum("ij,njc->nic", t, np.asarray(sh, np.float64)).astype(np.float32)


def similarity_parts(m: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(s, R [3, 3], t [3]) of a similarity M [4, 4] = [[s R, t], [0, 1]]; raises ValueError otherwise."""
    m = np.asarray(m, np.float64)
    a = m[:3, :3]
    s = np.cbrt(np.linalg.det(a))
    if not s > 0:
        raise ValueError("the transform reflects or collapses space (det <= 0); Gaussians cannot follow it")
    rot = a / s
    if not np.allclose(rot @ rot.T, np.eye(3), atol=1e-5):
        raise ValueError("the transform is not a similarity (uniform scale times rotation plus translation)")
    return float(s), rot, m[:3, 3].copy()


def rotation_to_quat(rot: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) [4] of a rotation matrix [3, 3] (Shepperd's method, w >= 0)."""
    r = np.asarray(rot, np.float64)
    tr = np.trace(r)
    cands = [1 + tr, 1 + 2 * r[0, 0] - tr, 1 + 2 * r[1, 1] - tr, 1 + 2 * r[2, 2] - tr]  # 4 w^2, 4 x^2, ...
    i = int(np.argmax(cands))
    f = 0.5 * np.sqrt(cands[i])
    if i == 0:
        q = [f, (r[2, 1] - r[1, 2]) / (4 * f), (r[0, 2] - r[2, 0]) / (4 * f), (r[1, 0] - r[0, 1]) / (4 * f)]
    elif i == 1:
        q = [(r[2, 1] - r[1, 2]) / (4 * f), f, (r[0, 1] + r[1, 0]) / (4 * f), (r[0, 2] + r[2, 0]) / (4 * f)]
    elif i == 2:
        q = [(r[0, 2] - r[2, 0]) / (4 * f), (r[0, 1] + r[1, 0]) / (4 * f), f, (r[1, 2] + r[2, 1]) / (4 * f)]
    else:
        q = [(r[1, 0] - r[0, 1]) / (4 * f), (r[0, 2] + r[2, 0]) / (4 * f), (r[1, 2] + r[2, 1]) / (4 * f), f]
    q = np.array(q)
    return q if q[0] >= 0 else -q


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a b of w-first quaternions (broadcasting [..., 4]): R(a b) = R(a) R(b)."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a, np.float64), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, np.float64), -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def transform_gaussians(params: dict, m: np.ndarray) -> dict:
    """The Gaussians `params` (numpy dict, gaussians.py's layout) moved by the similarity M [4, 4]."""
    s, rot, t = similarity_parts(m)
    out = dict(params)
    out["means"] = (np.asarray(params["means"], np.float64) * s @ rot.T + t).astype(np.float32)
    out["log_scales"] = (np.asarray(params["log_scales"], np.float64) + np.log(s)).astype(np.float32)
    out["quats"] = quat_multiply(rotation_to_quat(rot), params["quats"]).astype(np.float32)
    out["sh_dc"] = np.asarray(params["sh_dc"], np.float32)
    rest = np.asarray(params["sh_rest"], np.float32)
    if rest.shape[1]:
        full = np.concatenate([np.zeros_like(rest[:, :1]), rest], axis=1)
        out["sh_rest"] = rotate_sh(full, rot)[:, 1:]
    return out


def invert_similarity(m: np.ndarray) -> np.ndarray:
    """M^-1 [4, 4] of a similarity (e.g. nerfkit's normalised frame -> the capture's coordinates)."""
    s, rot, t = similarity_parts(m)
    inv = np.eye(4)
    inv[:3, :3] = rot.T / s
    inv[:3, 3] = -(rot.T @ t) / s
    return inv

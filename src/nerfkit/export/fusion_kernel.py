"""TSDF fusion on the CPU: tsdf.fuse_points' sums for whole grid lines, as one numba loop.

For grid point x = (axis[i], axis[j], axis[k]) and each view (c2w = [R | o], intrinsics fx, fy, cx, cy; OpenGL
axes), tsdf.view_terms' terms:

    p = R^T (x - o),  z = -p_z,  u = fx p_x / z + cx,  v = -fy p_y / z + cy
    the view counts only if z > 1e-6 and (u, v) lies in its image; then, with D, A its depth and opacity at
    pixel (floor v, floor u) and s = D - z:
        seen += 1
        A < A_FREE:            sum f += 1 - A,                              W += 1 - A        (f = +1)
        else, if s >= -tau:    sum f += A r clip(s / tau, -1, 1),           W += A r,   r = clip(1 + s / tau, 0, 1)

A grid line's sums stay in a small buffer (a few kB) while the views pass over it, and the points' coordinates come
from the axis, where XLA's scan over the views (tsdf.fuse_points, the reference the tests compare against) writes
and reads the sums and a dozen temporaries of a whole slab once per view, from main memory. float32 arithmetic,
as there. The kernel releases the GIL; fuse_lines spreads the grid lines over worker threads.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from nerfkit.core.threads import cpu_count, run_interleaved

CAMERA_FLOATS = 16  # R row-major (9), o (3), fx, fy, cx, cy


def camera_table(c2w: np.ndarray, intr: np.ndarray) -> np.ndarray:
    """[V, CAMERA_FLOATS] float32: each view's rotation (row-major), centre and intrinsics, the kernel's input."""
    c2w = np.asarray(c2w, np.float32)
    return np.ascontiguousarray(np.concatenate([c2w[:, :3, :3].reshape(-1, 9), c2w[:, :3, 3],
                                                np.asarray(intr, np.float32)], 1))


@njit(cache=True, nogil=True)
def fuse_line_kernel(axis, i0, lines, cams, depth, opacity, tau, a_free, fsum, wsum, seen, first, stride):
    """Grid lines l = first, first + stride, ... < lines: the points (axis[i0 + l // N], axis[l % N], axis[k]) for
    every k, their sums written to fsum, wsum, seen [*, N, N] at [l // N, l % N, k] (module docstring), the views
    taken one after the other over the whole line."""
    n = axis.shape[0]
    views, h, w = depth.shape
    zero, one, eps = np.float32(0.0), np.float32(1.0), np.float32(1e-6)
    wf, hf, inv_tau = np.float32(w), np.float32(h), one / tau
    fs, ws, ss = np.empty(n, np.float32), np.empty(n, np.float32), np.empty(n, np.float32)
    for line in range(first, lines, stride):
        a, b = line // n, line % n
        x, y = axis[i0 + a], axis[b]
        fs[:], ws[:], ss[:] = zero, zero, zero
        for v in range(views):
            c = cams[v]
            dx, dy = x - c[9], y - c[10]
            fx, fy, cx, cy = c[12], c[13], c[14], c[15]
            for k in range(n):
                dz = axis[k] - c[11]
                z = -(dx * c[2] + dy * c[5] + dz * c[8])
                if not z > eps:
                    continue
                inv = one / z
                u = fx * (dx * c[0] + dy * c[3] + dz * c[6]) * inv + cx
                vv = cy - fy * (dx * c[1] + dy * c[4] + dz * c[7]) * inv
                if not (u >= zero and u < wf and vv >= zero and vv < hf):
                    continue
                iu, iv = min(int(u), w - 1), min(int(vv), h - 1)
                d, alpha = depth[v, iv, iu], opacity[v, iv, iu]
                ss[k] += one
                s = (d - z) * inv_tau
                if alpha < a_free:
                    fs[k] += one - alpha
                    ws[k] += one - alpha
                elif s >= -one:
                    weight = alpha * min(one + s, one)
                    fs[k] += weight * min(s, one)
                    ws[k] += weight
        fsum[a, b], wsum[a, b], seen[a, b] = fs, ws, ss


def fuse_lines(axis: np.ndarray, i0: int, count: int, cams: np.ndarray, depth: np.ndarray, opacity: np.ndarray,
               tau: float, a_free: float, out: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
    """The sums of the grid's x-slices i0 .. i0 + count - 1 into out = (fsum, wsum, seen) [count, N, N] float32,
    the lines interleaved over one worker thread per CPU (core/threads.py)."""
    n = len(axis)
    args = (np.ascontiguousarray(axis, np.float32), i0, count * n, cams, np.ascontiguousarray(depth, np.float32),
            np.ascontiguousarray(opacity, np.float32), np.float32(tau), np.float32(a_free), *out)
    run_interleaved(fuse_line_kernel, args, cpu_count())

"""The control for export_silhouette.py: how exact geometry scores on its per-pixel silhouette test.

    python benchmarks/silhouette_control.py [--views 50] [--width 200]

Points sampled exactly on the surface of a sphere and of a capped rod (radii in pixels of a
width x width image seen from 4 units away), 50 views from random directions (elevation within
+-40 degrees), each view's silhouette as the exact pixel coverage (6 x 6 rays per pixel,
analytic ray-primitive intersections from nerfkit.data.procedural.scene). Scored with export_silhouette's
`score`: a point passes when the pixel it projects into has coverage > 0.5 in >= 95% of the
views that see it, strictly and within one pixel.

Why it matters: a surface point on the object's outer contour in some view projects onto the
silhouette's edge, where the pixel it falls in is covered less than half in about half the cases.
Every point of an isolated convex shape is on the contour for a band of view directions
(~sqrt(1 / radius_px) radians wide), so exact geometry misses the strict test in a few percent of
its views and many points fail the 95% bar, while all pass within one pixel.
"""

from __future__ import annotations

import argparse

import numpy as np
from export_silhouette import score

from nerfkit.data.procedural.scene import intersect_cylinder, intersect_sphere, look_at
from nerfkit.rays.cameras import Camera

DISTANCE = 4.0
SUPERSAMPLE = 6


def coverage(hit_fn, c2w: np.ndarray, cam: Camera) -> np.ndarray:
    """Exact-ish pixel coverage [H, W] of the primitive hit_fn(o, d) -> t (inf on miss)."""
    s = SUPERSAMPLE
    u, v = np.meshgrid((np.arange(cam.width * s) + 0.5) / s, (np.arange(cam.height * s) + 0.5) / s)
    d = np.stack([(u - cam.cx) / cam.fx, -(v - cam.cy) / cam.fy, -np.ones_like(u)], -1) @ c2w[:3, :3].T
    hit = np.isfinite(hit_fn(np.broadcast_to(c2w[:3, 3], d.shape), d))
    return hit.reshape(cam.height, s, cam.width, s).mean(axis=(1, 3))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--views", type=int, default=50)
    ap.add_argument("--width", type=int, default=200)
    ap.add_argument("--points", type=int, default=4000)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    cam = Camera.pinhole(args.width, args.width, 1.375 * args.width)  # ~40 degrees field of view
    az, el = rng.uniform(0, 2 * np.pi, args.views), np.radians(rng.uniform(-40, 40, args.views))
    poses = [look_at(DISTANCE * np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)]))
             for a, e in zip(az, el)]
    print(f"exact surface points, {args.views} views at {args.width}x{args.width}: points passing (inside in >= 95% "
          f"of the views that see them)")
    for kind, radius_px in (("sphere", 10), ("sphere", 30), ("sphere", 80), ("rod", 2), ("rod", 8)):
        r = radius_px * DISTANCE / cam.fx
        if kind == "sphere":
            g = rng.normal(size=(args.points, 3))
            pts = r * g / np.linalg.norm(g, axis=1, keepdims=True)

            def hit(o, d, r=r):
                return intersect_sphere(o, d, np.zeros(3), r)
        else:
            th, z = rng.uniform(0, 2 * np.pi, args.points), rng.uniform(-0.5, 0.5, args.points)
            pts = np.stack([r * np.cos(th), r * np.sin(th), z], -1)

            def hit(o, d, r=r):
                return intersect_cylinder(o, d, np.zeros(2), r, (-0.6, 0.6))
        views = [(coverage(hit, c2w, cam), c2w, cam) for c2w in poses]
        rates = []
        for tol in (0, 1):
            n, inside, _, _ = score(pts, views, tolerance_px=tol)
            seen = n > 0
            rates.append((100 * np.mean(inside[seen] / n[seen] >= 0.95), 100 * inside.sum() / n.sum()))
        print(f"  {kind:6s} radius {radius_px:3d} px: strict {rates[0][0]:5.1f}% pass ({rates[0][1]:.2f}% of "
              f"projections inside); within 1 px {rates[1][0]:5.1f}% pass ({rates[1][1]:.2f}%)", flush=True)


if __name__ == "__main__":
    main()

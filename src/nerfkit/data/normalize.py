"""Pose normalisation of real captures and the size of the box that holds a masked object.

A capture comes in whatever coordinates its SfM chose. nerfkit moves it into the frame the
fields assume (instant-ngp's convention, the Blender scenes' too):

    x_n = s R (x - c)

with c the focus point (the point closest to all optical axes), R the rotation taking the
mean camera up vector to +z (so orbits and viewers have a natural up), then turning about z
until the first camera (in file-name order) looks along +y, and s the scale that puts the
cameras at median distance CAMERA_RADIUS from c. So the result does not depend on the
coordinates SfM happened to choose. A camera-to-world pose becomes
[R R_cam | s R (t - c)]; depths (along unnormalised rays) scale by s. The 4x4 matrix
M = [[s R, -s R c], [0, 1]] is kept with the run, so renders and exports go back to the
capture's own coordinates with M^-1.
"""

from __future__ import annotations

import math

import numpy as np

from nerfkit.rays.cameras import Camera, scene_center

CAMERA_RADIUS = 4.0
FORWARD_DEGREES = 45.0  # forward-facing: every optical axis within this angle of the mean axis


def view_spread(poses: np.ndarray) -> float:
    """The largest angle, in degrees, between a camera's optical axis (-z of c2w [N, 4, 4]) and the
    mean axis: a few degrees for a forward-facing capture (LLFF's), 60-180 for one all around the scene
    (a ring looking down at 10-50 degrees of elevation: ~80)."""
    a = -np.asarray(poses, np.float64)[:, :3, 2]
    a /= np.linalg.norm(a, axis=-1, keepdims=True)
    mean = a.sum(0)
    norm = np.linalg.norm(mean)
    if norm < 1e-9:  # axes that cancel out: all around
        return 180.0
    return float(np.degrees(np.arccos(np.clip(a @ (mean / norm), -1.0, 1.0))).max())


def forward_facing(poses: np.ndarray) -> bool:
    """Whether every camera faces one way (view_spread under FORWARD_DEGREES): a forward-facing capture."""
    return len(poses) > 0 and view_spread(poses) < FORWARD_DEGREES


def rotation_to_z(up: np.ndarray) -> np.ndarray:
    """The rotation [3, 3] taking unit vector `up` to +z along the great circle (Rodrigues)."""
    up = np.asarray(up, np.float64) / np.linalg.norm(up)
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(up, z)
    c = float(up @ z)
    if c < -1 + 1e-9:  # up = -z: half a turn about x
        return np.diag([1.0, -1.0, -1.0])
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def focus_point(poses: np.ndarray) -> np.ndarray:
    """The point the cameras look at (least squares over optical axes); the mean camera
    position when that point lies behind most cameras (outward-facing or parallel captures)."""
    c = scene_center(poses)
    fwd = -poses[:, :3, 2]
    in_front = np.einsum("ki,ki->k", c[None] - poses[:, :3, 3], fwd) > 0
    return c if in_front.mean() >= 0.5 else poses[:, :3, 3].mean(0)


def normalizing_transform(poses: np.ndarray, radius: float = CAMERA_RADIUS) -> tuple[np.ndarray, float]:
    """(M [4, 4], s): x_n = M [x, 1] = s R (x - c), see the module docstring."""
    poses = np.asarray(poses, np.float64)
    c = focus_point(poses)
    rot = rotation_to_z(poses[:, :3, 1].mean(0))
    fwd = rot @ -poses[0, :3, 2]
    if np.hypot(fwd[0], fwd[1]) > 1e-6:  # turn about z: the first camera's view, seen from above, along +y
        a = math.atan2(fwd[0], fwd[1])
        yaw = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
        rot = yaw @ rot
    dist = np.median(np.linalg.norm(poses[:, :3, 3] - c, axis=-1))
    s = radius / dist if dist > 1e-12 else 1.0
    m = np.eye(4)
    m[:3, :3] = s * rot
    m[:3, 3] = -s * rot @ c
    return m, float(s)


def apply_transform(m: np.ndarray, scale: float, c2w: np.ndarray) -> np.ndarray:
    """Camera-to-world poses [..., 4, 4] moved by the similarity m (of scale `scale`)."""
    out = np.array(c2w, np.float64, copy=True)
    out[..., :3, :3] = (m[:3, :3] / scale) @ out[..., :3, :3]
    out[..., :3, 3] = out[..., :3, 3] @ m[:3, :3].T + m[:3, 3]
    return out


def undo_transform(m: np.ndarray, scale: float, c2w: np.ndarray) -> np.ndarray:
    """Camera-to-world poses [..., 4, 4] (float64) in the capture's own coordinates of normalised ones c2w:
    M^-1 c2w diag(s, s, s, 1), the inverse of apply_transform(m, scale, .)."""
    return np.linalg.inv(np.asarray(m, np.float64)) @ np.asarray(c2w, np.float64) @ np.diag([scale] * 3 + [1.0])


def masked_bound(poses: np.ndarray, cameras: list[Camera], alphas: np.ndarray, resolution: int = 64,
                 margin: float = 1.1) -> float | None:
    """Half-size B of the box [-B, B]^3 that holds a masked object: its visual hull.

    Points of a grid are kept when at least half of the cameras see them (the object is
    what was photographed) and every camera that sees them finds them inside its mask
    (alpha > 0.5, pinhole projection; a point outside an image says nothing, so objects
    cut by the frame edge keep their parts). A first grid spans the ball inside the nearest
    camera, a second one the box found by the first. B = margin * (the largest |coordinate|
    kept + one cell), or None if no point is kept.
    """
    extent = 0.95 * float(np.min(np.linalg.norm(poses[:, :3, 3], axis=-1)))
    for _ in range(2):
        g = (np.arange(resolution) + 0.5) / resolution * 2 * extent - extent
        pts = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
        keep = inside_visual_hull(pts, poses, cameras, alphas)
        if not keep.any():
            return None
        extent = min(extent, float(np.abs(pts[keep]).max() + 2 * extent / resolution))
    return margin * extent


def inside_visual_hull(pts, poses, cameras, alphas) -> np.ndarray:
    """bool [P]: points [P, 3] inside the visual hull of the silhouettes alphas [N, H, W] (> 1/2; uint8 or
    float) seen by pinhole cameras at poses [N, 4, 4]: seen by at least half of the cameras, and inside the
    silhouette of every camera that sees them (see masked_bound)."""
    keep = np.ones(len(pts), bool)
    n_seen = np.zeros(len(pts), np.int32)
    for pose, cam, alpha in zip(poses, cameras, alphas):
        rel = (pts - pose[:3, 3]) @ pose[:3, :3]  # camera coordinates (OpenGL)
        z = -rel[:, 2]
        front = z > 1e-6
        u = cam.fx * rel[:, 0] / np.where(front, z, 1) + cam.cx
        v = -cam.fy * rel[:, 1] / np.where(front, z, 1) + cam.cy
        h, w = alpha.shape
        seen = front & (u >= 0) & (u < w) & (v >= 0) & (v < h)
        ui = np.clip(u.astype(int), 0, w - 1)
        vi = np.clip(v.astype(int), 0, h - 1)
        inside = alpha[vi, ui] > 0.5 * (255 if alpha.dtype == np.uint8 else 1.0)
        keep &= ~seen | inside
        n_seen += seen
    return keep & (n_seen >= 0.5 * len(poses))


def sample_visual_hull(n: int, box: float, poses: np.ndarray, cameras: list[Camera], alphas: np.ndarray,
                       seed: int = 0, tries: int = 64) -> np.ndarray | None:
    """Up to n points [n, 3] uniform in the visual hull (inside_visual_hull) within [-box, box]^3: uniform
    points of the box, kept when inside, in rounds of 4n until n are kept, a round keeps none or `tries` rounds
    are done; None when nothing was kept (an empty hull)."""
    rng = np.random.default_rng(seed)
    kept: list[np.ndarray] = []
    total = 0
    for _ in range(tries):
        pts = rng.uniform(-box, box, (4 * n, 3))
        inside = pts[inside_visual_hull(pts, poses, cameras, alphas)]
        if not len(inside):
            break
        kept.append(inside)
        total += len(inside)
        if total >= n:
            break
    return np.concatenate(kept)[:n] if kept else None


NDC_NEAR_PERCENTILE, NDC_NEAR_MARGIN, NDC_EXTENT_MARGIN = 1.0, 0.9, 1.05


def mean_camera(poses: np.ndarray) -> np.ndarray:
    """The reference camera of a forward-facing capture [3, 4] = [R | c] (camera-to-world, looking along -z):
    c the mean camera centre, -z the mean optical axis, y the mean up vector made orthogonal to it."""
    poses = np.asarray(poses, np.float64)
    back = poses[:, :3, 2].mean(0)
    back /= np.linalg.norm(back)
    up = poses[:, :3, 1].mean(0)
    up -= (up @ back) * back
    up /= np.linalg.norm(up)
    return np.concatenate([np.stack([np.cross(up, back), up, back], 1), poses[:, :3, 3].mean(0)[:, None]], 1)


def ndc_space(poses: np.ndarray, cameras: list[Camera], points: np.ndarray) -> tuple[np.ndarray, float, list]:
    """(frame [3, 4], near n, slopes [a_x, a_y]) of the NDC of a forward-facing capture (rays/coord.ndc) from its
    camera-to-world poses [N, 4, 4], cameras and points [P, 3] (normalised coordinates):
        frame   mean_camera(poses)
        n       NDC_NEAR_MARGIN (0.9) x the NDC_NEAR_PERCENTILE-th (1st) percentile of the depths z of the points
                ahead of it (LLFF's and NeRF's near bound: 0.9 x a low percentile of the SfM points' depths)
        a       NDC_EXTENT_MARGIN (1.05) x the largest |q_x / z|, |q_y / z| on the rays through the photos' corner
                pixels from where they cross the near plane (or leave their camera, if it is beyond) to infinity:
                every pixel's ray lies inside the cube past the near plane.
    ValueError when no point lies ahead of the reference camera."""
    frame = mean_camera(poses)
    rot, c = frame[:, :3], frame[:, 3]
    z = -(np.asarray(points, np.float64) - c) @ rot[:, 2]
    z = z[z > 0]
    if z.size == 0:
        raise ValueError("no point lies in front of the cameras")
    near = NDC_NEAR_MARGIN * float(np.percentile(z, NDC_NEAR_PERCENTILE))
    slopes = np.zeros(2)
    for pose, cam in zip(np.asarray(poses, np.float64), cameras):
        x, y = cam.normalized_coords(np.array([0.0, cam.width, 0.0, cam.width]),
                                     np.array([0.0, 0.0, cam.height, cam.height]))
        d = np.stack([x, -y, -np.ones_like(x)], -1) @ pose[:3, :3].T @ rot  # corner rays in the frame [4, 3]
        o = (pose[:3, 3] - c) @ rot
        d = d[d[:, 2] < 0]  # rays that go deeper (a corner ray that does not never reaches the scene)
        if not len(d):
            continue
        t0 = np.maximum(0.0, (-near - o[2]) / d[:, 2])
        start = o + t0[:, None] * d  # the slope q / z is monotone along a ray: its extremes are at the ends
        ends = np.concatenate([start[:, :2] / -start[:, 2:], d[:, :2] / -d[:, 2:]])
        slopes = np.maximum(slopes, np.abs(ends).max(0))
    return frame, near, (NDC_EXTENT_MARGIN * slopes).tolist()

"""Cameras and rays (OpenGL convention: camera looks down -z, +y up, x right).

A `Camera` holds one image's intrinsics in COLMAP's pixel convention: pixel (row i, col j)
has its centre at image coordinates (u, v) = (j + 0.5, i + 0.5). For a pinhole camera with
focal lengths fx, fy and principal point (cx, cy) the ray through that pixel has, in camera
coordinates,

    d_cam = ((u - cx) / fx,  -(v - cy) / fy,  -1)

and in world coordinates d = R d_cam, o = c2w[:3, 3]. A camera with a lens model (radial,
OpenCV, fisheye: any COLMAP model) maps (u, v) to the undistorted normalised coordinates
(x, y) = (X/Z, Y/Z) with pycolmap's `cam_from_img`, and d_cam = (x, -y, -1) (OpenCV's y
points down, OpenGL's up). Directions are NOT normalised, so the ray parameter t of a point
o + t d is its depth along the camera's viewing axis (z-depth): near/far bounds and
rendered depth maps are in that unit.

The Blender scenes' cameras are pinhole with cx = W/2, cy = H/2 and fx = fy = focal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.rays.frustum import pixel_base_radius

PINHOLE_MODELS = ("PINHOLE", "SIMPLE_PINHOLE")
# Perspective models that are an ideal pinhole when all their distortion terms are zero
# (fisheye and other models never are).
POLYNOMIAL_MODELS = ("SIMPLE_RADIAL", "RADIAL", "OPENCV", "FULL_OPENCV")


@dataclass(frozen=True)
class Camera:
    """Intrinsics of one image: size, pinhole part, and an optional COLMAP lens model.

    `params` is the model's full COLMAP parameter vector (e.g. OPENCV: fx, fy, cx, cy, k1,
    k2, p1, p2), empty for a pinhole camera; fx, fy, cx, cy repeat its pinhole part.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    model: str = "PINHOLE"
    params: tuple[float, ...] = field(default=())

    @staticmethod
    def pinhole(width: int, height: int, focal: float) -> "Camera":
        """The ideal camera of the Blender scenes: fx = fy = focal, principal point at the centre."""
        return Camera(int(width), int(height), float(focal), float(focal), 0.5 * width, 0.5 * height)

    def colmap(self) -> tuple[str, list[float]]:
        """(COLMAP model name, parameter vector) of this camera: its lens model and parameters, or PINHOLE
        (fx, fy, cx, cy) without one; from_colmap's inverse."""
        if self.params:
            return self.model, [float(p) for p in self.params]
        return "PINHOLE", [float(self.fx), float(self.fy), float(self.cx), float(self.cy)]

    @staticmethod
    def from_colmap(model: str, width: int, height: int, params) -> "Camera":
        """A camera from a COLMAP model name and parameter vector (read through pycolmap)."""
        from nerfkit.rays.colmap_compat import (
            pycolmap,  # deferred: pycolmap loads only for lens cameras
        )

        cam = pycolmap.Camera(model=model, width=int(width), height=int(height), params=[float(p) for p in params])
        return _from_pycolmap(cam)

    @property
    def distorted(self) -> bool:
        """True when pixels must go through the lens model (any non-zero distortion term)."""
        if self.model in PINHOLE_MODELS or not self.params:
            return False
        if self.model not in POLYNOMIAL_MODELS:
            return True
        cam = self._pycolmap()
        return bool(np.any(np.asarray(cam.params)[list(cam.extra_params_idxs())] != 0))

    def _pycolmap(self):
        from nerfkit.rays.colmap_compat import (
            pycolmap,  # deferred: pycolmap loads only for lens cameras
        )

        return pycolmap.Camera(model=self.model, width=self.width, height=self.height, params=list(self.params))

    def scaled(self, factor: float, width: int | None = None, height: int | None = None) -> "Camera":
        """The same camera for images resized by `factor` (< 1 shrinks): focal lengths and
        principal point scale by exactly `factor`, distortion terms (in normalised
        coordinates) do not. width / height default to the rounded scaled size (pass the
        floor when the remainder was cropped off)."""
        w = int(round(self.width * factor)) if width is None else int(width)
        h = int(round(self.height * factor)) if height is None else int(height)
        params = self.params
        if params:
            cam = self._pycolmap()
            p = np.asarray(cam.params, np.float64)
            idx = list(cam.focal_length_idxs()) + list(cam.principal_point_idxs())
            p[idx] *= factor
            params = tuple(float(x) for x in p)
        return Camera(w, h, self.fx * factor, self.fy * factor, self.cx * factor, self.cy * factor, self.model, params)

    def undistorted(self) -> "Camera":
        """The pinhole camera COLMAP's undistorter makes of this one (pycolmap.undistort_camera with its
        defaults: the same focal lengths, and the size and principal point of the largest image whose every
        pixel sees inside the photo); the camera itself when it is not distorted."""
        if not self.distorted:
            return self
        from nerfkit.rays.colmap_compat import (
            pycolmap,  # deferred: pycolmap loads only for lens cameras
        )

        return _from_pycolmap(pycolmap.undistort_camera(pycolmap.UndistortCameraOptions(), self._pycolmap()))

    def with_size(self, width: int, height: int) -> "Camera":
        """A pinhole camera of another size with the same field of view and centred
        principal point (for renders at a new resolution; the lens model is dropped)."""
        s = width / self.width
        return Camera(int(width), int(height), self.fx * s, self.fy * s, 0.5 * width, 0.5 * height)

    def normalized_coords(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Undistorted normalised coordinates (x, y) = (X/Z, Y/Z), OpenCV axes, of image points (u, v)."""
        u = np.asarray(u, np.float64)
        v = np.asarray(v, np.float64)
        if not self.distorted:
            return (u - self.cx) / self.fx, (v - self.cy) / self.fy
        xy = self._pycolmap().cam_from_img(np.stack([u.ravel(), v.ravel()], -1))
        return xy[:, 0].reshape(u.shape), xy[:, 1].reshape(u.shape)

    def project(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Image coordinates (u, v) of normalised coordinates (x, y): the inverse of normalized_coords."""
        x = np.asarray(x, np.float64)
        y = np.asarray(y, np.float64)
        if not self.distorted:
            return x * self.fx + self.cx, y * self.fy + self.cy
        pts = np.stack([x.ravel(), y.ravel(), np.ones(x.size)], -1)
        uv = self._pycolmap().img_from_cam(pts, check_cheirality=False)
        return uv[:, 0].reshape(x.shape), uv[:, 1].reshape(x.shape)

    def directions(self) -> np.ndarray:
        """Camera-space ray directions of all pixel centres, [H, W, 3] float32, z = -1."""
        v, u = np.meshgrid(np.arange(self.height) + 0.5, np.arange(self.width) + 0.5, indexing="ij")
        x, y = self.normalized_coords(u, v)
        return np.stack([x, -y, -np.ones_like(x)], -1).astype(np.float32)

    def to_json(self) -> dict:
        out = {"width": self.width, "height": self.height, "fx": self.fx, "fy": self.fy, "cx": self.cx, "cy": self.cy,
               "model": self.model}
        if self.params:
            out["params"] = list(self.params)
        return out

    @staticmethod
    def from_json(d: dict) -> "Camera":
        return Camera(int(d["width"]), int(d["height"]), float(d["fx"]), float(d["fy"]), float(d["cx"]),
                      float(d["cy"]), d.get("model", "PINHOLE"), tuple(float(p) for p in d.get("params", ())))


def _from_pycolmap(cam) -> Camera:
    model = cam.model.name
    params = tuple(float(p) for p in cam.params)
    if model in PINHOLE_MODELS:
        params = ()
        model = "PINHOLE"
    return Camera(int(cam.width), int(cam.height), float(cam.focal_length_x), float(cam.focal_length_y),
                  float(cam.principal_point_x), float(cam.principal_point_y), model, params)



def pinhole_directions(i, j, fx, fy, cx, cy):
    """Camera-space directions [..., 3] ((u - cx)/fx, -(v - cy)/fy, -1), u = j + 0.5, v = i + 0.5.

    i, j and the intrinsics broadcast against each other (numpy or jax arrays)."""
    xp = jnp if any(isinstance(a, jnp.ndarray) for a in (i, j, fx)) else np
    x = (j + 0.5 - cx) / fx
    y = -(i + 0.5 - cy) / fy
    return xp.stack([x, y, -xp.ones_like(x)], axis=-1)


def rotate_directions(c2w, d_cam):
    """World-space rays of camera-space directions d_cam [..., 3] for cameras c2w [..., 4, 4].

    Returns origins, directions, both [..., 3]."""
    xp = jnp if isinstance(c2w, jnp.ndarray) or isinstance(d_cam, jnp.ndarray) else np
    rot = c2w[..., :3, :3]
    d = xp.sum(rot * d_cam[..., None, :], axis=-1)
    o = xp.broadcast_to(c2w[..., :3, 3], d.shape)
    return o, d




def camera_rays(c2w: np.ndarray, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """All pixel-centre rays of `camera` at pose c2w (lens model included): [H, W, 3] each."""
    o, d = rotate_directions(np.asarray(c2w, np.float32)[None, None], camera.directions())
    return o.astype(np.float32), d.astype(np.float32)


def project_points(points: np.ndarray, c2w: np.ndarray, camera: Camera):
    """Image coordinates (u, v) [N] of world points [N, 3] seen by `camera` at pose c2w (lens model
    included), and in_front [N]: the point lies in front of the camera (z-depth > 0; u, v are
    meaningless elsewhere). The inverse of the rays above: x_cam = R^T (x - o), (x, y) =
    (x_cam / z, -y_cam / z) with z = -z_cam, then the lens."""
    p = (np.asarray(points, np.float64) - c2w[:3, 3]) @ np.asarray(c2w, np.float64)[:3, :3]
    z = -p[:, 2]
    front = z > 1e-6
    zs = np.where(front, z, 1.0)
    u, v = camera.project(p[:, 0] / zs, -p[:, 1] / zs)
    return u, v, front


def ray_table(cameras: list[Camera]) -> dict:
    """What the jitted training step needs to make the ray of any pixel of any frame.

    Pinhole cameras: per-frame fx, fy, cx, cy [N], and "radius" [N], the cone radius per unit z-depth of
    the frame's pixels (frustum.pixel_base_radius; mip-NeRF's cones). If any camera has a lens model, also
    "lens": [C, H, W, 2] undistorted normalised coordinates of every pixel of each distinct
    camera and "lens_idx": [N], the table of each frame. All frames share one image size.
    """
    out = {k: np.array([getattr(c, k) for c in cameras], np.float32) for k in ("fx", "fy", "cx", "cy")}
    out["radius"] = np.asarray(pixel_base_radius(out["fx"], out["fy"]), np.float32)
    if any(c.distorted for c in cameras):
        unique: list[Camera] = []
        idx = []
        for c in cameras:
            if c not in unique:
                unique.append(c)
            idx.append(unique.index(c))
        tables = []
        for c in unique:
            d = c.directions()
            tables.append(np.stack([d[..., 0], -d[..., 1]], -1))
        out["lens"] = np.stack(tables).astype(np.float32)
        out["lens_idx"] = np.array(idx, np.int32)
    return out


def draw_pixels(key, n: int, sizes: jnp.ndarray):
    """n pixels drawn uniformly over all pixels of images of sizes [N, 2] (height, width): image
    indices img [n] (image k with probability H_k W_k / sum H W) and rows i, columns j [n]."""
    k_img, k_i, k_j = jax.random.split(key, 3)
    hw = sizes.astype(jnp.float32)
    img = jax.random.categorical(k_img, jnp.log(hw[:, 0] * hw[:, 1]), shape=(n,))
    i = jnp.floor(jax.random.uniform(k_i, (n,)) * hw[img, 0]).astype(jnp.int32)
    j = jnp.floor(jax.random.uniform(k_j, (n,)) * hw[img, 1]).astype(jnp.int32)
    return img, i, j


def table_directions(table: dict, img, i, j):
    """Camera-space directions [..., 3] of pixels (i, j) (int arrays) of frames img, from `ray_table`."""
    if "lens" in table:
        xy = table["lens"][table["lens_idx"][img], i, j]
        return jnp.stack([xy[..., 0], -xy[..., 1], -jnp.ones_like(xy[..., 0])], axis=-1)
    return pinhole_directions(i.astype(jnp.float32), j.astype(jnp.float32), table["fx"][img], table["fy"][img],
                              table["cx"][img], table["cy"][img])


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray = np.array([0.0, 0.0, 1.0])) -> np.ndarray:
    """Camera-to-world matrix [4, 4] of a camera at `eye` looking at `target` (-z toward it)."""
    z = eye - target
    z = z / np.linalg.norm(z)
    x = np.cross(up, z)
    if np.linalg.norm(x) < 1e-8:  # looking straight along `up`: any perpendicular x will do
        x = np.cross(np.array([0.0, 1.0, 0.0]), z)
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, y, z, eye
    return m.astype(np.float32)


def scene_center(poses: np.ndarray) -> np.ndarray:
    """Least-squares point closest to all optical axes (the point cameras look at).

    Minimises sum_k |(I - a_k a_k^T)(p - o_k)|^2 for axes through o_k with unit direction a_k.
    """
    a = -poses[:, :3, 2].astype(np.float64)
    a /= np.linalg.norm(a, axis=-1, keepdims=True)
    o = poses[:, :3, 3].astype(np.float64)
    proj = np.eye(3)[None] - a[:, :, None] * a[:, None, :]
    lhs = proj.sum(0)
    rhs = np.einsum("kij,kj->i", proj, o)
    if np.linalg.cond(lhs) > 1e8:  # all axes parallel: no closest point, use the mean camera position
        return o.mean(0)
    return np.linalg.solve(lhs, rhs)


def orbit_poses(poses: np.ndarray, n_frames: int) -> np.ndarray:
    """A circular orbit [n_frames, 4, 4] around the scene centre, world +z up.

    Radius and elevation are the medians of the given cameras' (the dataset's typical view).
    """
    center = scene_center(poses)
    rel = poses[:, :3, 3] - center
    radius = float(np.median(np.linalg.norm(rel, axis=-1)))
    elev = float(np.median(np.arcsin(np.clip(rel[:, 2] / np.linalg.norm(rel, axis=-1), -1, 1))))
    out = []
    for k in range(n_frames):
        az = 2 * math.pi * k / n_frames
        eye = center + radius * np.array([math.cos(elev) * math.cos(az), math.cos(elev) * math.sin(az), math.sin(elev)])
        out.append(look_at(eye, center))
    return np.stack(out)


def ellipse_orbit_poses(poses: np.ndarray, n_frames: int, center: np.ndarray | None = None) -> np.ndarray:
    """An orbit [n_frames, 4, 4] that follows the cameras of a real capture (world +z up).

    The camera centres, relative to `center` (default: the point the cameras look at), are
    projected on the xy plane; their principal axes (PCA) give the ellipse's orientation and
    the 90th percentile of |coordinate| along each axis its semi-axes (mip-NeRF 360's
    ellipse path). Height: the median camera height. Every frame looks at the centre.
    """
    center = scene_center(poses) if center is None else np.asarray(center, np.float64)
    rel = poses[:, :3, 3].astype(np.float64) - center
    xy = rel[:, :2]
    _, vecs = np.linalg.eigh(np.cov(xy.T) + 1e-12 * np.eye(2))
    axes = vecs[:, ::-1]  # major axis first
    proj = xy @ axes
    semi = np.maximum(np.percentile(np.abs(proj), 90, axis=0), 1e-6)
    z = float(np.median(rel[:, 2]))
    out = []
    for k in range(n_frames):
        a = 2 * math.pi * k / n_frames
        p2 = axes @ np.array([semi[0] * math.cos(a), semi[1] * math.sin(a)])
        out.append(look_at(center + np.array([p2[0], p2[1], z]), center))
    return np.stack(out)

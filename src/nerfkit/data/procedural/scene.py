"""Embedded procedural demo scene: a tiny numpy ray tracer and a Blender-format writer.

The scene is a handful of analytic solids inside the cube [-SCENE_BOUNDS, SCENE_BOUNDS]^3,
coloured with mid-frequency procedural textures and lit by one fixed directional light
plus ambient (Lambertian, so the colour of a surface point does not depend on the view).
Everything outside the solids is empty (alpha = 0), which makes it a drop-in stand-in for
the NeRF "Blender synthetic" scenes:

    out_dir/transforms_{train,val,test}.json
    out_dir/{train,val,test}/r_{k}.png        RGBA uint8, straight alpha, rgb = 0 off-object
    out_dir/{train,val,test}/r_{k}_depth.npy  float32 [H, W] exact z-depth, inf off-object

Rays are o + t * d with d not necessarily unit length; every intersection routine solves
for that same t, so with camera_rays (whose directions have d_cam.z = -1) t is the depth
along the camera's viewing axis (z-depth), exact at pixel centres.

All routines are small pure vectorised numpy functions over arbitrary leading batch
shapes [...]; geometry is computed in float64 and cast to float32 on output.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import imageio.v3 as iio
import numpy as np

from nerfkit.core.errors import DataError
from nerfkit.core.outputs import staged_folder

# --- scene constants -----------------------------------------------------------------------

SCENE_BOUNDS = 1.2  # all geometry lies inside [-SCENE_BOUNDS, SCENE_BOUNDS]^3
CAMERA_RADIUS = 4.0  # cameras sit on a sphere of this radius around the origin
CAMERA_ANGLE_X = 0.6911112070083618  # horizontal field of view (radians), as in lego

# Large sphere, checkerboard in spherical coordinates (red / yellow).
BIG_SPHERE_CENTER = np.array([-0.35, -0.25, 0.05])
BIG_SPHERE_RADIUS = 0.55
# Small sphere, latitude bands (green / white).
SMALL_SPHERE_CENTER = np.array([0.45, -0.55, -0.3])
SMALL_SPHERE_RADIUS = 0.3
# Axis-aligned box, diagonal stripes (blue / pale cyan).
BOX_MIN = np.array([0.15, 0.05, -0.6])
BOX_MAX = np.array([0.75, 0.65, 0.0])
# Upright z-axis cylinder with caps, horizontal rings (magenta / orange).
CYLINDER_CENTER_XY = np.array([-0.3, 0.6])
CYLINDER_RADIUS = 0.2
CYLINDER_Z_RANGE = (-0.6, 0.5)
# Ground: a thin z-axis cylinder (disk slab), grey checkerboard.
GROUND_RADIUS = 1.1
GROUND_Z_RANGE = (-0.7, -0.6)

LIGHT_DIRECTION = np.array([0.4, 0.3, 0.85]) / np.linalg.norm([0.4, 0.3, 0.85])
AMBIENT = 0.35

_EPS = 1e-9  # hits with t <= _EPS are ignored (rays start on or inside the surface)


# --- intersections: each returns t [...] (float64, inf on miss) ----------------------------


def _nearest_root(a, half_b, c):
    """Smallest root t > _EPS of a t^2 + 2 half_b t + c = 0, inf where there is none."""
    disc = half_b**2 - a * c
    hit = disc >= 0
    sq = np.sqrt(np.where(hit, disc, 0.0))
    a_safe = np.where(a > 0, a, 1.0)
    t0 = (-half_b - sq) / a_safe
    t1 = (-half_b + sq) / a_safe
    t = np.where(t0 > _EPS, t0, np.where(t1 > _EPS, t1, np.inf))
    return np.where(hit & (a > 0), t, np.inf)


def intersect_sphere(o, d, center, radius):
    """First t > 0 with |o + t d - center| = radius.

    Solves (d.d) t^2 + 2 (oc.d) t + (oc.oc - r^2) = 0 with oc = o - center.
    o, d: [..., 3]. Returns t [...], inf on miss.
    """
    oc = o - center
    a = np.sum(d * d, axis=-1)
    half_b = np.sum(oc * d, axis=-1)
    c = np.sum(oc * oc, axis=-1) - radius**2
    return _nearest_root(a, half_b, c)


def intersect_box(o, d, lo, hi):
    """First t > 0 where o + t d enters (or, from inside, leaves) the box [lo, hi].

    Slab method: per axis the ray is inside for t between (lo - o)/d and (hi - o)/d;
    t_near = max over axes of the entry times, t_far = min of the exit times, hit iff
    t_near <= t_far. o, d: [..., 3]. Returns t [...], inf on miss.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        t1 = (lo - o) * inv
        t2 = (hi - o) * inv
    t_near = np.max(np.minimum(t1, t2), axis=-1)
    t_far = np.min(np.maximum(t1, t2), axis=-1)
    hit = (t_near <= t_far) & (t_far > _EPS)
    t = np.where(t_near > _EPS, t_near, t_far)
    return np.where(hit, t, np.inf)


def intersect_cylinder(o, d, center_xy, radius, z_range):
    """First t > 0 on a capped cylinder about the z axis: |xy - center_xy| <= r, z0 <= z <= z1.

    Side: the quadratic |oxy + t dxy - c|^2 = r^2, kept where z0 <= z(t) <= z1.
    Caps: t = (z_k - o_z) / d_z, kept where |xy(t) - c| <= r.
    o, d: [..., 3]. Returns t [...], inf on miss.
    """
    z0, z1 = z_range
    oc = o[..., :2] - center_xy
    dxy = d[..., :2]
    a = np.sum(dxy * dxy, axis=-1)
    half_b = np.sum(oc * dxy, axis=-1)
    c = np.sum(oc * oc, axis=-1) - radius**2
    disc = half_b**2 - a * c
    ok = (disc >= 0) & (a > 0)
    sq = np.sqrt(np.where(ok, disc, 0.0))
    a_safe = np.where(a > 0, a, 1.0)
    candidates = [(-half_b - sq) / a_safe, (-half_b + sq) / a_safe]
    ts = []
    for t in candidates:
        z = o[..., 2] + t * d[..., 2]
        ts.append(np.where(ok & (z >= z0) & (z <= z1) & (t > _EPS), t, np.inf))
    dz_safe = np.where(d[..., 2] != 0, d[..., 2], 1.0)
    for zk in (z0, z1):
        t = (zk - o[..., 2]) / dz_safe
        xy = oc + t[..., None] * dxy
        inside = np.sum(xy * xy, axis=-1) <= radius**2
        ts.append(np.where((d[..., 2] != 0) & inside & (t > _EPS), t, np.inf))
    return np.min(np.stack(ts, axis=0), axis=0)


# --- shading: each maps hit points p [N, 3] to (outward normal [N, 3], albedo [N, 3]) -------


def _parity(*cells):
    """1.0 where the sum of the integer cell indices is odd, else 0.0."""
    return (np.sum(np.stack(cells, 0), axis=0).astype(np.int64) % 2).astype(np.float64)


def _mix(mask, colour_a, colour_b):
    """colour_a where mask == 0, colour_b where mask == 1; mask [N] -> [N, 3]."""
    m = mask[:, None]
    return (1.0 - m) * np.asarray(colour_a) + m * np.asarray(colour_b)


def _spherical_angles(q):
    """Azimuth in [0, 2pi) and polar angle in [0, pi] of the unit vectors q [N, 3]."""
    phi = np.mod(np.arctan2(q[:, 1], q[:, 0]), 2 * np.pi)
    theta = np.arccos(np.clip(q[:, 2], -1.0, 1.0))
    return phi, theta


def _shade_big_sphere(p):
    """8 x 5 checkerboard over (azimuth, polar angle), red / yellow."""
    n = (p - BIG_SPHERE_CENTER) / BIG_SPHERE_RADIUS
    phi, theta = _spherical_angles(n)
    m = _parity(np.floor(phi / (2 * np.pi) * 8), np.floor(theta / np.pi * 5))
    return n, _mix(m, (0.9, 0.12, 0.08), (0.98, 0.8, 0.1))


def _shade_small_sphere(p):
    """6 latitude bands, green / white."""
    n = (p - SMALL_SPHERE_CENTER) / SMALL_SPHERE_RADIUS
    _, theta = _spherical_angles(n)
    m = _parity(np.floor(theta / np.pi * 6))
    return n, _mix(m, (0.1, 0.75, 0.2), (0.92, 0.95, 0.9))


def _shade_box(p):
    """Diagonal stripes of width 0.2 in x + y + z, blue / pale cyan.

    The normal is the face whose normalised offset |p - centre| / half_size is largest.
    """
    centre = 0.5 * (BOX_MIN + BOX_MAX)
    half = 0.5 * (BOX_MAX - BOX_MIN)
    rel = (p - centre) / half
    axis = np.argmax(np.abs(rel), axis=-1)
    n = np.zeros_like(p)
    n[np.arange(len(p)), axis] = np.sign(rel[np.arange(len(p)), axis])
    m = _parity(np.floor(np.sum(p, axis=-1) / 0.2))
    return n, _mix(m, (0.1, 0.3, 0.9), (0.7, 0.92, 0.98))


def _cylinder_normal(p, center_xy, radius, z_range):
    """Outward normal on a capped z-cylinder: cap if |z offset|/half_height wins, else radial."""
    z0, z1 = z_range
    radial = p[:, :2] - center_xy
    rel_r = np.linalg.norm(radial, axis=-1) / radius
    zc, hz = 0.5 * (z0 + z1), 0.5 * (z1 - z0)
    rel_z = (p[:, 2] - zc) / hz
    on_cap = np.abs(rel_z) >= rel_r
    n = np.concatenate([radial / radius, np.zeros_like(p[:, :1])], axis=-1)
    cap_n = np.zeros_like(p)
    cap_n[:, 2] = np.sign(rel_z)
    return np.where(on_cap[:, None], cap_n, n)


def _shade_cylinder(p):
    """Horizontal rings of height 0.15, magenta / orange."""
    n = _cylinder_normal(p, CYLINDER_CENTER_XY, CYLINDER_RADIUS, CYLINDER_Z_RANGE)
    m = _parity(np.floor(p[:, 2] / 0.15))
    return n, _mix(m, (0.85, 0.1, 0.7), (1.0, 0.55, 0.1))


def _shade_ground(p):
    """Checkerboard of 0.25 squares in (x, y), light / dark grey."""
    n = _cylinder_normal(p, np.zeros(2), GROUND_RADIUS, GROUND_Z_RANGE)
    m = _parity(np.floor(p[:, 0] / 0.25), np.floor(p[:, 1] / 0.25))
    return n, _mix(m, (0.78, 0.78, 0.75), (0.35, 0.36, 0.4))


_SOLIDS = (
    (lambda o, d: intersect_sphere(o, d, BIG_SPHERE_CENTER, BIG_SPHERE_RADIUS), _shade_big_sphere),
    (
        lambda o, d: intersect_sphere(o, d, SMALL_SPHERE_CENTER, SMALL_SPHERE_RADIUS),
        _shade_small_sphere,
    ),
    (lambda o, d: intersect_box(o, d, BOX_MIN, BOX_MAX), _shade_box),
    (
        lambda o, d: intersect_cylinder(
            o, d, CYLINDER_CENTER_XY, CYLINDER_RADIUS, CYLINDER_Z_RANGE
        ),
        _shade_cylinder,
    ),
    (
        lambda o, d: intersect_cylinder(o, d, np.zeros(2), GROUND_RADIUS, GROUND_Z_RANGE),
        _shade_ground,
    ),
)


# --- public API ------------------------------------------------------------------------------


def trace(origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ray-trace the demo scene.

    For each ray o + t d (d need not be unit) the first hit over all solids is
    t* = min_k t_k > 0; its colour is albedo(p) * (AMBIENT + (1 - AMBIENT) max(0, n . l))
    at p = o + t* d with outward normal n and light direction l (view-independent).

    Args:
      origins, directions: [..., 3] float, broadcastable against each other.

    Returns:
      rgb [..., 3] float32 in [0, 1] (0 on miss), alpha [...] float32 (1 on hit, 0 on miss),
      t [...] float32 ray parameter of the first hit (inf on miss).
    """
    o, d = np.broadcast_arrays(np.asarray(origins, np.float64), np.asarray(directions, np.float64))
    if o.shape[-1:] != (3,):
        raise DataError(f"trace: origins/directions must have shape [..., 3], got {o.shape}")
    batch = o.shape[:-1]
    o = o.reshape(-1, 3)
    d = d.reshape(-1, 3)
    ts = np.stack([intersect(o, d) for intersect, _ in _SOLIDS], axis=0)  # [K, N]
    which = np.argmin(ts, axis=0)
    t = ts[which, np.arange(len(o))]
    hit = np.isfinite(t)
    rgb = np.zeros_like(o)
    for k, (_, shade) in enumerate(_SOLIDS):
        sel = hit & (which == k)
        if not np.any(sel):
            continue
        p = o[sel] + t[sel, None] * d[sel]
        n, albedo = shade(p)
        lambert = np.maximum(n @ LIGHT_DIRECTION, 0.0)
        rgb[sel] = albedo * (AMBIENT + (1.0 - AMBIENT) * lambert[:, None])
    rgb = np.clip(rgb, 0.0, 1.0).astype(np.float32).reshape(*batch, 3)
    alpha = hit.astype(np.float32).reshape(batch)
    return rgb, alpha, t.astype(np.float32).reshape(batch)


def camera_rays(c2w: np.ndarray, height: int, width: int, focal: float) -> tuple[np.ndarray, np.ndarray]:
    """Pixel-centre rays of a pinhole camera (NeRF / OpenGL convention).

    The camera looks down its -z axis with +y up and +x right. Pixel (row i, col j) has
        d_cam = ((j + 0.5 - W/2) / focal, -(i + 0.5 - H/2) / focal, -1),
        d_world = R d_cam   (R = c2w[:3, :3]; not normalised, so t is z-depth),
        o = c2w[:3, 3].

    Returns origins, directions: [H, W, 3] float64.
    """
    c2w = np.asarray(c2w, np.float64)
    if c2w.shape not in ((3, 4), (4, 4)):
        raise DataError(f"camera_rays: c2w must be 3x4 or 4x4, got shape {c2w.shape}")
    j, i = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    d_cam = np.stack(
        [(j + 0.5 - 0.5 * width) / focal, -(i + 0.5 - 0.5 * height) / focal, -np.ones_like(i)],
        axis=-1,
    )
    directions = d_cam @ c2w[:3, :3].T
    origins = np.broadcast_to(c2w[:3, 3], directions.shape).copy()
    return origins, directions


def look_at(position, target=(0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Camera-to-world 4x4 for a camera at `position` looking at `target` (Blender style).

    Columns are the camera axes in world coordinates: z = normalise(position - target)
    (pointing away from the target), x = normalise(up x z), y = z x x; last column is
    the position.
    """
    position = np.asarray(position, np.float64)
    z = position - np.asarray(target, np.float64)
    z /= np.linalg.norm(z)
    x = np.cross(np.asarray(up, np.float64), z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    c2w = np.eye(4)
    c2w[:3, 0], c2w[:3, 1], c2w[:3, 2], c2w[:3, 3] = x, y, z, position
    return c2w


def orbit_pose(azimuth: float, elevation: float, radius: float = CAMERA_RADIUS) -> np.ndarray:
    """c2w [4, 4] of a camera at radius * (cos el cos az, cos el sin az, sin el) looking at 0."""
    position = radius * np.array(
        [math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth),
         math.sin(elevation)]
    )
    return look_at(position)


def _split_poses(split: str, n: int, seed: int) -> list[np.ndarray]:
    """Train/val: seeded random azimuth in [0, 2pi), elevation in [10, 70] deg; test: orbit."""
    if split == "test":
        return [orbit_pose(2 * np.pi * k / n, math.radians(30.0)) for k in range(n)]
    rng = np.random.default_rng([seed, {"train": 0, "val": 1}[split]])
    az = rng.uniform(0.0, 2 * np.pi, size=n)
    el = rng.uniform(math.radians(10.0), math.radians(70.0), size=n)
    return [orbit_pose(a, e) for a, e in zip(az, el)]


def render_view(c2w: np.ndarray, size: int, supersample: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Render a size x size view: RGBA uint8 [H, W, 4] (straight alpha) and z-depth float32 [H, W] at the pixel
    centres. supersample S > 1 integrates each pixel's area as a sensor does: alpha and the premultiplied colour are
    the means of S x S samples on a regular grid inside the pixel, rgb = mean(rgb alpha) / mean(alpha)."""
    focal = 0.5 * size / math.tan(0.5 * CAMERA_ANGLE_X)
    rgb, alpha, t = trace(*camera_rays(c2w, size, size, focal))
    if supersample > 1:
        s = supersample
        fine_rgb, fine_alpha, _ = trace(*camera_rays(c2w, size * s, size * s, focal * s))
        alpha = fine_alpha.reshape(size, s, size, s).mean((1, 3))
        premult = (fine_rgb * fine_alpha[..., None]).reshape(size, s, size, s, 3).mean((1, 3))
        rgb = premult / np.maximum(alpha, 1e-8)[..., None]
    rgba = np.concatenate([rgb * (alpha[..., None] > 0), alpha[..., None]], axis=-1)
    return np.round(np.clip(rgba, 0.0, 1.0) * 255.0).astype(np.uint8), t


MAX_SIZE = 4096  # pixels a side: larger photos of this scene would not fit in memory to train on
MAX_VIEWS = 10_000


def make_scene(
    out_dir, *, size: int = 100, n_train: int = 60, n_val: int = 10, n_test: int = 10, seed: int = 0,
    supersample: int = 1,
) -> Path:
    """Write the demo scene in the NeRF Blender-synthetic layout and return out_dir.

    For split in (train, val, test) writes transforms_{split}.json =
    {"camera_angle_x": CAMERA_ANGLE_X, "frames": [{"file_path": "./{split}/r_k",
    "rotation": 0.0, "transform_matrix": c2w 4x4}]}, the RGBA uint8 PNG
    {split}/r_k.png and the float32 [size, size] z-depth {split}/r_k_depth.npy
    (inf on background). Cameras look at the origin from radius CAMERA_RADIUS. supersample S > 1: each
    pixel integrates S x S samples (render_view), as a camera's sensor does.
    """
    if not 1 <= size <= MAX_SIZE or not 0 <= min(n_train, n_val, n_test) <= max(n_train, n_val, n_test) <= MAX_VIEWS:
        raise DataError(
            f"make_scene: --size must be 1-{MAX_SIZE} and the view counts 0-{MAX_VIEWS}, got --size {size}, "
            f"--n-train {n_train}, --n-val {n_val}, --n-test {n_test}"
        )
    if seed < 0:
        raise DataError(f"make_scene: --seed must be >= 0 (got {seed})")
    out = Path(out_dir)
    with staged_folder(out) as tmp:  # all the files or none (a full disk, Ctrl-C)
        for split, n in (("train", n_train), ("val", n_val), ("test", n_test)):
            (tmp / split).mkdir(parents=True, exist_ok=True)
            frames = []
            for k, c2w in enumerate(_split_poses(split, n, seed)):
                rgba, depth = render_view(c2w, size, supersample)
                iio.imwrite(tmp / split / f"r_{k}.png", rgba)
                np.save(tmp / split / f"r_{k}_depth.npy", depth)
                frames.append({"file_path": f"./{split}/r_{k}", "rotation": 0.0, "transform_matrix": c2w.tolist()})
            meta = {"camera_angle_x": CAMERA_ANGLE_X, "frames": frames}
            (tmp / f"transforms_{split}.json").write_text(json.dumps(meta, indent=2))
    return out

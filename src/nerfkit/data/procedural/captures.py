"""Photo-like captures of the procedural scene, with exact rays and depth, for tests and demos.

`make_capture` renders the scene of data/procedural/scene.py through any `Camera` (lens models
included: each pixel's ray comes from the camera's own unprojection) and writes it in a
photo-capture format: nerfstudio transforms.json, LLFF poses_bounds.npy or a COLMAP
model, with the images under images/ and the exact z-depth under depth/.

With `environment=True` the scene gets a far, textured surround (a sphere of radius
ENV_RADIUS around the origin), so every pixel is covered and nothing is transparent: an
unbounded scene, like a photo of an object in a room. With `masks=True` (objects only) the
images show the objects on a grey backdrop and masks/ holds their exact silhouettes.
"""

from __future__ import annotations

import math
from pathlib import Path

import imageio.v3 as iio
import jax.numpy as jnp
import numpy as np
import trimesh

from nerfkit.core.errors import DataError
from nerfkit.data.formats.colmap import write_colmap
from nerfkit.data.formats.llff import write_llff
from nerfkit.data.formats.nerfstudio import write_nerfstudio
from nerfkit.data.procedural import scene as proc
from nerfkit.rays.cameras import Camera, rotate_directions
from nerfkit.rays.correction import perturb_poses, so3_exp

ENV_RADIUS = 12.0
BACKDROP = 0.5  # grey behind masked objects (the masks say what is object)


def environment(o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Colour [N, 3] and t [N] where rays o + t d from inside the sphere |x| = ENV_RADIUS leave it.

    Texture: a 12 x 6 checkerboard over (azimuth, elevation) of the exit point, sky blue /
    sand above the horizon, green / dark green below, shaded by elevation.
    """
    a = np.sum(d * d, -1)
    half_b = np.sum(o * d, -1)
    c = np.sum(o * o, -1) - ENV_RADIUS**2
    t = (-half_b + np.sqrt(np.maximum(half_b**2 - a * c, 0.0))) / a  # the far root (c < 0 inside)
    q = (o + t[:, None] * d) / ENV_RADIUS
    az = np.mod(np.arctan2(q[:, 1], q[:, 0]), 2 * np.pi)
    el = np.arcsin(np.clip(q[:, 2], -1, 1))
    check = (np.floor(az / (2 * np.pi) * 12) + np.floor((el + np.pi / 2) / np.pi * 6)) % 2
    up = el >= 0
    sky = np.where(check[:, None] > 0, [0.45, 0.65, 0.95], [0.95, 0.85, 0.6])
    ground = np.where(check[:, None] > 0, [0.2, 0.55, 0.25], [0.1, 0.3, 0.15])
    rgb = np.where(up[:, None], sky, ground) * (0.75 + 0.25 * np.abs(np.sin(el)))[:, None]
    return rgb, t


def render(c2w: np.ndarray, camera: Camera, env: bool = False):
    """rgb [H, W, 3] float, alpha [H, W], z-depth [H, W] (inf where nothing is hit) of the scene
    seen by `camera` at pose c2w (OpenGL), through pixel centres, lens model included."""
    o, d = rotate_directions(np.asarray(c2w, np.float64)[None, None], camera.directions().astype(np.float64))
    o, d = o.reshape(-1, 3), d.reshape(-1, 3)
    rgb, alpha, t = proc.trace(o, d)
    rgb, t = rgb.astype(np.float64), t.astype(np.float64)
    if env:
        miss = alpha < 0.5
        rgb[miss], t[miss] = environment(o[miss], d[miss])
        alpha = np.ones_like(alpha)
    shape = (camera.height, camera.width)
    return rgb.reshape(*shape, 3), alpha.reshape(shape), t.reshape(shape)


def _surface_samples(c2w: np.ndarray, camera: Camera, rgb: np.ndarray, depth: np.ndarray, n: int, rng):
    """(points [n', 3], colours [n', 3]) at n pixels drawn uniformly (n' <= n: those that hit a surface):
    x = o + z d for the pixel's ray (d with unit z-depth, as render traces it) and its z-depth z."""
    o, d = rotate_directions(np.asarray(c2w, np.float64)[None, None], camera.directions().astype(np.float64))
    pick = rng.choice(depth.size, size=min(n, depth.size), replace=False)
    z = depth.reshape(-1)[pick]
    hit = np.isfinite(z)
    pick, z = pick[hit], z[hit]
    return o.reshape(-1, 3)[pick] + z[:, None] * d.reshape(-1, 3)[pick], rgb.reshape(-1, 3)[pick]


def ring_poses(n: int, seed: int = 0, radius: float = proc.CAMERA_RADIUS) -> np.ndarray:
    """n cameras looking at the origin from `radius`, evenly spread in azimuth (with a seeded
    jitter) at elevations 10..50 degrees: [n, 4, 4] OpenGL camera-to-world."""
    rng = np.random.default_rng(seed)
    az = 2 * np.pi * (np.arange(n) + rng.uniform(0, 0.5, n)) / n
    el = np.radians(rng.uniform(10, 50, n))
    return np.stack([proc.orbit_pose(a, e, radius) for a, e in zip(az, el)])


def forward_poses(n: int, seed: int = 0, distance: float = proc.CAMERA_RADIUS, spread: float = 0.35) -> np.ndarray:
    """n cameras facing one way, as a hand-held forward-facing capture (LLFF's): on a grid in the plane
    y = -distance spanning +-spread x distance across and half that up (plus a seeded jitter of a tenth of
    a cell), each at 1.0 unit of height looking along +y, turned by up to 3 degrees at random: [n, 4, 4]."""
    rng = np.random.default_rng(seed)
    cols = math.ceil(math.sqrt(n * 2))
    rows = math.ceil(n / cols)
    gx, gz = np.meshgrid(np.linspace(-1, 1, cols), np.linspace(-1, 1, rows) if rows > 1 else [0.0])
    cells = np.stack([gx.ravel(), gz.ravel()], -1)[:n]
    cells += rng.uniform(-0.1, 0.1, cells.shape) / max(cols, rows)
    out = []
    for cx, cz in cells:
        pos = np.array([cx * spread * distance, -distance, 1.0 + cz * 0.5 * spread * distance])
        c2w = proc.look_at(pos, pos + np.array([0.0, 1.0, 0.0]))
        axis = rng.normal(size=3)
        w = np.radians(rng.uniform(0, 3)) * axis / np.linalg.norm(axis)
        c2w[:3, :3] = np.asarray(so3_exp(jnp.asarray(w)), np.float64) @ c2w[:3, :3]
        out.append(c2w)
    return np.stack(out)


def render_area(c2w: np.ndarray, camera: Camera, env: bool = False, supersample: int = 1):
    """render's rgb [H, W, 3] and alpha [H, W] integrated over each pixel's area, as a sensor does: the mean of
    supersample^2 samples on a regular grid inside the pixel (rays of camera.scaled(supersample), box-averaged),
    and the z-depth [H, W] at the pixel centres. supersample 1 is render's point sampling, whose jagged edges cap
    how closely any scene can match the photo (benchmarks/corrections.py's exact capture, 64 px: 24.8 dB
    point-sampled, 32.2 with supersample 4)."""
    rgb, alpha, depth = render(c2w, camera, env)
    if supersample > 1:
        s, (h, w) = supersample, (camera.height, camera.width)
        fine_rgb, fine_alpha, _ = render(c2w, camera.scaled(s, w * s, h * s), env)
        rgb = fine_rgb.reshape(h, s, w, s, 3).mean((1, 3))
        alpha = fine_alpha.reshape(h, s, w, s).mean((1, 3))
    return rgb, alpha, depth


def _photograph(out: Path, stem: str, c2w: np.ndarray, cam: Camera, environment: bool, masks: bool,
                gain: np.ndarray, supersample: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Render one photo (render_area) and write out/images/STEM.png (times its RGB gain), out/depth/STEM.npy and,
    with masks, out/masks/STEM.png (the photo then shows the objects on the backdrop); (rgb, z-depth)."""
    rgb, alpha, depth = render_area(c2w, cam, environment, supersample)
    if masks:
        rgb = rgb * alpha[..., None] + (1 - alpha[..., None]) * BACKDROP
        iio.imwrite(out / "masks" / f"{stem}.png", (alpha * 255).astype(np.uint8))
    rgb = rgb * gain
    iio.imwrite(out / "images" / f"{stem}.png", np.round(np.clip(rgb, 0, 1) * 255).astype(np.uint8))
    np.save(out / "depth" / f"{stem}.npy", depth.astype(np.float32), allow_pickle=False)
    return rgb, depth


def rig_poses(rig: str, n: int, seed: int = 0) -> np.ndarray:
    """The poses [n, 4, 4] of a rig: "ring" (ring_poses) or "forward" (forward_poses)."""
    if rig not in ("ring", "forward"):
        raise DataError(f"make_capture: unknown rig {rig!r} (ring, forward)")
    return ring_poses(n, seed) if rig == "ring" else forward_poses(n, seed)


def _write_points(path: Path, cloud: list[tuple[np.ndarray, np.ndarray]], n: int) -> None:
    """The first n of the (points, colours in [0, 1]) pairs in cloud as a coloured PLY point cloud."""
    xyz, col = (np.concatenate(a)[:n] for a in zip(*cloud))
    rgba = np.concatenate([np.round(np.clip(col, 0, 1) * 255), np.full((len(col), 1), 255)], 1)
    trimesh.PointCloud(xyz, colors=rgba.astype(np.uint8)).export(path)


def _imperfections(n: int, gains: float, exact_every: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """(gains [n, 3] drawn uniformly in [1 - gains, 1 + gains], spared [n] bool): the photos every exact_every-th
    (index % exact_every == 0) keep gain 1 and their exact pose (make_capture)."""
    photo_gains = rng.uniform(1 - gains, 1 + gains, (n, 3)) if gains else np.ones((n, 3))
    spared = np.arange(n) % exact_every == 0 if exact_every else np.zeros(n, bool)
    photo_gains[spared] = 1.0
    return photo_gains, spared


def _written_poses(out: Path, poses: np.ndarray, photo_gains: np.ndarray, pose_noise: tuple[float, float],
                   spared: np.ndarray, seed: int) -> np.ndarray:
    """Save the exact poses and gains under out/truth/ and return the poses to write: perturbed by pose_noise
    (degrees, share of the camera radius; correction.perturb_poses), the spared photos' kept exact."""
    (out / "truth").mkdir(exist_ok=True)
    np.save(out / "truth" / "poses.npy", poses, allow_pickle=False)
    np.save(out / "truth" / "gains.npy", photo_gains, allow_pickle=False)
    moved = perturb_poses(poses, pose_noise[0], pose_noise[1] * proc.CAMERA_RADIUS, seed)
    return np.where(spared[:, None, None], poses, moved)


def make_capture(out: str | Path, fmt: str = "nerfstudio", *, n_views: int = 16, size: int = 48,
                 camera: Camera | None = None, environment: bool = False, masks: bool = False, seed: int = 0,
                 text: bool = True, pose_noise: tuple[float, float] = (0.0, 0.0), gains: float = 0.0, points: int = 0,
                 rig: str = "ring", exact_every: int = 0, supersample: int = 1) -> Path:
    """Write a synthetic photo capture (see the module docstring) and return its folder.

    fmt: "nerfstudio" | "llff" | "colmap". camera: intrinsics of every image (default: an
    ideal pinhole with the Blender scenes' field of view, size x size). LLFF needs a
    pinhole camera centred on the image (its hwf column has room for nothing else).

    Imperfect captures, as SfM and a phone give them: pose_noise (degrees, fraction of the camera
    radius) writes every pose turned and moved by those amounts in random directions
    (correction.perturb_poses) while the photos are taken at the exact ones; gains g multiplies each
    photo's red, green and blue by factors drawn uniformly in [1 - g, 1 + g] (exposure and white
    balance). The exact poses and gains [N, 3] are written to truth/poses.npy and truth/gains.npy.
    exact_every E > 0 spares every E-th photo (index % E == 0: the held-out split of --holdout-every E) both:
    held-out photos whose score measures the scene learned, not their own errors (BARF's protocol).

    rig: "ring" (ring_poses: all around the objects) or "forward" (forward_poses: every camera facing
    one way, LLFF-like; with environment=True the room's far wall fills the view behind the objects).

    points P > 0 (nerfstudio format): sparse_pc.ply holds P exact surface points, the same number from
    each photo at pixels drawn uniformly, unprojected at their exact depth and coloured as the photo
    shows them: the best start SfM could give (benchmarks compare triangulated points against it).
    supersample S > 1: each pixel integrates S x S samples, as a camera's sensor does (render_area).
    """
    out = Path(out)
    cam = camera or Camera.pinhole(size, size, 0.5 * size / math.tan(0.5 * proc.CAMERA_ANGLE_X))
    if fmt == "llff" and (cam.params or abs(cam.cx - cam.width / 2) > 1e-9 or cam.fx != cam.fy):
        raise DataError("make_capture: LLFF holds only centred pinhole cameras")
    poses = rig_poses(rig, n_views, seed)
    rng = np.random.default_rng([seed, 1])
    photo_gains, spared = _imperfections(n_views, gains, exact_every, rng)
    for sub in ("images", "depth") + (("masks",) if masks else ()):
        (out / sub).mkdir(parents=True, exist_ok=True)
    if points and fmt != "nerfstudio":
        raise DataError("make_capture: exact points are written for the nerfstudio format (sparse_pc.ply)")
    names, bounds, cloud = [], [], []
    for k, c2w in enumerate(poses):
        rgb, depth = _photograph(out, f"frame_{k:04d}", c2w, cam, environment, masks, photo_gains[k], supersample)
        if points:
            cloud.append(_surface_samples(c2w, cam, rgb, depth, -(-points // n_views), rng))
        names.append(f"frame_{k:04d}.png")
        hit = depth[np.isfinite(depth)]
        bounds.append([hit.min(), hit.max()] if hit.size else [1.0, 10.0])
    if any(pose_noise) or gains:
        poses = _written_poses(out, poses, photo_gains, pose_noise, spared, seed)
    frames = [{"file_path": f"images/{name}", "transform_matrix": c2w.tolist(),
               "mask_path": f"masks/{name}" if masks else None} for name, c2w in zip(names, poses)]
    if fmt == "nerfstudio":
        write_nerfstudio(out / "transforms.json", frames, [cam] * n_views)
        if points:
            _write_points(out / "sparse_pc.ply", cloud, points)
    elif fmt == "llff":
        write_llff(out, poses, [cam] * n_views, np.array(bounds))
    elif fmt == "colmap":
        write_colmap(out / "sparse" / "0", names, poses, [cam] * n_views, text=text)
    else:
        raise DataError(f"make_capture: unknown format {fmt!r} (nerfstudio, llff, colmap)")
    return out

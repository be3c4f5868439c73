"""Photo-capture loaders (nerfstudio, LLFF, COLMAP): exact rays of known cameras, masks,
holdout splits, pose normalisation, and one-line errors for bad captures.

Captures are rendered from the procedural scene (nerfkit.data.procedural.captures) with exact depth,
so a loaded ray must reach the rendered surface point at the rendered depth.
"""

import json
import math

import numpy as np
import pytest
from reference import surface_distance

from nerfkit.core.errors import DataError
from nerfkit.data.loader import detect_format, load_scene, read_capture
from nerfkit.data.normalize import CAMERA_RADIUS
from nerfkit.data.procedural import scene as proc
from nerfkit.data.procedural.captures import make_capture, render, render_area, ring_poses
from nerfkit.rays.cameras import Camera, camera_rays, ray_table, table_directions

W, H = 40, 32
OPENCV = Camera(W, H, 45.0, 46.0, 19.5, 16.5, "OPENCV", (45.0, 46.0, 19.5, 16.5, -0.12, 0.03, 0.001, -0.002))
PINHOLE = Camera.pinhole(W, H, 45.0)


def opencv_project(x, y, k1, k2, p1, p2):
    """OpenCV's distortion of normalised coordinates (x, y), written out here independently of pycolmap."""
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 * r2
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return xd, yd


def capture_points(data, k, depth):
    """World points (capture coordinates) where the loaded rays of frame k reach `depth` (capture units)."""
    o, d = camera_rays(data.poses[k], data.cameras[k])
    p = o.astype(np.float64) + (depth[..., None] * data.scale) * d.astype(np.float64)
    inv = np.linalg.inv(data.transform)
    return p @ inv[:3, :3].T + inv[:3, 3]


@pytest.mark.parametrize("fmt,cam", [("nerfstudio", OPENCV), ("colmap", OPENCV), ("llff", PINHOLE)])
def test_loaders_recover_exact_rays(tmp_path, fmt, cam):
    root = make_capture(tmp_path / fmt, fmt, n_views=6, camera=cam)
    assert detect_format(root) == fmt
    data = load_scene(root, "all")
    assert len(data) == 6 and data.cameras[0] == cam
    poses = ring_poses(6)
    for k in range(6):
        depth = np.load(root / "depth" / f"frame_{k:04d}.npy")
        hit = np.isfinite(depth)
        # The loaded ray of each pixel reaches, at the rendered depth, the point the renderer hit.
        want_o, want_d = camera_rays(poses[k], cam)
        want = want_o + np.where(hit, depth, 0)[..., None] * want_d
        got = capture_points(data, k, np.where(hit, depth, 0))
        np.testing.assert_allclose(got[hit], want[hit], atol=2e-4)
        rgb, _, _ = render(poses[k], cam)
        np.testing.assert_allclose(data.images[k], np.round(rgb * 255) / 255, atol=1e-6)


def test_distorted_rays_project_back_to_their_pixel_centres():
    # The loader's per-pixel directions, pushed through OpenCV's distortion formula (written in this
    # test, not taken from pycolmap), land on the pixel centres (j + 0.5, i + 0.5).
    d = OPENCV.directions().astype(np.float64)
    x, y = d[..., 0] / -d[..., 2], -d[..., 1] / -d[..., 2]
    xd, yd = opencv_project(x, y, *OPENCV.params[4:])
    u, v = OPENCV.fx * xd + OPENCV.cx, OPENCV.fy * yd + OPENCV.cy
    jj, ii = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    np.testing.assert_allclose(u, jj, atol=1e-4)
    np.testing.assert_allclose(v, ii, atol=1e-4)
    assert np.abs(x - (jj - OPENCV.cx) / OPENCV.fx).max() > 0.005  # the lens does bend rays here


def test_training_ray_table_matches_full_image_rays():
    import jax.numpy as jnp

    cams = [OPENCV, OPENCV.scaled(1.0), PINHOLE]
    table = {k: jnp.asarray(v) for k, v in ray_table(cams).items()}
    assert "lens" in table and table["lens"].shape == (2, H, W, 2)  # two distinct cameras
    i, j = np.meshgrid(np.arange(H), np.arange(W), indexing="ij")
    for n, cam in enumerate(cams):
        got = table_directions(table, jnp.full(i.size, n), jnp.asarray(i.ravel()), jnp.asarray(j.ravel()))
        np.testing.assert_allclose(np.asarray(got).reshape(H, W, 3), cam.directions(), atol=1e-6)


def test_camera_scaling_keeps_the_rays_of_the_same_footprint():
    # A pixel of a 2x smaller image sees the ray through the centre of the 2x2 block it replaces.
    small = OPENCV.scaled(0.5, W // 2, H // 2)
    x_s, y_s = small.normalized_coords(np.array([3.5]), np.array([5.5]))
    x_b, y_b = OPENCV.normalized_coords(np.array([7.0]), np.array([11.0]))
    np.testing.assert_allclose([x_s, y_s], [x_b, y_b], atol=1e-9)


def test_llff_hwf_refers_to_the_original_photo_size(tmp_path):
    root = make_capture(tmp_path / "llff", "llff", n_views=4, camera=PINHOLE)
    pb = np.load(root / "poses_bounds.npy")
    m = pb[:, :15].reshape(-1, 3, 5)
    m[:, :, 4] *= 4  # hwf of 4x larger original photos; the stored images stay 40x32
    np.save(root / "poses_bounds.npy", np.concatenate([m.reshape(-1, 15), pb[:, 15:]], 1))
    data = load_scene(root, "all")
    assert data.cameras[0].fx == pytest.approx(PINHOLE.fx, rel=1e-9)


def test_masks_make_the_background_and_can_be_ignored(tmp_path):
    root = make_capture(tmp_path / "m", "llff", n_views=3, camera=PINHOLE, masks=True)
    masked = load_scene(root, "all", background="white")
    plain = load_scene(root, "all", masks=False)
    depth = np.load(root / "depth" / "frame_0000.npy")
    off = ~np.isfinite(depth)
    assert masked.has_masks and not plain.has_masks
    np.testing.assert_allclose(masked.images[0][off], 1.0)  # outside the mask: the background colour
    np.testing.assert_allclose(plain.images[0][off], round(0.5 * 255) / 255)  # the grey backdrop
    np.testing.assert_allclose(masked.images[0][~off], plain.images[0][~off])
    # masks named IMG_mask.jpg are found too
    (root / "masks" / "frame_0001.png").rename(root / "masks" / "frame_0001_mask.png")
    assert load_scene(root, "all").has_masks


def test_holdout_every_eighth_image_sorted_by_name(tmp_path):
    root = make_capture(tmp_path / "ns", "nerfstudio", n_views=17, size=8)
    meta = json.loads((root / "transforms.json").read_text())
    meta["frames"] = meta["frames"][::-1]  # file order must not matter
    (root / "transforms.json").write_text(json.dumps(meta))
    cap = read_capture(root, "train")
    names = lambda split: [f.image.name for f in cap.splits[split]]  # noqa: E731
    assert names("test") == [f"frame_{k:04d}.png" for k in (0, 8, 16)]
    assert len(names("train")) == 14 and not set(names("train")) & set(names("test"))
    assert [f.image.name for f in read_capture(root, "train", holdout_every=4).splits["test"]] == \
           [f"frame_{k:04d}.png" for k in (0, 4, 8, 12, 16)]
    assert len(load_scene(root, "test[1:3]")) == 2
    with pytest.raises(DataError, match="no split 'val'.*it has: all, test, train"):
        load_scene(root, "val")


def test_normalisation_undoes_any_similarity_of_the_capture(tmp_path):
    root = make_capture(tmp_path / "ns", "nerfstudio", n_views=8, size=8)
    base = load_scene(root, "all")
    meta = json.loads((root / "transforms.json").read_text())
    rng = np.random.default_rng(0)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))
    sim = np.eye(4)
    sim[:3, :3], sim[:3, 3] = 7.5 * q, [3.0, -2.0, 10.0]
    for f in meta["frames"]:
        c2w = sim @ np.array(f["transform_matrix"])
        c2w[:3, :3] /= 7.5
        f["transform_matrix"] = c2w.tolist()
    (root / "transforms.json").write_text(json.dumps(meta))
    moved = load_scene(root, "all")
    np.testing.assert_allclose(moved.poses, base.poses, atol=1e-4)
    assert moved.scale == pytest.approx(base.scale / 7.5, rel=1e-6)
    dist = np.linalg.norm(moved.poses[:, :3, 3], axis=-1)
    assert np.median(dist) == pytest.approx(CAMERA_RADIUS, rel=1e-5)
    up = moved.poses[:, :3, 1].mean(0)
    np.testing.assert_allclose(up / np.linalg.norm(up), [0, 0, 1], atol=1e-6)


def test_nerfstudio_per_frame_intrinsics_and_camera_angle(tmp_path):
    root = make_capture(tmp_path / "ns", "nerfstudio", n_views=3, size=16)
    meta = json.loads((root / "transforms.json").read_text())
    for key in ("fl_x", "fl_y", "cx", "cy", "w", "h", "camera_model"):
        meta.pop(key)
    meta["camera_angle_x"] = proc.CAMERA_ANGLE_X  # instant-ngp style
    meta["frames"][1]["fl_x"] = meta["frames"][1]["fl_y"] = 30.0
    (root / "transforms.json").write_text(json.dumps(meta))
    data = load_scene(root, "all")
    assert data.cameras[0].fx == pytest.approx(8 / math.tan(0.5 * proc.CAMERA_ANGLE_X))
    assert data.cameras[1].fx == 30.0 and data.cameras[1].fy == 30.0


@pytest.mark.parametrize("breakage,match", [
    (lambda r: (r / "poses_bounds.npy").write_bytes(b"junk"), r"poses_bounds\.npy: not a readable \.npy"),
    (lambda r: np.save(r / "poses_bounds.npy", np.zeros((3, 15))), r"expected an \[N, 17\] array"),
    (lambda r: np.save(r / "poses_bounds.npy", np.load(r / "poses_bounds.npy")[:2]),
     r"2 rows but 3 images"),
    (lambda r: (r / "masks" / "frame_0001.png").unlink(), r"masks: no mask for frame_0001\.png.*--no-masks"),
    (lambda r: __import__("imageio.v3").v3.imwrite(r / "masks" / "frame_0002.png", np.zeros((5, 5), np.uint8)),
     r"frame_0002\.png: mask is 5x5 but its image frame_0002\.png is 40x32"),
    (lambda r: [p.unlink() for p in (r / "images").iterdir()], r"images: no images found"),
])
def test_bad_llff_captures_are_one_line_errors(tmp_path, breakage, match):
    root = make_capture(tmp_path / "llff", "llff", n_views=3, camera=PINHOLE, masks=True)
    breakage(root)
    with pytest.raises(DataError, match=match) as e:
        load_scene(root, "all")
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("edit,match", [
    (lambda m: [m.pop(k) for k in ("fl_x", "fl_y")], r"frame 0: no intrinsics .*fl_x"),
    (lambda m: m.update(camera_model="EQUIRECTANGULAR"), r"camera_model 'EQUIRECTANGULAR' is not supported"),
    (lambda m: m["frames"][1].update(file_path="images/nope.png"), r"nope\.png: missing file for .*frame 1"),
    (lambda m: m.update(frames=[]), r"non-empty 'frames' list"),
    (lambda m: m["frames"][2].update(transform_matrix=[[1, 0], [0, 1]]), r"frame 2: transform_matrix must be 4x4"),
])
def test_bad_transforms_json_is_a_one_line_error(tmp_path, edit, match):
    root = make_capture(tmp_path / "ns", "nerfstudio", n_views=3, size=8)
    meta = json.loads((root / "transforms.json").read_text())
    edit(meta)
    (root / "transforms.json").write_text(json.dumps(meta))
    with pytest.raises(DataError, match=match) as e:
        load_scene(root, "all")
    assert "\n" not in str(e.value)


def test_folder_without_a_capture_says_how_to_make_one(tmp_path):
    (tmp_path / "photos").mkdir()
    with pytest.raises(DataError, match=r"no capture found.*nerfkit process-data images"):
        load_scene(tmp_path / "photos", "train")


@pytest.mark.parametrize("fmt", ["llff", "nerfstudio", "colmap"])
def test_no_masks_drops_the_masks_a_capture_has(tmp_path, fmt):
    """--no-masks on a capture with masks: no frame keeps one, and the capture knows it had them (so the flag
    is not refused as having no effect); one photo without its mask is what --no-masks is for."""
    root = make_capture(tmp_path / fmt, fmt, n_views=3, camera=PINHOLE, masks=True)
    assert read_capture(root, "all").has_masks
    cap = read_capture(root, "all", masks=False)
    assert not cap.has_masks and cap.masks_dropped
    bare = make_capture(tmp_path / f"{fmt}_bare", fmt, n_views=3, camera=PINHOLE)
    assert not read_capture(bare, "all", masks=False).masks_dropped
    if fmt != "nerfstudio":  # (nerfstudio names each mask in transforms.json)
        next((root / "masks").iterdir()).unlink()
        with pytest.raises(DataError, match="--no-masks"):
            read_capture(root, "all")
        assert read_capture(root, "all", masks=False).masks_dropped


def test_exact_points_lie_on_the_surfaces_the_photos_show(tmp_path):
    """make_capture(points=P): sparse_pc.ply holds P points, each on a solid of the scene or on the far
    environment sphere, coloured as a photo shows it; through an OpenCV lens too; random points do not pass."""
    from nerfkit.data.procedural.captures import ENV_RADIUS

    root = make_capture(tmp_path / "c", "nerfstudio", n_views=6, size=32, camera=OPENCV, environment=True,
                        points=600)
    cap = read_capture(root, "train")
    pts, cols = cap.points, cap.point_colors
    assert pts.shape == (600, 3) and cols.shape == (600, 3) and cap.points_file.endswith("sparse_pc.ply")
    far = np.abs(np.linalg.norm(pts, axis=-1) - ENV_RADIUS) < 1e-3
    near = surface_distance(pts) < 1e-3
    assert np.all(far | near) and 0.1 < near.mean() < 0.9, (far.mean(), near.mean())
    noise = np.random.default_rng(0).uniform(-1.5, 1.5, (600, 3))
    assert (surface_distance(noise) < 1e-3).mean() < 0.05
    # Colours are the photos': the objects' points are not the environment's sky/ground palette alone.
    assert cols.max() <= 1.0 and cols[near].std(0).min() > 0.05
    with pytest.raises(DataError, match="nerfstudio"):
        make_capture(tmp_path / "l", "llff", n_views=4, size=16, points=10)


def test_imperfect_captures_spare_the_held_out_photos_when_asked(tmp_path):
    """pose_noise and gains reach every photo, or with exact_every only the training split's."""
    from nerfkit.rays.correction import pose_error

    def written(root):
        meta = json.loads((root / "transforms.json").read_text())
        return np.array([f["transform_matrix"] for f in sorted(meta["frames"], key=lambda f: f["file_path"])])

    every = make_capture(tmp_path / "all", n_views=9, size=8, pose_noise=(1.0, 0.02), gains=0.2)
    spared = make_capture(tmp_path / "spared", n_views=9, size=8, pose_noise=(1.0, 0.02), gains=0.2, exact_every=4)
    truth = np.load(spared / "truth" / "poses.npy")
    held = np.arange(9) % 4 == 0
    for root, exact in ((every, np.zeros(9, bool)), (spared, held)):
        deg, dist = pose_error(written(root), truth)
        assert np.all(deg[exact] < 1e-4) and np.all(dist[exact] < 1e-5)
        assert np.allclose(deg[~exact], 1.0, atol=1e-3) and np.allclose(dist[~exact], 0.02 * proc.CAMERA_RADIUS)
        gains = np.load(root / "truth" / "gains.npy")
        assert np.all(gains[exact] == 1.0) and np.all(np.abs(gains[~exact] - 1.0).max(1) > 0.01)


def test_area_rendering_averages_the_sub_pixel_grid():
    """render_area's S x S supersampling is the mean of S^2 point-sampled photos whose pixel centres sit on the
    sub-pixel grid (cameras with their principal point moved by 0.5 - (m + 0.5) / S), depth at the centres."""
    s, c2w = 3, ring_poses(4, seed=2)[1]
    rgb, alpha, depth = render_area(c2w, PINHOLE, True, s)
    subs = [render(c2w, Camera(W, H, PINHOLE.fx, PINHOLE.fy, PINHOLE.cx + 0.5 - (a + 0.5) / s,
                               PINHOLE.cy + 0.5 - (b + 0.5) / s), True)[0]
            for a in range(s) for b in range(s)]
    np.testing.assert_allclose(rgb, np.mean(subs, 0), atol=1e-6)
    point_rgb, _, point_depth = render(c2w, PINHOLE, True)
    np.testing.assert_array_equal(depth, point_depth)
    assert np.abs(rgb - point_rgb).max() > 0.1  # the edges differ: the test sees the averaging
    one = render_area(c2w, PINHOLE, True, 1)
    np.testing.assert_array_equal(one[0], point_rgb)
    assert np.all((alpha >= 0) & (alpha <= 1))

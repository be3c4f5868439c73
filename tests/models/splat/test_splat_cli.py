"""`--preset splat` through the same command line as the radiance fields: train, resume, eval, render, the
exports (splat .ply, cameras, point cloud) and the refusals; SfM-point initialisation."""

import dataclasses
import json

import numpy as np
import pytest
from plyfile import PlyData

from nerfkit.cli.main import main
from nerfkit.data.formats.nerfstudio import write_nerfstudio
from nerfkit.data.loader import load_scene, read_capture
from nerfkit.data.procedural.scene import make_scene
from nerfkit.models.splat.method import SplatModel
from nerfkit.models.splat.gaussians import render
from nerfkit.models.splat.formats.ply import import_ply
from nerfkit.run.folder import RunFolder

TRAIN = ["--preset", "splat", "--no-progress", "--capacity", "2000", "--max-steps", "40"]


@pytest.fixture
def run(splat_run, tmp_path):
    """A copy of the shared run (tests here write evaluations and exports into it)."""
    import shutil

    scene, out = splat_run
    shutil.copytree(out, tmp_path / "run")
    return scene, tmp_path / "run"


def test_run_folder_like_the_other_presets(run):
    _, out = run
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["field"]["kind"] == "splat" and cfg["splat"]["capacity"] == 2000
    rows = [json.loads(x) for x in (out / "metrics.jsonl").read_text().splitlines()]
    assert [r["step"] for r in rows] == [50, 100, 150, 200]
    assert all({"loss", "psnr", "lr", "elapsed", "gaussians"} <= set(r) for r in rows)
    assert rows[-1]["loss"] < rows[0]["loss"]  # the photometric loss falls
    vals = [json.loads(x) for x in (out / "val_metrics.jsonl").read_text().splitlines()]
    assert [v["step"] for v in vals] == [100, 200]
    assert sorted(p.name for p in (out / "checkpoints").iterdir()) == ["ckpt_00000100.msgpack",
                                                                       "ckpt_00000200.msgpack"]
    assert (out / "report.html").is_file() and (out / "scene.json").is_file()
    run_ = RunFolder(out).load()
    cfg2, model, params, aux, step = run_.cfg, run_.model, run_.params, run_.aux, run_.step
    assert step == 200 and params["means"].shape == (2000, 3) and aux["active"].dtype == bool
    assert 0 < float(aux["clock"]) < 600


def test_the_renderer_keeps_a_models_gaussians_and_sees_a_changed_model(run):
    """SplatRenderer selects, transforms and copies the Gaussians once per model (a viewer's frames), and again
    whenever the arrays it is handed are others (a live run's new step, or one parameter or the active set
    replaced): each image equals that of a fresh renderer."""
    from nerfkit.render.images import make_renderer
    from nerfkit.rays.cameras import Camera

    _, out = run
    run_ = RunFolder(out).load()
    params, aux = dict(run_.params), dict(run_.aux)
    c2w, cam = np.asarray(run_.scene["train_poses"][0]), Camera.pinhole(32, 32, 40.0)
    renderer = make_renderer(run_.model)

    def fresh(p, a):
        return make_renderer(run_.model).render_camera(p, a, c2w, cam)["rgb"]

    first = renderer.render_camera(params, aux, c2w, cam)["rgb"]
    kept = renderer._held_out[2]
    np.testing.assert_array_equal(renderer.render_camera(params, aux, c2w, cam)["rgb"], first)
    assert renderer._held_out[2] is kept  # the same model: nothing selected or copied again
    params["sh_dc"] = np.asarray(params["sh_dc"]) * 0.5  # one array replaced
    darker = renderer.render_camera(params, aux, c2w, cam)["rgb"]
    np.testing.assert_array_equal(darker, fresh(params, aux))
    assert not np.array_equal(darker, first)
    active = np.asarray(aux["active"]).copy()
    active[np.flatnonzero(active)[::2]] = False  # the active set replaced
    aux["active"] = active
    fewer = renderer.render_camera(params, aux, c2w, cam)["rgb"]
    np.testing.assert_array_equal(fewer, fresh(params, aux))
    assert not np.array_equal(fewer, darker)


def test_resume_continues_to_the_total_steps(run, tmp_path):
    scene, copy = run
    assert main(["train", str(scene), "--out", str(copy), "--resume", "--no-progress", "--max-steps", "250",
                 "--log-every", "50"]) == 0
    rows = [json.loads(x) for x in (copy / "metrics.jsonl").read_text().splitlines()]
    assert [r["step"] for r in rows] == [50, 100, 150, 200, 250]
    assert RunFolder(copy).load().step == 250


def test_resume_refuses_a_preset_of_another_family(run, capsys):
    """--resume keeps the run's own model: the command repeated with its --preset continues, another family's
    --preset is refused in one line (it would otherwise be ignored) and the run is left as it was."""
    scene, copy = run
    before = (copy / "config.json").read_text()
    assert main(["train", str(scene), "--out", str(copy), "--resume", "--preset", "tiny", "--max-steps", "5"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--preset tiny" in err[0] and "drop --preset" in err[0], err
    assert (copy / "config.json").read_text() == before
    assert main(["train", str(scene), "--out", str(copy), "--resume", "--preset", "splat", "--no-progress"]) == 0


def test_eval_and_render(run, tmp_path):
    scene, out = run
    assert main(["eval", str(out), "--split", "test"]) == 0
    ev = json.loads((out / "eval_test.json").read_text())
    assert ev["step"] == 200 and len(ev["per_view"]) == 2 and 8 < ev["psnr"] < 40
    assert (out / "eval_test" / "view_000.png").is_file()
    assert main(["render", str(out), "--split", "test", "--width", "48", "--out", str(tmp_path / "r")]) == 0
    depth = np.load(tmp_path / "r" / "depth_0000.npy")
    assert depth.shape == (48, 48) and np.isfinite(depth).all()
    assert (tmp_path / "r" / "rgb.mp4").is_file() and (tmp_path / "r" / "rgb_0001.png").is_file()
    assert main(["render", str(out), "--orbit", "3", "--out", str(tmp_path / "o")]) == 0
    assert len(list((tmp_path / "o").glob("rgb_*.png"))) == 3
    assert main(["eval", str(out), "--split", "test", "--chunk", "64", "--overwrite"]) == 1  # refused


def test_export_splat_reads_back_and_renders_the_same_image(run, tmp_path, capsys):
    scene, out = run
    ply = tmp_path / "scene.ply"
    assert main(["export", "splat", str(out), "--out", str(ply)]) == 0
    v = PlyData.read(str(ply))["vertex"]
    names = list(v.data.dtype.names)
    assert names[:9] == ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
    assert names[9:54] == [f"f_rest_{i}" for i in range(45)]
    assert names[54:] == ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    run_ = RunFolder(out).load()
    cfg, model, params, aux = run_.cfg, run_.model, run_.params, run_.aux
    active = np.asarray(aux["active"], bool)
    assert len(v.data) == active.sum()
    # The file (capture coordinates) moved back by scene.json's transform renders the run's own image.
    sc = json.loads((out / "scene.json").read_text())
    back = import_ply(ply, transform=np.asarray(sc["transform"]))
    test = load_scene(scene, "test")
    mine = {k: np.asarray(params[k])[active] for k in back}
    a = render(mine, test.poses[0], test.cameras[0])["rgb"]
    b = render(back, test.poses[0], test.cameras[0])["rgb"]
    np.testing.assert_allclose(a, b, atol=1e-4)
    assert main(["export", "splat", str(out), "--out", str(ply)]) == 1  # never replaced without --overwrite
    assert "--overwrite" in capsys.readouterr().err
    assert main(["export", "splat", str(out), "--out", str(ply), "--overwrite"]) == 0
    assert (out / "exports" / "splat.png").is_file()
    assert main(["export", "mesh", str(out), "--out", str(tmp_path / "m.ply"), "--method", "levelset"]) == 1
    assert "--method tsdf" in capsys.readouterr().err  # splats mesh by fusion (tests/export/test_splat_mesh.py)
    assert main(["export", "cameras", str(out), "--out", str(tmp_path / "c.json")]) == 0


def test_export_splat_picks_the_format_by_extension(run, tmp_path, capsys):
    _, out = run
    recs = {}
    for ext in ("ply", "spz", "splat"):
        assert main(["export", "splat", str(out), "--out", str(tmp_path / f"s.{ext}")]) == 0
        recs[ext] = json.loads((out / "exports" / "export_splat.json").read_text())
        assert recs[ext]["bytes"] == (tmp_path / f"s.{ext}").stat().st_size > 0
    assert recs["ply"]["format"] == "Inria 3DGS .ply" and recs["ply"]["psnr_vs_run"] >= 100  # float32: exact
    assert recs["spz"]["psnr_vs_run"] >= 40 and recs["ply"]["bytes"] >= 8 * recs["spz"]["bytes"]
    assert recs["splat"]["sh_degree"] == 0 and recs["splat"]["bytes"] == 32 * recs["splat"]["gaussians"]
    assert "Niantic .spz" in capsys.readouterr().out
    assert main(["export", "splat", str(out), "--out", str(tmp_path / "s.obj")]) == 1
    assert "unsupported extension '.obj'; use .ply, .spz, .splat" in capsys.readouterr().err
    assert not (tmp_path / "s.obj").exists()


def test_pointcloud_is_the_centres(run, tmp_path, capsys):
    import trimesh

    scene, out = run
    run_ = RunFolder(out).load()
    cfg, model, params, aux = run_.cfg, run_.model, run_.params, run_.aux
    active = np.asarray(aux["active"], bool)
    opacity = 1 / (1 + np.exp(-np.asarray(params["opacity"])[active]))
    assert main(["export", "pointcloud", str(out), "--out", str(tmp_path / "p.ply"), "--min-opacity", "0.05",
                 "--voxel-size", "0"]) == 0
    pts = np.asarray(trimesh.load(tmp_path / "p.ply").vertices)
    assert len(pts) == (opacity >= 0.05).sum() > 0
    sc = json.loads((out / "scene.json").read_text())
    m = np.asarray(sc["transform"])
    want = np.asarray(params["means"])[active][opacity >= 0.05]
    np.testing.assert_allclose(pts @ m[:3, :3].T + m[:3, 3], want, atol=1e-4)  # capture coordinates
    assert main(["export", "pointcloud", str(out), "--out", str(tmp_path / "q.ply"), "--split", "test"]) == 1
    assert "--split" in capsys.readouterr().err and not (tmp_path / "q.ply").exists()


def test_init_from_sfm_points(tmp_path):
    """A nerfstudio capture with sparse_pc.ply: the Gaussians start at its points, in the normalised frame."""
    import trimesh

    scene = make_scene(tmp_path / "scene", size=16, n_train=6, n_val=1, n_test=1)
    from nerfkit.data.formats.blender import read_blender

    frames = read_blender(scene, "train").frames("train")
    write_nerfstudio(scene / "transforms.json", [{"file_path": str(f.image.relative_to(scene)),
                                                  "transform_matrix": f.c2w} for f in frames],
                     [f.camera for f in frames])
    pts = np.random.default_rng(0).uniform(-1, 1, (200, 3))
    rgba = np.concatenate([np.full((200, 3), 200, np.uint8), np.full((200, 1), 255, np.uint8)], 1)
    trimesh.PointCloud(pts, colors=rgba).export(scene / "sparse_pc.ply")
    cap = read_capture(scene, "train", "nerfstudio")
    assert cap.points_file == str(scene / "sparse_pc.ply")  # the format hands its points to the model
    np.testing.assert_allclose(cap.points, pts, atol=1e-5)
    np.testing.assert_allclose(cap.point_colors, 200 / 255, atol=1e-6)
    data = load_scene(scene, "train", format="nerfstudio")
    from nerfkit.core.presets import preset

    cfg = preset("splat")
    cfg.splat.far_points = "off"
    model = SplatModel(cfg)
    model.bind_data(cap, data, log=lambda *_: None)
    params, aux = model.init()
    m = np.asarray(data.transform)
    np.testing.assert_allclose(params["means"][:200], pts @ m[:3, :3].T + m[:3, 3], atol=1e-5)
    # --far-points on (auto, on these photos without masks): more start on the far sphere, after the SfM points
    cfg.splat.far_points = "on"
    far = SplatModel(cfg)
    far.bind_data(cap, data, log=lambda *_: None)
    far_params, far_aux = far.init()
    n = int(np.asarray(far_aux["active"]).sum()) - 200
    radius = 3.0 * np.linalg.norm(data.poses[:, :3, 3], axis=1).max()
    assert n > 100 and "on a far sphere" in far.init_note
    np.testing.assert_allclose(far_params["means"][:200], params["means"][:200])
    np.testing.assert_allclose(np.linalg.norm(far_params["means"][200:200 + n], axis=1), radius, rtol=1e-4)
    assert aux["active"].sum() == 200
    colour = 0.28209479 * params["sh_dc"][:200, 0] + 0.5
    np.testing.assert_allclose(colour, 200 / 255, atol=1e-5)
    # SfM points far beyond that sphere (a far wall, as a forward-facing capture's): it moves out behind them
    wall = np.random.default_rng(1).normal(size=(300, 3))
    wall *= 5.0 * radius / np.linalg.norm(wall, axis=1, keepdims=True)  # normalised frame, 5 x the sphere
    wall = (wall - m[:3, 3]) @ np.linalg.inv(m[:3, :3]).T  # capture coordinates
    trimesh.PointCloud(np.concatenate([pts, wall]), colors=np.tile(rgba, (3, 1))[:500]).export(scene / "sparse_pc.ply")
    walled = SplatModel(cfg)
    walled.bind_data(read_capture(scene, "train", "nerfstudio"), data, log=lambda *_: None)
    wp, wa = walled.init()
    far_means = np.asarray(wp["means"])[500:int(np.asarray(wa["active"]).sum())]
    assert len(far_means) > 100 and f"far sphere of radius {5 * radius:.3g}" in walled.init_note, walled.init_note
    np.testing.assert_allclose(np.linalg.norm(far_means, axis=1), 5.0 * radius, rtol=1e-4)


def test_sfm_init_refused_without_points(run, tmp_path, capsys):
    scene, _ = run
    assert main(["train", str(scene), "--out", str(tmp_path / "x"), *TRAIN, "--init-points", "sfm"]) == 1
    err = capsys.readouterr().err.strip()
    assert "init-points" in err and err.count("\n") == 0 and not (tmp_path / "x").exists()


def test_init_from_colmap_points(tmp_path):
    """A COLMAP capture's points3D (with colours) seed the Gaussians, moved into the normalised frame."""
    from nerfkit.core.presets import preset
    from nerfkit.data.formats.colmap import read_colmap, write_colmap
    from nerfkit.data.procedural.captures import make_capture

    root = make_capture(tmp_path / "cap", "colmap", n_views=6, size=16)
    cap = read_colmap(root, 8, True)
    frames = cap.frames("all")
    pts = np.random.default_rng(1).uniform(-1, 1, (50, 3))
    cols = np.tile(np.uint8([[10, 200, 30]]), (50, 1))
    write_colmap(root / "sparse" / "0", [f.image.name for f in frames], np.stack([f.c2w for f in frames]),
                 [f.camera for f in frames], pts, cols)
    cap = read_colmap(root, 8, True)
    data = load_scene(root, "train", format="colmap")
    assert not np.allclose(data.transform, np.eye(4))  # photo captures are normalised
    model = SplatModel(preset("splat"))
    model.bind_data(cap, data, log=lambda *_: None)
    params, aux = model.init()
    m = np.asarray(data.transform)
    got = params["means"][:50][np.lexsort(params["means"][:50].T)]
    want = (pts @ m[:3, :3].T + m[:3, 3])
    np.testing.assert_allclose(got, want[np.lexsort(want.T)], atol=1e-4)
    np.testing.assert_allclose(0.28209479 * params["sh_dc"][:50, 0] + 0.5, np.tile([10, 200, 30], (50, 1)) / 255,
                               atol=1e-5)


def test_without_points_a_masked_scene_starts_in_its_visual_hull(tmp_path):
    """No SfM points but an alpha channel (a Blender scene): the Gaussians start uniform in the visual hull of
    the training silhouettes, every one inside it; --init-points random keeps the box; hull without
    silhouettes is refused in one line."""
    from nerfkit.core.errors import DataError
    from nerfkit.core.presets import preset
    from nerfkit.data.normalize import inside_visual_hull

    scene = make_scene(tmp_path / "scene", size=24, n_train=8, n_val=1, n_test=1)
    cap = read_capture(scene, "train", "auto")
    data = load_scene(scene, "train")
    assert data.alphas is not None
    model = SplatModel(preset("splat"))
    model.bind_data(cap, data, log=lambda *_: None)
    params, aux = model.init()
    means = params["means"][aux["active"]]
    assert "visual hull" in model.init_note and len(means) > 1000
    assert inside_visual_hull(means, data.poses, data.cameras, data.alphas).all()
    cfg = preset("splat")
    cfg.splat.init_points = "random"
    boxed = SplatModel(cfg)
    boxed.bind_data(cap, data, log=lambda *_: None)
    p2, a2 = boxed.init()
    assert "box" in boxed.init_note
    assert inside_visual_hull(p2["means"][a2["active"]], data.poses, data.cameras, data.alphas).mean() < 0.5
    # silhouettes that hold nothing: --init-points hull is refused in one line, auto falls back to the box
    empty = dataclasses.replace(data, alphas=np.zeros_like(data.alphas))
    cfg.splat.init_points = "hull"
    with pytest.raises(DataError, match="visual hull is empty"):
        SplatModel(cfg).bind_data(cap, empty, log=lambda *_: None)
    auto = SplatModel(preset("splat"))
    auto.bind_data(cap, empty, log=lambda *_: None)
    assert "box" in auto.init_note


def test_hull_init_without_silhouettes_is_refused(tmp_path):
    from nerfkit.core.errors import DataError
    from nerfkit.core.presets import preset
    from nerfkit.data.formats.colmap import read_colmap
    from nerfkit.data.procedural.captures import make_capture

    root = make_capture(tmp_path / "cap", "colmap", n_views=6, size=16)
    cfg = preset("splat")
    cfg.splat.init_points = "hull"
    with pytest.raises(DataError, match="--init-points hull, but the capture has neither masks nor an alpha"):
        SplatModel(cfg).bind_data(read_colmap(root, 8, True), load_scene(root, "train", format="colmap"))


def test_coarse_to_fine_by_default_only_on_photos_large_enough(tmp_path):
    """--coarse unset: half resolution for the first COARSE_AUTO of the budget on photos of at least
    COARSE_MIN_PIXELS (maryrose at 432 px), full resolution on smaller ones (lego at 200 px, the test scene);
    a --coarse the user sets is taken as it is; bind_data says which and why."""
    from nerfkit.core.presets import preset
    from nerfkit.models.splat.method import COARSE_AUTO, COARSE_MIN_PIXELS, coarse_share

    assert coarse_share(None, 432 * 432) == COARSE_AUTO > 0 and coarse_share(None, 200 * 200) == 0.0
    assert coarse_share(None, COARSE_MIN_PIXELS) == COARSE_AUTO and coarse_share(None, COARSE_MIN_PIXELS - 1) == 0
    assert coarse_share(0.3, 200 * 200) == 0.3 and coarse_share(0.0, 10**6) == 0.0
    scene = make_scene(tmp_path / "scene", size=24, n_train=4, n_val=1, n_test=0)
    cap, data = read_capture(scene, "train", "auto"), load_scene(scene, "train")
    lines: list[str] = []
    for coarse, want in ((None, 0.0), (0.25, 0.25)):
        cfg = preset("splat")
        cfg.splat.coarse = coarse
        model = SplatModel(cfg)
        model.bind_data(cap, data, log=lines.append)
        assert model.sc.coarse_until == want
    assert "full resolution throughout (photos of 576 pixels < 100,000; set --coarse)" in lines[0]
    assert lines[1].endswith("half resolution for the first 25% of the budget")


def test_the_runs_screen_dilation_reaches_its_renders_depth_and_exports(run, tmp_path, capsys):
    """A run's --screen-dilation (config.json) is the floor its renders, median depth (export mesh) and the
    export's comparison draw with; `export splat` says that viewers draw with 0.3. A floor of 0 is refused."""
    from nerfkit.models.splat.depth import median_depth
    from nerfkit.models.splat.gaussians import intrinsics_of, render_frame
    from nerfkit.rays.cameras import Camera
    from nerfkit.render.images import make_renderer

    scene, out = run
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["splat"]["screen_dilation"] == 0.3
    cfg["splat"]["screen_dilation"] = 2.0  # as if trained with --screen-dilation 2
    (out / "config.json").write_text(json.dumps(cfg))
    run_ = RunFolder(out).load()
    renderer = make_renderer(run_.model)
    c2w, cam = np.asarray(run_.scene["train_poses"][0]), Camera.pinhole(32, 32, 40.0)
    got = renderer.render_camera(run_.params, run_.aux, c2w, cam, median=True)
    p, on_device = renderer.gaussians(run_.params, run_.aux)
    at = {d: render_frame(on_device, c2w, cam, run_.model.background, run_.cfg.splat.sh_degree, dilation=d)
          for d in (2.0, 0.3)}
    np.testing.assert_array_equal(got["rgb"], at[2.0]["rgb"])
    assert np.abs(got["rgb"] - at[0.3]["rgb"]).max() > 0.05
    # the same alpha both times, so that only the floor the depth's Gaussians are drawn with differs
    depth = {d: median_depth(p, c2w, intrinsics_of(cam), 32, 32, at[2.0]["alpha"], dilation=d) for d in (2.0, 0.3)}
    np.testing.assert_array_equal(got["depth_median"], depth[2.0])
    assert np.mean(depth[2.0] != depth[0.3]) > 0.1
    assert main(["export", "splat", str(out), "--out", str(tmp_path / "s.ply")]) == 0
    said = capsys.readouterr().out
    assert "--screen-dilation 2 px^2" in said and "viewers draw them with 0.3" in said
    record = json.loads((out / "exports" / "export_splat.json").read_text())
    assert record["psnr_vs_run"] < 40.0  # the file drawn at 0.3 against the run's own render at 2
    assert main(["train", str(scene), "--out", str(tmp_path / "r"), *TRAIN, "--screen-dilation", "0"]) == 1
    assert "--screen-dilation must be > 0" in capsys.readouterr().err and not (tmp_path / "r").exists()

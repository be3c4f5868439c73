"""Every flag of every verb is used or refused. `nerfkit train`'s settings are walked against every preset in
training/test_flags.py; the other verbs' flags are listed here, each with the tests that exercise it (a flag a test
passes and checks the effect of, or a refusal it checks). A flag without an entry, or an entry whose test
does not mention the flag, fails test_every_verb_flag_has_a_test: a new flag cannot go untested.

The tests below cover the flags no other test did."""

from __future__ import annotations

import ast
import dataclasses
import json
import re
import signal
import subprocess
import sys
import urllib.request
from pathlib import Path

import imageio.v2 as imageio_v2
import numpy as np
import pytest
import trimesh

from nerfkit.cli import args as cli_args
from nerfkit.cli import main as cli
from nerfkit.cli.main import main
from nerfkit.data.procedural.scene import make_scene
from nerfkit.export.registry import EXPORTERS, exporter

TESTS = Path(__file__).resolve().parents[1]
T = "cli/test_verb_flags.py"

PROOFS = {
    "EvalArgs": {
        "data": ["cli/test_main.py::test_eval_writes_json"], "split": ["cli/test_main.py::test_eval_writes_json"],
        "downscale": [f"{T}::test_eval_and_render_replace_only_with_overwrite"],
        "every": ["cli/test_main.py::test_eval_writes_json"],
        "chunk": [f"{T}::test_eval_and_render_replace_only_with_overwrite"],
        "baked": ["bake/test_bake.py::test_eval_baked_through_the_cli"],
        "fit_poses": ["models/splat/test_pose_fit.py::test_eval_fit_poses_through_the_cli",
                      "cli/test_main.py::test_eval_fit_poses_is_refused_where_the_model_cannot_fit_a_pose"],
        "fit_colour": ["cli/test_main.py::test_eval_fit_colour_scores_the_right_halves_of_any_run",
                       "models/splat/test_pose_fit.py::test_eval_fit_poses_through_the_cli"],
        "overwrite": [f"{T}::test_eval_and_render_replace_only_with_overwrite"]},
    "RenderArgs": {
        "data": ["cli/test_main.py::test_render_split_at_other_resolution"],
        "split": ["cli/test_main.py::test_render_split_at_other_resolution"], "orbit": ["cli/test_main.py::test_render_orbit"],
        "width": ["cli/test_main.py::test_render_split_at_other_resolution"], "height": [f"{T}::test_render_height_and_fps"],
        "out": [f"{T}::test_render_height_and_fps"], "camera_path": ["cli/test_main.py::test_render_camera_path"],
        "fps": [f"{T}::test_render_height_and_fps"],
        "chunk": [f"{T}::test_eval_and_render_replace_only_with_overwrite"],
        "overwrite": [f"{T}::test_eval_and_render_replace_only_with_overwrite"]},
    "ExportMeshArgs": {
        "out": ["export/test_export.py::test_no_carve_through_the_cli"],
        "resolution": ["export/test_export.py::test_no_carve_through_the_cli"],
        "threshold": ["export/test_export.py::test_empty_field_is_a_clear_error_and_writes_nothing"],
        "max_faces": ["export/test_export.py::test_simplified_mesh_keeps_the_shape"],
        "visible_only": [f"{T}::test_mesh_switches_change_the_mesh"], "snap": [f"{T}::test_mesh_switches_change_the_mesh"],
        "carve": ["export/test_export.py::test_no_carve_through_the_cli"],
        "every": [f"{T}::test_mesh_switches_change_the_mesh", f"{T}::test_mesh_texture_box_and_every"],
        "method": ["export/test_export.py::test_levelset_mesh_lies_on_the_true_surfaces_in_capture_coordinates",
                   "export/test_export.py::test_bad_export_arguments_are_one_line_errors"],
        "box": [f"{T}::test_mesh_texture_box_and_every"],
        "watertight": ["export/test_export.py::test_watertight_tsdf_mesh_is_closed_and_still_on_the_surfaces"],
        "texture": [f"{T}::test_mesh_texture_box_and_every"],
        "texture_size": [f"{T}::test_mesh_texture_box_and_every"],
        "smooth": ["export/test_splat_mesh.py::test_smoothing_changes_the_mesh_and_is_recorded",
                   "export/test_splat_mesh.py::test_bad_smoothing_is_refused_in_one_line"],
        "taubin": ["export/test_splat_mesh.py::test_taubin_smooths_the_mesh_keeps_its_size_and_is_recorded"],
        "bilateral": ["export/test_splat_mesh.py::test_bilateral_filtering_flattens_the_mesh_keeps_its_size_and_is_"
                      "recorded"],
        "data": ["reliability/test_bad_runs.py::test_damaged_run_folders"],
        "progress": [f"{T}::test_no_progress_hides_the_bars"],
        "overwrite": ["export/test_export.py::test_exports_refuse_to_replace_a_file_and_leave_nothing_behind"]},
    "ExportPointcloudArgs": {
        "out": ["export/test_export.py::test_exports_refuse_to_replace_a_file_and_leave_nothing_behind"],
        "split": [f"{T}::test_pointcloud_split_every_and_voxel_size"],
        "every": [f"{T}::test_pointcloud_split_every_and_voxel_size"],
        "min_opacity": ["export/test_export.py::test_bad_export_arguments_are_one_line_errors"],
        "voxel_size": [f"{T}::test_pointcloud_split_every_and_voxel_size"],
        "data": ["reliability/test_bad_runs.py::test_damaged_run_folders"],
        "chunk": [f"{T}::test_pointcloud_split_every_and_voxel_size"],
        "progress": [f"{T}::test_no_progress_hides_the_bars"],
        "overwrite": ["export/test_export.py::test_exports_refuse_to_replace_a_file_and_leave_nothing_behind"]},
    "ExportSplatArgs": {f: ["models/splat/test_splat_cli.py::test_export_splat_reads_back_and_renders_the_same_image"]
                        for f in ("out", "overwrite")},
    "ImportSplatArgs": {
        "out": ["run/test_imported.py::test_a_file_without_a_capture_gets_one_of_its_own_renders"],
        "data": ["run/test_imported.py::test_a_file_imported_with_its_capture_is_the_run_that_wrote_it"],
        "overwrite": ["run/test_imported.py::test_bad_files_and_folders_are_refused_and_nothing_is_written"]},
    "ExportCamerasArgs": {
        "out": ["export/test_export.py::test_exports_refuse_to_replace_a_file_and_leave_nothing_behind"],
        "split": ["export/test_export.py::test_cameras_round_trip_through_nerfstudio"],
        "poses": ["training/test_pose_refine.py::test_a_refined_run_is_seen_from_its_refined_poses"],
        "data": ["reliability/test_bad_runs.py::test_damaged_run_folders"],
        "overwrite": ["export/test_export.py::test_cameras_round_trip_through_nerfstudio"]},
    "BakeArgs": {
        "out": ["bake/test_bake.py::test_bad_bake_arguments_are_one_line_errors"],
        "resolution": ["bake/test_bake.py::test_bad_bake_arguments_are_one_line_errors"],
        "sh_bands": ["bake/test_bake.py::test_bad_bake_arguments_are_one_line_errors"],
        "finetune_minutes": ["bake/test_bake.py::test_a_baked_scene_is_replaced_only_with_overwrite"],
        "max_mb": ["bake/test_bake.py::test_default_resolution_is_the_finest_that_fits_the_budget"],
        "progress": ["bake/test_bake.py::test_a_baked_scene_is_replaced_only_with_overwrite"],
        "overwrite": ["bake/test_bake.py::test_a_baked_scene_is_replaced_only_with_overwrite"]},
    "ViewArgs": {
        "port": ["cli/test_main.py::test_view_serves_on_loopback_and_stops_on_ctrl_c"], "host": [f"{T}::test_view_host"],
        "chunk": [f"{T}::test_view_host"]},
    "ViewBakedArgs": {
        "baked": ["reliability/test_bad_runs.py::test_a_baked_folder_that_is_not_one"],
        "port": ["reliability/test_bad_runs.py::test_a_baked_folder_that_is_not_one"],
        "host": ["bake/test_web.py::test_serve_baked_prints_the_address_and_stops_on_ctrl_c"]},
    "MakeSceneArgs": {
        "size": ["cli/test_main.py::test_make_scene"], "n_train": ["cli/test_main.py::test_make_scene"],
        "n_val": ["cli/test_main.py::test_make_scene"], "n_test": ["cli/test_main.py::test_make_scene"],
        "seed": ["cli/test_main.py::test_make_scene"], "overwrite": ["cli/test_main.py::test_make_scene"]},
    "MakeMultiscaleArgs": {f: ["data/formats/test_multiscale.py::multiscale"] for f in ("out", "levels", "progress")},
    "DemoArgs": {f: ["cli/test_demo.py::test_demo_end_to_end"] for f in ("out", "max_steps", "size", "orbit_frames", "overwrite")}
    | {f: [f"{T}::test_demo_preset_reaches_the_trainer"] for f in ("preset", "max_minutes", "max_steps")},
    "ExperimentArgs": {f: [f"{T}::test_experiment_flags_reach_the_experiment"] for f in (
        "out", "budget_minutes", "max_steps", "preset", "seed", "eval_every", "orbit_frames", "grid_views", "val_every",
        "train_split", "val_split", "target_width", "downscale", "models", "mlp_size", "progress")},
    "BenchmarkArgs": {
        "out": ["experiments/test_benchmark.py::test_a_result_with_other_settings_is_refused_or_retrained_with_overwrite"],
        "preset": ["experiments/test_benchmark.py::test_a_result_with_other_settings_is_refused_or_retrained_with_overwrite"],
        "budget_minutes": [f"{T}::test_benchmark_budget_minutes"],
        "max_steps": ["experiments/test_benchmark.py::test_a_result_with_other_settings_is_refused_or_retrained_with_overwrite"],
        "jobs": ["experiments/test_benchmark.py::test_jobs_run_scenes_in_their_own_processes"],
        "only": ["experiments/test_benchmark.py::test_a_result_with_other_settings_is_refused_or_retrained_with_overwrite"],
        "eval_every": [f"{T}::test_benchmark_budget_minutes"],
        "overwrite": ["experiments/test_benchmark.py::test_a_result_with_other_settings_is_refused_or_retrained_with_overwrite"],
        "progress": ["experiments/test_benchmark.py::test_a_result_with_other_settings_is_refused_or_retrained_with_overwrite"]},
    "ProcessArgs": {
        "out": ["test_smoke.py::test_process_data_images"],
        "masks": ["process/test_process_data.py::test_bad_masks_are_one_line_errors"],
        "camera_model": ["test_smoke.py::test_process_data_video_with_the_opencv_lens"],
        "matching": [f"{T}::test_process_data_matching_and_verbose"],
        "frames": ["test_smoke.py::test_process_data_video_with_the_opencv_lens", f"{T}::test_frames_is_refused_for_images"],
        "max_image_size": [
            "process/test_process_data.py::test_maryrose_subset_registers_and_agrees_with_the_reference_poses"],
        "overwrite": ["process/test_process_data.py::test_existing_output_is_not_overwritten"],
        "verbose": [f"{T}::test_process_data_matching_and_verbose"],
        "progress": ["test_smoke.py::test_process_data_images"]},
    "ReportArgs": {},
    "TrainArgs": {
        "out": ["training/test_flags.py::_run"],
        "preset": ["training/test_flags.py::test_every_setting_is_used_or_refused"],
        "resume": ["cli/test_main.py::test_resume_continues_to_total_steps"],
        "overwrite": [f"{T}::test_train_overwrite"],
        "progress": [f"{T}::test_no_progress_hides_the_bars"],
        "viewer": [f"{T}::test_train_viewer_flags"], "viewer_host": [f"{T}::test_train_viewer_flags"],
        "viewer_port": [f"{T}::test_train_viewer_flags"]},
}


def _functions(path: Path) -> dict[str, str]:
    """{function name: its source, decorators (parametrized cases) included} of a test file."""
    text = path.read_text()
    lines = text.splitlines()
    return {n.name: "\n".join(lines[min([n.lineno] + [d.lineno for d in n.decorator_list]) - 1:n.end_lineno])
            for n in ast.parse(text).body if isinstance(n, ast.FunctionDef)}


def test_every_verb_flag_has_a_test():
    classes = {n: c for n, c in vars(cli_args).items() if n.endswith("Args") and dataclasses.is_dataclass(c)}
    classes.update({exporter(name).args.__name__: exporter(name).args for name in EXPORTERS})
    assert set(classes) == set(PROOFS)
    problems = []
    for name, cls in classes.items():
        flags = {f.name for f in dataclasses.fields(cls) if "Positional" not in str(f.type) and f.name != "cfg"}
        if flags != set(PROOFS[name]):
            problems.append(f"{name}: flags without an entry or entries without a flag: {flags ^ set(PROOFS[name])}")
        for flag, proofs in PROOFS[name].items():
            dashed = flag.replace("_", "-")
            for proof in proofs:
                file, func = proof.split("::")
                source = _functions(TESTS / file).get(func)
                if source is None:
                    problems.append(f"{proof} (for {name}.{flag}) does not exist")
                elif not re.search(rf"--(no-)?{dashed}\b|\b{flag}=", source):
                    problems.append(f"{proof} does not use {name}.{flag}")
    assert not problems, "\n".join(problems)


# --- the tests of the flags no other test covered ------------------------------------------------------


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    root = tmp_path_factory.mktemp("verbflags")
    scene = make_scene(root / "scene", size=16, n_train=6, n_val=2, n_test=3)
    assert main(["train", str(scene), "--out", str(root / "run"), "--preset", "tiny", "--no-progress",
                 "--max-steps", "30", "--val-every", "30", "--ckpt-every", "30", "--log-every", "10"]) == 0
    return root / "run"


def test_render_height_and_fps(run, tmp_path):
    out = tmp_path / "r"
    assert main(["render", str(run), "--orbit", "3", "--height", "12", "--fps", "7", "--out", str(out)]) == 0
    info = json.loads((out / "render.json").read_text())
    assert (info["height"], info["width"]) == (12, 12)  # square images: the width follows the height
    assert imageio_v2.get_reader(out / "rgb.mp4").get_meta_data()["fps"] == pytest.approx(7)


def test_eval_and_render_replace_only_with_overwrite(run, tmp_path, capsys):
    assert main(["eval", str(run), "--split", "test"]) == 0
    first = (run / "eval_test.json").read_text()
    capsys.readouterr()
    assert main(["eval", str(run), "--split", "test"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--overwrite" in err and (run / "eval_test.json").read_text() == first
    # (--chunk bounds the memory of rendering, not its result: reliability/test_memory.py measures that)
    assert main(["eval", str(run), "--split", "test", "--every", "2", "--downscale", "2", "--chunk", "64",
                 "--overwrite"]) == 0
    res = json.loads((run / "eval_test.json").read_text())
    assert res["n_views"] == 2 and (res["width"], res["height"]) == (8, 8)  # the run trained at 16x16
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("the user's")
    assert main(["render", str(run), "--orbit", "2", "--out", str(out)]) == 1
    assert "not empty" in capsys.readouterr().err and sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    assert main(["render", str(run), "--orbit", "2", "--out", str(out), "--chunk", "0", "--overwrite"]) == 1
    assert "--chunk must be >= 1" in capsys.readouterr().err
    assert main(["render", str(run), "--orbit", "2", "--out", str(out), "--chunk", "100", "--overwrite"]) == 0
    assert (out / "notes.txt").read_text() == "the user's" and (out / "rgb.mp4").is_file()


def test_mesh_switches_change_the_mesh(procedural_run, tmp_path, capsys):
    run = procedural_run[0]  # a field with surfaces (the tiny run has none to snap to)
    common = ["export", "mesh", str(run), "--method", "levelset", "--resolution", "32", "--no-carve", "--no-progress"]
    meshes, records = {}, {}
    for name, extra in (("default", ["--every", "4"]), ("no_visible", ["--no-visible-only"]),
                        ("no_snap", ["--no-snap", "--every", "4"])):
        assert main([*common, "--out", str(tmp_path / f"{name}.ply"), *extra]) == 0, capsys.readouterr().err
        meshes[name] = trimesh.load(tmp_path / f"{name}.ply", process=False)
        records[name] = json.loads((run / "exports" / "export_mesh.json").read_text())
    # Without the visibility pass, faces no training view sees stay; without the snap, vertices stay on the grid.
    assert records["no_visible"]["faces"] > records["default"]["faces"]
    assert records["no_visible"]["faces"] == records["no_visible"]["faces_of_level_set"]
    assert len(meshes["no_snap"].vertices) == len(meshes["default"].vertices)
    assert not np.allclose(meshes["no_snap"].vertices, meshes["default"].vertices)
    capsys.readouterr()
    assert main([*common, "--out", str(tmp_path / "x.ply"), "--no-visible-only", "--every", "2"]) == 1
    assert "--every" in capsys.readouterr().err and not (tmp_path / "x.ply").exists()


def test_mesh_texture_box_and_every(procedural_run, tmp_path, capsys):
    """--texture writes a GLB whose image has about --texture-size texels a side; --box bounds the mesh
    (normalised units; the run's frame is the scene's); --every thins the fused views."""
    run = procedural_run[0]
    common = ["export", "mesh", str(run), "--resolution", "48", "--no-progress"]
    assert main([*common, "--out", str(tmp_path / "t.glb"), "--texture", "--texture-size", "256"]) == 0
    rec = json.loads((run / "exports" / "export_mesh.json").read_text())
    glb = trimesh.load(tmp_path / "t.glb", force="mesh")
    w, h = glb.visual.material.baseColorTexture.size
    # xatlas scales its charts to fill about that many texels; padding between many small charts makes the
    # atlas of a small mesh larger (measured 463 px here, 2361 for 2048 on a sphere)
    assert 128 <= w <= 512 and 128 <= h <= 512 and rec["texture"]["size"] == [w, h]
    assert len(glb.faces) == rec["faces"] and rec["views"] == 24
    assert main([*common, "--out", str(tmp_path / "b.ply"), "--box", "0.5", "--every", "3"]) == 0
    rec = json.loads((run / "exports" / "export_mesh.json").read_text())
    small = trimesh.load(tmp_path / "b.ply", process=False)
    assert rec["bound"] == 0.5 and rec["views"] == 8 and np.abs(small.vertices).max() <= 0.5 + 1e-5
    assert np.abs(glb.vertices).max() > 0.8  # the default box (the field's, 1.5) holds more of the scene


def test_pointcloud_split_every_and_voxel_size(run, tmp_path):
    def points(*extra):
        out = tmp_path / f"p{len(list(tmp_path.iterdir()))}.ply"
        assert main(["export", "pointcloud", str(run), "--out", str(out), "--min-opacity", "0.01", "--no-progress",
                     *extra]) == 0
        return json.loads((run / "exports" / "export_pointcloud.json").read_text())

    fine, coarse = points("--voxel-size", "0"), points("--voxel-size", "0.5")
    assert coarse["points"] < fine["points"]
    one = points("--split", "test", "--every", "3", "--voxel-size", "0", "--chunk", "64")
    assert one["views"] == 1 and one["points"] < fine["points"]


def test_no_progress_hides_the_bars(run, tmp_path, capfd):
    """The bars (tqdm, on stderr) of an export and of training show by default and not with --no-progress (the
    verbs in this process: what they write to file descriptor 2 is what a user's terminal shows)."""
    def stderr(argv):
        capfd.readouterr()
        assert main(argv) == 0
        return capfd.readouterr().err

    def pointcloud(*extra):
        return stderr(["export", "pointcloud", str(run), "--out", str(tmp_path / f"{len(extra)}.ply"),
                       "--min-opacity", "0.01", *extra])

    assert "%|" in pointcloud() and "%|" not in pointcloud("--no-progress")
    assert "%|" not in stderr(["export", "mesh", str(run), "--out", str(tmp_path / "m.ply"), "--resolution", "24",
                               "--method", "levelset", "--threshold", "0.05", "--no-carve", "--no-progress"])
    scene = json.loads((run / "scene.json").read_text())["data_dir"]
    bars = ["%|" in stderr(["train", scene, "--out", str(tmp_path / f"t{k}"), "--preset", "tiny", "--max-steps", "3",
                            *extra]) for k, extra in enumerate(([], ["--no-progress"]))]
    assert bars == [True, False]


def test_view_host(run):
    """--host names the address served (a loopback name here), --chunk the render chunk."""
    proc = subprocess.Popen([sys.executable, "-m", "nerfkit", "view", str(run), "--host", "localhost", "--port", "0",
                             "--chunk", "512"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = next(x for x in proc.stdout if x.startswith("viewer for"))  # (viser's own banner comes first)
        url = re.search(r"http://localhost:\d+", line).group(0)
        with urllib.request.urlopen(url, timeout=60) as page:  # serving (its warm-up done)
            assert page.status == 200
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=60) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
    with pytest.raises(Exception, match="--chunk must be >= 1"):
        from nerfkit.viewer.run import view_run

        view_run(run, "127.0.0.1", 0, chunk=0)


def test_experiment_flags_reach_the_experiment(monkeypatch, tmp_path, capsys):
    """The CLI hands every experiment flag to the experiment (which the experiment tests show it uses)."""
    import inspect

    import nerfkit.experiments as experiments

    got = {}

    def record(name, real):
        def fake(*args, **kw):
            bound = inspect.signature(real).bind(*args, **kw)
            got[name] = dict(bound.arguments)
            out = bound.arguments["out"]
            out.mkdir(parents=True, exist_ok=True)
            (out / "results.md").write_text("| table |")
        return fake

    monkeypatch.setattr(experiments, "pe_ablation", record("pe", experiments.pe_ablation))
    monkeypatch.setattr(experiments, "antialias_experiment", record("aa", experiments.antialias_experiment))
    common = ["--out", str(tmp_path / "o"), "--budget-minutes", "2", "--max-steps", "9", "--seed", "3",
              "--eval-every", "4", "--grid-views", "3", "--val-every", "7", "--train-split", "train[0:2]",
              "--val-split", "val", "--no-progress"]
    assert main(["experiment", "pe-ablation", "data", *common, "--preset", "seed", "--orbit-frames", "5",
                 "--target-width", "8", "--downscale", "2"]) == 0
    pe = got["pe"]
    assert (pe["preset"], pe["orbit_frames"], pe["target_width"], pe["downscale"]) == ("seed", 5, 8, 2)
    assert main(["experiment", "antialias", "data", *common, "--models", "nerf,ngp", "--mlp-size", "paper"]) == 0
    aa = got["aa"]
    assert aa["models"] == ["nerf", "ngp"] and aa["mlp_size"] == "paper"
    for kw in (pe, aa):
        assert (kw["budget_minutes"], kw["max_steps"], kw["seed"], kw["eval_every"], kw["grid_views"],
                kw["val_every"], kw["train_split"], kw["val_split"], kw["progress"]) == \
               (2.0, 9, 3, 4, 3, 7, "train[0:2]", "val", False)
    from nerfkit.experiments.antialias import ANTIALIAS_MODELS, model_config

    nerf = next(m for m in ANTIALIAS_MODELS if m.run_dir == "nerf")
    small, paper = (model_config(nerf, size, 1.0, None, None, None, None, None) for size in ("small", "paper"))
    assert (small.field.width, paper.field.width) == (128, 256)


def test_benchmark_budget_minutes(tmp_path):
    root = tmp_path / "scenes"
    make_scene(root / "a", size=16, n_train=4, n_val=2, n_test=1)
    out = tmp_path / "b"
    assert main(["benchmark", str(root), "--out", str(out), "--preset", "tiny", "--budget-minutes", "0.5",
                 "--max-steps", "2", "--eval-every", "2", "--no-progress"]) == 0
    cfg = json.loads((out / "a" / "config.json").read_text())
    assert cfg["train"]["max_minutes"] == 0.5 and cfg["train"]["max_steps"] == 2
    assert json.loads((out / "a" / "benchmark.json").read_text())["n_views"] == 1  # every 2nd of 2


def test_demo_preset_reaches_the_trainer(monkeypatch, tmp_path):
    seen = {}

    class Stop(Exception):
        pass

    def fake_trainer(scene, run, cfg, overwrite=False):
        seen["kind"], seen["budget"] = cfg.field.kind, (cfg.train.max_minutes, cfg.train.max_steps)
        raise Stop

    monkeypatch.setattr("nerfkit.training.trainer.Trainer", fake_trainer)
    with pytest.raises(Stop):
        main(["demo", "--out", str(tmp_path / "d"), "--preset", "tiny", "--size", "8"])
    assert seen["kind"] == "mlp" and seen["budget"][0] == 3.0  # the demo's own budget
    # --max-minutes sets the time budget; --max-steps alone replaces it; both: whichever comes first
    for k, (extra, minutes, steps) in enumerate(((["--max-minutes", "0.5"], 0.5, None), (["--max-steps", "7"], None, 7),
                                                 (["--max-steps", "7", "--max-minutes", "2"], 2.0, 7))):
        with pytest.raises(Stop):
            main(["demo", "--out", str(tmp_path / f"e{k}"), "--preset", "tiny", "--size", "8", *extra])
        assert seen["budget"][0] == minutes and (steps is None or seen["budget"][1] == steps)


@pytest.mark.parametrize("bad", [["--max-minutes", "nan"], ["--max-steps", "-1"], ["--orbit-frames", "0"],
                                 ["--size", "100000"]])
def test_demo_checks_its_flags_before_it_writes_the_scene(tmp_path, capsys, bad):
    out = tmp_path / "d"
    assert main(["demo", "--out", str(out), "--preset", "tiny", "--size", "8", *bad]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and bad[0] in err[0] and not out.exists(), err


def test_frames_is_refused_for_images(tmp_path, capsys):
    assert main(["process-data", "images", str(tmp_path), "--out", str(tmp_path / "o"), "--frames", "10"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--frames" in err and "video" in err


def test_train_overwrite(tmp_path, capsys):
    scene = make_scene(tmp_path / "scene", size=8, n_train=2, n_val=1, n_test=0)
    run = tmp_path / "run"
    args = ["train", str(scene), "--out", str(run), "--preset", "tiny", "--max-steps", "2", "--no-progress"]
    assert main(args) == 0
    (run / "checkpoints").rename(tmp_path / "gone")  # a run that died before its first checkpoint
    (run / "notes.txt").write_text("mine")
    capsys.readouterr()
    assert main(args) == 1 and "--overwrite" in capsys.readouterr().err
    assert main([*args, "--overwrite"]) == 0
    assert [json.loads(x)["step"] for x in (run / "metrics.jsonl").read_text().splitlines()][0] == 2  # one run
    assert (run / "notes.txt").read_text() == "mine"
    _ = cli  # the module whose verbs these are


def test_process_data_matching_and_verbose(tmp_path):
    """--verbose prints COLMAP's own log (otherwise it goes to colmap.log only); --matching picks the matcher."""
    rng = np.random.default_rng(0)
    (tmp_path / "noise").mkdir()
    for k in range(3):
        imageio_v2.imwrite(tmp_path / "noise" / f"n{k}.png", rng.integers(0, 255, (48, 48, 3), dtype=np.uint8))

    def run_(name, *extra):
        return subprocess.run([sys.executable, "-m", "nerfkit", "process-data", "images", str(tmp_path / "noise"),
                               "--out", str(tmp_path / name), "--no-progress", *extra], capture_output=True, text=True,
                              timeout=300)

    quiet, loud = run_("a"), run_("b", "--verbose", "--matching", "sequential")
    assert quiet.returncode == loud.returncode == 1  # noise: nothing registers (the error is tested elsewhere)
    assert len(loud.stdout + loud.stderr) > len(quiet.stdout + quiet.stderr) + 200  # COLMAP's log, shown
    assert "try --matching exhaustive" in loud.stderr and "--matching" not in quiet.stderr  # advice for sequential


def test_train_viewer_flags(tmp_path):
    """--viewer serves the live run at --viewer-host:--viewer-port and stays open after training until Ctrl-C."""
    scene = make_scene(tmp_path / "scene", size=8, n_train=2, n_val=1, n_test=0)
    proc = subprocess.Popen([sys.executable, "-m", "nerfkit", "train", str(scene), "--out", str(tmp_path / "run"),
                             "--preset", "tiny", "--max-steps", "5", "--no-progress", "--viewer", "--viewer-host",
                             "localhost", "--viewer-port", "0"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    try:
        lines = []
        for line in proc.stdout:
            lines.append(line)
            if "the viewer stays open" in line:
                break
        text = "".join(lines)
        assert "viewer at http://localhost:" in text and "the viewer stays open" in text, text
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=60) == 0
    finally:
        if proc.poll() is None:
            proc.kill()

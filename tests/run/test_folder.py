"""RunFolder, the one reader of run folders: each file it reads, read back exactly, and refused in one
line naming the file when missing or broken (whole-run loading: tests/reliability/test_bad_runs.py)."""

import json

import pytest

from nerfkit.core.errors import ConfigError, NerfkitError
from nerfkit.core.presets import preset
from nerfkit.run.folder import SCENE_KEYS, RunFolder


def _scene(data_dir) -> dict:
    return {"data_dir": str(data_dir), "format": "blender", "height": 8, "width": 8, "camera": {},
            "transform": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], "scale": 1.0, "train_poses": []}


def test_config_round_trips_and_names_the_broken_file(tmp_path):
    cfg = preset("tiny")
    (tmp_path / "config.json").write_text(cfg.to_json())
    assert RunFolder(tmp_path).config() == cfg
    (tmp_path / "config.json").write_text("{ not json")
    with pytest.raises(ConfigError, match="config.json: not valid JSON"):
        RunFolder(tmp_path).config()
    (tmp_path / "config.json").unlink()
    with pytest.raises(ConfigError, match="config.json: missing"):
        RunFolder(tmp_path).config()


def test_scene_needs_every_key_and_data_dir_follows_it(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    scene = _scene(data)
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    assert RunFolder(tmp_path).scene() == scene
    assert RunFolder(tmp_path).data_dir() == data
    assert RunFolder(tmp_path).data_dir(tmp_path / "elsewhere") == tmp_path / "elsewhere"  # --data wins
    data.rmdir()
    with pytest.raises(ConfigError, match="data folder this run was trained on is gone; pass --data"):
        RunFolder(tmp_path).data_dir()
    for key in SCENE_KEYS:
        partial = {k: v for k, v in scene.items() if k != key}
        (tmp_path / "scene.json").write_text(json.dumps(partial))
        with pytest.raises(NerfkitError, match=f"missing {key}"):
            RunFolder(tmp_path).scene()


def test_load_refuses_a_folder_without_config_or_checkpoint(tmp_path):
    with pytest.raises(ConfigError, match="not a run folder"):
        RunFolder(tmp_path).load()
    (tmp_path / "config.json").write_text(preset("tiny").to_json())
    with pytest.raises(NerfkitError, match="no checkpoint yet"):
        RunFolder(tmp_path).load()


def test_export_records_round_trip_and_skip_broken_ones(tmp_path):
    folder = RunFolder(tmp_path)
    assert folder.records() == {}
    folder.write_record("mesh", {"file": "mesh.ply", "faces": 12})
    (folder.exports / "export_splat.json").write_text("{ broken")
    assert folder.records() == {"mesh": {"file": "mesh.ply", "faces": 12}}


def test_a_checkpoint_written_before_the_package_move_loads_and_scores_the_same(tmp_path):
    """fixtures/run_d912b0b: the tiny preset trained 40 steps on make_scene(size=16, ...) and scored on its
    test views by commit d912b0b, when the modules sat flat in src/nerfkit/ (expected.json holds that
    code's PSNR). The checkpoint format names no module, so it must load and render the same pixels."""
    import shutil
    from pathlib import Path

    from nerfkit.data.procedural.scene import make_scene
    from nerfkit.evaluation.evaluate import evaluate_run

    fixture = Path(__file__).with_name("fixtures") / "run_d912b0b"
    run = tmp_path / "run"
    shutil.copytree(fixture, run)
    scene = make_scene(tmp_path / "scene", size=16, n_train=6, n_val=2, n_test=2)
    expected = json.loads((fixture / "expected.json").read_text())
    trained = RunFolder(run).load()
    assert trained.step == expected["step"] == 40
    ev = evaluate_run(run, scene, "test", progress=False, write=False)
    # Same code path, same float32 math: equal to rounding (1e-4 dB).
    assert ev["psnr"] == pytest.approx(expected["psnr"], abs=1e-4)
    assert [v["psnr"] for v in ev["per_view"]] == pytest.approx(expected["per_view_psnr"], abs=1e-4)

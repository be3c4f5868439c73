"""Pose refinement for the ray methods (--pose-refine on; training/step.py): the corrections are parameters of
their own (zeros at the start, learned from the first step at their own rate), the rays of a step are
made from the corrected poses, and a run keeps them: `eval` and periodic validation render other views moved with
the training rig (rays/correction.run_poses, run/folder.TrainedRun.seen_from)."""

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.core.presets import preset
from nerfkit.data.loader import load_frames, read_capture
from nerfkit.data.procedural.captures import make_capture
from nerfkit.models.registry import build_model
from nerfkit.training.resolve import resolve_config
from nerfkit.training.step import POSE_LR, init_state, make_optimizer, make_train_step, pose_schedule


def _setup(tmp_path, refine: str):
    cap_dir = make_capture(tmp_path / "cap", "nerfstudio", n_views=8, size=16, masks=True, pose_noise=(1.0, 0.02))
    cfg = preset("tiny")
    cfg.train.pose_refine = refine
    cfg.train.max_steps = 40
    cap = read_capture(cap_dir, "train")
    train = load_frames(cap, "train")
    cfg = resolve_config(cfg, cap, train, log=lambda _: None)
    model = build_model(cfg)
    opt, _ = make_optimizer(cfg, model)
    return cfg, model, opt, train


def test_corrections_are_parameters_learned_from_the_first_step(tmp_path):
    cfg, model, opt, train = _setup(tmp_path, "on")
    state = init_state(model, opt, 0)
    assert state["params"]["cam_pose"].shape == (len(train.poses), 6) and not np.any(state["params"]["cam_pose"])
    lr = pose_schedule(cfg)
    assert np.isclose(float(lr(0)), POSE_LR) and POSE_LR > float(lr(1000)) > 0.0  # no warm-up; the field's decay
    step = make_train_step(model, opt, train, cfg)
    images, poses = jnp.asarray(train.images), jnp.asarray(train.poses)
    field0 = jax.tree_util.tree_leaves({k: v for k, v in state["params"].items() if k != "cam_pose"})
    field0 = [np.array(x) for x in field0]
    state, m = step(state, jnp.int32(0), images, poses)
    xi = np.asarray(state["params"]["cam_pose"])
    # Adam's first step moves every correction that has a gradient by about its rate
    seen = np.abs(xi).max(axis=1) > 0
    assert seen.sum() >= len(xi) // 2 and np.abs(xi).max() <= 1.01 * POSE_LR, xi
    field = jax.tree_util.tree_leaves({k: v for k, v in state["params"].items() if k != "cam_pose"})
    assert all(np.abs(np.asarray(a) - b).max() > 0 for a, b in zip(field, field0))  # the field learns alongside
    # the other parameters are the field's own (the model renders without looking at the corrections)
    assert set(state["params"]) == set(model.init(jax.random.PRNGKey(0))[0]) | {"cam_pose"}


def test_the_pose_optimiser_follows_the_pose_schedule(tmp_path):
    """Under a constant gradient Adam's update is lr(t) times its sign, so the corrections' updates read the
    schedule the optimiser really uses (here decaying tenfold every 2 steps), step by step."""
    import copy

    cfg, model, _, _ = _setup(tmp_path, "on")
    cfg = copy.deepcopy(cfg)
    cfg.train.lr_decay_steps = 2
    opt, _ = make_optimizer(cfg, model)
    params = init_state(model, opt, 0)["params"]
    grads = jax.tree_util.tree_map(jnp.ones_like, params)
    state, lr = opt.init(params), pose_schedule(cfg)
    for t in range(4):
        update, state = opt.update(grads, state, params)
        np.testing.assert_allclose(np.abs(np.asarray(update["cam_pose"])), float(lr(t)), rtol=1e-3)
    assert float(lr(3)) < 0.1 * POSE_LR


def test_off_adds_nothing(tmp_path):
    cfg, model, opt, train = _setup(tmp_path, "off")
    assert cfg.field.appearance_count == 0
    assert "cam_pose" not in init_state(model, opt, 0)["params"]


def test_a_refined_run_is_seen_from_its_refined_poses(tmp_path):
    """Through the CLI: a run trained with --pose-refine on keeps its corrections; its training photos are seen from
    their own refined poses (bake's fine-tuning, export's views), other views from their given poses moved by the
    similarity of the rig (eval, which says so)."""
    from nerfkit.cli.main import main
    from nerfkit.evaluation.evaluate import POSE_NOTE, evaluate_run
    from nerfkit.rays.correction import apply_similarity, camera_extent, corrected_pose, refinement_similarity
    from nerfkit.run.folder import RunFolder

    cap_dir = make_capture(tmp_path / "cap", "nerfstudio", n_views=8, size=16, masks=True, pose_noise=(1.0, 0.02))
    run = tmp_path / "run"
    assert main(["train", str(cap_dir), "--out", str(run), "--preset", "tiny", "--pose-refine", "on", "--max-steps",
                 "30", "--val-every", "30", "--ckpt-every", "30", "--no-progress"]) == 0
    loaded = RunFolder(run).load()
    assert loaded.refined_poses
    cap, val = read_capture(cap_dir, "train,val"), loaded.cfg.data.val_split
    train, views = load_frames(cap, "train").poses, load_frames(cap, val).poses
    xi = np.asarray(loaded.params["cam_pose"])
    assert xi.shape == (len(train), 6) and np.abs(xi).max() > 0
    want = np.asarray(corrected_pose(jnp.asarray(train), jnp.asarray(xi), camera_extent(train)))
    assert np.allclose(loaded.seen_from("train", train), want, atol=1e-6)
    moved = apply_similarity(views, *refinement_similarity(train, xi))
    assert np.allclose(loaded.seen_from(val, views), moved, atol=1e-5) and not np.allclose(moved, views, atol=1e-7)
    assert evaluate_run(run, None, val, progress=False, write=False)["poses"] == POSE_NOTE
    # `export cameras` writes the poses the run renders from (in the capture's coordinates); --poses given the
    # capture's own. Read back and normalised as the run normalised them, they are seen_from's.
    from nerfkit.data.formats.nerfstudio import read_nerfstudio
    from nerfkit.data.normalize import apply_transform
    from nerfkit.export.cameras import export_cameras

    m, s = loaded.transform, float(loaded.scene["scale"])
    for poses in ("refined", "given"):
        out = tmp_path / poses / "transforms.json"
        assert export_cameras(run, out, poses=poses, log=lambda _: None)["poses"] == poses
        back = read_nerfstudio(out.parent)
        got = {split: apply_transform(m, s, np.stack([f.c2w for f in back.frames(split)]))
               for split in ("train", "val")}
        want = {"train": loaded.seen_from("train", train), "val": moved} if poses == "refined" else \
            {"train": train, "val": views}
        for split in ("train", "val"):
            np.testing.assert_allclose(got[split], want[split], atol=2e-5)
    assert not np.allclose(loaded.seen_from("train", train), train, atol=1e-4)  # the two files differ

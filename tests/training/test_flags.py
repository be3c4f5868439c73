"""Every flag of `nerfkit train`, against every preset: either the model reads it (it changes the parameters,
the outputs, the schedule, the data or the loop) or the command refuses it with one line naming the flag.

The matrix gives each setting a value other than the preset's (`alternative`), runs the real command line up
to the point where the run would start, and compares what the run would use against the preset's own:

    data          the loaded images, poses and the validation views
    loop          the devices a step runs on, the renderer's chunk
    rays          the pixels drawn at steps 0 and 600
    schedule      the learning rate at steps 0, 1000 and 5000
    init          the initialisation of parameters, optimiser and occupancy state (as a jaxpr)
    step          the whole training step: rays, rendering, loss, gradients, Adam, occupancy update (as a jaxpr)

Settings the loop reads for every model alike (LOOP) are proven once, by a short real run each
(test_loop_settings_take_effect). A new setting must be given an alternative value here, so it cannot
be added without this test deciding whether it is used.
"""

from __future__ import annotations

import copy
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.cli.main import main
from nerfkit.cli.train import parse_train_args
from nerfkit.core.errors import NerfkitError
from nerfkit.core.presets import PRESETS, preset
from nerfkit.data.formats.nerfstudio import write_nerfstudio
from nerfkit.data.procedural.scene import make_scene
from nerfkit.models.registry import build_model
from nerfkit.training import checkpoint as ckpt_lib
from nerfkit.training.flags import (
    FROM_DATA,
    explicit_settings,
    flag_of,
    setting_names,
    unused,
)
from nerfkit.training.setup import refuse_given
from nerfkit.training.step import (
    draw_batch,
    init_state,
    make_optimizer,
    make_train_step,
)
from nerfkit.training.trainer import Trainer

# Read by Trainer.run for every model alike: proven by short real runs below (and --max-bad-steps by
# tests/reliability/test_nan_guard.py, which makes steps non-finite on purpose).
LOOP = {"train.max_steps", "train.max_minutes", "train.val_every", "train.val_max_fraction", "train.ckpt_every",
        "train.keep_ckpts", "train.log_every", "train.max_bad_steps"}


INIT_FILE: dict = {}  # "path": the splat file the scene fixture writes for --init


def alternative(name: str, cfg) -> list[str]:
    """argv that sets `name` to a valid value other than cfg's."""
    section, field = name.split(".")
    v = getattr(getattr(cfg, section), field)
    flag = flag_of(name)
    special = {
        "data.train_split": "train[0:3]", "data.val_split": "test", "data.downscale": "2", "data.target_width": "8",
        "data.background": "black" if v == "white" else "white", "data.format": "nerfstudio",
        "field.kind": "mlp" if v == "ngp" else "ngp", "field.scene_type": "unbounded", "field.bound": "2.5",
        "field.warp": "ndc" if v != "ndc" else "contract",
        "field.appearance_dim": "4", "field.hash_log2_size": "12", "field.hash_base_res": "4",
        "field.hash_max_res": "64", "sampler.near": "1.0", "sampler.far": "5.5", "sampler.max_samples": "16384",
        "train.devices": "2", "train.precrop_frac": "0.3",
        "train.adam_eps": "0.001", "train.val_max_fraction": "0.001",
        "splat.strategy": "mcmc" if v == "classic" else "classic", "splat.sh_degree": "1", "splat.init_points": "sfm",
        "splat.backend": "reference", "splat.appearance": "on", "train.pose_refine": "on",
        "splat.pose_hold_last": "on",
        "splat.far_points": "on", "splat.random_background": "on", "splat.init": str(INIT_FILE.get("path")),
        "splat.normal_consistency": "0.05", "splat.normal_consistency_from": "0.3",
        "splat.depth_distortion": "100", "splat.colour_transform": "affine" if v == "gain" else "gain",
        "splat.coarse": "0.25", "splat.ssim_lambda": "0.2", "splat.colour_lr": "0.005", "splat.pixel_loss": "rmse" if v == "l1" else "l1",
        "sampler.sampling": "proposal" if v != "proposal" else "occupancy",
    }
    if name == "field.kind" and v == "ngp":  # the MLP fields need a fixed [near, far]
        return [flag, "mlp", "--near", "2", "--far", "6"]
    if name == "train.val_views":  # the scene has 3 validation views
        return [flag, "1" if v == 2 else "2"]
    if name in special:
        return [flag, special[name]]
    if isinstance(v, bool):
        return [flag if not v else "--no-" + flag[2:]]
    if isinstance(v, int):
        return [flag, str(v // 2 if v > 3 else v + 1)]
    if isinstance(v, float):
        return [flag, repr(v * 0.5 if v < 1 else v * 1.5)]
    if v is None:
        return [flag, "0.05" if field == "max_minutes" else "3"]
    raise AssertionError(f"no alternative value for {name} ({v!r}); add one to alternative()")


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """The procedural scene (16 px) and, beside its Blender files, a transforms.json of 5 of its frames (so
    --format nerfstudio reads other data)."""
    root = make_scene(tmp_path_factory.mktemp("flags") / "scene", size=16, n_train=6, n_val=3, n_test=2)
    meta = json.loads((root / "transforms_train.json").read_text())
    from nerfkit.data.formats.blender import read_blender

    frames = read_blender(root, "train").frames("train")[:5]
    write_nerfstudio(root / "transforms.json", [{"file_path": str(f.image.relative_to(root)), "transform_matrix":
                                                 f.c2w} for f in frames], [f.camera for f in frames])
    assert meta["frames"]
    from nerfkit.models.splat.formats.ply import export_ply
    from nerfkit.models.splat.gaussians import init_random

    export_ply(INIT_FILE.setdefault("path", root / "start.ply"), init_random(50, box=0.5))  # for --init
    return root


def _traced(fn, *args):
    """A computation as data: the text of its jaxpr and its constants (arrays closed over)."""
    closed = jax.make_jaxpr(fn)(*args)
    return [str(closed.jaxpr), *[np.asarray(c) for c in closed.consts]]


def observe_splat(trainer):
    """observe() for a Gaussian-splatting run (one view per step, density control on the host): the data, the
    host's schedule (SH degree, the means' rate, the density-control window, at a few steps and progresses),
    the initial state (values) and the jitted view step (as a jaxpr)."""
    from nerfkit.models.splat.train import schedule_at
    from nerfkit.models.splat.train import make_step

    model, cfg, td = trainer.model, trainer.cfg, trainer.train_data

    def step():
        fn = make_step(model.sc, trainer.optimizer.opts, td.width, td.height, with_health=True)
        params, aux = model.init()
        args = ({k: jnp.asarray(v) for k, v in params.items()}, trainer.optimizer.init(params),
                {k: jnp.asarray(aux[k]) for k in ("grad_sum", "count", "max_radius")}, jnp.asarray(aux["active"]),
                jnp.asarray(model.training_views(td.images, td.alphas)), jnp.asarray(td.poses), jnp.zeros((len(td), 4)), jnp.ones(3), 0,
                jax.random.PRNGKey(0), 1e-3, 1)
        return _traced(fn, *args)

    return {
        "data": lambda: [td.images, td.poses, trainer.val_data.images, np.asarray(trainer.val_ids)],
        "schedule": lambda: [sorted(schedule_at(s, p, model.sc).items()) for s in (0, 300, 500, 1000, 1500, 3000)
                             for p in (0.0, 0.3, 0.5, 0.9)],
        "init": lambda: jax.tree_util.tree_leaves(init_state(model, trainer.optimizer, cfg.train.seed)),
        "step": step,
    }


def observe(trainer):
    """What a run with this trainer would use, piece by piece, cheapest first; each entry is a thunk. The
    computations are compared as jaxprs (the program JAX compiles, with every shape and every constant
    baked in: two runs whose jaxprs and constants agree compute the same thing)."""
    model, cfg, td = trainer.model, trainer.cfg, trainer.train_data
    if hasattr(model, "make_train_step"):
        return observe_splat(trainer)

    def init():
        return _traced(lambda: init_state(model, trainer.optimizer, cfg.train.seed))

    def step():
        # Traced with at most 2 hash-grid levels (the levels are one piece of code repeated; 16 of them take
        # 1.2 s to trace). Settings of the grid itself already differ in `init`, before this is reached.
        small = copy.deepcopy(cfg)
        small.field.hash_levels = min(small.field.hash_levels, 2)
        m = build_model(small)
        optimizer, _ = make_optimizer(small)
        state = jax.eval_shape(lambda: init_state(m, optimizer, small.train.seed))
        fn = make_train_step(m, optimizer, td, small, trainer.mesh)
        return _traced(fn, state, jnp.int32(0), jax.ShapeDtypeStruct(td.images.shape, jnp.float32),
                       jax.ShapeDtypeStruct(td.poses.shape, jnp.float32))

    return {
        "data": lambda: [td.images, td.poses, trainer.val_data.images, np.asarray(trainer.val_ids)],
        "loop": lambda: [0 if trainer.mesh is None else trainer.mesh.size, trainer.renderer.chunk],
        "rays": lambda: [np.asarray(x) for s in (0, 600) for x in draw_batch(jax.random.PRNGKey(1), s, len(td),
                                                                              td.height, td.width, cfg.train,
                                                                              td.sizes)],
        "schedule": lambda: [np.float32(trainer.schedule(s)) for s in (0, 1000, 5000)],
        "init": init,
        "step": step,
    }


def _same(a, b) -> bool:
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, (dict, str)) or isinstance(b, (dict, str)):
        return a == b
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and bool(np.array_equal(a, b, equal_nan=a.dtype.kind == "f"))


def _trainer(scene, out, argv):
    args = parse_train_args([str(scene), "--out", str(out), *argv])
    refuse_given(args.data_dir, args.cfg, explicit_settings(argv), args.preset, False)  # what nerfkit train does
    return Trainer(args.data_dir, args.out, args.cfg, progress=False)


MODEL_SETTINGS = [n for n in setting_names() if n not in LOOP]


@pytest.mark.parametrize("name", PRESETS)
def test_every_setting_is_used_or_refused(scene, tmp_path, name, capsys):
    base_trainer = _trainer(scene, tmp_path / "base", ["--preset", name])
    base = observe(base_trainer)
    cache = {}
    used, refused = [], []
    for setting in MODEL_SETTINGS:
        argv = ["--preset", name, *alternative(setting, preset(name))]
        moot = setting in FROM_DATA or setting in unused(preset(name), base_trainer.capture)
        try:
            trainer = _trainer(scene, tmp_path / "x", argv)
        except NerfkitError as e:
            # Refused: through the real command line too, with one line naming the flag, exit 1.
            assert main(["train", str(scene), "--out", str(tmp_path / "y"), "--no-progress", *argv]) == 1
            err = capsys.readouterr().err.strip()
            assert err.count("\n") == 0 and flag_of(setting)[2:] in err, (setting, err)
            assert not (tmp_path / "y").exists(), "a refused run wrote its folder"
            assert moot or setting == "train.devices", f"{name}: {setting} refused but listed as used: {e}"
            refused.append(setting)
            continue
        assert not moot, f"{name}: {setting} is listed as unused but was accepted"
        obs = observe(trainer)
        changed = next((k for k in obs if not _same(obs[k](), cache.setdefault(k, base[k]()))), None)
        assert changed, f"--preset {name}: {' '.join(argv[2:])} was accepted but changed nothing the run uses"
        used.append((setting, changed))
    print({k: [s for s, c in used if c == k] for k in ("data", "loop", "rays", "schedule", "init", "step")})
    assert used and refused or name in ("tiny",)  # both sides are exercised for every preset
    print(f"{name}: {len(used)} used, {len(refused)} refused: {refused}")


def test_every_setting_has_a_proof():
    """A setting is either in the matrix above (MODEL_SETTINGS) or a loop setting proven below."""
    assert set(MODEL_SETTINGS) | LOOP == set(setting_names())
    for n in setting_names():
        for p in PRESETS:
            if n not in LOOP:
                alternative(n, preset(p))


def _run(scene, out, *argv):
    assert main(["train", str(scene), "--out", str(out), "--preset", "tiny", "--no-progress", *argv]) == 0
    rows = [json.loads(x) for x in (out / "metrics.jsonl").read_text().splitlines()]
    vrows = [json.loads(x) for x in (out / "val_metrics.jsonl").read_text().splitlines()]
    ckpts = [int(p.stem.split("_")[1]) for p in ckpt_lib.list_checkpoints(out / "checkpoints")]
    return [r["step"] for r in rows], [r["step"] for r in vrows], ckpts


def test_loop_settings_take_effect(scene, tmp_path):
    """max_steps, log_every, val_every, ckpt_every, keep_ckpts, max_minutes and val_max_fraction change what a
    real run does (each against the tiny preset's own value in one of these runs)."""
    base = ["--max-steps", "8", "--log-every", "2", "--val-every", "4", "--ckpt-every", "4", "--keep-ckpts", "3"]
    logs, vals, ckpts = _run(scene, tmp_path / "a", *base, "--val-max-fraction", "1")
    assert (logs, vals, ckpts) == ([2, 4, 6, 8], [4, 8], [4, 8])
    logs, vals, ckpts = _run(scene, tmp_path / "b", "--max-steps", "9", "--log-every", "3", "--val-every", "3",
                             "--ckpt-every", "2", "--keep-ckpts", "2", "--val-max-fraction", "1")
    assert (logs, vals, ckpts) == ([3, 6, 9], [3, 6, 9], [8, 9])
    # A validation costs far more than 0.1% of the time between them: only the first and the final one run.
    _, vals, _ = _run(scene, tmp_path / "c", *base[2:], "--max-steps", "12", "--val-max-fraction", "0.001")
    assert vals == [4, 12]
    # --max-minutes stops long before --max-steps.
    logs, _, _ = _run(scene, tmp_path / "d", "--max-steps", "100000", "--max-minutes", "0.05", "--log-every", "1")
    assert 0 < logs[-1] < 100000

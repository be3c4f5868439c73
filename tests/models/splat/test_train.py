"""train_splats end to end on nerfkit's procedural scene (32 x 32 px), and evaluate().

The floor: 300 steps of the default (MCMC) training from 1,500 random Gaussians reach
FLOOR_DB on the 4 held-out views. Measured: 16.5, 16.6, 16.2 dB with seeds 0, 1, 2 (training
views 17.3 dB: the model underfits, it does not overfit); an untrained cloud scores ~8 dB, the
white background alone ~11 dB. The paper's learning rates are made for 30k steps (a colour moves
by at most ~7e-4 per step), so 300 steps are far from converged: 3,000 steps reach 19.0 dB here.
For scale, the NeRF tests reach 17-20 dB on this 32 px scene (tests/models/test_ngp.py, training/test_trainer.py).
"""

import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.data.loader import load_scene
from nerfkit.data.procedural.scene import make_scene
from nerfkit.models.splat import densify, surface
from nerfkit.models.splat.optim import LearningRates, init_state, make_optimizers
from nerfkit.models.splat.strategy import MCMC, Classic, Window
from nerfkit.models.splat.gaussians import evaluate
from nerfkit.models.splat.train import (
    SplatConfig,
    host_control,
    initial_params,
    schedule_at,
)
from nerfkit.models.splat.fit import train_splats

FLOOR_DB = 15.0
STEPS = 300


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    root = make_scene(tmp_path_factory.mktemp("splat_scene"), size=32, n_train=24, n_val=4, n_test=0)
    return load_scene(root, "train"), load_scene(root, "val")


def test_trains_to_floor(scene):
    train, val = scene
    cfg = SplatConfig(capacity=3000, init_count=1500, sh_interval=100, log_every=10,
                      strategy=MCMC(window=Window(every=50, start=100), grow_rate=0.2))
    params, log = train_splats(train.images, train.poses, train.cameras, (1.0, 1.0, 1.0), cfg, steps=STEPS)
    assert [r[0] for r in log] == list(range(10, STEPS + 1, 10))
    elapsed = [r[1] for r in log]
    assert elapsed == sorted(elapsed)
    loss = [r[2] for r in log]
    assert np.mean(loss[-5:]) < 0.5 * np.mean(loss[:2])
    assert 1500 < len(params["means"]) <= 3000 and all(np.isfinite(v).all() for v in params.values())
    before = evaluate(initial_params(cfg)[0], val.images, val.poses, val.cameras)
    after = evaluate(params, val.images, val.poses, val.cameras)
    assert set(after) == {"psnr", "ssim", "psnr_mean", "ssim_mean"} and len(after["psnr"]) == 4
    assert after["psnr_mean"] > FLOOR_DB > before["psnr_mean"] + 5
    assert after["ssim_mean"] > before["ssim_mean"]


def test_refuses_bad_arguments(scene):
    train, _ = scene
    with pytest.raises(ValueError, match="minutes"):
        train_splats(train.images, train.poses, train.cameras)
    with pytest.raises(ValueError, match="strategy"):
        SplatConfig(strategy="adc")
    with pytest.raises(ValueError, match="one size"):
        train_splats(train.images[:2], train.poses[:2], [train.cameras[0], train.cameras[0].with_size(16, 16)], steps=1)


def _host_schedule(reset_every: int, steps: int, control_until: float = 0.8) -> list[tuple[int, list[str]]]:
    """(step, what host_control did) for every step that did something, on 40 random Gaussians."""
    cfg = SplatConfig(capacity=40, strategy=Classic(window=Window(every=100, start=100, until=control_until),
                                                    schedule=densify.ClassicSchedule(reset_every=reset_every)))
    p0, active = initial_params(cfg)
    params = {k: jnp.asarray(v) for k, v in p0.items()}
    opts = make_optimizers(LearningRates(), 1.0)
    opt_state, stats, rng = init_state(opts, params), densify.zero_stats(40), np.random.default_rng(0)
    done = []
    for step in range(1, steps + 1):
        params, opt_state, stats, active, what = host_control(cfg, step, step / steps, params, opt_state, stats, active,
                                                              rng, 1.0, 32)
        if what:
            done.append((step, what))
        if "reset" in what:
            assert float(jnp.max(jnp.where(jnp.asarray(active), params["opacity"], -jnp.inf))) <= np.log(0.01 / 0.99) + 1e-5
    return done


def test_opacity_reset_only_when_asked_and_inside_the_control_window():
    none = _host_schedule(reset_every=0, steps=1000)
    assert [s for s, w in none] == list(range(100, 800, 100)) and all(w == ["control"] for _, w in none)
    resets = [s for s, w in _host_schedule(reset_every=300, steps=1000) if "reset" in w]
    assert resets == [300, 600]  # 900 is past control_until (0.8 of 1000 steps)


def test_half_resolution_averages_pixels_and_keeps_the_geometry():
    """Coarse to fine trains on 2x2-averaged photos with the intrinsics halved: a small pixel j covers the big
    pixels 2j and 2j + 1 (centres at half-integers), so a point the full camera puts at u lands at u / 2. Checked
    on renders: one small dark Gaussian, off the pixel grid, has its darkness centroid at (u, v) in the full
    image and at (u, v) / 2 in the half one (to 0.02 px), and the averaged image is the blocks' mean."""
    from nerfkit.models.splat.gaussians import init_from_points, render_arrays
    from nerfkit.models.splat.train import half_resolution
    from nerfkit.data.procedural.scene import look_at

    g = init_from_points(np.array([[0.13, 0.0, -0.21]], np.float32), np.zeros((1, 3), np.float32), 0.9)
    g["log_scales"] = np.full((1, 3), np.log(0.04), np.float32)
    c2w = jnp.asarray(look_at(np.array([0.0, -3.0, 0.0])), jnp.float32)
    intr = jnp.asarray([[60.0, 60.0, 32.0, 32.0]])
    full = np.asarray(render_arrays(g, c2w, intr[0], (1.0, 1.0, 1.0), 0, 64, 64, depth=False)["rgb"])
    small_images, small_intr = half_resolution(jnp.asarray(full)[None], intr)
    np.testing.assert_allclose(small_intr, intr / 2)
    np.testing.assert_allclose(small_images[0], full.reshape(32, 2, 32, 2, 3).mean((1, 3)), atol=1e-6)
    half = np.asarray(render_arrays(g, c2w, small_intr[0], (1.0, 1.0, 1.0), 0, 32, 32, depth=False)["rgb"])

    def centroid(img):
        dark = 1.0 - img.mean(-1)
        j, i = np.meshgrid(np.arange(img.shape[1]) + 0.5, np.arange(img.shape[0]) + 0.5)
        return np.array([np.sum(dark * j), np.sum(dark * i)]) / dark.sum()

    c_full, c_half = centroid(full), centroid(half)
    assert np.abs(c_full - [32, 32]).min() > 2  # off the centre: a wrong cx / 2 would show
    np.testing.assert_allclose(c_half, c_full / 2, atol=0.02)


def test_coarse_to_fine_trains_at_half_then_full_resolution(scene):
    """coarse_until = 0.5: the first half of the steps run the half-resolution step (16 px views of the 32 px
    scene), the rest the full one; the run trains (the loss falls) and its Gaussians render full-size views."""
    train, val = scene
    cfg = SplatConfig(capacity=1500, init_count=1500, strategy="none", coarse_until=0.5, log_every=10)
    params, log = train_splats(train.images, train.poses, train.cameras, (1.0, 1.0, 1.0), cfg, steps=60)
    loss = [r[2] for r in log]
    assert len(loss) == 6 and np.mean(loss[-2:]) < np.mean(loss[:2])
    assert evaluate(params, val.images, val.poses, val.cameras)["psnr_mean"] > evaluate(
        initial_params(cfg)[0], val.images, val.poses, val.cameras)["psnr_mean"]


def test_the_surface_terms_come_on_at_their_share_of_the_budget(scene, monkeypatch):
    """normal_consistency_from = 0.5 over 6 steps: steps 0-2 (progress < 0.5) run the step without the term, so
    the photometric losses of steps 0-3 are those of a run without it, bit for bit; from the update of step 3
    on the term moves the Gaussians, and step 4's loss differs. With the term from the start, step 1's does.
    The depth-distortion term alone keeps the same schedule and moves them otherwise."""
    train, _ = scene

    def losses(**surface) -> list[float]:
        cfg = SplatConfig(capacity=300, strategy="none", log_every=1, **surface)
        return [r[2] for r in train_splats(train.images[:4], train.poses[:4], train.cameras[:4], (1.0, 1.0, 1.0),
                                           cfg, steps=6)[1]]

    late = SplatConfig(normal_consistency=0.1, normal_consistency_from=0.5)
    assert [schedule_at(s, s / 6, late)["surface"] for s in range(6)] == [False] * 3 + [True] * 3
    assert not schedule_at(5, 0.9, SplatConfig(normal_consistency_from=0.5))["surface"]  # no weight, no term
    plain, later = losses(), losses(normal_consistency=0.1, normal_consistency_from=0.5)
    assert later[:4] == plain[:4] and later[4] != plain[4]
    from_start = losses(normal_consistency=0.1)
    assert from_start[0] == plain[0] and from_start[1] != plain[1]
    distortion = SplatConfig(depth_distortion=100.0, normal_consistency_from=0.5)  # the same schedule, alone
    monkeypatch.setattr(surface, "EDGE_SPREAD", np.inf)  # the random start's rays are all depth edges
    assert [schedule_at(s, s / 6, distortion)["surface"] for s in range(6)] == [False] * 3 + [True] * 3
    later_d = losses(depth_distortion=100.0, normal_consistency_from=0.5)
    assert later_d[:4] == plain[:4] and later_d[4] != plain[4] and later_d[4] != later[4]


def test_rgba_views_train_on_a_random_background_their_alpha_composites_them_onto():
    """_loss_fn of an RGBA view (--random-background): the target is the photo re-composited by its alpha onto a
    background b' drawn from the step's key, the render is on b'. With no Gaussians the render is b' itself: a
    view that is all background (alpha 0) then costs nothing whatever b', an opaque one (alpha 1) costs |b' - c|,
    which changes with the key."""
    import jax

    from nerfkit.models.splat.gaussians import band_mask
    from nerfkit.models.splat.train import _loss_fn

    cfg = SplatConfig(capacity=50, backend="reference")
    params = {k: jnp.asarray(v) for k, v in initial_params(cfg)[0].items()}
    inactive = jnp.zeros(50, bool)
    c2w = jnp.asarray(np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]], np.float32))
    intr = jnp.asarray([20.0, 20.0, 8.0, 8.0])
    white = jnp.ones(3)

    def loss(image, seed):
        out = _loss_fn(params, jnp.zeros((50, 2)), image, c2w, intr, white, band_mask(0), inactive, 0,
                       jax.random.PRNGKey(seed), cfg=cfg, width=16, height=16, dilation=0.3, extent=1.0)
        return float(out[1][0])

    empty = jnp.concatenate([jnp.ones((16, 16, 3)), jnp.zeros((16, 16, 1))], -1)  # the white background, alpha 0
    opaque = jnp.concatenate([jnp.full((16, 16, 3), 0.3), jnp.ones((16, 16, 1))], -1)
    assert max(loss(empty, s) for s in range(3)) < 1e-6
    costs = [loss(opaque, s) for s in range(3)]
    assert min(costs) > 1e-3 and max(costs) - min(costs) > 1e-3
    assert loss(opaque[..., :3], 0) == pytest.approx(0.7, abs=1e-4)  # RGB views: the white background as before


def test_the_steps_draw_with_the_configs_screen_dilation(scene, monkeypatch):
    """--screen-dilation reaches the training step: _loss_fn is traced with cfg.screen_dilation px^2 at full
    resolution and a quarter of it at half resolution (coarse to fine: the same footprint in the photos' pixels),
    and a smaller floor renders, so scores, the same Gaussians otherwise."""
    from nerfkit.models.splat import train as train_module

    train, _ = scene
    seen = []
    real = train_module._loss_fn

    def spy(*args, dilation, **kwargs):
        seen.append(dilation)
        return real(*args, dilation=dilation, **kwargs)

    monkeypatch.setattr(train_module, "_loss_fn", spy)

    def first_loss(**settings) -> float:
        cfg = SplatConfig(capacity=300, strategy="none", log_every=1, **settings)
        return train_splats(train.images[:2], train.poses[:2], train.cameras[:2], (1.0, 1.0, 1.0), cfg,
                            steps=2)[1][0][2]

    first_loss(screen_dilation=0.7, coarse_until=0.5)
    assert sorted(set(seen)) == [pytest.approx(0.175), pytest.approx(0.7)]
    assert first_loss(screen_dilation=0.05) != first_loss()


def test_each_step_sets_the_colour_transforms_rate_from_the_schedule(scene, monkeypatch):
    """The step's colour-transform rate is optim.colour_lr at the step's progress: a schedule that answers 0 keeps
    every transform at the identity, where the optimiser's own rate (3e-3) would have moved them."""
    from nerfkit.models.splat import train as train_module

    train, _ = scene
    asked = []
    monkeypatch.setattr(train_module, "colour_lr", lambda progress, lrs: asked.append(progress) or 0.0)
    cfg = SplatConfig(capacity=600, init_count=600, appearance=True, n_views=len(train.images), log_every=5)
    last = {}
    train_splats(train.images, train.poses, train.cameras, (1.0, 1.0, 1.0), cfg, steps=10,
                 callback=lambda step, elapsed, params, active: last.update(params))
    assert asked == pytest.approx([k / 10 for k in range(10)])
    assert last["cam_color"].shape == (len(train.images), 3, 4) and np.all(np.asarray(last["cam_color"]) == 0.0)

"""The numba tile rasteriser against the brute-force JAX reference and finite differences.

Images are 44 x 36 px: neither side is a multiple of the 16 px tile, so the last tile column
and row are partial. Tolerances:
  - float64 (kernel vs reference under jax.enable_x64): 1e-12. Both compute the same
    sums in the same order up to rounding (~1e-16 per operation), so any blending-rule
    difference (a skipped or extra Gaussian: >= 1/255 of a colour) would show at once.
  - float32 forward: 5e-6 absolute. The kernel computes in float64 from float32 inputs, the
    reference in float32: each pixel blends <= ~40 terms with products of <= ~40 factors,
    relative rounding 6e-8 each, on values <= 1 + background.
  - float32 gradients: 2e-5 x max |gradient| of each array. Gradients are sums over pixels of
    terms whose float32 rounding is ~40 x 6e-8 relative; the observed gap is <= 5e-7 x max.
  - finite differences (float64 kernel, h = 1e-6 central): 1e-6 x max |gradient| plus 1e-7;
    truncation is O(h^2) and cancellation ~1e-16 / h = 1e-10 relative.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.models.splat import tiles_numba
from nerfkit.models.splat.rasterize import rasterize
from nerfkit.models.splat.reference import rasterize_reference

try:  # the x64 context manager: top-level since JAX 0.8, jax.experimental before
    from jax import enable_x64
except ImportError:
    from jax.experimental import enable_x64

W, H = 44, 36
NAMES = ("means2d", "conics", "colors", "opacities", "background")


def conic_of(cov):
    """Conic (a, b, c) [N, 3] and radius [N] of 2D covariances [N, 2, 2] (as project.conic_and_radius)."""
    inv = np.linalg.inv(cov)
    radius = np.ceil(3.0 * np.sqrt(np.linalg.eigvalsh(cov)[:, -1])).astype(np.int32)
    return np.stack([inv[:, 0, 0], inv[:, 0, 1], inv[:, 1, 1]], -1), radius


def random_scene(n=40, channels=3, seed=0, dtype=np.float32):
    """Gaussians around and partly outside the image: some clamped (opacity ~1), some culled (radius 0)."""
    rng = np.random.default_rng(seed)
    means = np.stack([rng.uniform(-6, W + 6, n), rng.uniform(-6, H + 6, n)], -1)
    lin = rng.normal(size=(n, 2, 2)) * rng.uniform(0.7, 5.0, (n, 1, 1))
    conics, radii = conic_of(lin @ lin.transpose(0, 2, 1) + 0.3 * np.eye(2))
    radii[::13] = 0
    opacities = rng.uniform(0.02, 1.0, n)
    opacities[::7] = 1.0
    colors = rng.uniform(0, 1, (n, channels))
    depths = rng.uniform(1, 5, n)
    background = rng.uniform(0, 1, channels)
    return tuple(np.asarray(a, dtype) for a in (means, conics, colors, opacities, depths)) + (
        radii, np.asarray(background, dtype))


def padded(scene, n=40):
    """The scene plus culled (radius 0) Gaussians up to n: tests share compiled reference shapes."""
    extra = n - len(scene[0])
    pad = [np.concatenate([a, np.ones((extra,) + a.shape[1:], a.dtype)]) for a in scene[:5]]
    return pad + [np.concatenate([scene[5], np.zeros(extra, np.int32)]), scene[6]]


def as_jax(scene):
    return tuple(jnp.asarray(a) for a in scene)


N_FRONT = 5  # opaque_front_scene's front stack
FRONT_CENTRE = (22.0, 18.0)


def opaque_front_scene():
    """Five wide opaque Gaussians in front of two small ones at the image centre (float32, padded): the front
    stack drives T below T_MIN around the centre, so blending stops before the small ones. (Opacity 0.98, not
    >= 0.99: two clamped alphas give T = (1 - 0.99)^2, exactly T_MIN, where float32 and float64 rounding
    disagree on whether the second one is blended.)"""
    cx, cy = FRONT_CENTRE
    cov = np.array([[900.0, 0.0], [0.0, 900.0]] * N_FRONT + [[2.0, 0.3], [0.3, 1.5]] * 2).reshape(-1, 2, 2)
    conics, radii = conic_of(cov)
    means = np.array([[cx, cy]] * N_FRONT + [[cx + 0.4, cy - 0.3], [cx - 0.5, cy + 0.2]])
    opacities = np.array([0.98] * N_FRONT + [0.9, 0.5])
    colors = np.random.default_rng(0).uniform(0, 1, (len(means), 3))
    depths = np.array([1.0, 1.1, 1.2, 1.3, 1.4, 3.0, 4.0])
    return padded([np.asarray(a, np.float32) for a in (means, conics, colors, opacities, depths)] + [
        radii, np.full(3, 0.5, np.float32)])


def straddle_scene(center):
    """An elongated, rotated Gaussian centred at `center` (on or next to a tile corner) over a faint one behind
    it (float64, padded; call under enable_x64)."""
    cov = np.array([[[40.0, 25.0], [25.0, 30.0]], [[200.0, 0.0], [0.0, 150.0]]])
    conics, radii = conic_of(cov)
    return padded([np.asarray(a, np.float64) for a in (
        [center, (20.0, 17.0)], conics, [[0.9, 0.2, 0.1], [0.1, 0.3, 0.8]], [0.8, 0.3], [1.0, 2.0])] + [
        radii, np.zeros(3)])


def needle_scene():
    """Covariances far below the 0.3 px^2 dilation (conic a up to 1e4 px^-2) and a long thin needle (float64,
    padded; call under enable_x64); the sharpest lights pixel (7, 10)."""
    cov = np.array([[[1e-4, 0.0], [0.0, 1e-4]], [[0.02, 0.0], [0.0, 3.0]], [[60.0, 59.7], [59.7, 60.0]],
                    [[0.5, 0.0], [0.0, 0.04]]])
    conics, radii = conic_of(cov)
    return padded([np.asarray(a, np.float64) for a in (
        [(10.5, 7.5), (20.3, 12.0), (22.0, 18.0), (30.0, 30.1)], conics, np.eye(4)[:, :3] + 0.1,
        [0.9, 0.8, 0.7, 1.0], [1.0, 2.0, 3.0, 4.0])] + [radii, np.zeros(3)])


def loss_weights(seed, channels, dtype):
    rng = np.random.default_rng(100 + seed)
    return rng.normal(size=(H, W, channels)).astype(dtype), rng.normal(size=(H, W)).astype(dtype)


def kernel_grads(scene, g_img, g_alpha):
    """Host forward + backward for L = sum(g_img * image) + sum(g_alpha * alpha); T_final = 1 - alpha."""
    _, t_final, n_contrib = tiles_numba.forward(*scene, W, H)
    return tiles_numba.backward(*scene, W, H, t_final, n_contrib, g_img, -g_alpha)


@jax.jit
def _reference_grads(m, q, c, o, d, r, bg, g_img, g_alpha):
    def loss(m, q, c, o, bg):
        image, alpha = rasterize_reference(m, q, c, o, d, r, bg, W, H)
        return jnp.sum(image * g_img) + jnp.sum(alpha * g_alpha)

    return jax.grad(loss, argnums=(0, 1, 2, 3, 4))(m, q, c, o, bg)


def reference_grads(scene, g_img, g_alpha):
    """Autodiff gradients of the reference for the loss of kernel_grads (one compile per shape)."""
    return [np.asarray(g) for g in _reference_grads(*as_jax(scene), g_img, g_alpha)]


_reference_forward = jax.jit(rasterize_reference, static_argnums=(7, 8))


def assert_grads_close(got, want, rel, names=NAMES):
    for name, g, w in zip(names, got, want):
        scale = max(float(np.abs(w).max()), 1e-12)
        np.testing.assert_allclose(g, w, rtol=0, atol=rel * scale, err_msg=name)


@pytest.mark.parametrize("channels", [3, 4])
def test_forward_float32_matches_reference(channels):
    scene = random_scene(channels=channels)
    image, t_final, n_contrib = tiles_numba.forward(*scene, W, H)
    ref_image, ref_alpha = _reference_forward(*as_jax(scene), W, H)
    np.testing.assert_allclose(image, ref_image, rtol=0, atol=5e-6)
    np.testing.assert_allclose(1.0 - t_final, ref_alpha, rtol=0, atol=5e-6)
    assert image.dtype == np.float32 and n_contrib.max() > 0 and (t_final >= 1e-4).all()


def test_forward_and_backward_float64_match_reference():
    with enable_x64(True):
        scene = random_scene(seed=1, dtype=np.float64)
        image, t_final, _ = tiles_numba.forward(*scene, W, H)
        ref_image, ref_alpha = _reference_forward(*as_jax(scene), W, H)
        np.testing.assert_allclose(image, ref_image, rtol=0, atol=1e-12)
        np.testing.assert_allclose(1.0 - t_final, ref_alpha, rtol=0, atol=1e-12)
        g_img, g_alpha = loss_weights(1, 3, np.float64)
        assert_grads_close(kernel_grads(scene, g_img, g_alpha), reference_grads(scene, g_img, g_alpha), 1e-10)


def test_backward_float32_matches_reference_autodiff():
    scene = random_scene(seed=2)
    g_img, g_alpha = loss_weights(2, 3, np.float32)
    got = kernel_grads(scene, g_img, g_alpha)
    assert all(g.dtype == np.float32 for g in got)
    assert_grads_close(got, reference_grads(scene, g_img, g_alpha), 2e-5)


def assert_finite_differences(scene, loss, got, h=1e-6):
    """got (gradients of NAMES) against central differences of loss(scene) (float64 scene): 1e-6 x max
    |gradient| plus 1e-7; every array must have some gradient."""
    for name, slot, grad in zip(NAMES, (0, 1, 2, 3, 6), got):
        fd = np.zeros_like(scene[slot])
        for idx in np.ndindex(fd.shape):
            plus, minus = [a.copy() for a in scene], [a.copy() for a in scene]
            plus[slot][idx] += h
            minus[slot][idx] -= h
            fd[idx] = (loss(plus) - loss(minus)) / (2 * h)
        assert np.abs(fd).max() > 0, name
        np.testing.assert_allclose(grad, fd, rtol=0, atol=1e-6 * np.abs(fd).max() + 1e-7, err_msg=name)


def test_backward_matches_finite_differences():
    scene = list(random_scene(n=14, seed=3, dtype=np.float64))
    g_img, g_alpha = loss_weights(3, 3, np.float64)

    def loss(s):
        image, t_final, _ = tiles_numba.forward(*s, W, H)
        return float(np.sum(image * g_img) - np.sum(t_final * g_alpha))

    assert_finite_differences(scene, loss, kernel_grads(scene, g_img, g_alpha))


def test_opaque_front_stops_blending_and_hidden_gaussians_get_zero_gradient():
    scene = opaque_front_scene()
    cx, cy = FRONT_CENTRE
    image, t_final, n_contrib = tiles_numba.forward(*scene, W, H)
    assert n_contrib[int(cy), int(cx)] <= N_FRONT  # the centre pixel stopped inside the front stack
    g_img, g_alpha = loss_weights(4, 3, np.float32)
    got = kernel_grads(scene, g_img, g_alpha)
    for g in got[:4]:
        assert np.all(g[N_FRONT:] == 0.0)  # exactly zero, not just small (the padding too)
        assert np.any(g[:N_FRONT] != 0.0)
    assert_grads_close(got, reference_grads(scene, g_img, g_alpha), 2e-5)
    hidden = [a.copy() for a in scene]
    hidden[2][N_FRONT:] = 1.0 - hidden[2][N_FRONT:]  # recolouring the hidden ones changes nothing
    assert np.array_equal(tiles_numba.forward(*hidden, W, H)[0], image)


@pytest.mark.parametrize("center", [(16.0, 16.0), (15.5, 15.5), (32.2, 31.7)])
def test_gaussian_straddling_tile_corners(center):
    with enable_x64(True):
        scene = straddle_scene(center)
        image, t_final, n_contrib = tiles_numba.forward(*scene, W, H)
        ref_image, _ = _reference_forward(*as_jax(scene), W, H)
        np.testing.assert_allclose(image, ref_image, rtol=0, atol=1e-12)
        tx, ty = (int(round(v / 16)) * 16 for v in center)  # the nearest tile corner
        corner = n_contrib[ty - 1:ty + 1, tx - 1:tx + 1]  # the 4 pixels around the tile corner, 4 tiles
        assert corner.shape == (2, 2) and np.all(corner >= 1)
        g_img, g_alpha = loss_weights(5, 3, np.float64)
        assert_grads_close(kernel_grads(scene, g_img, g_alpha), reference_grads(scene, g_img, g_alpha), 1e-10)


def test_sharp_and_needle_conics_match_reference():
    # the scanline spans stay exact, and e^{-sigma} is not advanced by products where that would overflow
    with enable_x64(True):
        scene = needle_scene()
        image, _, _ = tiles_numba.forward(*scene, W, H)
        ref_image, _ = _reference_forward(*as_jax(scene), W, H)
        np.testing.assert_allclose(image, ref_image, rtol=0, atol=1e-12)
        assert image[7, 10, 0] > 0.8  # the sharpest one still lights its own pixel
        g_img, g_alpha = loss_weights(9, 3, np.float64)
        assert_grads_close(kernel_grads(scene, g_img, g_alpha), reference_grads(scene, g_img, g_alpha), 1e-10)


@pytest.mark.parametrize("backend", ["numba", "pallas"])
def test_empty_scene_gives_background(backend):
    background = np.array([0.2, 0.4, 0.6], np.float32)
    empty = [np.zeros((0, 2), np.float32), np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32),
             np.zeros(0, np.float32), np.zeros(0, np.float32), np.zeros(0, np.int32), background]
    image, alpha = jax.jit(lambda *a: rasterize(*a, W, H, backend=backend))(*empty)
    assert np.array_equal(np.asarray(image), np.broadcast_to(background, (H, W, 3)))
    assert np.array_equal(np.asarray(alpha), np.zeros((H, W), np.float32))
    g_bg = jax.grad(lambda bg: jnp.sum(rasterize(*empty[:6], bg, W, H, backend=backend)[0]))(background)
    np.testing.assert_allclose(g_bg, np.full(3, W * H), rtol=1e-6)


def test_culled_and_offscreen_gaussians_contribute_nothing():
    scene = list(random_scene(n=6, seed=6))
    scene[5] = np.zeros(6, np.int32)  # all culled (e.g. behind the camera)
    image, t_final, n_contrib = tiles_numba.forward(*scene, W, H)
    assert np.array_equal(image, np.broadcast_to(scene[6], image.shape)) and np.all(t_final == 1.0)
    assert np.all(n_contrib == 0)
    off = list(random_scene(n=6, seed=6))
    off[0] = np.asarray([[-40.0, 10.0], [W + 40.0, 10.0], [10.0, -40.0], [10.0, H + 40.0], [-30, -30],
                         [W + 30, H + 30]], np.float32)  # outside by more than their radii
    assert np.all(off[5] < 30)
    g_img, g_alpha = loss_weights(6, 3, np.float32)
    for s in (scene, off):
        assert np.array_equal(tiles_numba.forward(*s, W, H)[0], np.broadcast_to(s[6], (H, W, 3)))
        assert all(np.all(g == 0.0) for g in kernel_grads(s, g_img, g_alpha)[:4])


def test_jax_wrapper_jit_grad_vmap():
    host_scene = random_scene(seed=7)
    scene = as_jax(host_scene)
    g_img, g_alpha = loss_weights(7, 3, np.float32)

    def loss(m, q, c, o, bg):
        image, alpha = rasterize(m, q, c, o, scene[4], scene[5], bg, W, H, backend="numba")
        return jnp.sum(image * g_img) + jnp.sum(alpha * g_alpha)

    args = (scene[0], scene[1], scene[2], scene[3], scene[6])
    got = jax.jit(jax.grad(loss, argnums=(0, 1, 2, 3, 4)))(*args)
    assert_grads_close([np.asarray(g) for g in got], reference_grads(host_scene, g_img, g_alpha), 2e-5)
    ops = jnp.stack([scene[3], 0.5 * scene[3]])
    batched = jax.vmap(lambda o: rasterize(scene[0], scene[1], scene[2], o, scene[4], scene[5], scene[6], W, H,
                                           backend="numba")[0])(ops)
    np.testing.assert_allclose(batched[1], _reference_forward(*scene[:3], ops[1], *scene[4:], W, H)[0], atol=5e-6)


def test_xla_candidate_matches_reference():
    """The padded-XLA candidate of benchmarks/splat_raster.py (benchmarks/splat_alt_xla.py) renders the same image."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[3] / "benchmarks" / "splat_alt_xla.py"
    spec = importlib.util.spec_from_file_location("splat_alt_xla", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    rasterize_xla = module.rasterize_xla

    scene = as_jax(random_scene(n=30, seed=8))
    image, alpha = jax.jit(lambda *a: rasterize_xla(*a, W, H, 64, 512))(*scene)
    ref_image, ref_alpha = _reference_forward(*scene, W, H)
    np.testing.assert_allclose(image, ref_image, rtol=0, atol=5e-6)
    np.testing.assert_allclose(alpha, ref_alpha, rtol=0, atol=5e-6)


def test_auto_picks_the_host_kernels_off_a_gpu():
    """Off a GPU "auto" runs the numba tile kernels (on a GPU the pallas ones: test_rasterize_pallas.py):
    return_contrib, a numba-only output, works."""
    assert jax.default_backend() != "gpu"
    scene = as_jax(random_scene(seed=3))
    image, alpha, n_contrib = rasterize(*scene, W, H, return_contrib=True)
    want_image, want_alpha = _reference_forward(*scene, W, H)
    np.testing.assert_allclose(image, want_image, atol=5e-6)
    np.testing.assert_allclose(alpha, want_alpha, atol=5e-6)
    assert int(n_contrib.max()) > 0


@pytest.mark.parametrize("channels", [3, 4])
def test_frame_writes_the_forward_image_at_every_tile_size(channels):
    """tiles_numba.frame (the numba backend's `frame`: a view only looked at) writes forward()'s pixels: rgb clipped
    to [0, 1], the channels after the third unclipped, alpha = 1 - T_final; at tiles of 16 (forward's), 32 and 64
    px (larger than the image: one partial tile), and with one in three Gaussians at the same depth (the blend takes
    ties in index order, whatever order frame keeps its arrays in: tiles_numba.local_order; threads 1 and 2)."""
    scene = list(random_scene(n=60, seed=5, channels=channels))
    scene[2] = scene[2] * 1.6 - 0.3  # colours past 0 and 1
    scene[4][::3] = scene[4][1]
    image, t_final, _ = tiles_numba.forward(*scene, W, H)
    assert (image[..., :3] > 1).any() and (image[..., :3] < 0).any()  # the clip is exercised
    for tile, threads in ((16, 1), (16, 2), (32, 2), (64, 2)):
        rgb, extra, alpha = tiles_numba.frame(*scene, W, H, threads=threads, tile=tile)
        assert rgb.shape == (H, W, 3) and extra.shape == (H, W, channels - 3) and alpha.shape == (H, W)
        np.testing.assert_array_equal(rgb, np.clip(image[..., :3], 0, 1))
        np.testing.assert_array_equal(extra, image[..., 3:])
        np.testing.assert_allclose(alpha, 1 - t_final, atol=1e-7)


def test_depth_order_is_a_stable_argsort():
    rng = np.random.default_rng(11)
    depths = rng.choice(np.array([-2.5, -0.0, 0.0, 1e-30, 0.7, 0.7, 3.0, np.inf], np.float32), 300)
    depths[::7] = rng.normal(size=len(depths[::7])).astype(np.float32)
    live = np.flatnonzero(rng.uniform(size=300) < 0.8)
    want = live[np.argsort(depths[live], kind="stable")]
    np.testing.assert_array_equal(tiles_numba.depth_order(depths, live), want)
    big = rng.normal(size=70_000).astype(np.float32)  # every byte of the radix sort's keys in use
    big[::5] = big[3]
    live_big = np.flatnonzero(rng.uniform(size=big.size) < 0.9)
    np.testing.assert_array_equal(tiles_numba.depth_order(big, live_big),
                                  live_big[np.argsort(big[live_big], kind="stable")])
    d64 = depths.astype(np.float64) + rng.normal(size=300) * 1e-12  # other dtypes: numpy's stable argsort
    np.testing.assert_array_equal(tiles_numba.depth_order(d64, live), live[np.argsort(d64[live], kind="stable")])


def test_backward_takes_the_forwards_tile_lists(monkeypatch):
    """rasterize under jax.grad bins once per step: the backward takes the lists its forward kept (by token);
    a token that is gone (or none) bins again, with the same gradients."""
    scene = random_scene(seed=12)
    g_img, g_alpha = loss_weights(12, 3, np.float32)
    calls = []
    binner = tiles_numba.bin_local
    monkeypatch.setattr(tiles_numba, "bin_local", lambda *a: calls.append(1) or binner(*a))
    image, t_final, n_contrib, token = tiles_numba.forward(*scene, W, H, keep_bins=True)
    kept = tiles_numba.backward(*scene, W, H, t_final, n_contrib, g_img, -g_alpha, bins=token)
    assert len(calls) == 1
    again = tiles_numba.backward(*scene, W, H, t_final, n_contrib, g_img, -g_alpha, bins=token)  # taken: gone
    assert len(calls) == 2
    for a, b in zip(kept, again):
        np.testing.assert_array_equal(a, b)
    calls.clear()
    sj = as_jax(scene)

    def loss(m, q, c, o, bg):
        image, alpha = rasterize(m, q, c, o, sj[4], sj[5], bg, W, H, backend="numba")
        return jnp.sum(image * g_img) + jnp.sum(alpha * g_alpha)

    got = jax.jit(jax.grad(loss, argnums=(0, 1, 2, 3, 4)))(sj[0], sj[1], sj[2], sj[3], sj[6])
    assert len(calls) == 1
    for a, b in zip(got, kept):
        np.testing.assert_allclose(np.asarray(a), b, rtol=0, atol=1e-6 * np.abs(b).max())


def test_an_image_wider_than_int16_columns_matches_reference():
    # the rows' spans are int16 below 2^15 columns and int32 from there (tiles_numba.table_spans)
    wide, high = 2**15 + 40, 20
    with enable_x64(True):
        scene = list(random_scene(seed=4, dtype=np.float64))
        scene[0][:, 0] += wide - W - 20  # the Gaussians straddle column 2^15
        scene[0][:, 1] *= high / H
        m64, c64, o64 = tiles_numba._f64(scene[0], scene[1], scene[3])
        spans = tiles_numba.bin_local(m64, c64, o64, scene[4], scene[5].astype(np.int32), wide, high, None).rows[2]
        assert spans.dtype == np.int32 and spans.max() >= 2**15  # the int32 path, reached
        image, _, _ = tiles_numba.forward(*scene, wide, high)
        ref_image, _ = _reference_forward(*as_jax(scene), wide, high)
        assert np.abs(image).max() > 0.1
        np.testing.assert_allclose(image, ref_image, rtol=0, atol=1e-12)

"""The pallas backend's kernels (rasterize_pallas.py) against the brute-force reference and finite differences.

On a CPU the kernels run in Pallas's interpret mode: the same kernel source the GPU compiles, so every
rule (alpha test, 3-sigma cut, T_MIN stop, chunk and rectangle skipping, the front-to-back backward) is
checked here. The scenes and tolerances are test_rasterize.py's (44 x 36 px: partial edge tiles); the
float64 ones are tighter than float32 rounding could meet, so a skipped or extra Gaussian would show. The
last tests lower the kernels for CUDA (no GPU needed): what a GPU would compile is Triton, not the
interpreter, and "auto" picks it there.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_rasterize import (
    N_FRONT,
    H,
    W,
    _reference_forward,
    as_jax,
    assert_finite_differences,
    assert_grads_close,
    conic_of,
    enable_x64,
    loss_weights,
    needle_scene,
    opaque_front_scene,
    random_scene,
    reference_grads,
    straddle_scene,
)

from nerfkit.models.splat import backends
from nerfkit.models.splat.project import project_gaussians
from nerfkit.models.splat.rasterize import rasterize
from nerfkit.models.splat.rasterize_pallas import (
    CHUNK,
    MAX_SEGMENTS,
    interpret_default,
    rasterize_pallas,
    segment_count,
)
from nerfkit.rays.cameras import look_at

def _kernels(segments: int | None = None):
    """(forward, gradients) of the kernels in interpret mode, jitted, the backward in `segments` per tile
    (None: segment_count's)."""
    forward = jax.jit(lambda *a: rasterize_pallas(*a, W, H, interpret=True, segments=segments))

    @jax.jit
    def grads(m, q, c, o, d, r, bg, g_img, g_alpha):
        def loss(m, q, c, o, bg):
            image, alpha = rasterize_pallas(m, q, c, o, d, r, bg, W, H, interpret=True, segments=segments)
            return jnp.sum(image * g_img) + jnp.sum(alpha * g_alpha)

        return jax.grad(loss, argnums=(0, 1, 2, 3, 4))(m, q, c, o, bg)

    return forward, grads


_forward, _grads = _kernels()


def pallas_grads(scene, g_img, g_alpha, grads=_grads):
    return [np.asarray(g) for g in grads(*as_jax(scene), g_img, g_alpha)]


def test_interpret_mode_is_the_default_off_a_gpu():
    assert jax.default_backend() != "gpu" and interpret_default()


@pytest.mark.parametrize("channels", [3, 4])
def test_forward_float32_matches_reference(channels):
    scene = as_jax(random_scene(channels=channels))
    image, alpha = _forward(*scene)
    ref_image, ref_alpha = _reference_forward(*scene, W, H)
    np.testing.assert_allclose(image, ref_image, rtol=0, atol=5e-6)
    np.testing.assert_allclose(alpha, ref_alpha, rtol=0, atol=5e-6)
    assert image.dtype == jnp.float32 and float(alpha.max()) > 0.5 and float(alpha.max()) <= 1.0 - 1e-4


def test_forward_and_backward_float64_match_reference():
    with enable_x64(True):
        scene = random_scene(seed=1, dtype=np.float64)
        image, alpha = _forward(*as_jax(scene))
        ref_image, ref_alpha = _reference_forward(*as_jax(scene), W, H)
        np.testing.assert_allclose(image, ref_image, rtol=0, atol=1e-12)
        np.testing.assert_allclose(alpha, ref_alpha, rtol=0, atol=1e-12)
        g_img, g_alpha = loss_weights(1, 3, np.float64)
        assert_grads_close(pallas_grads(scene, g_img, g_alpha), reference_grads(scene, g_img, g_alpha), 1e-10)


def test_backward_float32_matches_reference_autodiff():
    scene = random_scene(n=3 * CHUNK + 5, seed=2)  # several chunks, the last one part padding
    g_img, g_alpha = loss_weights(2, 3, np.float32)
    got = pallas_grads(scene, g_img, g_alpha)
    assert all(g.dtype == np.float32 for g in got)
    assert_grads_close(got, reference_grads(scene, g_img, g_alpha), 2e-5)


def test_backward_matches_finite_differences():
    with enable_x64(True):
        scene = list(random_scene(n=14, seed=3, dtype=np.float64))
        g_img, g_alpha = loss_weights(3, 3, np.float64)

        def loss(s):
            image, alpha = _forward(*as_jax(s))
            return float(np.sum(np.asarray(image) * g_img) + np.sum(np.asarray(alpha) * g_alpha))

        assert_finite_differences(scene, loss, pallas_grads(scene, g_img, g_alpha))


def test_opaque_front_stops_blending_and_hidden_gaussians_get_zero_gradient():
    scene = opaque_front_scene()
    image, _ = _forward(*as_jax(scene))
    g_img, g_alpha = loss_weights(4, 3, np.float32)
    got = pallas_grads(scene, g_img, g_alpha)
    for g in got[:4]:
        assert np.all(g[N_FRONT:] == 0.0)  # exactly zero: never blended (the padding too)
        assert np.any(g[:N_FRONT] != 0.0)
    assert_grads_close(got, reference_grads(scene, g_img, g_alpha), 2e-5)
    hidden = [a.copy() for a in scene]
    hidden[2][N_FRONT:] = 1.0 - hidden[2][N_FRONT:]  # recolouring the hidden ones changes nothing
    assert np.array_equal(np.asarray(_forward(*as_jax(hidden))[0]), np.asarray(image))


@pytest.mark.parametrize("center", [(16.0, 16.0), (15.5, 15.5), (32.2, 31.7)])
def test_gaussian_straddling_tile_corners(center):
    with enable_x64(True):
        scene = straddle_scene(center)
        image, _ = _forward(*as_jax(scene))
        ref_image, _ = _reference_forward(*as_jax(scene), W, H)
        np.testing.assert_allclose(image, ref_image, rtol=0, atol=1e-12)
        tx, ty = (int(round(v / 16)) * 16 for v in center)
        corner = np.asarray(image)[ty - 1:ty + 1, tx - 1:tx + 1, 0]  # 4 pixels, 4 tiles, all lit by the first
        assert corner.shape == (2, 2) and np.all(corner > 0.05)
        g_img, g_alpha = loss_weights(5, 3, np.float64)
        assert_grads_close(pallas_grads(scene, g_img, g_alpha), reference_grads(scene, g_img, g_alpha), 1e-10)


def test_sharp_and_needle_conics_match_reference():
    with enable_x64(True):
        scene = needle_scene()
        image, _ = _forward(*as_jax(scene))
        ref_image, _ = _reference_forward(*as_jax(scene), W, H)
        np.testing.assert_allclose(image, ref_image, rtol=0, atol=1e-12)
        assert image[7, 10, 0] > 0.8
        g_img, g_alpha = loss_weights(9, 3, np.float64)
        assert_grads_close(pallas_grads(scene, g_img, g_alpha), reference_grads(scene, g_img, g_alpha), 1e-10)


def test_gaussians_behind_the_camera_and_off_screen_contribute_nothing():
    # a real projection: half the Gaussians in front of a camera, half behind it (project culls them:
    # radius 0) or far off to the side; the image and the gradients of the ones in front are the same
    # as with the others removed, and the others get exactly zero gradient
    rng = np.random.default_rng(10)
    n = 24
    c2w = look_at(np.array([0.0, 0.0, 4.0]), np.zeros(3))
    front = rng.uniform(-0.5, 0.5, (n, 3))
    behind = front + np.array([0.0, 0.0, 8.0])  # 4 units behind the camera
    aside = front + np.array([30.0, 0.0, 0.0])  # far outside the view
    means = np.concatenate([front, behind, aside]).astype(np.float32)
    m = len(means)
    log_scales = np.full((m, 3), np.log(0.08), np.float32)
    quats = np.tile(np.array([1.0, 0.0, 0.0, 0.0], np.float32), (m, 1))
    colors = rng.uniform(0, 1, (m, 3)).astype(np.float32)
    opacities = rng.uniform(0.3, 0.9, m).astype(np.float32)
    p = project_gaussians(jnp.asarray(means), jnp.asarray(log_scales), jnp.asarray(quats),
                          jnp.asarray(c2w, jnp.float32), (40.0, 40.0, 0.5 * W, 0.5 * H), W, H)
    means2d, conics, depths, radii = p["means2d"], p["conics"], p["depths"], p["radii"]
    assert int((radii[:n] > 0).sum()) == n and int((radii[n:2 * n] > 0).sum()) == 0
    bg = jnp.full(3, 0.3, jnp.float32)
    args = (means2d, conics, jnp.asarray(colors), jnp.asarray(opacities), depths, radii, bg)
    image, alpha = _forward(*args)
    ref_image, _ = _reference_forward(*args, W, H)
    np.testing.assert_allclose(image, ref_image, rtol=0, atol=5e-6)
    only_front = tuple(a[:n] for a in args[:6]) + (bg,)
    np.testing.assert_allclose(image, _forward(*only_front)[0], rtol=0, atol=1e-6)
    assert float(alpha.max()) > 0.5
    g_img, g_alpha = loss_weights(10, 3, np.float32)
    got = [np.asarray(g) for g in _grads(*args, g_img, g_alpha)]
    alone = [np.asarray(g) for g in _grads(*only_front, g_img, g_alpha)]
    for g, a in zip(got[:4], alone[:4]):
        assert np.all(g[n:] == 0.0)
        np.testing.assert_allclose(g[:n], a, rtol=0, atol=1e-5 * np.abs(a).max())


def _cuda_text(fn, *args) -> str:
    """fn lowered for CUDA (on any machine: lowering needs no GPU), as StableHLO text. From jax 0.11 the Triton
    lowering asks which GPU it targets and, with none present, wants an abstract one: an H100 (the H200's chip)."""
    def lower():
        return jax.jit(fn).trace(*args).lower(lowering_platforms=("cuda",)).as_text()

    try:
        return lower()
    except RuntimeError as e:
        if "No supported GPU devices found" not in str(e):
            raise
    device = jax.sharding.AbstractDevice(device_kind="NVIDIA H100", num_cores=None, platform="gpu")
    with jax.sharding.use_abstract_mesh(jax.sharding.AbstractMesh((), (), abstract_device=device)):
        return lower()


@pytest.mark.parametrize("segments", [None, 1])
def test_the_gpu_path_lowers_to_triton_kernels(segments):
    """What a GPU runs: interpret=False lowers both kernels to Triton (custom calls holding Triton IR), a
    forward and a backward under value_and_grad, with no host callback; with the backward in segments (here
    one per chunk) and in one (large images)."""
    scene = as_jax(random_scene(seed=4))
    g_img, g_alpha = loss_weights(4, 3, np.float32)

    def loss(m, q, c, o, bg):
        image, alpha = rasterize_pallas(m, q, c, o, scene[4], scene[5], bg, W, H, interpret=False, segments=segments)
        return jnp.sum(image * g_img) + jnp.sum(alpha * g_alpha)

    text = _cuda_text(jax.value_and_grad(loss, argnums=(0, 1, 2, 3, 4)), *scene[:4], scene[6])
    calls = [line for line in text.splitlines() if "custom_call" in line]
    triton = [line for line in calls if "xla.gpu.triton" in line]
    assert len(triton) == 2, calls
    assert any('name = "splat_forward"' in c for c in triton) and any('name = "splat_backward"' in c for c in triton)
    assert not any("callback" in c for c in calls)


def test_auto_picks_the_pallas_kernels_on_a_gpu(monkeypatch):
    assert backends.backend("auto").name == "numba"
    monkeypatch.setattr(jax, "default_backend", lambda: "gpu")
    assert backends.backend("auto").name == "pallas" and not interpret_default()
    scene = as_jax(random_scene(seed=5))
    text = _cuda_text(lambda *a: rasterize(*a, W, H), *scene)  # backend "auto"
    assert text.count("xla.gpu.triton") == 1 and "callback" not in text


def test_splat_training_runs_with_the_pallas_backend(tmp_path):
    """`nerfkit train --preset splat --backend pallas`: the whole step (projection, rasteriser, loss, Adam) with
    the pallas kernels trains as the numba ones do: the same validation PSNR after the same steps."""
    from nerfkit.cli.main import main
    from nerfkit.core.viz import read_jsonl
    from nerfkit.data.procedural.scene import make_scene

    scene = make_scene(tmp_path / "scene", size=32, n_train=6, n_val=2, n_test=1)
    psnr = {}
    for name in ("pallas", "numba"):
        run = tmp_path / name
        assert main(["train", str(scene), "--out", str(run), "--preset", "splat", "--no-progress", "--capacity", "1000",
                     "--max-steps", "40", "--val-every", "40", "--backend", name]) == 0
        rows = read_jsonl(run / "val_metrics.jsonl")
        assert rows[-1]["step"] == 40
        psnr[name] = rows[-1]["psnr"]
    assert psnr["pallas"] > 10.0 and abs(psnr["pallas"] - psnr["numba"]) < 0.05, psnr


def test_segment_count_fills_a_gpu_at_small_images_only():
    assert segment_count(13 * 13, 1563) == 13  # lego at 200 px, 50,000 Gaussians: 2197 programs
    assert segment_count(50 * 50, 1563) == 1  # at 800 px the tiles alone are enough
    assert segment_count(9, 2) == 2 and segment_count(9, 1000) == MAX_SEGMENTS and segment_count(1, 0) == 1


def dense_scene(channels: int, n: int = 3 * CHUNK + 5):
    """n wide, nearly opaque Gaussians over the whole image (float64, 4 chunks, the last one part padding): most
    pixels are done (T below T_MIN) within the first chunk, so later segments start with done pixels."""
    rng = np.random.default_rng(8)
    sigma = rng.uniform(4.0, 10.0, n)
    shear = rng.uniform(-3, 3, n)
    cov = np.einsum("n,ij->nij", sigma ** 2, np.eye(2)) + np.einsum("n,ij->nij", shear, [[0, 1], [1, 0]])
    conics, radii = conic_of(cov)
    means = np.stack([rng.uniform(0, W, n), rng.uniform(0, H, n)], -1)
    return [means, conics, rng.uniform(0, 1, (n, channels)), rng.uniform(0.85, 0.97, n), rng.uniform(1, 5, n),
            radii, rng.uniform(0, 1, channels)]


@pytest.mark.parametrize("segments, channels", [(2, 3), (4, 4)])
@pytest.mark.parametrize("make", [lambda ch: random_scene(n=3 * CHUNK + 5, channels=ch, seed=6, dtype=np.float64),
                                  dense_scene], ids=["sparse", "dense"])
def test_segmented_backward_gives_the_same_gradients(make, segments, channels):
    """Each (tile, segment) program starts from the forward's checkpoint of that segment: the pixels and the
    gradients are the unsegmented kernels' exactly (float64), and the reference's gradients to 1e-10. In the
    dense scene most pixels are done before the second segment starts; in the sparse one none is."""
    with enable_x64(True):
        scene = [np.asarray(a, np.int32 if k == 5 else np.float64) for k, a in enumerate(make(channels))]
        fwd, grads = _kernels(segments)
        one_fwd, one_grads = _kernels(1)
        assert np.array_equal(np.asarray(fwd(*as_jax(scene))[0]), np.asarray(one_fwd(*as_jax(scene))[0]))
        g_img, g_alpha = loss_weights(6, channels, np.float64)
        got = pallas_grads(scene, g_img, g_alpha, grads)
        assert all(np.array_equal(a, b) for a, b in zip(got, pallas_grads(scene, g_img, g_alpha, one_grads)))
        assert_grads_close(got, reference_grads(scene, g_img, g_alpha), 1e-10)


def test_the_stop_carries_across_segments():
    """The opaque front in the first two chunks (padding's culled Gaussians sort among them), the small Gaussians
    it hides two chunks later (culled ones in between): with three segments the hidden ones are another
    program's, which must start with the front's pixels done, so they get exactly zero gradient."""
    front = opaque_front_scene()
    n = len(front[0])
    fill = 2 * CHUNK
    scene = []
    for k, a in enumerate(front):
        a = np.asarray(a)
        filler = np.repeat(a[N_FRONT:N_FRONT + 1], fill, axis=0)
        if k == 4:
            filler = np.full(fill, 2.0, a.dtype)  # depths between the front (1.0-1.4) and the hidden (3.0, 4.0)
        if k == 5:
            filler = np.zeros(fill, a.dtype)  # radius 0: culled
        scene.append(a if k == 6 else np.concatenate([a[:N_FRONT], filler, a[N_FRONT:n]]))
    fwd, grads = _kernels(3)
    g_img, g_alpha = loss_weights(7, 3, np.float32)
    got = pallas_grads(scene, g_img, g_alpha, grads)
    for g in got[:4]:
        assert np.all(g[N_FRONT:] == 0.0) and np.any(g[:N_FRONT] != 0.0)
    assert_grads_close(got, reference_grads(scene, g_img, g_alpha), 2e-5)
    np.testing.assert_allclose(fwd(*as_jax(scene))[0], _reference_forward(*as_jax(scene), W, H)[0], rtol=0, atol=5e-6)

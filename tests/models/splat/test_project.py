"""Projection of 3D Gaussians (EWA), SH colours, and the whole chain under jax.grad."""

import jax
import jax.numpy as jnp
import numpy as np
import optax

from nerfkit.encoding.sh import sh_encode
from nerfkit.models.splat.project import (
    LOWPASS_DILATION,
    SH_C0,
    covariance_3d,
    project_gaussians,
    quaternion_to_rotation,
    sh_colors,
    world_to_camera,
)
from nerfkit.models.splat.rasterize import rasterize
from nerfkit.rays.cameras import Camera, camera_rays, look_at

try:  # the x64 context manager: top-level since JAX 0.8, jax.experimental before
    from jax import enable_x64
except ImportError:
    from jax.experimental import enable_x64

CAM = Camera(44, 36, 40.0, 42.0, 21.0, 19.5)  # off-centre principal point, fx != fy
INTR = (CAM.fx, CAM.fy, CAM.cx, CAM.cy)
C2W = look_at(np.array([3.0, -2.0, 1.5]), np.array([0.1, 0.2, 0.0]))


_project = jax.jit(project_gaussians, static_argnums=(5, 6))


def project(means, log_scales=None, quats=None, c2w=C2W):
    n = len(means)
    log_scales = np.full((n, 3), np.log(0.05), np.float32) if log_scales is None else log_scales
    quats = np.tile(np.float32([1, 0, 0, 0]), (n, 1)) if quats is None else quats
    return _project(jnp.asarray(means), jnp.asarray(log_scales), jnp.asarray(quats), jnp.asarray(c2w), INTR,
                    CAM.width, CAM.height)


def test_means_land_on_the_nerf_pixel_rays():
    # a point t along the NeRF ray of pixel (i, j) projects to that pixel's centre at z-depth t
    origins, dirs = camera_rays(C2W, CAM)
    rng = np.random.default_rng(0)
    i, j = rng.integers(0, CAM.height, 20), rng.integers(0, CAM.width, 20)
    t = rng.uniform(1.0, 6.0, 20)
    points = (origins[i, j] + t[:, None] * dirs[i, j]).astype(np.float32)
    out = project(points)
    np.testing.assert_allclose(out["means2d"], np.stack([j + 0.5, i + 0.5], -1), atol=2e-4)
    np.testing.assert_allclose(out["depths"], t, rtol=1e-5)
    assert np.all(np.asarray(out["radii"]) > 0)


def test_covariance_from_scales_and_normalised_quaternion():
    rng = np.random.default_rng(1)
    log_s = rng.normal(size=(5, 3)) * 0.5
    q = rng.normal(size=(5, 4))
    rot = np.asarray(quaternion_to_rotation(jnp.asarray(q)))
    np.testing.assert_allclose(rot @ rot.transpose(0, 2, 1), np.broadcast_to(np.eye(3), (5, 3, 3)), atol=1e-6)
    np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-6)
    cov = np.asarray(covariance_3d(jnp.asarray(log_s), jnp.asarray(q)))
    np.testing.assert_allclose(cov, np.asarray(covariance_3d(jnp.asarray(log_s), jnp.asarray(3.0 * q))), rtol=1e-5)
    np.testing.assert_allclose(np.linalg.eigvalsh(cov), np.sort(np.exp(2 * log_s), -1), rtol=1e-4)
    # w-first: (cos t/2, 0, 0, sin t/2) rotates x toward y about z
    half = 0.5 * np.pi / 2
    np.testing.assert_allclose(np.asarray(quaternion_to_rotation(jnp.array([np.cos(half), 0, 0, np.sin(half)])))
                               @ np.array([1.0, 0, 0]), [0, 1, 0], atol=1e-6)


def test_ewa_covariance_is_the_projection_jacobian_sandwich():
    with enable_x64(True):
        rng = np.random.default_rng(2)
        means = rng.uniform(-0.5, 0.5, (6, 3))
        log_s = rng.normal(size=(6, 3)) * 0.3 - 2.0
        q = rng.normal(size=(6, 4))
        c2w = C2W.astype(np.float64)
        out = _project(jnp.asarray(means), jnp.asarray(log_s), jnp.asarray(q), jnp.asarray(c2w), INTR,
                       CAM.width, CAM.height)
        view, origin = world_to_camera(jnp.asarray(c2w))

        def pixel(p):  # (u, v) of a world point
            pc = view @ (p - origin)
            return jnp.stack([CAM.fx * pc[0] / pc[2] + CAM.cx, CAM.fy * pc[1] / pc[2] + CAM.cy])

        jac = np.asarray(jax.vmap(jax.jacfwd(pixel))(jnp.asarray(means)))  # [N, 2, 3]
        sigma = np.asarray(covariance_3d(jnp.asarray(log_s), jnp.asarray(q)))
        want = jac @ sigma @ jac.transpose(0, 2, 1) + LOWPASS_DILATION * np.eye(2)
        np.testing.assert_allclose(out["cov2d"], want, rtol=1e-10)
        np.testing.assert_allclose(out["means2d"], np.asarray(jax.vmap(pixel)(jnp.asarray(means))), rtol=1e-12)
        inv = np.linalg.inv(want)
        np.testing.assert_allclose(out["conics"], np.stack([inv[:, 0, 0], inv[:, 0, 1], inv[:, 1, 1]], -1), rtol=1e-9)
        lam = np.linalg.eigvalsh(want)[:, -1]
        np.testing.assert_array_equal(out["radii"], np.ceil(3 * np.sqrt(lam)).astype(np.int32))



def test_half_resolution_with_a_quarter_of_the_dilation_is_the_full_footprint_halved():
    """Coarse to fine renders with intrinsics / 2 and dilation LOWPASS_DILATION / 4 (train.make_step's scale
    0.5): every Gaussian's screen covariance is then exactly the full-resolution one / 4 and its mean / 2, the
    same footprint in the photo's pixels; with the full dilation it would be 0.3 px^2 x 3/4 wider per axis."""
    with enable_x64(True):
        rng = np.random.default_rng(4)
        means, log_s, q = rng.uniform(-0.5, 0.5, (8, 3)), rng.normal(size=(8, 3)) * 0.5 - 3.5, rng.normal(size=(8, 4))
        args = (jnp.asarray(means), jnp.asarray(log_s), jnp.asarray(q), jnp.asarray(C2W.astype(np.float64)))
        full = project_gaussians(*args, INTR, CAM.width, CAM.height)
        half_intr, w, h = tuple(v / 2 for v in INTR), CAM.width // 2, CAM.height // 2
        half = project_gaussians(*args, half_intr, w, h, dilation=LOWPASS_DILATION / 4)
        np.testing.assert_allclose(half["cov2d"], np.asarray(full["cov2d"]) / 4, rtol=1e-10)
        np.testing.assert_allclose(half["means2d"], np.asarray(full["means2d"]) / 2, rtol=1e-12)
        eroding = project_gaussians(*args, half_intr, w, h)
        np.testing.assert_allclose(np.asarray(eroding["cov2d"]) - np.asarray(half["cov2d"]),
                                   np.broadcast_to(0.75 * LOWPASS_DILATION * np.eye(2), (8, 2, 2)), atol=1e-12)

def test_culling_behind_camera_and_outside_the_image():
    view, origin = (np.asarray(x) for x in world_to_camera(jnp.asarray(C2W)))
    to_world = lambda pc: origin + view.T @ pc  # noqa: E731  (view is a rotation)
    pts = np.array([to_world(np.array(p)) for p in [
        (0.0, 0.0, 2.0),  # in front, centre: kept
        (0.0, 0.0, -2.0),  # behind
        (0.0, 0.0, 0.005),  # in front of the eye but before the near plane
        (30.0, 0.0, 2.0),  # far right of the image
        (0.0, -30.0, 2.0),  # far above
        ((CAM.width - CAM.cx) * 2.0 / CAM.fx + 0.05, 0.0, 2.0),  # centre just right of the image, radius reaches in
    ]], np.float32)
    radii = np.asarray(project(pts, log_scales=np.full((6, 3), np.log(0.08), np.float32))["radii"])
    assert radii[0] > 0 and radii[5] > 0
    assert np.all(radii[1:5] == 0)
    out = project(pts)
    assert all(np.isfinite(np.asarray(v)).all() for v in out.values())


def test_sh_colors_use_the_encoding_basis_with_3dgs_offset():
    rng = np.random.default_rng(3)
    means = jnp.asarray(rng.normal(size=(8, 3)), jnp.float32)
    sh = jnp.asarray(rng.normal(size=(8, 16, 3)) * 0.3, jnp.float32)
    center = jnp.array([0.5, -3.0, 1.0])
    d = np.array(means - center)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    np.testing.assert_allclose(sh_colors(sh, means, center, 0), np.maximum(SH_C0 * sh[:, 0] + 0.5, 0), rtol=1e-6)
    c1 = 0.48860251190291987  # 3DGS's degree-1 terms: -C1 y sh1 + C1 z sh2 - C1 x sh3
    want1 = SH_C0 * sh[:, 0] + c1 * (-d[:, 1:2] * sh[:, 1] + d[:, 2:3] * sh[:, 2] - d[:, 0:1] * sh[:, 3]) + 0.5
    np.testing.assert_allclose(sh_colors(sh, means, center, 1), np.maximum(want1, 0), rtol=1e-5, atol=1e-6)
    want3 = np.einsum("nk,nkc->nc", np.asarray(sh_encode(jnp.asarray(d), 4)), np.asarray(sh)) + 0.5
    np.testing.assert_allclose(sh_colors(sh, means, center, 3), np.maximum(want3, 0), rtol=1e-5, atol=1e-6)


def splat_scene(seed=4, n=60):
    rng = np.random.default_rng(seed)
    return {"means": jnp.asarray(rng.uniform(-0.8, 0.8, (n, 3)), jnp.float32),
            "log_scales": jnp.asarray(np.log(0.08) + 0.3 * rng.normal(size=(n, 3)), jnp.float32),
            "quats": jnp.asarray(rng.normal(size=(n, 4)), jnp.float32),
            "sh": jnp.asarray(rng.normal(size=(n, 4, 3)) * 0.3, jnp.float32),
            "logit_opacity": jnp.asarray(rng.normal(size=n), jnp.float32)}


def render(params, backend, c2w=C2W):
    p = project_gaussians(params["means"], params["log_scales"], params["quats"], jnp.asarray(c2w), INTR,
                          CAM.width, CAM.height)
    colors = sh_colors(params["sh"], params["means"], jnp.asarray(c2w[:3, 3]), 1)
    return rasterize(p["means2d"], p["conics"], colors, jax.nn.sigmoid(params["logit_opacity"]), p["depths"],
                     p["radii"], jnp.ones(3), CAM.width, CAM.height, backend=backend)[0]


def test_end_to_end_gradients_and_an_adam_step():
    params = splat_scene()
    v, u = np.meshgrid(np.linspace(0, 1, CAM.height), np.linspace(0, 1, CAM.width), indexing="ij")
    target = jnp.asarray(np.stack([u, v, 1 - u * v], -1), jnp.float32)
    loss = lambda p, backend: jnp.mean((render(p, backend) - target) ** 2)  # noqa: E731
    value_and_grad = jax.jit(jax.value_and_grad(lambda p: loss(p, "numba")))
    value, got = value_and_grad(params)
    want = jax.jit(jax.grad(lambda p: loss(p, "reference")))(params)
    for k in params:
        scale = float(jnp.abs(want[k]).max())
        assert scale > 0, k
        np.testing.assert_allclose(got[k], want[k], rtol=0, atol=2e-5 * scale, err_msg=k)
    opt = optax.adam(1e-2)
    updates, _ = opt.update(got, opt.init(params))
    assert float(value_and_grad(optax.apply_updates(params, updates))[0]) < float(value)

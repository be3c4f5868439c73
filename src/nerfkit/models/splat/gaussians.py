"""A set of N 3D Gaussians: parameters, initialisation, and rendering through a nerfkit Camera.

Parameters (a dict of float32 arrays, the layout 3DGS optimises):

    means       [N, 3]      world-space centres mu
    log_scales  [N, 3]      s, Sigma = R(q) diag(e^{2s}) R(q)^T
    quats       [N, 4]      q = (w, x, y, z), normalised when used
    opacity     [N]         logit: o = sigmoid(opacity)
    sh_dc       [N, 1, 3]   band-0 SH coefficient of R, G, B: colour = SH_C0 sh_dc + 0.5 at degree 0
    sh_rest     [N, 15, 3]  bands 1..3 (encoding/sh.py's basis and order, the same as 3DGS's)

Initialisation follows the 3DGS code: from points with colours (an SfM cloud) with scales
s = log(mean distance to the 3 nearest neighbours), identity rotations, opacity 0.1 and
sh_dc = (rgb - 0.5) / SH_C0; without points (Blender scenes), the same from random points
in a box with random colours.

render() projects (project.py), colours by SH at the view direction, and rasterises with
an extra depth channel: rgb [H, W, 3] on the background, depth [H, W] = sum_k w_k z_k
(z-depth, not divided by alpha, as nerfkit's NeRF renders report it) and alpha [H, W].
"""

from __future__ import annotations

from functools import lru_cache, partial

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.core.metrics import psnr, ssim
from nerfkit.models.splat.backends import backend as backend_named
from nerfkit.models.splat.project import LOWPASS_DILATION, SH_C0, project_gaussians, sh_colors
from nerfkit.models.splat.rasterize import rasterize
from nerfkit.rays.correction import mean_color

SH_DEGREE = 3
N_REST = (SH_DEGREE + 1) ** 2 - 1  # 15 coefficients of bands 1..3
INIT_OPACITY = 0.1
BLENDER_BOX = 1.5  # nerfkit's Blender scenes live in [-1.5, 1.5]^3 (normalised frame)
PARAM_NAMES = ("means", "log_scales", "quats", "opacity", "sh_dc", "sh_rest")


def logit(p):
    """log(p / (1 - p)), the inverse of the sigmoid (numpy)."""
    p = np.asarray(p, np.float64)
    return np.log(p) - np.log1p(-p)


def rgb_to_sh_dc(rgb: np.ndarray) -> np.ndarray:
    """sh_dc [N, 1, 3] whose degree-0 colour SH_C0 sh_dc + 0.5 is rgb [N, 3]."""
    return ((np.asarray(rgb, np.float32) - 0.5) / SH_C0)[:, None, :]


def knn_log_scales(points: np.ndarray, k: int = 3, floor: float = 1e-7) -> np.ndarray:
    """Isotropic log scales [N, 3] = log(mean distance to the k nearest other points), as 3DGS (k = 3).

    The 3DGS code takes the square root of the mean squared distance; the mean distance is used
    here (within ~10% of it). Distances are floored at `floor` (duplicated points)."""
    from scipy.spatial import cKDTree

    points = np.asarray(points, np.float64)
    k_eff = min(k, len(points) - 1)
    if k_eff < 1:
        return np.zeros((len(points), 3), np.float32)
    dist, _ = cKDTree(points).query(points, k=k_eff + 1)  # column 0: the point itself
    mean = np.maximum(dist[:, 1:].mean(axis=1), floor)
    return np.repeat(np.log(mean)[:, None], 3, axis=1).astype(np.float32)


def init_from_points(points: np.ndarray, colors: np.ndarray, opacity: float = INIT_OPACITY) -> dict:
    """Parameters of N Gaussians at points [N, 3] with colours [N, 3] in [0, 1] (uint8 is divided by 255).

    Scales from knn_log_scales, identity rotations, opacity `opacity`, SH bands >= 1 zero."""
    points = np.asarray(points, np.float32)
    colors = np.asarray(colors)
    colors = colors / 255.0 if colors.dtype == np.uint8 else colors
    n = len(points)
    return {
        "means": points,
        "log_scales": knn_log_scales(points),
        "quats": np.tile(np.float32([1, 0, 0, 0]), (n, 1)),
        "opacity": np.full(n, logit(float(opacity)), np.float32),
        "sh_dc": rgb_to_sh_dc(colors[:, :3]),
        "sh_rest": np.zeros((n, N_REST, 3), np.float32),
    }


def init_random(n: int, box: float = BLENDER_BOX, seed: int = 0, opacity: float = INIT_OPACITY) -> dict:
    """Parameters of n Gaussians uniform in [-box, box]^3 (no SfM points), grey.

    Colours are 0.5 + SH_C0 u, u ~ U[0, 1/255) per channel: the 3DGS code's random init
    (sh_dc = u), i.e. mid-grey; random colours in [0, 1] started ~2 dB worse and took 3DGS's
    colour learning rate (2.5e-3 per step in SH units; nerfkit's is 8x that, optim.py) hundreds of
    steps to undo."""
    rng = np.random.default_rng(seed)
    points = rng.uniform(-box, box, (n, 3)).astype(np.float32)
    colors = 0.5 + SH_C0 * rng.uniform(0, 1 / 255, (n, 3))
    return init_from_points(points, colors.astype(np.float32), opacity)


def count(params: dict) -> int:
    """Number of Gaussians N."""
    return int(params["means"].shape[0])


def with_color_transform(params: dict, m: np.ndarray) -> dict:
    """The Gaussians of `params` (numpy) with every colour mapped by the affine colour transform m [3, 4]
    (rays/correction.py): c' = M c + b, M = I + m[:, :3], b = m[:, 3], for every view direction. Colours are
    linear in the SH coefficients (c = SH_C0 sh_dc + sum_k Y_k sh_rest_k + 0.5), so the map folds into them:

        sh_dc' = M sh_dc + (M 0.5 + b - 0.5) / SH_C0,    sh_rest'_k = M sh_rest_k

    and since a render is sum_i w_i c_i + (1 - alpha) background with alpha = sum_i w_i, the render of the
    folded Gaussians is correction.corrected_composite of the render (exact where no colour is clamped at 0)."""
    m = np.asarray(m, np.float32)
    mat, b = np.eye(3, dtype=np.float32) + m[:, :3], m[:, 3]
    out = dict(params)
    out["sh_dc"] = (np.asarray(params["sh_dc"], np.float32) @ mat.T + (mat @ np.full(3, 0.5, np.float32) + b - 0.5)
                    / SH_C0).astype(np.float32)
    out["sh_rest"] = (np.asarray(params["sh_rest"], np.float32) @ mat.T).astype(np.float32)
    return out


def held_out_gaussians(params: dict, aux: dict) -> dict:
    """The active Gaussians (numpy, PARAM_NAMES) as a view that is no training photo sees them: with the mean of the
    training photos' colour transforms folded in where the run learned them (--appearance; with_color_transform)."""
    active = np.asarray(aux["active"], bool)
    p = {k: np.asarray(params[k])[active] for k in PARAM_NAMES}
    return with_color_transform(p, mean_color(params["cam_color"])) if "cam_color" in params else p


def to_device(params: dict) -> dict:
    """The parameters as float32 JAX arrays."""
    return {k: jnp.asarray(params[k], jnp.float32) for k in PARAM_NAMES}


def intrinsics_of(camera) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) of a nerfkit Camera; lens-distorted cameras are refused (no splat undistortion yet)."""
    if getattr(camera, "distorted", False):
        raise ValueError(f"splat rendering supports pinhole cameras only; this camera has lens model "
                         f"{camera.model} with non-zero distortion (undistort the images first)")
    return (float(camera.fx), float(camera.fy), float(camera.cx), float(camera.cy))


def splat_inputs(params: dict, c2w, intrinsics, width: int, height: int, sh: jax.Array,
                 dilation: float = LOWPASS_DILATION):
    """Projection and SH colours of all Gaussians for one camera (the rasteriser's inputs).

    sh [N, 16, 3]: the coefficients to use (bands above the current degree zeroed by the caller);
    dilation: project.project_gaussians' low-pass floor in px^2.
    Returns (proj dict of project_gaussians, colours [N, 3], opacities [N] = sigmoid(opacity))."""
    proj = project_gaussians(params["means"], params["log_scales"], params["quats"], c2w, intrinsics, width, height,
                             dilation)
    cam_center = c2w[:3, 3]
    colors = sh_colors(sh, params["means"], cam_center, SH_DEGREE)
    return proj, colors, jax.nn.sigmoid(params["opacity"])


def all_sh(params: dict) -> jax.Array:
    """[N, 16, 3]: sh_dc and sh_rest stacked."""
    return jnp.concatenate([params["sh_dc"], params["sh_rest"]], axis=1)


def band_mask(degree) -> jax.Array:
    """[16, 1] float mask keeping SH bands 0..degree (degree may be traced): coefficient k
    (band floor(sqrt(k))) is kept iff k < (degree + 1)^2."""
    return (jnp.arange(16) < (jnp.asarray(degree) + 1) ** 2).astype(jnp.float32)[:, None]


def raster_inputs(params: dict, c2w, intrinsics, background, sh_degree, width: int, height: int, depth: bool = True,
                  dilation: float = LOWPASS_DILATION):
    """The rasteriser's arguments (means2d, conics, colours, opacities, depths, radii, background) for one view
    (jittable; width, height, depth, dilation static): splat_inputs with the bands above sh_degree zeroed and, if
    depth, a fourth colour channel z (background 0), so that the blend's fourth channel is sum_k w_k z_k."""
    fx, fy, cx, cy = (intrinsics[i] for i in range(4))
    sh = all_sh(params) * band_mask(sh_degree)
    proj, colors, opac = splat_inputs(params, c2w, (fx, fy, cx, cy), width, height, sh, dilation)
    bg = jnp.asarray(background, jnp.float32)
    if depth:
        colors = jnp.concatenate([colors, proj["depths"][:, None]], axis=-1)
        bg = jnp.concatenate([bg, jnp.zeros(1, jnp.float32)])
    return proj["means2d"], proj["conics"], colors, opac, proj["depths"], proj["radii"], bg


def render_arrays(params: dict, c2w, intrinsics, background, sh_degree, width: int, height: int,
                  backend: str = "auto", depth: bool = True, dilation: float = LOWPASS_DILATION) -> dict:
    """Render (jittable; width, height, backend, depth, dilation static; dilation: the screen floor in px^2).

    c2w [4, 4] OpenGL camera-to-world; intrinsics [4] (fx, fy, cx, cy); background [3];
    sh_degree 0..3 (may be traced). Returns rgb [H, W, 3], alpha [H, W] and, if depth,
    depth [H, W] = sum_k w_k z_k (blending weights w_k = T_k alpha_k)."""
    inputs = raster_inputs(params, c2w, intrinsics, background, sh_degree, width, height, depth, dilation)
    image, alpha = rasterize(*inputs, width, height, backend=backend)
    out = {"rgb": image[..., :3], "alpha": alpha}
    if depth:
        out["depth"] = image[..., 3]
    return out


@lru_cache(maxsize=32)
def _render_jit(width: int, height: int, backend: str, depth: bool, dilation: float):
    return jax.jit(partial(render_arrays, width=width, height=height, backend=backend, depth=depth,
                           dilation=dilation))


@lru_cache(maxsize=32)
def _inputs_jit(width: int, height: int, depth: bool, dilation: float):
    return jax.jit(partial(raster_inputs, width=width, height=height, depth=depth, dilation=dilation))


def _view_args(params: dict, c2w, camera, background, sh_degree: int) -> tuple:
    return (to_device(params), jnp.asarray(c2w, jnp.float32), jnp.asarray(intrinsics_of(camera), jnp.float32),
            jnp.asarray(background, jnp.float32), jnp.int32(sh_degree))


def render(params: dict, c2w, camera, background=(1.0, 1.0, 1.0), sh_degree: int = SH_DEGREE,
           backend: str = "auto", depth: bool = True, dilation: float = LOWPASS_DILATION) -> dict:
    """Render N Gaussians seen by a nerfkit Camera (pinhole) at pose c2w [4, 4] (OpenGL), with a screen floor of
    `dilation` px^2 (the run's --screen-dilation; project.py).

    Returns numpy rgb [H, W, 3] (on `background` [3]), depth [H, W] (sum_k w_k z_k; omitted
    when depth=False) and alpha [H, W]. One compiled function per (size, backend, depth, dilation)."""
    fn = _render_jit(int(camera.width), int(camera.height), backend, bool(depth), float(dilation))
    out = fn(*_view_args(params, c2w, camera, background, sh_degree))
    return {k: np.asarray(v) for k, v in out.items()}


def render_frame(params: dict, c2w, camera, background=(1.0, 1.0, 1.0), sh_degree: int = SH_DEGREE,
                 backend: str = "auto", depth: bool = True, dilation: float = LOWPASS_DILATION) -> dict:
    """render() for a view that is only looked at, with rgb clipped to [0, 1]: where the backend renders on the
    host (its `frame`, backends.py), the projection is jitted and the blend called directly, with no callback,
    no gradient bookkeeping and no copies of the image after (lego at 800 x 800: about a tenth of the frame);
    elsewhere render() clipped."""
    b = backend_named(backend)
    if b.frame is None:
        out = render(params, c2w, camera, background, sh_degree, backend, depth, dilation)
        return {**out, "rgb": np.clip(out["rgb"], 0.0, 1.0)}
    width, height = int(camera.width), int(camera.height)
    inputs = _inputs_jit(width, height, bool(depth), float(dilation))(*_view_args(params, c2w, camera, background,
                                                                                   sh_degree))
    rgb, extra, alpha = b.frame(*(np.asarray(a) for a in inputs), width, height)
    return {"rgb": rgb, "alpha": alpha, **({"depth": extra[..., 0]} if depth else {})}


def evaluate(params: dict, images, poses, cameras, background=(1.0, 1.0, 1.0), sh_degree: int = 3,
             backend: str = "auto", dilation: float = LOWPASS_DILATION) -> dict:
    """Render every camera (screen floor `dilation` px^2) and score it: {"psnr": [V], "ssim": [V], "psnr_mean",
    "ssim_mean"} (nerfkit.core.metrics)."""
    ps, ss = [], []
    for k, cam in enumerate(cameras):
        rgb = render_frame(params, poses[k], cam, background, sh_degree, backend, depth=False, dilation=dilation)["rgb"]
        target = np.asarray(images[k])[: cam.height, : cam.width]
        ps.append(psnr(rgb, target))
        ss.append(ssim(rgb, target))
    return {"psnr": ps, "ssim": ss, "psnr_mean": float(np.mean(ps)), "ssim_mean": float(np.mean(ss))}

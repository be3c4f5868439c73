"""3DGS-MCMC density control (Kheradmand et al. 2024): a fixed budget of Gaussians, relocation, SGLD noise.

The Gaussians are treated as samples of a distribution updated by stochastic gradient Langevin
dynamics; densification becomes moving samples, so the count never changes (static shapes here:
one compiled step for the whole run).

Noise, after every Adam step (positions only):

    mu <- mu + lambda_noise lr_mu(t) sig(1 - o) Sigma eps,   eps ~ N(0, I_3),
    sig(x) = 1 / (1 + exp(-k (x - x0))),  k = 100, x0 = 0.995,

Sigma = R S S^T R^T the Gaussian's covariance and lambda_noise = 5e5: Gaussians of opacity
below ~0.01 wander within their own shape, opaque ones stay put (sig(1 - o) < 1e-4 at o > 0.1).

Regularisers, added to the photometric loss (means over the active Gaussians i and their axes j,
as gsplat's MCMC strategy: opacities.mean() and exp(scales).mean() over all N x 3 entries):

    lambda_o mean_i o_i + lambda_Sigma mean_ij e^{s_ij},   lambda_o = lambda_Sigma = 0.01.

Relocation, every 100 steps: dead Gaussians (o <= 0.005) are moved onto live ones sampled
with probability proportional to opacity (with replacement). A source sampled m times
becomes n = m + 1 copies (itself and m dead slots), all with (paper eq. 9)

    o_new = 1 - (1 - o)^(1 / n),
    scale_new = scale * o / (sum_{i=1}^{n} sum_{k=0}^{i-1} C(i-1, k) (-1)^k o_new^(k+1) / sqrt(k+1)),

which keeps the summed contribution of the n copies at the source's to first order; other
parameters are copied. Adam's moments of all touched Gaussians are reset. Growth (MCMC's
"add 5% every 100 steps up to the cap") is the same move into slots not yet in use, so a run
can start with fewer active Gaussians than its fixed capacity.

The relocation and growth run on the host in numpy (a few ms at 100k Gaussians).
"""

from __future__ import annotations

from math import comb

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.models.splat.project import covariance_3d

NOISE_LR = 5e5
NOISE_K = 100.0
NOISE_X0 = 0.995
DEAD_OPACITY = 0.005
OPACITY_REG = 0.01
SCALE_REG = 0.01
MAX_COPIES = 51  # n is clipped here (the binomial sums lose precision beyond; the paper's table size)
_BINOM = np.array([[comb(i, k) if k <= i else 0 for k in range(MAX_COPIES)] for i in range(MAX_COPIES)], np.float64)


def noise_gate(opacity: jax.Array) -> jax.Array:
    """sig(1 - o) = 1 / (1 + exp(-k (1 - o - x0))), [N]: ~1 for dead Gaussians, ~0 for opaque ones."""
    return jax.nn.sigmoid(NOISE_K * (1.0 - opacity - NOISE_X0))


def position_noise(key, params: dict, lr_means, noise_lr: float = NOISE_LR) -> jax.Array:
    """SGLD noise [N, 3] = noise_lr lr_means sig(1 - o) Sigma eps (see module docstring); jittable."""
    eps = jax.random.normal(key, params["means"].shape, params["means"].dtype)
    cov = covariance_3d(jax.lax.stop_gradient(params["log_scales"]), jax.lax.stop_gradient(params["quats"]))
    gate = noise_gate(jax.nn.sigmoid(params["opacity"]))
    return noise_lr * lr_means * gate[:, None] * jnp.einsum("nij,nj->ni", cov, eps)


def regularizer(params: dict, opacity_reg: float = OPACITY_REG, scale_reg: float = SCALE_REG,
                active: jax.Array | None = None) -> jax.Array:
    """lambda_o mean_i(o_i) + lambda_Sigma mean_ij(e^{s_ij}) (scalar), over the slots with active [N] True
    (all when None): inactive slots get no gradient, so Adam leaves them where they are."""
    w = jnp.ones(params["opacity"].shape, jnp.float32) if active is None else active.astype(jnp.float32)
    n = jnp.maximum(jnp.sum(w), 1.0)
    return (opacity_reg * jnp.sum(w * jax.nn.sigmoid(params["opacity"])) / n
            + scale_reg * jnp.sum(w[:, None] * jnp.exp(params["log_scales"])) / (3.0 * n))


def relocation_update(opacity: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(o_new [M], scale factor [M]) for sources of opacity o [M] split into n [M] >= 1 copies (eq. 9).

    scale_new = factor * scale. n = 1 leaves both unchanged."""
    o = np.asarray(opacity, np.float64)
    n = np.clip(np.asarray(n, np.int64), 1, MAX_COPIES - 1)
    o_new = 1.0 - (1.0 - o) ** (1.0 / n)
    k = np.arange(MAX_COPIES)
    powers = o_new[:, None] ** (k + 1)[None, :] / np.sqrt(k + 1)[None, :]  # [M, K]
    signs = (-1.0) ** k
    # inner(i) = sum_k C(i-1, k) (-1)^k o_new^(k+1) / sqrt(k+1), for i = 1..MAX_COPIES-1
    inner = (_BINOM[None, : MAX_COPIES - 1, :] * (signs * powers)[:, None, :]).sum(-1)  # [M, i-1 = 0..]
    upto = np.arange(1, MAX_COPIES)[None, :] <= n[:, None]
    denom = (inner * upto).sum(-1)
    return o_new, o / denom


def _apply_copies(params: dict, src: np.ndarray, dst: np.ndarray, min_opacity: float) -> dict:
    """Copy Gaussians src [M] (repeats allowed) into slots dst [M] and apply eq. 9 to all copies and sources."""
    out = {k: np.array(v) for k, v in params.items()}
    sources, copies = np.unique(src, return_counts=True)
    o = 1.0 / (1.0 + np.exp(-out["opacity"][sources].astype(np.float64)))
    o_new, factor = relocation_update(o, copies + 1)
    o_new = np.clip(o_new, min_opacity, 1.0 - 1e-7)
    new_logit = (np.log(o_new) - np.log1p(-o_new)).astype(np.float32)
    new_log_scales = out["log_scales"][sources] + np.log(factor).astype(np.float32)[:, None]
    for k in out:
        out[k][dst] = out[k][src]
    out["opacity"][sources] = new_logit
    out["log_scales"][sources] = new_log_scales
    where = np.searchsorted(sources, src)  # each copy takes its source's new opacity and scale
    out["opacity"][dst] = new_logit[where]
    out["log_scales"][dst] = new_log_scales[where]
    return out


def sample_sources(opacity: np.ndarray, candidates: np.ndarray, num: int, rng) -> np.ndarray:
    """num indices drawn from candidates [M] with replacement, probability proportional to opacity."""
    p = np.asarray(opacity, np.float64)[candidates]
    p = p / p.sum() if p.sum() > 0 else np.full(len(candidates), 1.0 / len(candidates))
    return candidates[rng.choice(len(candidates), size=num, replace=True, p=p)]


def relocate(params: dict, active: np.ndarray, rng, min_opacity: float = DEAD_OPACITY
             ) -> tuple[dict, np.ndarray]:
    """Move the dead active Gaussians (o <= min_opacity) onto live ones (see module docstring).

    params: numpy dict; active [N] bool (slots in use). Returns (new params, touched [M] int:
    the relocated slots and their sources, whose Adam moments the caller resets). Nothing
    happens if no Gaussian is dead or none is alive."""
    o = 1.0 / (1.0 + np.exp(-np.asarray(params["opacity"], np.float64)))
    dead = np.flatnonzero(active & (o <= min_opacity))
    alive = np.flatnonzero(active & (o > min_opacity))
    if len(dead) == 0 or len(alive) == 0:
        return params, np.zeros(0, np.int64)
    src = sample_sources(o, alive, len(dead), rng)
    return _apply_copies(params, src, dead, min_opacity), np.union1d(dead, src)


def grow(params: dict, active: np.ndarray, rng, rate: float = 0.05, min_opacity: float = DEAD_OPACITY
         ) -> tuple[dict, np.ndarray, np.ndarray]:
    """Activate min(free slots, floor(rate x active)) slots as copies of live Gaussians (MCMC's growth).

    Returns (new params, new active mask, touched indices)."""
    n_active = int(active.sum())
    free = np.flatnonzero(~active)
    num = min(len(free), int(rate * n_active))
    o = 1.0 / (1.0 + np.exp(-np.asarray(params["opacity"], np.float64)))
    alive = np.flatnonzero(active & (o > min_opacity))
    if num <= 0 or len(alive) == 0:
        return params, active, np.zeros(0, np.int64)
    dst = free[:num]
    src = sample_sources(o, alive, num, rng)
    new_active = active.copy()
    new_active[dst] = True
    return _apply_copies(params, src, dst, min_opacity), new_active, np.union1d(dst, src)

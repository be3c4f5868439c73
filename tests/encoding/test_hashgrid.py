"""Exact-math tests of the multiresolution hash encoding (nerfkit.encoding.hashgrid)."""

import dataclasses
import itertools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from nerfkit.encoding import hashgrid as hg

DEFAULT = hg.HashGridConfig()
# b = 2 exactly: resolutions 16, 32, ..., 2048, so x = v / N_l and x * N_l are exact in
# float32 and vertex lookups are bit-exact. Levels 16..64 are dense, 128.. hashed.
POW2 = hg.HashGridConfig(n_levels=8, log2_table_size=19, base_resolution=16, finest_resolution=2048)
# Small grid with both dense (N <= 9) and hashed levels and a tiny table (many collisions).
SMALL = hg.HashGridConfig(
    n_levels=5, features_per_level=3, log2_table_size=10, base_resolution=4, finest_resolution=64
)


def random_tables(cfg, seed=0):
    """Tables ~ N(0, 1) (instead of U(+-1e-4)) so that errors are not hidden by scale."""
    rng = np.random.default_rng(seed)
    return {
        "tables": [
            jnp.asarray(rng.standard_normal((n, cfg.features_per_level), np.float32))
            for n in hg.level_table_sizes(cfg)
        ]
    }


# ---------------------------------------------------------------- straightforward reference
def ref_row(v, res, table_size):
    """Row of integer vertex v = (i, j, k) at a level of resolution res (pure Python ints)."""
    if (res + 1) ** 3 <= table_size:
        return v[0] + v[1] * (res + 1) + v[2] * (res + 1) ** 2
    h = (v[0] * 1) ^ (v[1] * 2654435761) ^ (v[2] * 805459861)
    return (h % 2**32) % table_size


def ref_corners(x, res, table_size):
    """[(row, weight)] of the 8 corners of point x (3 floats in [0, 1]) at one level."""
    pos = [float(np.float32(xd) * np.float32(res)) for xd in x]
    cell = [min(max(math.floor(p), 0), res - 1) for p in pos]
    frac = [p - c for p, c in zip(pos, cell)]
    out = []
    for oz, oy, ox in itertools.product((0, 1), repeat=3):  # corner order: x fastest
        o = (ox, oy, oz)
        v = [c + od for c, od in zip(cell, o)]
        w = 1.0
        for d in range(3):
            w *= frac[d] if o[d] else 1.0 - frac[d]
        out.append((ref_row(v, res, table_size), w))
    return out


def ref_encode(params, xs, cfg):
    """Per-point, per-level, per-corner loop implementation of the encoding.

    Rows and weights come from the pure-Python loops above; only the final contraction
    with the tables is a jnp op (one per level), so jax.grad of it is cheap to trace.
    """
    xs = np.asarray(xs)
    per_level = []
    for lvl, res in enumerate(hg.level_resolutions(cfg)):
        corners = [ref_corners(x, res, cfg.table_size) for x in xs]  # [n][8] (row, w)
        rows = np.array([[r for r, _ in c] for c in corners])
        w = jnp.asarray(np.array([[w for _, w in c] for c in corners]), jnp.float32)
        per_level.append(jnp.einsum("nc,ncf->nf", w, params["tables"][lvl][rows]))
    return jnp.concatenate(per_level, axis=-1)


ENC = jax.jit(hg.encode_hashgrid, static_argnums=2)
IDX = jax.jit(hg.hashgrid_indices, static_argnums=1)


# ---------------------------------------------------------------- tests
def test_level_resolutions_match_formula():
    for cfg in (DEFAULT, POW2, SMALL, dataclasses.replace(DEFAULT, n_levels=1)):
        got = hg.level_resolutions(cfg)
        n_lv = cfg.n_levels
        if n_lv == 1:
            assert got == [cfg.base_resolution]
            continue
        b = np.exp((np.log(cfg.finest_resolution) - np.log(cfg.base_resolution)) / (n_lv - 1))
        want = [int(np.floor(cfg.base_resolution * b**lv + 1e-6)) for lv in range(n_lv)]
        assert got == want
        assert got[0] == cfg.base_resolution and got[-1] == cfg.finest_resolution
    assert hg.level_resolutions(DEFAULT) == [
        16, 22, 30, 42, 58, 80, 111, 153, 212, 294, 406, 561, 776, 1072, 1482, 2048
    ]  # fmt: skip
    assert hg.level_resolutions(POW2) == [16 * 2**i for i in range(8)]


def test_table_sizes_and_init():
    sizes = hg.level_table_sizes(DEFAULT)
    assert sizes[:5] == [(r + 1) ** 3 for r in (16, 22, 30, 42, 58)]  # dense: (N+1)^3 <= 2^19
    assert sizes[5:] == [2**19] * 11  # (80 + 1)^3 > 2^19: hashed
    params = hg.init_hashgrid(jax.random.PRNGKey(0), SMALL)
    for t, n in zip(params["tables"], hg.level_table_sizes(SMALL)):
        assert t.shape == (n, 3) and t.dtype == jnp.float32
        assert float(jnp.max(jnp.abs(t))) <= 1e-4


@pytest.mark.parametrize("cfg", [DEFAULT, SMALL], ids=["default", "small"])
def test_indices_in_range_random_and_boundary(cfg):
    corners = np.array(list(itertools.product((0.0, 1.0), repeat=3)), np.float32)
    edge = np.array(
        [[1.0, 1.0 - 1e-7, 0.5], [1e-7, 0.0, 1.0], [1.0 - 6e-8, 1.0, 1.0], [-0.1, 1.2, 0.5]],
        np.float32,
    )
    rnd = np.random.default_rng(3).random((4096, 3), np.float32)
    x = jnp.asarray(np.concatenate([corners, edge, rnd]))
    idx, w = IDX(x, cfg)
    assert idx.shape == (x.shape[0], cfg.n_levels, 8) and idx.dtype == jnp.int32
    sizes = np.array(hg.level_table_sizes(cfg))[None, :, None]
    assert np.all(np.asarray(idx) >= 0) and np.all(np.asarray(idx) < sizes)
    np.testing.assert_allclose(np.asarray(w).sum(-1), 1.0, atol=1e-6)
    assert np.all(np.asarray(w) >= 0)
    # The indices equal the pure-Python reference (dense formula / uint32 hash).
    x_np = np.clip(np.asarray(x), 0, 1)
    for n in list(range(len(corners) + len(edge))) + [100, 2000]:
        for lvl, res in enumerate(hg.level_resolutions(cfg)):
            xn = x_np[n]
            rows = [r for r, _ in ref_corners(xn, res, cfg.table_size)]
            assert list(np.asarray(idx[n, lvl])) == rows


def test_exact_at_grid_vertices_pow2():
    cfg = POW2
    params = random_tables(cfg)
    rng = np.random.default_rng(0)
    f = cfg.features_per_level
    verts, xs = [], []
    for res in hg.level_resolutions(cfg):
        v = rng.integers(0, res + 1, size=(64, 3))
        v[:8] = np.array(list(itertools.product((0, res), repeat=3)))  # cube corners
        verts.append(v)
        xs.append(v / res)  # exact in float32 (res is a power of two)
    enc = np.asarray(ENC(params, jnp.asarray(np.concatenate(xs), jnp.float32), cfg))
    for lvl, (res, v) in enumerate(zip(hg.level_resolutions(cfg), verts)):
        got = enc[64 * lvl : 64 * (lvl + 1), lvl * f : (lvl + 1) * f]
        rows = [ref_row(list(vi), res, cfg.table_size) for vi in v]
        np.testing.assert_array_equal(got, np.asarray(params["tables"][lvl])[rows])


def test_vertices_default_config():
    # Non-power-of-two resolutions: x = v / N_l is rounded to float32, so x * N_l is within
    # N_l * 2^-23 ~ 2.5e-4 of v; the blend is that close to the vertex row.
    cfg = DEFAULT
    params = random_tables(cfg, seed=1)
    rng = np.random.default_rng(1)
    x_all, want = [], []
    for lvl, res in enumerate(hg.level_resolutions(cfg)):
        v = rng.integers(0, res + 1, size=(64, 3))
        x_all.append(v / res)
        want.append(
            np.asarray(params["tables"][lvl])[[ref_row(list(vi), res, cfg.table_size) for vi in v]]
        )
    enc = np.asarray(ENC(params, jnp.asarray(np.concatenate(x_all), jnp.float32), cfg))
    for lvl in range(cfg.n_levels):
        got = enc[64 * lvl : 64 * (lvl + 1), 2 * lvl : 2 * lvl + 2]
        np.testing.assert_allclose(got, want[lvl], atol=3e-3)


@pytest.mark.parametrize("cfg", [SMALL, DEFAULT], ids=["small", "default"])
def test_forward_and_table_gradient_match_loop_reference(cfg):
    params = random_tables(cfg, seed=2)
    rng = np.random.default_rng(4)
    x = rng.random((6, 3), np.float32)
    x[0] = [1.0, 0.0, 0.999999]  # boundary cells
    x = jnp.asarray(x)
    g = jnp.asarray(rng.standard_normal((6, cfg.output_dim), np.float32))

    enc = ENC(params, x, cfg)
    assert enc.shape == (6, cfg.output_dim) and enc.dtype == jnp.float32
    np.testing.assert_allclose(enc, ref_encode(params, x, cfg), rtol=1e-5, atol=1e-5)

    grad = jax.jit(jax.grad(lambda p: jnp.sum(hg.encode_hashgrid(p, x, cfg) * g)))(params)
    grad_ref = jax.grad(lambda p: jnp.sum(ref_encode(p, x, cfg) * g))(params)
    for a, b in zip(grad["tables"], grad_ref["tables"]):
        assert a.shape == b.shape
        np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6)
    assert any(float(jnp.abs(a).sum()) > 0 for a in grad["tables"])


def test_continuity():
    cfg = DEFAULT
    params = random_tables(cfg, seed=3)
    enc = ENC
    tmax = max(float(jnp.max(jnp.abs(t))) for t in params["tables"])
    res = np.repeat(np.array(hg.level_resolutions(cfg), np.float64), cfg.features_per_level)

    # Lipschitz: |d enc_l / d x_d| <= 2 N_l max|theta|, so |delta enc_l| <= 2 N_l max|theta| |dx|_1.
    rng = np.random.default_rng(6)
    x = jnp.asarray(rng.uniform(0.01, 0.99, (1024, 3)).astype(np.float32))
    dx = jnp.asarray(1e-5 * rng.standard_normal((1024, 3)).astype(np.float32))
    diff = np.abs(np.asarray(enc(params, x + dx, cfg) - enc(params, x, cfg)))
    bound = 2 * res[None] * tmax * np.abs(np.asarray(dx)).sum(-1, keepdims=True) + 1e-5
    assert np.all(diff <= bound)

    # Across a cell face of the finest level: both sides blend the same 4 face corners.
    n_f = cfg.finest_resolution
    base = rng.random((1024, 3))
    base[:, 0] = np.round(base[:, 0] * n_f) / n_f
    lo = base.copy()
    hi = base.copy()
    lo[:, 0] -= 1e-6
    hi[:, 0] += 1e-6
    diff = np.abs(np.asarray(enc(params, jnp.asarray(hi), cfg) - enc(params, jnp.asarray(lo), cfg)))
    assert np.all(diff <= 2 * res[None] * tmax * 2.2e-6 + 1e-5)
    assert diff.max() < 0.1  # a seam would give O(1) jumps with N(0, 1) tables


def test_level_weights_are_the_chance_of_staying_within_half_a_cell():
    """omega_l = erf(1 / sqrt(8 s^2 N_l^2)) = P(|z| < 1 / (2 N_l)) for z ~ N(0, s^2) (Zip-NeRF's downweighting):
    against the normal CDF, 1 for s = 0, and falling from coarse to fine levels."""
    from scipy.stats import norm

    scales = np.array([0.0, 1e-4, 1e-3, 4e-3, 2e-2], np.float32)
    w = np.asarray(hg.level_weights(jnp.asarray(scales), DEFAULT))
    res = np.asarray(hg.level_resolutions(DEFAULT), np.float64)
    for s, row in zip(scales[1:], w[1:]):
        expect = 2 * norm.cdf(1 / (2 * res * s)) - 1
        np.testing.assert_allclose(row, expect, atol=1e-6)
        assert np.all(np.diff(row) <= 1e-7)  # finer levels never weigh more
    np.testing.assert_array_equal(w[0], 1.0)
    assert w[-1, -1] < 0.02 and w[-1, 0] > 0.85  # a footprint of a third of a coarse cell: coarse level only


def test_encoding_with_footprints_scales_each_level_by_its_weight():
    params = random_tables(SMALL)
    x = jnp.asarray(np.random.default_rng(3).uniform(0, 1, (64, 3)), jnp.float32)
    scale = jnp.asarray(np.random.default_rng(4).uniform(0, 0.05, 64), jnp.float32)
    plain = np.asarray(hg.encode_hashgrid(params, x, SMALL)).reshape(64, SMALL.n_levels, -1)
    aa = np.asarray(hg.encode_hashgrid(params, x, SMALL, scale)).reshape(64, SMALL.n_levels, -1)
    w = np.asarray(hg.level_weights(scale, SMALL))
    np.testing.assert_allclose(aa, plain * w[..., None], rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(hg.encode_hashgrid(params, x, SMALL, jnp.zeros(64)), plain.reshape(64, -1))

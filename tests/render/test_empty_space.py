"""The wavefront renderer's helpers: bit masks, the empty-space distance field and its skip
(the renderer itself: tests/models/test_ngp.py)."""

import jax.numpy as jnp
import numpy as np
import pytest
import reference
from reference import image_rays

from nerfkit.rays.cameras import look_at
from nerfkit.render.empty_space import empty_distance, first_set_bits, pack_bits, skip_empty
from nerfkit.sampling import occupancy


def test_pack_bits_and_first_set_bits_match_a_direct_scan():
    rng = np.random.default_rng(0)
    k = 5
    for density in (0.0, 0.03, 0.2, 0.9):
        keep = rng.random((300, 64)) < density
        keep[0] = False
        keep[1] = True
        keep[2, :] = False
        keep[2, 63] = True  # only the last candidate
        pos, ok, rest = (np.asarray(a) for a in first_set_bits(pack_bits(jnp.asarray(keep)), k))
        for row in range(keep.shape[0]):
            want = np.flatnonzero(keep[row])
            n = min(want.size, k)
            assert ok[row].tolist() == [True] * n + [False] * (k - n)
            assert pos[row, :n].tolist() == want[:n].tolist()
            assert rest[row] == (want[k] if want.size > k else -1)


def test_pack_bits_sets_bit_b_of_word_m_for_candidate_32m_plus_b():
    keep = np.zeros((1, 64), bool)
    keep[0, [0, 5, 31, 32, 63]] = True
    words = np.asarray(pack_bits(jnp.asarray(keep)))
    assert words.dtype == np.uint32
    assert words[0, 0] == (1 | 1 << 5 | 1 << 31) and words[0, 1] == (1 | 1 << 31)


def test_empty_distance_is_the_chessboard_distance_to_the_nearest_occupied_cell():
    rng = np.random.default_rng(0)
    r = 9
    bits = rng.random(r**3) < 0.02
    got = empty_distance(bits, r).reshape(r, r, r)
    occ = np.argwhere(bits.reshape(r, r, r))
    for c in np.ndindex(r, r, r):
        assert got[c] == np.abs(occ - np.array(c)).max(axis=1).min()
    assert (empty_distance(np.zeros(r**3, bool), r) == r).all()  # nothing occupied: as far as the grid goes


@pytest.mark.parametrize("unbounded", [False, True])
def test_skip_empty_skips_only_unoccupied_candidates_and_stops_at_occupied_ones(unbounded):
    """Every candidate skipped has its midpoint in an unoccupied cell (so the same samples are shaded as
    without skipping), and the skip reaches the first occupied candidate to within the clearance's rounding."""
    bound, radius, res, steps = 1.5, 1.0, 24, 300
    cfg = occupancy.OccupancyConfig(resolution=res, bound=2.0 if unbounded else bound)
    centres = np.asarray(reference.cell_centers(cfg))
    bits = np.linalg.norm(centres - np.array([0.3, 0.0, 0.1]), axis=-1) < 0.5  # a ball in grid coordinates
    aux = {"bits": jnp.asarray(bits)}
    if unbounded:
        from nerfkit.rays.coord import contract

        to_grid, lipschitz = (lambda x: contract(x / radius)), 1.0 / radius

        def candidates(o, d, key, index):
            return occupancy.contracted_candidates(o.shape[0], 0.05, 1e3, radius, steps, key, index)
    else:
        to_grid, lipschitz = (lambda x: x), 1.0

        def candidates(o, d, key, index):
            return occupancy.box_candidates(o, d, 0.0, 1e4, bound, 2 * 3**0.5 * bound / steps, steps, key, index)

    o, d = image_rays(look_at(np.array([0.5, -3.5, 1.2]), np.array([0.3, 0.0, 0.1])), 12, 12, 20.0)
    o, d = jnp.asarray(o.reshape(-1, 3)), jnp.asarray(d.reshape(-1, 3))
    k0 = jnp.zeros(o.shape[0], jnp.int32)
    k = np.asarray(skip_empty(candidates, to_grid, cfg, jnp.asarray(empty_distance(bits, res)), lipschitz, o, d, k0))
    idx = jnp.broadcast_to(jnp.arange(steps)[None, :], (o.shape[0], steps))
    t0, t1, cand = candidates(o, d, None, idx)
    x = o[:, None, :] + (0.5 * (t0 + t1))[..., None] * d[:, None, :]
    occ = np.asarray(occupancy.query_occupancy(aux, to_grid(x.reshape(-1, 3)), cfg).reshape(x.shape[:2]) & cand)
    first = np.where(occ.any(axis=1), occ.argmax(axis=1), steps)
    assert (k <= first).all()  # nothing occupied was skipped
    hit = occ.any(axis=1)
    assert hit.sum() > 10 and (~hit).sum() > 10
    assert (k[hit] > 0.5 * first[hit]).all()  # and most of the empty run before the ball was
    assert (k[~hit] > 0).all()

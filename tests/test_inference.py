"""Bit-mask helpers of the wavefront renderer (the renderer itself: tests/test_ngp.py)."""

import jax.numpy as jnp
import numpy as np

from nerfkit.inference import first_set_bits, pack_bits


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

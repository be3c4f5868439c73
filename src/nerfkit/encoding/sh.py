"""Real spherical-harmonics encoding of view directions.

Same basis, ordering, signs and constants as the "SphericalHarmonics" encoding of
tiny-cuda-nn / Instant-NGP, for degree (number of bands) 1..5, i.e. bands l = 0..degree-1
and degree**2 outputs ordered by band l and then m = -l..l.
Difference in the input convention: tiny-cuda-nn takes directions remapped to [0, 1]^3 and
undoes it with d = 2 * in - 1; here d is the unit direction itself.

The basis is orthonormal on the unit sphere S^2:

    integral_{S^2} Y_i(d) Y_j(d) dA(d) = delta_ij,   Y_0 = 1 / (2 sqrt(pi)) = 0.28209479.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

MAX_SH_DEGREE = 5


def sh_encode(d: jax.Array, degree: int = 4) -> jax.Array:
    """Real spherical harmonics Y_k(d), k = 0 .. degree**2 - 1.

    Args:
      d: float [..., 3] unit directions (not normalised here; callers normalise).
      degree: number of SH bands, 1 <= degree <= 5 (static). degree=4 gives 16 outputs.

    Returns:
      float32 [..., degree**2].
    """
    if not 1 <= degree <= MAX_SH_DEGREE:
        raise ValueError(f"sh_encode supports degree 1..{MAX_SH_DEGREE}, got {degree}")
    d = jnp.asarray(d, jnp.float32)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    xy, xz, yz = x * y, x * z, y * z
    x2, y2, z2 = x * x, y * y, z * z

    out = [jnp.full_like(x, 0.28209479177387814)]  # 1/(2 sqrt(pi))
    if degree > 1:
        out += [
            -0.48860251190291987 * y,  # -sqrt(3) y / (2 sqrt(pi))
            0.48860251190291987 * z,  # sqrt(3) z / (2 sqrt(pi))
            -0.48860251190291987 * x,  # -sqrt(3) x / (2 sqrt(pi))
        ]
    if degree > 2:
        out += [
            1.0925484305920792 * xy,  # sqrt(15) xy / (2 sqrt(pi))
            -1.0925484305920792 * yz,  # -sqrt(15) yz / (2 sqrt(pi))
            0.94617469575755997 * z2 - 0.31539156525251999,  # sqrt(5) (3z^2 - 1) / (4 sqrt(pi))
            -1.0925484305920792 * xz,  # -sqrt(15) xz / (2 sqrt(pi))
            0.54627421529603959 * x2 - 0.54627421529603959 * y2,  # sqrt(15)(x^2-y^2)/(4 sqrt(pi))
        ]
    if degree > 3:
        out += [
            0.59004358992664352 * y * (-3.0 * x2 + y2),  # sqrt(70) y (-3x^2 + y^2) / (8 sqrt(pi))
            2.8906114426405538 * xy * z,  # sqrt(105) xyz / (2 sqrt(pi))
            0.45704579946446572 * y * (1.0 - 5.0 * z2),  # sqrt(42) y (1 - 5z^2) / (8 sqrt(pi))
            0.3731763325901154 * z * (5.0 * z2 - 3.0),  # sqrt(7) z (5z^2 - 3) / (4 sqrt(pi))
            0.45704579946446572 * x * (1.0 - 5.0 * z2),  # sqrt(42) x (1 - 5z^2) / (8 sqrt(pi))
            1.4453057213202769 * z * (x2 - y2),  # sqrt(105) z (x^2 - y^2) / (4 sqrt(pi))
            0.59004358992664352 * x * (-x2 + 3.0 * y2),  # sqrt(70) x (-x^2 + 3y^2) / (8 sqrt(pi))
        ]
    if degree > 4:
        x4, y4, z4 = x2 * x2, y2 * y2, z2 * z2
        out += [
            2.5033429417967046 * xy * (x2 - y2),  # 3 sqrt(35) xy (x^2 - y^2) / (4 sqrt(pi))
            1.7701307697799304 * yz * (-3.0 * x2 + y2),  # 3 sqrt(70) yz (-3x^2+y^2) / (8 sqrt(pi))
            0.94617469575756008 * xy * (7.0 * z2 - 1.0),  # 3 sqrt(5) xy (7z^2 - 1) / (4 sqrt(pi))
            0.66904654355728921 * yz * (3.0 - 7.0 * z2),  # 3 sqrt(10) yz (3 - 7z^2) / (8 sqrt(pi))
            -3.1735664074561294 * z2
            + 3.7024941420321507 * z4
            + 0.31735664074561293,  # 3 (35z^4 - 30z^2 + 3) / (16 sqrt(pi))
            0.66904654355728921 * xz * (3.0 - 7.0 * z2),  # 3 sqrt(10) xz (3 - 7z^2) / (8 sqrt(pi))
            0.47308734787878004 * (x2 - y2) * (7.0 * z2 - 1.0),  # 3 sqrt(5)(x^2-y^2)(7z^2-1)/(8 sqrt(pi))
            1.7701307697799304 * xz * (-x2 + 3.0 * y2),  # 3 sqrt(70) xz (-x^2+3y^2) / (8 sqrt(pi))
            -3.7550144126950569 * x2 * y2
            + 0.62583573544917614 * x4
            + 0.62583573544917614 * y4,  # 3 sqrt(35)(x^4 - 6x^2y^2 + y^4) / (16 sqrt(pi))
        ]
    return jnp.stack(out, axis=-1).astype(jnp.float32)

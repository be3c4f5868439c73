"""Speed of the multiresolution hash encoding on the local device.

Prints the median wall time of a jitted forward+backward pass, i.e.
jax.value_and_grad(lambda tables: sum(encode_hashgrid(tables, x) * g)) for 2^18 points,
at the default config and at log2_table_size 15 / 17 / 19.

    python benchmarks/hashgrid_speed.py              # per-level gathers (the implementation)
    python benchmarks/hashgrid_speed.py --compare    # also a single batched gather over a
                                                     # concatenated table, for comparison
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time

import jax
import jax.numpy as jnp
import numpy as np

from nerfkit.encoding import hashgrid as hg


def encode_single_gather(table, x, cfg):
    """Alternative layout: one concatenated table [sum rows_l, F], one gather for all levels.

    Same output as hg.encode_hashgrid; kept here only to re-measure the design choice.
    """
    offsets = np.concatenate([[0], np.cumsum(hg.level_table_sizes(cfg))[:-1]]).astype(np.int32)
    idx, w = hg.hashgrid_indices(x, cfg)  # [N, L, 8]
    gidx = idx + jnp.asarray(offsets)[:, None]
    feats = table.at[gidx].get(mode="promise_in_bounds")  # [N, L, 8, F]
    out = sum(w[:, :, k, None] * feats[:, :, k, :] for k in range(8))
    return out.reshape(x.shape[0], -1)


def median_time(fn, *args, reps):
    jax.block_until_ready(fn(*args))  # compile + warm up
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--log2-points", type=int, default=18)
    parser.add_argument("--reps", type=int, default=10)
    parser.add_argument("--compare", action="store_true")
    args = parser.parse_args()

    n = 1 << args.log2_points
    x = jax.random.uniform(jax.random.PRNGKey(1), (n, 3), jnp.float32)
    base = hg.HashGridConfig()
    configs = [("default", base)] + [
        (f"log2_table_size={t}", dataclasses.replace(base, log2_table_size=t)) for t in (15, 17, 19)
    ]
    print(f"backend={jax.default_backend()} devices={jax.devices()} points=2^{args.log2_points}")
    for name, cfg in configs:
        params = hg.init_hashgrid(jax.random.PRNGKey(0), cfg)
        g = jax.random.normal(jax.random.PRNGKey(2), (n, cfg.output_dim), jnp.float32)

        fwd_bwd = jax.jit(
            jax.value_and_grad(lambda p, x: jnp.sum(hg.encode_hashgrid(p, x, cfg) * g))
        )
        fwd = jax.jit(lambda p, x: hg.encode_hashgrid(p, x, cfg))
        t_fb = median_time(fwd_bwd, params, x, reps=args.reps)
        t_f = median_time(fwd, params, x, reps=args.reps)
        rows = sum(hg.level_table_sizes(cfg))
        print(
            f"{name:22s} rows={rows:8d}  fwd+bwd {t_fb * 1e3:8.1f} ms   fwd {t_f * 1e3:8.1f} ms"
            f"   ({n / t_fb / 1e6:.2f} Mpts/s fwd+bwd)"
        )
        if args.compare:
            table = jnp.concatenate(params["tables"], axis=0)
            fb1 = jax.jit(
                jax.value_and_grad(lambda t, x: jnp.sum(encode_single_gather(t, x, cfg) * g))
            )
            t1 = median_time(fb1, table, x, reps=args.reps)
            print(f"{'':22s} single-gather/concatenated-table variant: fwd+bwd {t1 * 1e3:8.1f} ms")


if __name__ == "__main__":
    main()

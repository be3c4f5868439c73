"""The presets `nerfkit train --preset P` starts from: a registry (PRESETS) of named Configs."""

from __future__ import annotations

from nerfkit.core.config import Config, FieldConfig, SamplerConfig, TrainConfig
from nerfkit.core.errors import ConfigError


def _seed() -> Config:
    # The reference report's Model-1: D=4, W=128, L=10/4, 64 stratified samples, near 0,
    # far 5, 1024 rays/step, lr 5e-4 * 0.1^(step/250k). (The report's seed protocol is data:
    # --train-split "train,val[0:50]" --val-split "val[50:100]" --target-width 200.)
    return Config(
        field=FieldConfig(depth=4, width=128, l_xyz=10, l_dir=4),
        sampler=SamplerConfig(n_samples=64, n_importance=0, near=0.0, far=5.0),
        train=TrainConfig(max_minutes=20.0, val_every=1000, ckpt_every=1000, val_views=4),
    )


def _nerf() -> Config:
    # Mildenhall et al. 2020, Blender scenes: D=8, W=256, 64 coarse + 128 fine samples,
    # near 2, far 6, 1024 rays, centre-crop warm-up of 500 steps, lr decay over 500k steps.
    return Config(
        field=FieldConfig(depth=8, width=256),
        sampler=SamplerConfig(n_samples=64, n_importance=128, near=2.0, far=6.0),
        train=TrainConfig(max_minutes=30.0, lr_decay_steps=500_000, precrop_steps=500, precrop_frac=0.5),
    )


def _mipnerf() -> Config:
    # Barron et al. 2021, Blender scenes: the NeRF MLP (D=8, W=256) fed integrated positional encodings
    # of conical frustums (L_xyz=16: the encoding damps the frequencies a frustum cannot resolve, so more
    # of them do no harm), queried twice, 128 coarse then 128 resampled fine samples, near 2, far 6.
    return Config(
        field=FieldConfig(kind="mip", depth=8, width=256, l_xyz=16, l_dir=4),
        sampler=SamplerConfig(n_samples=128, n_importance=128, near=2.0, far=6.0),
        train=TrainConfig(max_minutes=30.0, lr_decay_steps=500_000),
    )


def _demo() -> Config:
    # The fast field sized for the embedded procedural scene (geometry within 1.2 of the origin,
    # 256 px) so `nerfkit demo` trains, evaluates and renders in about 5 minutes on 2 CPU cores.
    cfg = _ngp()
    cfg.field.hash_log2_size = 16
    cfg.train.val_views, cfg.train.log_every, cfg.train.max_minutes = 3, 25, 3.0
    return cfg


def _tiny() -> Config:
    # Smallest sensible model: used by the test-suite and smoke tests.
    return Config(
        field=FieldConfig(depth=2, width=32, l_xyz=4, l_dir=2),
        sampler=SamplerConfig(n_samples=16, near=2.0, far=6.0),
        train=TrainConfig(
            max_steps=50, batch_rays=256, lr=5e-3, val_every=25, ckpt_every=25, val_views=1, log_every=5,
            chunk=1024,
        ),
    )


def _ngp() -> Config:
    # Instant-NGP: hash grid of 16 levels x 2 features with 2^17 rows per level (2^19 is the
    # paper's; on 2 CPU cores the encoding's forward+backward ran 1.4x faster at 2^17 in
    # benchmarks/hashgrid_speed.py), finest level 1024, a 64^3 occupancy grid (a 128^3 update
    # costs ~8x more on CPU), 512 marching steps, 2^16 samples per step. Scene box / contraction,
    # near / far and appearance embeddings come from the data (see resolve.py).
    return Config(
        field=FieldConfig(kind="ngp", hash_log2_size=17, hash_max_res=1024),
        sampler=SamplerConfig(near=None, far=None, occ_res=64, march_steps=512, max_samples=1 << 16),
        train=TrainConfig(
            max_steps=20_000, max_minutes=10.0, batch_rays=4096, lr=1e-2, lr_decay_steps=20_000, adam_b2=0.99,
            adam_eps=1e-15,
            val_every=500, ckpt_every=500, val_views=4, log_every=25, chunk=4096,
        ),
    )


def _splat() -> Config:
    # 3D Gaussian splatting (Kerbl et al. 2023) with its classic density control (3DGS-MCMC, Kheradmand et
    # al. 2024, is --strategy mcmc; lego through the CLI in 10 min: 33.09 vs 32.39 dB, 5.9 vs 4.6 steps/s):
    # 50k Gaussians at most (the CPU's budget), one training view per step, Adam with the paper's
    # per-parameter rates (splat/optim.py) and eps 1e-15. The step counters (validation, checkpoints,
    # log) count views; 20k steps is more than 10 minutes of 200 px lego on 2 cores.
    return Config(
        field=FieldConfig(kind="splat"),
        sampler=SamplerConfig(near=None, far=None),
        train=TrainConfig(max_steps=30_000, max_minutes=10.0, adam_eps=1e-15, val_every=1000, ckpt_every=1000,
                          val_views=4, log_every=50),
    )


DEFAULT_PRESET = "ngp"
PRESETS = {"seed": _seed, "nerf": _nerf, "mipnerf": _mipnerf, "ngp": _ngp, "demo": _demo, "tiny": _tiny,
           "splat": _splat}
PRESET_HELP = {
    "seed": "the reference report's Model-1 (D=4, W=128, 64 samples, near 0, far 5)",
    "nerf": "the original NeRF (D=8, W=256, 64 coarse + 128 fine, near 2, far 6)",
    "mipnerf": "mip-NeRF: cones and integrated positional encoding, anti-aliased (D=8, W=256, 128 + 128)",
    "ngp": "hash grid + occupancy grid (Instant-NGP): minutes instead of hours (the default)",
    "demo": "the fast field sized for the embedded procedural scene (nerfkit demo)",
    "tiny": "smallest model, for tests",
    "splat": "3D Gaussian splatting (up to 50k Gaussians): fast rendering, a standard .ply, a web page",
}


def set_budget(cfg: Config, max_minutes: float | None, max_steps: int | None) -> Config:
    """The budget a user gave, in place of the preset's: minutes and/or steps, whichever comes first; steps
    alone lift the preset's default time budget (None: keep the preset's value)."""
    if max_steps is not None:
        cfg.train.max_steps = int(max_steps)
        cfg.train.max_minutes = None
    if max_minutes is not None:
        cfg.train.max_minutes = float(max_minutes)
    return cfg


def preset(name: str) -> Config:
    if name not in PRESETS:
        raise ConfigError(f"unknown preset {name!r}; choose one of {', '.join(PRESETS)}")
    return PRESETS[name]()

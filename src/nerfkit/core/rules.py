"""The rules a nerfkit Config must satisfy (config.validate runs them): every value of the type its dataclass
annotates, and the ranges and combinations each setting allows. Each rule raises ConfigError naming the flag
and the fix. Rules that belong to one method live with it (its `check`, run by models/registry.check)."""

from __future__ import annotations

import dataclasses
import functools
import math
import types
import typing
from typing import Any, Literal, Union

from nerfkit.core.errors import ConfigError


def check(cfg) -> None:
    """ConfigError for the first value of cfg (a config.Config) that breaks a rule."""
    s, t, f, d = cfg.sampler, cfg.train, cfg.field, cfg.data
    _check_types(cfg)
    _check_sampling(s, f, d)
    _check_training(t)
    _check_field_sizes(f, s)
    _check_splat_and_images(cfg.splat, d)


def _matches(v: Any, tp: Any) -> bool:
    """isinstance for the annotations used in these dataclasses (int, float, bool, str, X | None, Literal)."""
    origin = typing.get_origin(tp)
    if origin is Literal:
        return v in typing.get_args(tp)
    if origin in (Union, types.UnionType):
        return any(_matches(v, a) for a in typing.get_args(tp))
    if tp is type(None):
        return v is None
    if tp is bool:
        return isinstance(v, bool)
    if tp is int:
        return isinstance(v, int) and not isinstance(v, bool)
    if tp is float:
        return isinstance(v, (int, float)) and not isinstance(v, bool)
    if origin is list:
        return isinstance(v, list) and all(_matches(x, typing.get_args(tp)[0]) for x in v)
    return isinstance(v, tp)


def _type_name(tp: Any) -> str:
    if typing.get_origin(tp) is Literal:
        return "one of " + ", ".join(map(repr, typing.get_args(tp)))
    if typing.get_origin(tp) in (Union, types.UnionType):
        return " or ".join(_type_name(a) for a in typing.get_args(tp))
    if typing.get_origin(tp) is list:
        return f"a list of {_type_name(typing.get_args(tp)[0])}"
    return "null" if tp is type(None) else tp.__name__


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    """typing.get_type_hints(cls), once per class (it compiles every annotation string)."""
    return typing.get_type_hints(cls)


def _check_types(cfg) -> None:
    for section in cfg.sections():
        obj = getattr(cfg, section)
        hints = _hints(type(obj))
        for f in dataclasses.fields(obj):
            v = getattr(obj, f.name)
            if not _matches(v, hints[f.name]):
                raise ConfigError(f"{section}.{f.name} must be {_type_name(hints[f.name])} (got {v!r}); "
                                  f"set --{f.name.replace('_', '-')}")
            if isinstance(v, float) and not math.isfinite(v):
                raise ConfigError(f"--{f.name.replace('_', '-')} must be a finite number (got {v})")


def _need(ok: bool, msg: str) -> None:
    """ConfigError(msg) unless ok."""
    if not ok:
        raise ConfigError(msg)


def _check_sampling(s, f, d) -> None:
    """The ray interval, the appearance table, the hold-out period, the sample counts and the occupancy warm-up."""
    for name in ("near", "far"):
        v = getattr(s, name)
        _need(v is None or math.isfinite(v), "--near and --far must be finite numbers")
    _need(s.near is None or s.near >= 0, f"--near must be >= 0 (got {s.near})")
    _need(s.near is None or s.far is None or s.near < s.far,
          f"--near must be smaller than --far (got near={s.near}, far={s.far})")
    _need(f.appearance_dim is None or f.appearance_dim >= 0, f"--appearance-dim must be >= 0 (got {f.appearance_dim})")
    _need(f.appearance_count >= 0, f"--appearance-count must be >= 0 (got {f.appearance_count})")
    _need(d.holdout_every >= 1, f"--holdout-every must be >= 1 (got {d.holdout_every})")
    _need(s.n_samples >= 2, f"--n-samples must be at least 2 (got {s.n_samples})")
    _need(s.n_importance >= 0, f"--n-importance must be >= 0 (got {s.n_importance})")
    _need(s.occ_warmup >= 0, f"--occ-warmup must be >= 0 (got {s.occ_warmup})")
    _need(0 < s.occ_warmup_decay < 1, f"--occ-warmup-decay must be in (0, 1) (got {s.occ_warmup_decay})")


def _check_training(t) -> None:
    """The budget, the batch, the optimiser's schedule and the loop's periods and counts."""
    _need(t.max_steps >= 0, f"--max-steps must be >= 0 (got {t.max_steps})")
    _need(t.max_minutes is None or t.max_minutes > 0, f"--max-minutes must be positive (got {t.max_minutes})")
    _need(t.batch_rays >= 1, f"--batch-rays must be >= 1 (got {t.batch_rays})")
    _need(t.lr > 0 and math.isfinite(t.lr), f"--lr must be a positive number (got {t.lr})")
    _need(t.lr_decay_steps > 0, f"--lr-decay-steps must be positive (got {t.lr_decay_steps})")
    _need(0 < t.lr_decay_rate <= 1, f"--lr-decay-rate must be in (0, 1] (got {t.lr_decay_rate})")
    _need(0 < t.precrop_frac <= 1, f"--precrop-frac must be in (0, 1] (got {t.precrop_frac})")
    _need(0 < t.val_max_fraction <= 1, f"--val-max-fraction must be in (0, 1] (got {t.val_max_fraction})")
    _need(t.precrop_steps >= 0, f"--precrop-steps must be >= 0 (got {t.precrop_steps})")
    for name in ("val_every", "ckpt_every", "log_every", "chunk", "val_views", "keep_ckpts", "max_bad_steps"):
        v = getattr(t, name)
        _need(v >= 1, f"--{name.replace('_', '-')} must be >= 1 (got {v})")
    _need(t.devices is None or t.devices >= 1, f"--devices must be >= 1 (got {t.devices})")
    _need(0 <= t.adam_b2 < 1, f"--adam-b2 must be in [0, 1) (got {t.adam_b2})")
    _need(t.adam_eps > 0, f"--adam-eps must be positive (got {t.adam_eps})")


def _check_field_sizes(f, s) -> None:
    """The MLP's sizes and frequencies (the methods check their own settings: their `check`)."""
    _need(f.depth >= 1, f"--depth must be >= 1 (got {f.depth})")
    _need(f.width >= 1, f"--width must be >= 1 (got {f.width})")
    _need(f.hidden >= 1, f"--hidden must be >= 1 (got {f.hidden})")
    _need(f.l_xyz >= 0 and f.l_dir >= 0, f"--l-xyz and --l-dir must be >= 0 (got {f.l_xyz}, {f.l_dir})")


def _check_splat_and_images(g, d) -> None:
    """The Gaussians' capacity, SH schedule and loss mix; the image size settings."""
    _need(g.capacity >= 1, f"--capacity must be >= 1 (got {g.capacity})")
    _need(0 <= g.sh_degree <= 3, f"--sh-degree must be 0, 1, 2 or 3 (got {g.sh_degree})")
    _need(g.sh_interval >= 1, f"--sh-interval must be >= 1 (got {g.sh_interval})")
    _need(g.coarse is None or 0.0 <= g.coarse < 1.0, f"--coarse must be in [0, 1): the share of the budget at half "
                                                     f"resolution (got {g.coarse})")
    _need(0 <= g.ssim_lambda <= 1, f"--ssim-lambda must be in [0, 1] (got {g.ssim_lambda})")
    _need(g.normal_consistency >= 0, f"--normal-consistency must be >= 0 (got {g.normal_consistency})")
    _need(g.depth_distortion >= 0, f"--depth-distortion must be >= 0 (got {g.depth_distortion})")
    _need(g.colour_lr is None or g.colour_lr > 0, f"--colour-lr must be > 0 (got {g.colour_lr}; unset: by the capture)")
    _need(g.colour_transform_lr > 0, f"--colour-transform-lr must be > 0 (got {g.colour_transform_lr}; default 3e-3)")
    _need(g.screen_dilation > 0, f"--screen-dilation must be > 0 px^2 (got {g.screen_dilation}; 3DGS: 0.3)")
    _need(0.0 <= g.normal_consistency_from < 1.0, f"--normal-consistency-from must be in [0, 1): the share of the "
                                                  f"budget before the term comes on (got {g.normal_consistency_from})")
    _need(d.downscale is None or d.downscale >= 1, f"--downscale must be a positive integer (got {d.downscale})")
    _need(d.target_width is None or d.target_width >= 1, f"--target-width must be positive (got {d.target_width})")
